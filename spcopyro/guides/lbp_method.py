"""Loopy BP as an :class:`~spcopyro.inference.protocol.InferenceMethod` (registry: ``lbp``): its
options, its :func:`init` / :func:`step` (one outer iteration: the global factors' optimum
given the beliefs alternating with :class:`~spcopyro.guides.lbp.LoopyBP`'s message passes,
traced by the Bethe objective), the run (the shared driver,
:func:`spcopyro.inference.driver.drive`) and the method object."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal, NamedTuple

import torch

from spcopyro._util.number_checks import is_int, is_number
from spcopyro.config import SpCoConfig
from spcopyro.guides.cavi import num_used, update_globals
from spcopyro.guides.cavi_method import output_from_variational
from spcopyro.guides.factors import GlobalFactors, PiFamily
from spcopyro.guides.lbp import LoopyBP, bethe_objective, node_log_potentials
from spcopyro.guides.options import VariationalOptions, warn_numba_only_options
from spcopyro.guides.run import (
    VariationalRun,
    initial_q,
    remaining,
    resumed,
    warn_flat_fit,
)
from spcopyro.inference.driver import Trajectory, drive
from spcopyro.inference.protocol import InferenceMethod, InferenceOutput, RunArgs
from spcopyro.inference.schedule import warn_unfinished_annealing
from spcopyro.model import ModelData


@dataclass(frozen=True)
class LBPOptions:
    """How loopy belief propagation runs.

    Attributes:
        damping: each new message is mixed with the old one,
            ``m <- (1 - damping) m_new + damping m_old`` (0: undamped sum-product, which can
            oscillate on a loopy grid at strong coupling).
        passes: message passes (every colour class sends once per pass) per outer iteration,
            between two updates of the global factors.
        anneal_iterations: gamma rises linearly to the model's value over this many outer
            iterations (0: none), on the schedule of every method
            (:func:`spcopyro.inference.schedule.annealed_gamma`).
        pi_family: q(pi) as the model states it (``"dirichlet"``) or the truncated
            stick-breaking DP (``"stick-breaking"``).
        tolerance: stop once an outer iteration at full gamma changes the Bethe objective by less
            than ``tolerance * |objective|`` (0: run every iteration). The default 1e-7 is
            CAVI's: on the embedded house LBP settles within a few iterations and, without it,
            ran all 5000 of a plain ``spcopyro fit --method lbp`` (2 minutes).
        backend: ``"torch"`` (the dense reference, :mod:`spcopyro.guides.lbp`), ``"numba"`` (the
            compiled sparse messages of :mod:`spcopyro.guides.numba_lbp`) or ``"auto"`` (numba
            where it imports and gamma D <= 300, else torch).
        support: the numba backend keeps at most this many excess entries a message (0: all L).
        threshold: the numba backend drops a message's excess entries below this (each such
            entry moves the message by at most a factor 1 + threshold against the others).
        active_tolerance: the numba backend skips a cell while twice the bound on its inputs'
            drift plus its damping residual stays <= this (its messages then lie within a factor
            e^(+-active_tolerance) of fresh undamped ones; 0: skip only unchanged cells).
    """

    damping: float = 0.5
    passes: int = 2
    anneal_iterations: int = 0
    pi_family: PiFamily = "dirichlet"
    tolerance: float = 1e-7
    backend: Literal["auto", "torch", "numba"] = "auto"
    support: int = 0
    threshold: float = 1e-4
    active_tolerance: float = 1e-3

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"LBPOptions.{name}={getattr(self, name)!r}: {why}")

        if not is_int(self.passes) or self.passes < 1:
            raise bad("passes", "must be an integer >= 1")
        if not (is_number(self.threshold) and 0 <= self.threshold < math.inf):
            raise bad("threshold", "must be a finite number >= 0")
        # The shared options check the rest, damping among them (and name the field).
        try:
            VariationalOptions(damping=self.damping, anneal_iterations=self.anneal_iterations,
                               pi_family=self.pi_family, tolerance=self.tolerance,
                               backend=self.backend, support=self.support,
                               active_tolerance=self.active_tolerance)  # fmt: skip
        except ValueError as error:
            raise ValueError(str(error).replace("VariationalOptions", "LBPOptions")) from None


class LBPState(NamedTuple):
    """The state of loopy BP between outer iterations."""

    bp: LoopyBP
    """The messages (updated in place by :func:`step`: they are ``[N, D, L]``)."""
    q: torch.Tensor
    """[N, L] float64 the beliefs q(C_i = l)."""
    factors: GlobalFactors
    """q(pi) and every q(phi_m), optimal given the beliefs."""


class LBPInfo(NamedTuple):
    """What one outer iteration of loopy BP did."""

    objective: float
    """The Bethe objective after it, at the model's gamma (NaN where not finite)."""
    num_concepts: int
    """Concepts that are some cell's most probable one."""
    gamma: float
    """The coupling of its message passes."""


def resolve_lbp_backend(options: LBPOptions, data: ModelData, config: SpCoConfig) -> str:
    """``"torch"`` or ``"numba"`` for these options: ``"auto"`` is numba where it imports and
    its products stay finite (:func:`spcopyro.guides.numba_lbp.usable`), else torch.

    Raises:
        ImportError: ``"numba"`` was asked for and numba is missing.
        ValueError: ``"numba"`` was asked for and gamma D > 300.
    """
    if options.backend == "torch":
        return "torch"
    try:
        import spcopyro.guides.numba_lbp as compiled
    except ImportError:
        if options.backend == "numba":
            raise
        return "torch"
    if options.backend == "auto" and not compiled.usable(config, data):
        return "torch"
    return "numba"


def init(q: torch.Tensor, data: ModelData, config: SpCoConfig, options: LBPOptions) -> Any:
    """The state at beliefs ``q`` ``[N, L]``: the globals from them; the messages start from q
    at the first step's coupling. With the numba backend, the compiled
    :func:`spcopyro.guides.numba_lbp.init`'s state."""
    if resolve_lbp_backend(options, data, config) == "numba":
        import spcopyro.guides.numba_lbp as compiled

        return compiled.init(q, data, config, options)
    warn_numba_only_options(options, "loopy BP")
    bp = LoopyBP(data, config, options.damping, options.passes)
    return LBPState(bp, q, update_globals(q, data, config, options.pi_family))


def step(
    state: LBPState, data: ModelData, config: SpCoConfig, gamma: float, options: LBPOptions
) -> tuple[LBPState, LBPInfo]:
    """One outer iteration at coupling ``gamma``: ``options.passes`` message passes under the
    node potentials of the globals, the beliefs from the messages, the globals given the
    beliefs, the Bethe objective (the numba backend's state: its compiled step)."""
    if not isinstance(state, LBPState):
        import spcopyro.guides.numba_lbp as compiled

        state, value, used = compiled.step(state, data, config, gamma, options)
        return state, LBPInfo(value, used, float(gamma))
    bp = state.bp
    if bp.h is None:  # the first step: messages a cell with belief q would send
        bp.start_from(state.q, gamma)
    q = bp.run(node_log_potentials(state.factors, data, config), gamma)  # [N, L]
    factors = update_globals(q, data, config, options.pi_family)
    value = float(bethe_objective(bp, factors, data, config))
    value = value if math.isfinite(value) else float("nan")
    return LBPState(bp, q, factors), LBPInfo(value, num_used(q), float(gamma))


def _labels(state: Any) -> torch.Tensor:
    """[N] the argmax beliefs of either backend's state."""
    return state.q.argmax(-1) if isinstance(state, LBPState) else state.bp.labels()


def _beliefs(state: Any) -> torch.Tensor:
    """[N, L] the beliefs of either backend's state."""
    return state.q if isinstance(state, LBPState) else state.bp.beliefs()


def run_lbp(
    data: ModelData,
    config: SpCoConfig,
    iterations: int,
    *,
    q: torch.Tensor,
    options: LBPOptions | None = None,
    progress: bool | None = None,
    thin: int = 0,
    resume: Trajectory | None = None,
) -> tuple[VariationalRun, Any]:
    """At most ``iterations`` outer iterations of :func:`step` from beliefs ``q`` ``[N, L]``
    (written with the final beliefs), stopping once the Bethe objective settles
    (``options.tolerance``). Returns the run and the BP state (its messages: a
    :class:`~spcopyro.guides.lbp.LoopyBP` or, with the numba backend, a
    :class:`~spcopyro.guides.numba_lbp.SparseLoopyBP`). ``thin`` > 0
    keeps the argmax labels every ``thin`` iterations. ``resume``: the record of the run the
    beliefs ``q`` were reached by (a checkpoint's), continued here, the messages started
    afresh from ``q``."""
    options = LBPOptions() if options is None else options
    warn_unfinished_annealing(options.anneal_iterations, iterations, "anneal_iterations",
                              "iteration", resume)  # fmt: skip
    run = drive(
        init(q, data, config, options),
        lambda state, gamma: step(state, data, config, gamma, options), iterations,
        gamma=config.gamma, anneal=options.anneal_iterations, tolerance=options.tolerance,
        thin=thin, labels=_labels, num_concepts=config.num_concepts, progress=progress,
        description="LBP", resume=resume, marginals=_beliefs,
    )  # fmt: skip
    q.copy_(_beliefs(run.state))
    return VariationalRun.of(run, q, run.state.factors), run.state.bp


class LBPInference(InferenceMethod):
    """Loopy belief propagation (:mod:`spcopyro.guides.lbp`) behind the common interface:
    the beliefs are the marginals, the trace is the Bethe approximation of the ELBO."""

    name = "lbp"
    objective_name = "Bethe ELBO"
    options_type = LBPOptions
    title = "LBP"
    resumable = True

    def fit(
        self, data: ModelData, config: SpCoConfig, options: LBPOptions, request: RunArgs
    ) -> InferenceOutput:
        q, before = resumed(request) or (
            initial_q(data, config, request.generator, request.init_labels),
            None,
        )
        run, _ = run_lbp(data, config, remaining(request), q=q, options=options,
                         progress=request.progress, thin=request.thin,
                         resume=before)  # fmt: skip
        warn_flat_fit(run.q, config, "loopy BP", request, before, options.anneal_iterations,
                      mean_field=False)  # fmt: skip
        record = {"iterations": request.iterations, **dataclasses.asdict(options),
                  "backend_used": resolve_lbp_backend(options, data, config)}  # fmt: skip
        output = output_from_variational(run, record)
        trace = dataclasses.replace(output.trace, objective_name=self.objective_name)
        return dataclasses.replace(output, trace=trace)
