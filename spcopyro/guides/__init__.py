"""Variational inference for SpCoMapping, as :mod:`spcopyro.gibbs` holds the sampler.

Mean-field coordinate ascent (CAVI: :mod:`~spcopyro.guides.cavi`, its compiled backend
:mod:`~spcopyro.guides.numba_cavi`, the ``cavi`` method :mod:`~spcopyro.guides.cavi_method`),
loopy belief propagation (:mod:`~spcopyro.guides.lbp`), memoized block-coordinate VI
(:mod:`~spcopyro.guides.memoized`), VI then Gibbs (:mod:`~spcopyro.guides.vi_gibbs`), their
options, and exact-enumeration oracles for tests (:mod:`~spcopyro.guides.testing`). Each method
is a state NamedTuple with an ``init`` and a ``step`` (as :mod:`spcopyro.gibbs.sampler`), run by
the shared driver :func:`spcopyro.inference.driver.drive`.

The Pyro guide for :func:`spcopyro.model.spcomapping_model`, fitted with ``pyro.infer.SVI``:
:class:`~spcopyro.guides.mean_field.MeanFieldGuide` is the mean-field family as a Pyro program
(Dirichlet globals, per-cell categorical labels,
the model's site names), :class:`~spcopyro.guides.loss.MeanFieldELBO` the loss SVI fits it with
(globals reparameterised, labels in closed form), and :mod:`spcopyro.guides.svi_method` the ``svi``
inference method built from the two.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from spcopyro._util.lazy import lazy_names

if TYPE_CHECKING:  # pragma: no cover
    from spcopyro.guides.loss import MeanFieldELBO
    from spcopyro.guides.mean_field import MeanFieldGuide, WrongLossError

__all__ = ["MeanFieldELBO", "MeanFieldGuide", "WrongLossError"]


_HOMES = {"MeanFieldELBO": "loss", "MeanFieldGuide": "mean_field", "WrongLossError": "mean_field"}
"""The Pyro guide's names and the module (of this package) that defines each: imported when first
asked for, since Pyro (about 200 modules) is imported by neither the other methods' modules nor a
Gibbs fit's checkpoint code."""

__getattr__, __dir__ = lazy_names(__name__, _HOMES)
