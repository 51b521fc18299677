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

if TYPE_CHECKING:  # pragma: no cover
    from spcopyro.guides.loss import MeanFieldELBO
    from spcopyro.guides.mean_field import MeanFieldGuide, WrongLossError

__all__ = ["MeanFieldELBO", "MeanFieldGuide", "WrongLossError"]


def __getattr__(name: str) -> object:
    """The Pyro guide's names, imported when first asked for: Pyro (about 200 modules) is not
    imported by the other methods' modules, nor by a Gibbs fit's checkpoint code."""
    if name == "MeanFieldELBO":
        from spcopyro.guides.loss import MeanFieldELBO

        return MeanFieldELBO
    if name in ("MeanFieldGuide", "WrongLossError"):
        from spcopyro.guides import mean_field

        return getattr(mean_field, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
