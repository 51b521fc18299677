r"""Annealing of the Potts coupling gamma during burn-in (an option of the stability study, #4).

With ``A`` annealing sweeps, sweep ``s`` (0-based) of a run updates the labels under the coupling
of :func:`spcopyro.inference.schedule.annealed_gamma`, the schedule every inference method uses

.. math::

    \gamma_s = \gamma \, \min\!\left(1, \frac{s + 1}{A}\right),

so the first sweeps see an almost free field (the words and images place the labels, eqs. 13-15
with a weak MRF term), and from sweep ``A - 1`` on the chain runs the target model's kernel. The
annealed sweeps are burn-in: they are Gibbs sweeps of *other* models (coupling
:math:`\gamma_s < \gamma`), so only the sweeps from ``A - 1`` on are draws of the target chain.
Everything else (pi, theta, w, and the log joint recorded in the trace) uses the target
configuration throughout.

The motivation is the paper's open problem: with a strong coupling from the first sweep, regions
freeze around whatever the random start or the first few observations suggest. Whether annealing
helps is measured, not assumed: see the stability study, :mod:`spcopyro.study.robustness`.
"""

from __future__ import annotations

from spcopyro.config import SpCoConfig
from spcopyro.inference.schedule import annealed_gamma, check_anneal_steps

__all__ = ["annealed_config", "annealed_gamma", "check_anneal_sweeps"]


def check_anneal_sweeps(anneal_sweeps: int) -> int:
    """``anneal_sweeps`` as an int, or ValueError if it is not a non-negative integer."""
    return check_anneal_steps(anneal_sweeps, "anneal_sweeps")


def annealed_config(config: SpCoConfig, sweep: int, anneal_sweeps: int) -> SpCoConfig:
    """``config`` with gamma replaced by :func:`annealed_gamma` (``config`` itself once the
    annealing is over)."""
    gamma = annealed_gamma(config.gamma, sweep, anneal_sweeps)
    return config if gamma == config.gamma else config.replace(gamma=gamma)
