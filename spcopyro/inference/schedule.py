r"""The annealing schedule and the stopping rule, one definition for every inference method.

**Annealing.** With ``A`` annealing iterations, iteration ``s`` (0-based: a Gibbs sweep, a CAVI or
LBP iteration, a pass of memoized VI, an SVI step) uses the Potts coupling

.. math::

    \gamma_s = \gamma \, \min\!\left(1, \frac{s + 1}{A}\right),

so the first iterations see an almost free field (the observations place the labels) and from
iteration ``A - 1`` on the method runs at the model's gamma. ``A = 0`` is no annealing.

**Convergence.** An iterative variational method stops once its objective (the ELBO, or the
Bethe objective) settles at the model's coupling: with window ``w`` (1 for the exact
objectives of CAVI, LBP and memoized VI; more for SVI's noisy estimate), after iteration ``t``
when the last ``2 w`` iterations all ran at full gamma and

.. math::

    \left|\bar f_{t-w+1..t} - \bar f_{t-2w+1..t-w}\right| < \mathrm{tol}\,|\bar f_{t-w+1..t}|,

the means of the objective over the last window and the one before. ``tol = 0`` never stops.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
from collections.abc import Iterator, Sequence

import numpy as np

from spcopyro._util.context import set_within

logger = logging.getLogger("spcopyro")


def check_anneal_steps(anneal_steps: int, name: str = "anneal_sweeps") -> int:
    """``anneal_steps`` as an int, or ValueError (naming ``name``) if it is not a non-negative
    integer."""
    bad = ValueError(f"{name} must be a non-negative integer, got {anneal_steps!r}")
    try:  # int() of inf, nan, None or a string raised an error that named neither
        whole = int(anneal_steps)
    except (TypeError, ValueError, OverflowError):
        raise bad from None
    if isinstance(anneal_steps, bool) or whole != anneal_steps or anneal_steps < 0:
        raise bad
    return whole


_SHORT_RUNS_MEANT: contextvars.ContextVar[bool] = contextvars.ContextVar(
    "short_runs_meant", default=False
)


@contextlib.contextmanager
def short_runs_meant() -> Iterator[None]:
    """Within the block, :func:`warn_unfinished_annealing` says nothing: for runs cut short on
    purpose (the inference comparison's re-runs at n/2, n/4, ... of a budget that does cover
    the annealing)."""
    with set_within(_SHORT_RUNS_MEANT, True):
        yield


def short_runs_meant_now() -> bool:
    """Whether the caller runs inside :func:`short_runs_meant` (warnings about a run's end
    state, which a run cut short on purpose has not reached, are left out there too)."""
    return _SHORT_RUNS_MEANT.get()


def warn_unfinished_annealing(
    anneal: int,
    iterations: int,
    option: str,
    unit: str,
    resume: object | None = None,
    length: str | None = None,
) -> bool:
    """Warn (logger ``"spcopyro"``) when a run of ``iterations`` more iterations (after those of
    ``resume``, the record a resumed run continues: its ``objective``) stops before its
    annealing (``anneal`` iterations, the option ``option``) ends: gamma never reaches the
    model's value, so the fit is of a weaker coupling. ``length``: the option that sets the run's
    length, where it is not --sweeps (vi-gibbs's ``vi_iterations``). Returns whether it warned
    (never inside :func:`short_runs_meant`)."""
    iterations += 0 if resume is None else len(resume.objective)  # type: ignore[attr-defined]
    if anneal <= iterations or _SHORT_RUNS_MEANT.get():
        return False
    units = f"{unit}es" if unit.endswith("s") else f"{unit}s"
    longer = f"set {length}={anneal} or more" if length else f"run at least {anneal} {units}"
    logger.warning(
        "gamma is annealed over %d %s (%s) but the run has %d: it ends at %.0f%% of the "
        "model's gamma; %s, or set %s=%d or less",
        anneal, units, option, iterations, 100.0 * iterations / anneal, longer, option,
        iterations,
    )  # fmt: skip
    return True


def annealed_gamma(gamma: float, step: int, anneal_steps: int) -> float:
    """The coupling of 0-based iteration ``step``: ``gamma * min(1, (step + 1) / anneal_steps)``
    (``gamma`` itself when ``anneal_steps`` is 0)."""
    if anneal_steps <= 0 or step + 1 >= anneal_steps:
        return float(gamma)
    return float(gamma) * (step + 1) / anneal_steps


def converged(
    values: Sequence[float],
    gammas: Sequence[float],
    gamma: float,
    tolerance: float,
    window: int = 1,
) -> bool:
    """Whether the objective ``values`` (one per iteration, run at couplings ``gammas``) has
    settled at the model's ``gamma`` (module docstring; ``tolerance`` <= 0: never)."""
    if tolerance <= 0 or len(values) < 2 * window:
        return False
    if any(g != gamma for g in gammas[-2 * window :]):
        return False
    last = float(np.mean(values[-window:]))
    before = float(np.mean(values[-2 * window : -window]))
    return abs(last - before) < tolerance * abs(last)
