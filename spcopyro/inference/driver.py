"""The one run loop of inference: the Gibbs sampler's sweeps (:func:`spcopyro.gibbs.run.advance`)
and the iterations of CAVI (both backends), loopy BP, memoized VI and SVI.

Each method is two functions in BlackJAX's shape: ``init`` makes a state NamedTuple, and
``step(state, gamma)`` (the method's other arguments bound) does one iteration at coupling
``gamma`` and returns the new state and an info NamedTuple with at least ``objective`` (the value
traced: the log joint, the ELBO, or the Bethe objective), ``num_concepts`` (concepts in use) and
``gamma``. :func:`drive` runs ``step`` and owns everything around it, the same way for every
method:

* the annealing schedule (:func:`spcopyro.inference.schedule.annealed_gamma`), numbered from
  ``first`` so a continued run goes on with it;
* the trace (objective, concepts in use, cumulative seconds, coupling per iteration);
* the stop: at convergence (:func:`spcopyro.inference.schedule.converged`) or at the ceiling of
  ``iterations``, and why, in words (:attr:`Trajectory.stop_reason`);
* thinning: the labels every ``thin`` iterations, int16 as Gibbs' label maps;
* the progress bar, and a per-iteration ``callback``;
* Ctrl-C: a :class:`KeyboardInterrupt` during an iteration or its callback is raised again as
  :class:`DriveInterrupted` (still a KeyboardInterrupt, so code unaware of it stops) carrying
  the :class:`Trajectory` of the iterations completed before it (an interrupt in a callback
  comes after its iteration was recorded, which is kept), as is the ``SystemError`` a numba
  call ends with when the interrupt lands inside it
  (:func:`spcopyro._util.interrupts.caused_by_interrupt`). Its ``state`` is the last completed
  iteration's; a method that updates its state in place (the compiled CAVI backend, memoized
  VI, SVI's parameters) hands back the object the interrupted iteration was changing, a valid q
  part-way through that iteration, and the Gibbs chain undoes its cut-short sweep itself.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar

import numpy as np
import torch

from spcopyro._util.interrupts import caused_by_interrupt
from spcopyro._util.messages import plural
from spcopyro._util.number_checks import is_integer
from spcopyro._util.progress import noted_bar, progress_enabled, staged
from spcopyro.inference.schedule import annealed_gamma, converged


class StepInfo(Protocol):
    """What :func:`drive` reads from a method's info NamedTuple."""

    objective: float
    num_concepts: int
    gamma: float


StateT = TypeVar("StateT")
Step = Callable[[StateT, float], tuple[StateT, StepInfo]]
"""``step(state, gamma) -> (state, info)``: one iteration of a method at coupling ``gamma``."""


@dataclass
class Trajectory(Generic[StateT]):
    """What :func:`drive` returns. S iterations ran."""

    state: StateT
    """The state after the last iteration."""
    objective: np.ndarray
    """[S] float64 the objective after each iteration."""
    num_concepts: np.ndarray
    """[S] int64 concepts in use after each iteration."""
    seconds: np.ndarray
    """[S] float64 cumulative wall-clock seconds."""
    gammas: np.ndarray
    """[S] float64 the coupling of each iteration."""
    label_samples: np.ndarray | None
    """[S', N] int16 (int32 when L > 32768) argmax labels every ``thin`` iterations, or None."""
    sample_iterations: np.ndarray | None
    """[S'] the 0-based iterations of ``label_samples``."""
    stop_reason: str
    """Why the run stopped, in words: converged (the tolerance met), the ceiling of iterations,
    or interrupted."""
    converged: bool = False


class DriveInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped :func:`drive`; ``trajectory`` holds the iterations completed before it
    (and those of the run it resumed), ``marginals`` the ``[N, L]`` q(C) its state holds where
    the method hands one to :func:`drive` (what a variational checkpoint keeps), else None.
    ``progress``: how far the fit got, in words, where a method of several runs says it better
    than "k of n iterations" of the fit's own count (vi-gibbs: its CAVI start, then its sweeps);
    None by default."""

    def __init__(self, trajectory: Trajectory, marginals: torch.Tensor | None = None) -> None:
        super().__init__(trajectory.stop_reason)
        self.trajectory, self.marginals = trajectory, marginals
        self.progress: str | None = None


def label_storage(num_concepts: int) -> type:
    """The compact dtype of label maps in [0, L): int16 when L <= 32768, else int32."""
    return np.int16 if num_concepts <= np.iinfo(np.int16).max + 1 else np.int32


def drive(
    state: StateT,
    step: Step,
    iterations: int,
    *,
    gamma: float,
    anneal: int = 0,
    first: int = 0,
    tolerance: float = 0.0,
    window: int = 1,
    thin: int = 0,
    labels: Callable[[StateT], torch.Tensor] | None = None,
    num_concepts: int = 0,
    progress: bool | None = None,
    description: str = "VI",
    unit: str = "it",
    callback: Callable[[int, StateT], None] | None = None,
    resume: Trajectory | None = None,
    marginals: Callable[[StateT], torch.Tensor] | None = None,
    first_note: str | None = None,
) -> Trajectory[StateT]:
    """Run ``step`` from ``state`` for at most ``iterations`` iterations (module docstring).

    Args:
        gamma: the model's coupling; iteration ``s`` runs at ``annealed_gamma(gamma, s, anneal)``.
        anneal: annealing iterations (0: none).
        first: the number of the first iteration: a run continued from an earlier one (a Gibbs
            chain resumed) goes on with its schedule, thinning and callback numbers.
        tolerance, window: the stopping rule of :func:`~spcopyro.inference.schedule.converged`
            (``tolerance`` 0: run every iteration).
        thin: keep ``labels(state)`` ``[N]`` after iteration ``s`` when ``(s + 1) % thin == 0``
            (0: none); ``labels`` is required then, and ``num_concepts`` (L) picks the dtype.
        callback: called as ``callback(iteration, state)`` after every iteration is recorded;
            a Ctrl-C in it keeps that iteration.
        resume: the record of an earlier run that ``state`` continues (a variational
            checkpoint's): its iterations come first in the returned record, the new ones are
            numbered on from them (``first``), their seconds added to its last, and the stopping
            rule sees both.
        first_note: shown beside ``description`` on the progress bar over the first
            iterations, which compile code, with no rate or time left until they are done (their
            time is not the run's pace: :func:`~spcopyro._util.progress.noted_updates`).
        marginals: ``marginals(state)`` ``[N, L]``, the q(C) a Ctrl-C hands back in
            :class:`DriveInterrupted` (None: none).
    """
    if not is_integer(iterations) or iterations < 1:
        raise ValueError(f"iterations must be an integer >= 1, got {iterations!r}")
    if not is_integer(thin) or thin < 0:
        raise ValueError(f"thin must be an integer >= 0, got {thin!r}")
    if thin and labels is None:
        raise ValueError("thin > 0 needs labels(state) to keep")
    dtype = label_storage(num_concepts)
    # One row per completed iteration, appended in one operation, so a Ctrl-C anywhere leaves
    # whole rows: (objective, concepts in use, coupling, cumulative seconds).
    rows: list[tuple[float, int, float, float]] = []
    samples: list[np.ndarray] = []  # [N] each, the maps kept (appended before their row)
    sampled: list[int] = []
    recorded = state  # the state of the last completed iteration
    offset = 0.0  # the seconds of the run resumed
    if resume is not None:
        rows += zip(resume.objective.tolist(), resume.num_concepts.tolist(),
                    resume.gammas.tolist(), resume.seconds.tolist(), strict=True)  # fmt: skip
        if resume.label_samples is not None:
            samples += list(resume.label_samples)
            sampled += resume.sample_iterations.tolist()
        first, offset = len(rows), (rows[-1][3] if rows else 0.0)
    begun = len(rows)

    def trajectory(reason: str, done: bool = False) -> Trajectory[StateT]:
        table = np.asarray(rows, dtype=np.float64).reshape(len(rows), 4)  # [S, 4]
        kept = sum(1 for s in sampled if s < first - begun + len(rows))  # of completed iterations
        return Trajectory(
            recorded, table[:, 0], table[:, 1].astype(np.int64), table[:, 3], table[:, 2],
            np.stack(samples[:kept]) if kept else None,
            np.asarray(sampled[:kept], dtype=np.int64) if kept else None, reason, done,
        )  # fmt: skip

    def settled() -> bool:
        last = rows[-2 * window :]
        return converged([r[0] for r in last], [r[2] for r in last], gamma, tolerance, window)

    start = time.perf_counter()
    description = staged(description)  # a refined fit's stage: "Gibbs sweeps (model grid)"
    disable = not progress_enabled(progress)
    bar, update = noted_bar(iterations, description, first_note, unit, disable)
    with bar:
        try:
            for iteration in range(first, first + iterations):
                state, info = step(state, annealed_gamma(gamma, iteration, anneal))
                if thin and (iteration + 1) % thin == 0:
                    samples.append(labels(state).numpy().astype(dtype))
                    sampled.append(iteration)
                row = (float(info.objective), int(info.num_concepts), float(info.gamma),
                       offset + time.perf_counter() - start)  # fmt: skip
                rows.append(row)
                recorded = state
                if callback is not None:
                    callback(iteration, state)
                bar.set_postfix(objective=f"{row[0]:.6g}", concepts=row[1], refresh=False)
                update(1)
                if converged_now := settled():
                    break
        except (KeyboardInterrupt, SystemError) as error:
            if not caused_by_interrupt(error):  # a SystemError of its own
                raise
            reason = f"interrupted (Ctrl-C) after {plural(len(rows), 'iteration')}"
            held = None if marginals is None else marginals(recorded)
            raise DriveInterrupted(trajectory(reason), held) from None
    if converged_now:
        return trajectory(
            f"converged after {plural(len(rows), 'iteration')}: the objective changed by less than "
            f"tolerance {tolerance:g} x |objective|",
            done=True,
        )
    asked = "the 1 iteration" if len(rows) == 1 else f"the {len(rows)} iterations"
    reason = f"ran {asked} asked for (not converged within " + ("it" if len(rows) == 1 else "them")
    reason += f" at tolerance {tolerance:g})" if tolerance else ")"
    return trajectory(reason)
