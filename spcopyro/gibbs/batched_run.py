"""K Gibbs chains run in lock step on a device (:mod:`spcopyro.gibbs.batched`), recorded as
:func:`~spcopyro.gibbs.run.run_gibbs` records one chain: :func:`run_batched_chains` returns one
:class:`~spcopyro.gibbs.run.GibbsRun` per seed, so what a fit does after its sweeps (label
frequencies, the point estimate, posterior means) can take them as they are.

Chain k starts where :func:`~spcopyro.gibbs.run.start_chain` with seed k starts (its labels and
globals drawn on the CPU from that seed's generator); its sweeps then draw from the device's
generator (seeded from the first seed), so they are not the CPU chain's sweeps, only the same
distribution. The record is kept on the device and read back once at the end: per sweep the log
joint (:func:`~spcopyro.gibbs.batched.trace_batched` plus the state-independent constant, in
float64 whatever the state's dtype: the two are about +-2e7 under original-code, where float32
steps by 2 nats) and the concepts in use; each chain's best visited state, kept by a
``torch.where`` over the batch; the label maps every ``thin`` sweeps. On a GPU each sweep ends
with one synchronisation, for its wall-clock time. Not composed here (ValueError): annealing,
cluster, merge and region moves, hyperparameter sampling (:func:`spcopyro.gibbs.sampler.step`'s
moves); Ctrl-C is not caught (no checkpoint).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
import torch

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.batched import (
    BatchedState,
    gibbs_sweep_batched,
    make_batched_plan,
    stack_states,
    trace_batched,
)
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import GibbsRun, NonFiniteLogJointError, label_dtype
from spcopyro.gibbs.sampler import init
from spcopyro.likelihood import log_joint_constant
from spcopyro.model import DTYPE, ModelData

BACKEND_NAME = "batched"


def check_batched_options(options: GibbsOptions) -> None:
    """ValueError naming each option the batched chains cannot compose with their sweeps."""
    unsupported = [
        name
        for name, active in (
            ("anneal_sweeps", options.anneal_sweeps > 0),
            ("cluster_moves", options.cluster_moves > 0),
            ("merge_moves", options.merge_moves > 0),
            ("region_moves", options.region_moves > 0),
            ("hyper", options.hyper.active),
        )
        if active
    ]
    if unsupported:
        raise ValueError(
            f"batched chains run Algorithm 1's sweeps only; switch off {', '.join(unsupported)}"
        )


def start_states(data: ModelData, config: SpCoConfig, seeds: Sequence[int]) -> list:
    """Each seed's start: :func:`~spcopyro.gibbs.sampler.init` from a generator of that seed."""
    return [init(data, config, torch.Generator().manual_seed(int(seed))) for seed in seeds]


def _keep_best(best: BatchedState, state: BatchedState, improved: torch.Tensor) -> BatchedState:
    """Chain by chain, ``state`` where ``improved`` [B] else ``best``."""
    return BatchedState(
        torch.where(improved[:, None], state.labels, best.labels),
        torch.where(improved[:, None], state.log_pi, best.log_pi),
        tuple(
            torch.where(improved[:, None, None], new, old)
            for new, old in zip(state.log_emissions, best.log_emissions, strict=True)
        ),
    )


def run_batched_chains(
    data: ModelData,
    config: SpCoConfig,
    seeds: Sequence[int],
    num_sweeps: int,
    *,
    device: torch.device | str = "cpu",
    dtype: torch.dtype = DTYPE,
    thin: int = 0,
    options: GibbsOptions = GibbsOptions(),
) -> list[GibbsRun]:
    """One :class:`~spcopyro.gibbs.run.GibbsRun` per seed: ``num_sweeps`` sweeps of every chain
    at once on ``device`` in ``dtype`` (module docstring); label maps kept after sweep s when
    ``(s + 1) % thin == 0`` (none when ``thin`` is 0), as the run loop keeps them."""
    if num_sweeps < 1:
        raise ValueError(f"num_sweeps must be >= 1, got {num_sweeps}")
    if thin < 0:
        raise ValueError(f"thin must be >= 0, got {thin}")
    if not seeds:
        raise ValueError("run_batched_chains needs at least one seed")
    check_batched_options(options)
    cuda = torch.device(device).type == "cuda"
    plan = make_batched_plan(data, config, device, dtype)
    state = stack_states(start_states(data, config, seeds), device, dtype)
    generator = torch.Generator(device=device).manual_seed(int(seeds[0]))
    constant = float(log_joint_constant(data, config))
    B = len(seeds)
    values = torch.empty(num_sweeps, B, dtype=torch.float64, device=device)  # [S, B]: the sum
    # of a constant and a state part of about +-2e7 each (pi concentration 1e6) in float64
    concepts = torch.empty(num_sweeps, B, dtype=torch.long, device=device)  # [S, B]
    best, best_value = state, torch.full((B,), -math.inf, dtype=torch.float64, device=device)
    best_sweep = torch.zeros(B, dtype=torch.long, device=device)
    samples, sample_sweeps, seconds = [], [], []
    started = time.perf_counter()
    for sweep in range(num_sweeps):
        state = gibbs_sweep_batched(state, plan, config, generator, options.unobserved_refresh)
        value, concepts[sweep] = trace_batched(state, plan, config)
        values[sweep] = value + constant
        improved = values[sweep] > best_value  # [B]
        best = _keep_best(best, state, improved)
        best_value = torch.where(improved, values[sweep], best_value)
        best_sweep = torch.where(improved, sweep, best_sweep)
        if thin and (sweep + 1) % thin == 0:
            samples.append(state.labels.to(label_dtype(config.num_concepts)).clone())
            sample_sweeps.append(sweep)
        if cuda:
            torch.cuda.synchronize(device)
        seconds.append(time.perf_counter() - started)
    log_joint = values.to("cpu", torch.float64).numpy()  # [S, B]
    if not np.isfinite(log_joint).all():
        sweep, chain = np.argwhere(~np.isfinite(log_joint))[0]
        raise NonFiniteLogJointError(
            f"batched chain {chain} (seed {seeds[chain]}): the log joint after sweep {sweep} "
            f"(0-based) is {log_joint[sweep, chain]}, not finite"
        )
    kept = torch.stack(samples, 1).cpu().numpy() if samples else None  # [B, S', N]
    best_sweeps = best_sweep.cpu().tolist()
    return [
        GibbsRun(
            final_state=state.chain(b),
            best_state=best.chain(b),
            best_sweep=best_sweeps[b],
            log_joint=log_joint[:, b].copy(),
            num_concepts=concepts[:, b].cpu().numpy(),
            seconds=np.asarray(seconds, dtype=np.float64),
            label_samples=None if kept is None else kept[b],
            sample_sweeps=None if kept is None else np.asarray(sample_sweeps, dtype=np.int64),
            backend=BACKEND_NAME,
            final_config=config,
            initial_config=config,
        )
        for b in range(B)
    ]
