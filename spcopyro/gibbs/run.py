"""A Gibbs chain that sweeps, records, and can be continued from where it stopped.

:func:`start_chain` makes a :class:`GibbsChain` (the state after
:func:`~spcopyro.gibbs.sampler.init`, its generator, the map's sweep plan, the backend);
:func:`advance` runs sweeps of :func:`~spcopyro.gibbs.sampler.step` on it through the driver of
every inference method (:func:`spcopyro.inference.driver.drive`), recording what a run
needs and no more: the log joint and the number of concepts of every sweep (8 + 8 bytes a sweep),
the state of highest log joint visited (the "MAP-visited" state, annealing sweeps left out), and,
only if asked, label maps every ``thin`` sweeps as int16 (2 bytes a cell). A later :func:`advance`
continues the same chain -- same state, same generator, same sweep count -- which is how
``--sweeps auto`` (:mod:`spcopyro.gibbs.convergence`) runs its blocks and how a long fit can be
resumed (:mod:`spcopyro.gibbs.checkpoint` saves a chain to a file and loads it back).
:func:`run_gibbs` is start + advance in one call, returning a :class:`GibbsRun`.

Numerics: labels are stored as int16, or int32 when L > 32768 (:func:`label_dtype`); a sweep
whose log joint is not finite stops the chain (:class:`NonFiniteLogJointError`, naming the sweep
and the terms that are not finite) instead of running on.

A Ctrl-C (:class:`KeyboardInterrupt`) during :func:`advance` leaves the chain at its last
*completed* sweep: a sweep cut short is undone -- its state, its records and the draws it took
from the generator -- before the interrupt is raised again, so a chain saved then and continued
later is exactly the chain run without the interruption.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import torch

from spcopyro._util.number_checks import is_integer
from spcopyro._util.progress import progress_enabled
from spcopyro._util.random_draws import check_seed
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.backends import SweepBackend, get_backend, numba_compile_pending
from spcopyro.gibbs.hyperparameters import hyperparameter_names, hyperparameter_values
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.sampler import init, step, trace_point
from spcopyro.gibbs.state import GibbsState, SweepPlan, make_sweep_plan
from spcopyro.inference.driver import DriveInterrupted, Trajectory, drive
from spcopyro.likelihood import log_joint_constant, log_joint_terms
from spcopyro.model import ModelData

LABEL_DTYPE = torch.int16  # compact storage of label maps (L <= 32768; see label_dtype)


def label_dtype(num_concepts: int) -> torch.dtype:
    """The compact storage of labels in [0, L): int16 when L <= 32768, else int32."""
    return LABEL_DTYPE if num_concepts <= torch.iinfo(LABEL_DTYPE).max + 1 else torch.int32


class ChainsStopped(KeyboardInterrupt):
    """Raised by a chain's callback after a sweep, once Ctrl-C (or another chain's error) asked
    every chain to stop. A :class:`KeyboardInterrupt`, so that the driver keeps the sweeps the
    chain completed (:class:`~spcopyro.inference.driver.DriveInterrupted`) as for a Ctrl-C. Raised
    in a chain's thread (:mod:`spcopyro.gibbs.chains`) or its worker process
    (:mod:`spcopyro.gibbs.chain_processes`)."""


class NonFiniteLogJointError(FloatingPointError, ValueError):
    """A sweep's log joint is NaN or infinite: counts or hyperparameters beyond what float64
    carries (see :func:`spcopyro.fit.setting_warnings.config_warnings`). A ValueError, so the
    command line reports it as bad input."""


def _check_log_joint(chain: GibbsChain, sweep: int, value: float) -> None:
    """Raise :class:`NonFiniteLogJointError` if ``value``, the log joint of ``chain.state``
    after ``sweep``, is not finite, naming the terms that are not
    (:func:`spcopyro.likelihood.log_joint_terms`: computed only then)."""
    if math.isfinite(value):
        return
    state = chain.state
    terms = log_joint_terms(state.labels, state.log_pi, state.log_emissions, chain.data,
                            chain.model_config)  # fmt: skip
    bad = [f"{name} = {term}" for name, term in terms.items() if not math.isfinite(term)]
    which = (
        f"terms not finite: {', '.join(bad)}" if bad
        else "every term is finite but their sum is not (overflow)"
    )  # fmt: skip
    raise NonFiniteLogJointError(
        f"Gibbs sweep {sweep} (0-based): the log joint is {value}, not finite ({which}); "
        "stopping instead of running on: check the counts and the hyperparameters"
    )


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
    """[S', N] int16 (int32 when L > 32768) label maps every ``thin`` sweeps (None unless
    ``thin`` > 0). From :meth:`GibbsChain.to_run`: read-only, the chain's own maps (not a copy)."""
    sample_sweeps: np.ndarray | None
    """[S'] the 0-based sweeps of ``label_samples``."""
    backend: str = ""
    """The sweep backend that ran (``"torch"`` or ``"numba"``: ``"auto"`` resolved)."""
    hyperparameters: dict[str, np.ndarray] | None = None
    """When ``options.hyper`` samples hyperparameters: [S] float64 per name of
    :func:`~spcopyro.gibbs.hyperparameters.hyperparameter_names` (alpha, gamma, chi, beta, ...),
    the values after each sweep; else None."""
    final_config: SpCoConfig | None = None
    """The chain's model config after its last sweep (its sampled hyperparameters' values)."""
    initial_config: SpCoConfig | None = None
    """The model config the chain started from (the fit's settings)."""


def _compact(state: GibbsState) -> GibbsState:
    return state._replace(labels=state.labels.to(label_dtype(state.log_pi.shape[-1])))


@dataclass
class GibbsChain:
    """A Markov chain in progress: its state and generator, and what it has recorded so far."""

    data: ModelData
    config: SpCoConfig
    options: GibbsOptions
    generator: torch.Generator
    backend: SweepBackend
    plan: SweepPlan
    state: GibbsState
    constant: float
    """The log joint's state-independent part (:func:`spcopyro.likelihood.log_joint_constant`)."""
    sweeps_done: int = 0
    best_value: float = -np.inf
    best_state: GibbsState | None = None
    best_sweep: int = -1
    log_joint: list[float] = field(default_factory=list)
    num_concepts: list[int] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)
    label_samples: list[np.ndarray] = field(default_factory=list)
    sample_sweeps: list[int] = field(default_factory=list)
    current: SpCoConfig | None = None
    """The model config of the chain's state when hyperparameters are sampled (None: ``config``,
    the fit's own settings, which stay what the chain was started with)."""
    hyper_trace: list[list[float]] = field(default_factory=list)
    """Per sweep, the values of :func:`~spcopyro.gibbs.hyperparameters.hyperparameter_names`
    (recorded only when hyperparameters are sampled)."""

    @property
    def model_config(self) -> SpCoConfig:
        """The model config the next sweep runs under (``current``, else ``config``)."""
        return self.config if self.current is None else self.current

    def to_run(self) -> GibbsRun:
        """The chain's record so far as a :class:`GibbsRun`."""
        if not self.sweeps_done:
            raise ValueError("the chain has run no sweep yet: call advance() first")
        best = self.best_state if self.best_state is not None else _compact(self.state)
        return GibbsRun(
            final_state=self.state,
            best_state=best._replace(labels=best.labels.to(torch.long)),
            best_sweep=self.best_sweep,
            log_joint=np.asarray(self.log_joint, dtype=np.float64),
            num_concepts=np.asarray(self.num_concepts, dtype=np.int64),
            seconds=np.asarray(self.seconds, dtype=np.float64),
            label_samples=self.sample_stack(),
            sample_sweeps=(
                np.asarray(self.sample_sweeps, dtype=np.int64) if self.label_samples else None
            ),
            backend=self.backend.name,
            hyperparameters=self._hyper_arrays(),
            final_config=self.model_config,
            initial_config=self.config,
        )

    def sample_stack(self) -> np.ndarray | None:
        """[S', N] the kept label maps as one read-only array that the chain's rows are views of
        (None if it kept none): a read-only view of the stack whose rows are the chain's rows in
        order where there is one, else one new stack (made once; the chain then keeps it). So a
        map is held once, not by the chain and again by its run or a checkpoint being saved (at
        3.87 million cells, 100 maps: 0.77 GB each).

        The rows of one :func:`advance` are already the rows of its driver's stack, which is
        then handed out as it is. Rows of several (``--sweeps auto``'s blocks, a resumed
        checkpoint's and its new sweeps, a chain sent back by a worker process) are stacked
        once and the chain's rows become the new stack's rows (the same values): the old ones
        go. Read-only: a caller writing into it would change the chain's maps, which a
        checkpoint may still save (:class:`~spcopyro.fit.gibbs_chains.FitCheckpoint`); nothing
        overwrites them here either -- the chain only appends rows."""
        rows = self.label_samples
        if not rows:
            return None
        stack = _rows_base(rows)
        if stack is None:
            stack = np.stack(rows)  # [S', N]
            rows[:] = list(stack)
        view = stack.view()
        view.flags.writeable = False
        return view

    def _hyper_arrays(self) -> dict[str, np.ndarray] | None:
        if not self.options.hyper.active:
            return None
        values = np.asarray(self.hyper_trace, dtype=np.float64).reshape(
            len(self.hyper_trace), -1
        )  # [S, H]
        names = hyperparameter_names(self.data)
        return {name: values[:, h].copy() for h, name in enumerate(names)}

    def _mark(self) -> _Mark:
        """What :meth:`_undo` needs to bring the chain back to this point (cheap: the generator's
        state is 5 kB, everything else is a reference or a length)."""
        return _Mark(self.generator.get_state(), self.state, self.sweeps_done, self.best_value,
                     self.best_state, self.best_sweep, self.current, self.constant)  # fmt: skip

    def _undo(self, mark: _Mark) -> None:
        """Back to :meth:`_mark`'s point: a sweep cut short by Ctrl-C leaves no trace."""
        self.generator.set_state(mark.generator_state)
        self.state, self.sweeps_done = mark.state, mark.sweeps_done
        self.best_value, self.best_state, self.best_sweep = (
            mark.best_value, mark.best_state, mark.best_sweep
        )  # fmt: skip
        self.current, self.constant = mark.current, mark.constant
        del self.hyper_trace[mark.sweeps_done :]

    def _record(self, run: Trajectory) -> None:
        """Add the driver's record of the sweeps after ``len(self.log_joint)`` to the chain's."""
        elapsed = self.seconds[-1] if self.seconds else 0.0
        self.log_joint.extend(run.objective.tolist())
        self.num_concepts.extend(run.num_concepts.tolist())
        self.seconds.extend((elapsed + run.seconds).tolist())
        if run.label_samples is not None:
            self.label_samples.extend(run.label_samples)
            self.sample_sweeps.extend(run.sample_iterations.tolist())


def _rows_base(rows: list[np.ndarray]) -> np.ndarray | None:
    """The [S', N] array whose rows 0, 1, ... are exactly ``rows`` [N] (views of it, in order,
    covering it whole), else None."""
    base = rows[0].base
    if not isinstance(base, np.ndarray) or base.base is not None:
        return None
    if base.ndim != 2 or base.shape[0] != len(rows) or not base.flags.c_contiguous:
        return None
    start, step = base.__array_interface__["data"][0], base.strides[0]
    for s, row in enumerate(rows):
        if (
            row.base is not base or row.shape != base.shape[1:] or row.dtype != base.dtype
            or row.strides != base.strides[1:]
            or row.__array_interface__["data"][0] != start + s * step
        ):  # fmt: skip
            return None
    return base


class _Mark(NamedTuple):
    """A chain's position before a sweep (:meth:`GibbsChain._mark`)."""

    generator_state: torch.Tensor  # [5056] uint8
    state: GibbsState
    sweeps_done: int
    best_value: float
    best_state: GibbsState | None
    best_sweep: int
    current: SpCoConfig | None
    constant: float


def start_chain(
    data: ModelData,
    config: SpCoConfig,
    *,
    options: GibbsOptions = GibbsOptions(),
    generator: torch.Generator | None = None,
    seed: int | None = None,
    init_labels: torch.Tensor | None = None,
) -> GibbsChain:
    """A new chain at :func:`~spcopyro.gibbs.sampler.init` from ``init_labels`` (random if None).

    ``generator`` / ``seed``: randomness, at most one of them (``seed`` makes a fresh
    generator; neither: seed 0, so a run reproduces unless told otherwise -- pass
    ``seed=random.randrange(2**63)`` for a fresh one). A seeded chain reproduces bit for bit
    (on one backend: the backends' random streams differ).
    """
    if generator is not None and seed is not None:  # the seed was dropped silently
        raise ValueError(f"give a generator or a seed, not both (seed {seed!r})")
    if generator is None:
        generator = torch.Generator().manual_seed(0 if seed is None else check_seed(seed))
    backend = get_backend(options.backend)
    state = init(data, config, generator, init_labels)
    constant = float(log_joint_constant(data, config))
    return GibbsChain(
        data, config, options, generator, backend, make_sweep_plan(data), state, constant
    )


class SweepInfo(NamedTuple):
    """What the driver records of one sweep of a chain."""

    objective: float
    """The log joint of the target model after the sweep (:func:`trace_point`)."""
    num_concepts: int
    gamma: float
    """The coupling the labels were drawn under (below gamma while annealing)."""


def _sweep(chain: GibbsChain) -> SweepInfo:
    """One sweep of ``chain`` (in place), its best state and sampled hyperparameters updated."""
    data, sweep, before = chain.data, chain.sweeps_done, chain.model_config
    chain.state, info = step(
        chain.state, data, before, chain.generator, sweep=sweep, options=chain.options,
        backend=chain.backend, plan=chain.plan,
    )  # fmt: skip
    if info.config is not None and info.config != before:
        chain.current = info.config
        chain.constant = float(log_joint_constant(data, info.config))
    value, concepts = trace_point(chain.state, data, chain.model_config, chain.constant,
                                  chain.backend, chain.options)  # fmt: skip
    _check_log_joint(chain, sweep, value)
    if chain.options.hyper.active:
        chain.hyper_trace.append(hyperparameter_values(data, chain.model_config))
    if value > chain.best_value and sweep + 1 >= chain.options.anneal_sweeps:
        chain.best_value, chain.best_state, chain.best_sweep = value, _compact(chain.state), sweep
    chain.sweeps_done = sweep + 1
    return SweepInfo(value, concepts, info.gamma)


COMPILING = "compiling the numba code: first run only"
"""The progress bar's note while the first sweep compiles (:func:`numba_compile_pending`)."""


def compile_note(chains: list[GibbsChain]) -> str | None:
    """:data:`COMPILING` when a chain runs the compiled sweep and its code is not in numba's
    cache yet (:func:`~spcopyro.gibbs.backends.numba_compile_pending`), else None."""
    compiled = any(chain.backend.name == "numba" for chain in chains)
    return COMPILING if compiled and numba_compile_pending() else None


def _check_sweeps(num_sweeps: int) -> None:
    """ValueError naming ``num_sweeps`` unless it is an integer >= 1 (2.5 was refused as the
    driver's "iterations", "3" by a TypeError)."""
    if not is_integer(num_sweeps) or num_sweeps < 1:
        raise ValueError(f"num_sweeps must be >= 1 (an integer), got {num_sweeps!r}")


def advance(
    chain: GibbsChain,
    num_sweeps: int,
    *,
    thin: int = 0,
    progress: bool | None = None,
    callback: Callable[[int, GibbsState], None] | None = None,
) -> GibbsChain:
    """Run ``num_sweeps`` more sweeps of ``chain`` (in place; returned for chaining), through the
    driver of every inference method (:func:`spcopyro.inference.driver.drive`, numbered from the
    chain's sweeps so far), and add what it recorded to the chain's.

    On Ctrl-C the sweep in progress is undone (see the module docstring) and the
    :class:`~spcopyro.inference.driver.DriveInterrupted` (a :class:`KeyboardInterrupt`) raised
    again: the chain then holds its last completed sweep. An interrupt raised by ``callback``
    comes after its sweep was recorded, so that sweep is kept.

    Args:
        thin: keep a label map every ``thin`` sweeps of the chain (0: keep none).
        progress: tqdm bar (default: on unless ``$CI`` is set).
        callback: called as ``callback(sweep, state)`` after every sweep (0-based in the chain).
    """
    _check_sweeps(num_sweeps)
    if thin < 0:
        raise ValueError(f"thin must be >= 0, got {thin}")
    first = chain.sweeps_done
    last: list[_Mark] = []  # the chain before the sweep it is in: what a Ctrl-C undoes

    def one_sweep(state: GibbsState, gamma: float) -> tuple[GibbsState, SweepInfo]:
        # ``gamma`` is the schedule's coupling of this sweep; step() anneals by the same
        # schedule from the chain's sweep count (a chain sampling gamma runs at its own).
        last[:] = [chain._mark()]
        info = _sweep(chain)  # chain.state is the new one only after it
        return chain.state, info

    note = compile_note([chain]) if progress_enabled(progress) else None
    try:
        run = drive(
            chain.state, one_sweep, num_sweeps, gamma=chain.config.gamma,
            anneal=chain.options.anneal_sweeps, first=first, thin=thin,
            labels=lambda state: state.labels, num_concepts=chain.state.log_pi.shape[-1],
            progress=progress, description="Gibbs sweeps", unit="sweep", callback=callback,
            first_note=note,
        )  # fmt: skip
    except DriveInterrupted as stop:
        completed = first + len(stop.trajectory.objective)
        if last and last[0].sweeps_done == completed:  # a sweep begun and not recorded
            chain._undo(last[0])
        chain._record(stop.trajectory)
        raise
    chain._record(run)
    return chain


def run_gibbs(
    data: ModelData,
    config: SpCoConfig,
    num_sweeps: int,
    *,
    options: GibbsOptions = GibbsOptions(),
    generator: torch.Generator | None = None,
    seed: int | None = None,
    init_labels: torch.Tensor | None = None,
    thin: int = 0,
    progress: bool | None = None,
    callback: Callable[[int, GibbsState], None] | None = None,
) -> GibbsRun:
    """Run ``num_sweeps`` Gibbs sweeps from ``init_labels`` (random if None): :func:`start_chain`
    then :func:`advance` (see both for the arguments).

    With ``options.anneal_sweeps`` A > 0 the first A sweeps ramp gamma up
    (:mod:`spcopyro.gibbs.anneal`); they are burn-in, so the best state is taken from sweep
    A - 1 on. The trace's log joint is always the target model's.
    """
    _check_sweeps(num_sweeps)
    if options.anneal_sweeps > num_sweeps:
        raise ValueError(
            f"anneal_sweeps ({options.anneal_sweeps}) must not exceed num_sweeps ({num_sweeps})"
        )
    chain = start_chain(
        data, config, options=options, generator=generator, seed=seed, init_labels=init_labels
    )
    return advance(chain, num_sweeps, thin=thin, progress=progress, callback=callback).to_run()
