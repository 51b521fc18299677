"""The run loop: sweeps with a progress bar, a per-sweep trace, compact thinned label storage.

The kernel functions in ``sweep.py`` are pure; :func:`run_gibbs` drives them, keeping what a run
needs and no more: the log joint and the number of concepts of every sweep (8 + 8 bytes a sweep),
the final state, the state of highest log joint visited (the "MAP-visited" state), and, only if
asked, label maps every ``thin`` sweeps as int16 (2 bytes a cell). A 5000-sweep run on a
27,746-cell house thus holds a few hundred kilobytes unless label samples are requested.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from tqdm.auto import tqdm

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.anneal import annealed_config, check_anneal_sweeps
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.init import initial_state
from spcopyro.gibbs.state import GibbsState, make_sweep_plan
from spcopyro.gibbs.sweep import log_joint_constant, log_joint_variable
from spcopyro.model import ModelData

LABEL_DTYPE = torch.int16  # compact storage of label maps (L <= 32767)


def progress_enabled(progress: bool | None) -> bool:
    """Progress bars are on unless switched off, or when running under CI (``$CI`` set)."""
    if progress is None:
        return not os.environ.get("CI")
    return progress


@dataclass
class GibbsRun:
    """What :func:`run_gibbs` returns. S sweeps, N free cells."""

    final_state: GibbsState
    best_state: GibbsState
    """The visited state of highest log joint (after the annealing sweeps, if any)."""
    best_sweep: int
    """0-based sweep at which ``best_state`` was visited."""
    log_joint: np.ndarray
    """[S] float64 log joint after each sweep."""
    num_concepts: np.ndarray
    """[S] int64 concepts in use after each sweep."""
    seconds: np.ndarray
    """[S] float64 cumulative wall-clock seconds after each sweep."""
    label_samples: np.ndarray | None
    """[S', N] int16 label maps every ``thin`` sweeps (None unless ``thin`` > 0)."""
    sample_sweeps: np.ndarray | None
    """[S'] the 0-based sweeps of ``label_samples``."""


def _compact(state: GibbsState) -> GibbsState:
    return state._replace(labels=state.labels.to(LABEL_DTYPE))


def run_gibbs(
    data: ModelData,
    config: SpCoConfig,
    num_sweeps: int,
    *,
    generator: torch.Generator | None = None,
    seed: int | None = None,
    init_labels: torch.Tensor | None = None,
    thin: int = 0,
    backend: str = "auto",
    progress: bool | None = None,
    callback: Callable[[int, GibbsState], None] | None = None,
    anneal_sweeps: int = 0,
) -> GibbsRun:
    """Run ``num_sweeps`` Gibbs sweeps from ``init_labels`` (random if None).

    Args:
        generator / seed: randomness; give one (``seed`` makes a fresh generator). A seeded run
            reproduces bit for bit.
        thin: keep a label map every ``thin`` sweeps (0: keep none).
        backend: ``"torch"``, ``"numba"`` or ``"auto"`` (see :func:`sweep_function`).
        progress: tqdm bar (default: on unless ``$CI`` is set).
        callback: called as ``callback(sweep, state)`` after every sweep.
        anneal_sweeps: ramp the labels' coupling gamma up over the first ``anneal_sweeps``
            sweeps (:mod:`spcopyro.gibbs.anneal`); those sweeps are burn-in, so the best
            state is taken from sweep ``anneal_sweeps - 1`` on. The trace's log joint is always
            the target model's.
    """
    if num_sweeps < 1:
        raise ValueError(f"num_sweeps must be >= 1, got {num_sweeps}")
    if thin < 0:
        raise ValueError(f"thin must be >= 0, got {thin}")
    anneal_sweeps = check_anneal_sweeps(anneal_sweeps)
    if anneal_sweeps > num_sweeps:
        raise ValueError(
            f"anneal_sweeps ({anneal_sweeps}) must not exceed num_sweeps ({num_sweeps})"
        )
    if generator is None:
        generator = torch.Generator().manual_seed(0 if seed is None else int(seed))
    sweeper = get_backend(backend)
    plan = make_sweep_plan(data)
    state = initial_state(data, config, generator, init_labels)

    constant = float(log_joint_constant(data, config, state))
    trace_log_joint = np.empty(num_sweeps)
    trace_concepts = np.empty(num_sweeps, dtype=np.int64)
    trace_seconds = np.empty(num_sweeps)
    samples: list[np.ndarray] = []
    sample_sweeps: list[int] = []
    best_value, best_state, best_sweep = -np.inf, _compact(state), -1

    start = time.perf_counter()
    bar = tqdm(range(num_sweeps), desc="Gibbs sweeps", disable=not progress_enabled(progress))
    for sweep in bar:
        sweep_config = annealed_config(config, sweep, anneal_sweeps)
        state = sweeper.sweep(state, data, sweep_config, generator, plan)
        label_counts = torch.bincount(state.labels, minlength=config.num_concepts)  # [L]
        agreements = sweeper.potts_agreements(state.labels, data.pairs)
        value = constant + float(log_joint_variable(state, data, config, label_counts, agreements))
        trace_log_joint[sweep] = value
        trace_concepts[sweep] = int((label_counts > 0).sum())
        trace_seconds[sweep] = time.perf_counter() - start
        if value > best_value and sweep + 1 >= anneal_sweeps:
            best_value, best_state, best_sweep = value, _compact(state), sweep
        if thin and (sweep + 1) % thin == 0:
            samples.append(state.labels.to(LABEL_DTYPE).numpy().copy())
            sample_sweeps.append(sweep)
        if callback is not None:
            callback(sweep, state)
        if sweep % 50 == 0:
            bar.set_postfix(log_joint=f"{value:.4g}", concepts=int(trace_concepts[sweep]))
    bar.close()

    return GibbsRun(
        final_state=state,
        best_state=best_state._replace(labels=best_state.labels.to(torch.long)),
        best_sweep=best_sweep,
        log_joint=trace_log_joint,
        num_concepts=trace_concepts,
        seconds=trace_seconds,
        label_samples=np.stack(samples) if samples else None,
        sample_sweeps=np.asarray(sample_sweeps, dtype=np.int64) if samples else None,
    )
