"""Pyro guides for :func:`spcopyro.model.spcomapping_model`, fitted with ``pyro.infer.SVI``.

:class:`~spcopyro.guides.mean_field.MeanFieldGuide` is the mean-field family of
:mod:`spcopyro.variational` as a Pyro program (Dirichlet globals, per-cell categorical labels,
the model's site names), :class:`~spcopyro.guides.loss.MeanFieldELBO` the loss SVI fits it with
(globals reparameterised, labels in closed form), and :mod:`spcopyro.guides.method` the ``svi``
inference method built from the two.
"""

from spcopyro.guides.loss import MeanFieldELBO
from spcopyro.guides.mean_field import MeanFieldGuide, WrongLossError

__all__ = ["MeanFieldELBO", "MeanFieldGuide", "WrongLossError"]
