r"""A stopping rule for the Gibbs sampler: run chains until they agree (``--sweeps auto``).

The paper leaves "automatically determine the number of iterations" open. This module runs K
chains from different seeds, in blocks of sweeps, and after every block computes the split
Gelman-Rubin statistic (split R-hat, Pyro's :func:`pyro.ops.stats.split_gelman_rubin`) of two
*label-invariant* per-sweep statistics -- the log joint and the number of concepts in use --
over the second half of the sweeps run so far (the first half is discarded as warm-up). With
chains k = 1..K each cut into two halves of n draws, B the variance between the 2K half-chain
means (times n) and W the mean within-half variance,

.. math::

    \hat R = \sqrt{\frac{\frac{n - 1}{n} W + \frac{1}{n} B}{W}} .

The chains stop when R-hat < ``threshold`` (1.05 by default) for *both* statistics, or at
``max_sweeps``. Labels themselves are never compared (concept numbers switch between chains).
The answer is the chain of highest log joint, with the diagnostics of every check.

With ``options.anneal_sweeps`` A > 0 every chain's first block starts with A sweeps of gamma
annealing (:mod:`spcopyro.gibbs.anneal`); they are burn-in, left out of the R-hat windows and of
``max_sweeps`` (the trace keeps them, first).

Chains run one after another, each block continuing its chain where the last one stopped
(:func:`spcopyro.gibbs.run.advance`: same state, same generator), so K chains of S sweeps in
blocks are exactly K chains of S sweeps. One progress bar counts the sweeps of all chains
against the most they may run, K (A + ``max_sweeps``), with the last check's R-hat beside it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from tqdm.auto import tqdm

from spcopyro._util.progress import progress_enabled, staged
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.chains import AUTO, advance_chains
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import GibbsRun, start_chain
from spcopyro.model import ModelData

DEFAULT_CHAINS = 4
DEFAULT_BLOCK = 250
DEFAULT_THRESHOLD = 1.05
DEFAULT_MAX_SWEEPS = 5000
MIN_DRAWS = 8
"""Fewest draws per chain in the window (second half) before R-hat is trusted."""


def split_rhat(traces: np.ndarray) -> float:
    """Split R-hat of ``traces`` ``[K, S]`` (K >= 2 chains, S >= 4 draws each).

    Degenerate cases that Pyro leaves as NaN or inf are decided explicitly: all values equal
    (e.g. every chain keeps the same number of concepts throughout) gives 1.0 (the chains
    agree); no variation within the half-chains but different values between them gives inf.
    """
    traces = np.asarray(traces, dtype=np.float64)  # [K, S]
    if traces.ndim != 2 or traces.shape[0] < 2 or traces.shape[1] < 4:
        raise ValueError(f"split_rhat needs [K >= 2, S >= 4] traces, got shape {traces.shape}")
    if not np.all(np.isfinite(traces)):
        raise ValueError("split_rhat: traces hold NaN or inf")
    if np.ptp(traces) == 0:
        return 1.0
    half = traces.shape[1] // 2
    halves = np.concatenate([traces[:, :half], traces[:, -half:]])  # [2K, half]
    if np.all(np.ptp(halves, axis=1) == 0):
        return math.inf
    from pyro.ops.stats import split_gelman_rubin  # here: a fit that checks no R-hat skips Pyro

    value = float(split_gelman_rubin(torch.as_tensor(traces), chain_dim=0, sample_dim=1))
    return value if math.isfinite(value) else math.inf


@dataclass(frozen=True)
class ConvergenceCheck:
    """R-hat of both statistics after ``sweeps`` sweeps per chain (window: the second half)."""

    sweeps: int
    rhat_log_joint: float
    rhat_num_concepts: float

    def passed(self, threshold: float) -> bool:
        return self.rhat_log_joint < threshold and self.rhat_num_concepts < threshold


def check_convergence(
    log_joint: np.ndarray, num_concepts: np.ndarray, threshold: float = DEFAULT_THRESHOLD
) -> tuple[bool, ConvergenceCheck]:
    """Whether chains with these traces (``[K, S]`` each) have converged, and the check.

    R-hat is computed over the second half of the S sweeps; fewer than :data:`MIN_DRAWS` draws
    there never pass.
    """
    log_joint = np.asarray(log_joint, dtype=np.float64)  # [K, S]
    num_concepts = np.asarray(num_concepts, dtype=np.float64)  # [K, S]
    if log_joint.shape != num_concepts.shape:
        raise ValueError(
            f"log_joint {log_joint.shape} and num_concepts {num_concepts.shape} traces differ"
        )
    sweeps = log_joint.shape[1]
    window = slice(sweeps - sweeps // 2, sweeps)
    if sweeps // 2 < MIN_DRAWS:
        return False, ConvergenceCheck(sweeps, math.inf, math.inf)
    check = ConvergenceCheck(
        sweeps, split_rhat(log_joint[:, window]), split_rhat(num_concepts[:, window])
    )
    return check.passed(threshold), check


@dataclass(frozen=True, eq=False)
class ConvergenceDiagnostics:
    """What :func:`run_until_converged` measured."""

    converged: bool
    sweeps: int
    """Sweeps run per chain."""
    threshold: float
    seeds: tuple[int, ...]
    best_chain: int
    """Index (into ``seeds``) of the chain whose visited state has the highest log joint."""
    checks: tuple[ConvergenceCheck, ...]
    log_joint: np.ndarray  # [K, S]
    num_concepts: np.ndarray  # [K, S]
    best_log_joint: np.ndarray = field(default_factory=lambda: np.empty(0))  # [K]

    def to_json(self) -> dict[str, object]:
        def number(x: float) -> float | str:
            return x if math.isfinite(x) else str(x)

        return {
            "converged": self.converged,
            "sweeps_per_chain": self.sweeps,
            "threshold": self.threshold,
            "seeds": list(self.seeds),
            "best_chain": self.best_chain,
            "best_log_joint": [float(v) for v in self.best_log_joint],
            "checks": [
                {
                    "sweeps": c.sweeps,
                    "rhat_log_joint": number(c.rhat_log_joint),
                    "rhat_num_concepts": number(c.rhat_num_concepts),
                }
                for c in self.checks
            ],
        }


class ConvergenceInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped :func:`run_until_converged` (a :class:`KeyboardInterrupt`); ``where``: how
    far the chains had got."""

    def __init__(self, where: str) -> None:
        super().__init__(where)
        self.where = where


def run_until_converged(
    data: ModelData,
    config: SpCoConfig,
    *,
    options: GibbsOptions = GibbsOptions(),
    chains: int = DEFAULT_CHAINS,
    block: int = DEFAULT_BLOCK,
    max_sweeps: int = DEFAULT_MAX_SWEEPS,
    threshold: float = DEFAULT_THRESHOLD,
    seed: int = 0,
    init_labels: Sequence[torch.Tensor | None] | None = None,
    progress: bool | None = None,
    workers: int | str | None = AUTO,
) -> tuple[GibbsRun, ConvergenceDiagnostics]:
    """Run ``chains`` chains (seeds ``seed``, ``seed + 1``, ...) in blocks of ``block`` sweeps until
    the split R-hat of the log joint and of the number of concepts are both below ``threshold``
    (see the module docstring), or ``max_sweeps`` sweeps per chain.

    ``init_labels``: one ``[N]`` start (or None for random) per chain. ``options``: the sampler's
    options; its ``anneal_sweeps`` come before the first block (see the module docstring).
    ``progress``: one tqdm bar over all chains (default: on unless ``$CI`` is set).
    ``workers``: chains advancing at once within a block
    (:func:`~spcopyro.gibbs.chains.advance_chains`; the chains are the same whatever it is).
    Returns the run of the chain of highest log joint, and the diagnostics.
    """
    if chains < 2:
        raise ValueError(f"chains must be >= 2 to compare chains, got {chains}")
    if block < 1:
        raise ValueError(f"block must be >= 1, got {block}")
    if max_sweeps < 1:
        raise ValueError(f"max_sweeps must be >= 1, got {max_sweeps}")
    if not (math.isfinite(threshold) and threshold > 1.0):
        raise ValueError(f"threshold must be a finite number > 1, got {threshold}")
    anneal_sweeps = options.anneal_sweeps
    starts = list(init_labels) if init_labels is not None else [None] * chains
    if len(starts) != chains:
        raise ValueError(f"init_labels has {len(starts)} entries for {chains} chains")
    seeds = tuple(int(seed) + k for k in range(chains))
    runs = [
        start_chain(data, config, options=options, seed=s, init_labels=start)
        for s, start in zip(seeds, starts, strict=True)
    ]

    checks: list[ConvergenceCheck] = []
    done, converged = 0, False
    bar = tqdm(  # one bar for all chains and blocks: sweeps done of the most that may run
        total=chains * (anneal_sweeps + max_sweeps),
        desc=f"{staged('Gibbs sweeps')}, {chains} chains",
        unit="sweep",
        disable=not progress_enabled(progress),
    )
    try:
        while done < max_sweeps and not converged:
            sweeps = min(block, max_sweeps - done)
            anneal = anneal_sweeps if done == 0 else 0
            advance_chains([(chain, anneal + sweeps) for chain in runs], workers=workers,
                           progress=False, on_sweep=bar.update)  # fmt: skip
            done += sweeps
            log_joint = np.array([chain.log_joint for chain in runs])  # [K, S]
            concepts = np.array([chain.num_concepts for chain in runs], dtype=np.float64)
            converged, check = check_convergence(
                log_joint[:, anneal_sweeps:], concepts[:, anneal_sweeps:], threshold
            )
            checks.append(check)
            bar.set_postfix(rhat_log_joint=f"{check.rhat_log_joint:.3f}",
                            rhat_concepts=f"{check.rhat_num_concepts:.3f}")  # fmt: skip
    except KeyboardInterrupt:
        at = ", ".join(str(chain.sweeps_done) for chain in runs)
        raise ConvergenceInterrupted(
            f"{chains} chains at {at} of at most {anneal_sweeps + max_sweeps} sweeps, "
            f"not yet converged after {len(checks)} check(s)"
        ) from None
    finally:
        bar.close()  # else its last line came again after the interruption's message

    merged = [chain.to_run() for chain in runs]
    best_values = np.array([run.log_joint[run.best_sweep] for run in merged])  # [K]
    best_chain = int(np.argmax(best_values))
    diagnostics = ConvergenceDiagnostics(
        converged=converged,
        sweeps=done,
        threshold=threshold,
        seeds=seeds,
        best_chain=best_chain,
        checks=tuple(checks),
        log_joint=np.stack([run.log_joint for run in merged]),
        num_concepts=np.stack([run.num_concepts for run in merged]),
        best_log_joint=best_values,
    )
    return merged[best_chain], diagnostics
