"""The run loop of the iterative variational methods: one driver for CAVI (both backends), loopy
BP, memoized VI and SVI.

Each method is two functions in BlackJAX's shape, as the Gibbs sampler is
(:mod:`spcopyro.gibbs.sampler`): ``init`` makes a state NamedTuple, and ``step(state, gamma)``
(the method's other arguments bound) does one iteration at coupling ``gamma`` and returns the
new state and an info NamedTuple with at least ``objective`` (the value traced: the ELBO, or the
Bethe objective), ``num_concepts`` (concepts that are some cell's most probable one) and
``gamma``. :func:`drive` runs ``step`` and owns everything around it, the same way for every
method:

* the annealing schedule (:func:`spcopyro.inference.schedule.annealed_gamma`, Gibbs' too);
* the trace (objective, concepts in use, cumulative seconds, coupling per iteration);
* the stop: at convergence (:func:`spcopyro.inference.schedule.converged`) or at the ceiling of
  ``iterations``, and why, in words (:attr:`Trajectory.stop_reason`);
* thinning: the argmax labels every ``thin`` iterations, int16 as Gibbs' label maps;
* the progress bar, and a per-iteration ``callback``;
* Ctrl-C: a :class:`KeyboardInterrupt` during an iteration is raised again as
  :class:`DriveInterrupted` (still a KeyboardInterrupt, so code unaware of it stops) carrying
  the :class:`Trajectory` of the iterations completed before it. Several methods update their
  state in place (the compiled CAVI backend, memoized VI, SVI's parameters), so its ``state`` is
  the one the interrupted iteration left: a valid q, part-way through that iteration.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar

import numpy as np
import torch
from tqdm.auto import tqdm

from spcopyro._util.progress import progress_enabled
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
    """[S', N] int16 (int32 when L > 32767) argmax labels every ``thin`` iterations, or None."""
    sample_iterations: np.ndarray | None
    """[S'] the 0-based iterations of ``label_samples``."""
    stop_reason: str
    """Why the run stopped, in words: converged (the tolerance met), the ceiling of iterations,
    or interrupted."""
    converged: bool = False


class DriveInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped :func:`drive`; ``trajectory`` holds the iterations completed before it."""

    def __init__(self, trajectory: Trajectory) -> None:
        super().__init__(trajectory.stop_reason)
        self.trajectory = trajectory


def label_storage(num_concepts: int) -> type:
    """The compact dtype of label maps in [0, L): int16 when L <= 32767, else int32."""
    return np.int16 if num_concepts <= np.iinfo(np.int16).max else np.int32


def drive(
    state: StateT,
    step: Step,
    iterations: int,
    *,
    gamma: float,
    anneal: int = 0,
    tolerance: float = 0.0,
    window: int = 1,
    thin: int = 0,
    labels: Callable[[StateT], torch.Tensor] | None = None,
    num_concepts: int = 0,
    progress: bool | None = None,
    description: str = "VI",
    unit: str = "it",
    callback: Callable[[int, StateT], None] | None = None,
) -> Trajectory[StateT]:
    """Run ``step`` from ``state`` for at most ``iterations`` iterations (module docstring).

    Args:
        gamma: the model's coupling; iteration ``s`` runs at ``annealed_gamma(gamma, s, anneal)``.
        anneal: annealing iterations (0: none).
        tolerance, window: the stopping rule of :func:`~spcopyro.inference.schedule.converged`
            (``tolerance`` 0: run every iteration).
        thin: keep ``labels(state)`` ``[N]`` every ``thin`` iterations (0: none); ``labels`` is
            required then, and ``num_concepts`` (L) picks the storage dtype.
        callback: called as ``callback(iteration, state)`` after every iteration (0-based).
    """
    if not isinstance(iterations, (int, np.integer)) or iterations < 1:
        raise ValueError(f"iterations must be an integer >= 1, got {iterations!r}")
    if not isinstance(thin, (int, np.integer)) or isinstance(thin, bool) or thin < 0:
        raise ValueError(f"thin must be an integer >= 0, got {thin!r}")
    if thin and labels is None:
        raise ValueError("thin > 0 needs labels(state) to keep")
    dtype = label_storage(num_concepts)
    values: list[float] = []
    used: list[int] = []
    seconds: list[float] = []
    gammas: list[float] = []
    samples: list[np.ndarray] = []
    sampled: list[int] = []

    def trajectory(reason: str, done: bool = False) -> Trajectory[StateT]:
        return Trajectory(
            state, np.asarray(values, dtype=np.float64), np.asarray(used, dtype=np.int64),
            np.asarray(seconds, dtype=np.float64), np.asarray(gammas, dtype=np.float64),
            np.stack(samples) if samples else None,
            np.asarray(sampled, dtype=np.int64) if samples else None, reason, done,
        )  # fmt: skip

    start = time.perf_counter()
    bar = tqdm(total=iterations, desc=description, unit=unit,
               disable=not progress_enabled(progress))  # fmt: skip
    with bar:
        for iteration in range(iterations):
            coupling = annealed_gamma(gamma, iteration, anneal)
            try:
                state, info = step(state, coupling)
            except KeyboardInterrupt:
                reason = f"interrupted (Ctrl-C) after {iteration} iterations"
                raise DriveInterrupted(trajectory(reason)) from None
            values.append(float(info.objective))
            used.append(int(info.num_concepts))
            gammas.append(float(info.gamma))
            if thin and (iteration + 1) % thin == 0:
                samples.append(labels(state).numpy().astype(dtype))
                sampled.append(iteration)
            seconds.append(time.perf_counter() - start)
            if callback is not None:
                callback(iteration, state)
            bar.update()
            bar.set_postfix(objective=f"{values[-1]:.6g}", concepts=used[-1])
            if converged(values, gammas, gamma, tolerance, window):
                return trajectory(
                    f"converged after {iteration + 1} iterations: the objective changed by less "
                    f"than tolerance {tolerance:g} x |objective|",
                    done=True,
                )
    reason = f"ran the {iterations} iterations asked for (not converged within them"
    reason += f" at tolerance {tolerance:g})" if tolerance else ")"
    return trajectory(reason)
