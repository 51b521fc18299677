r"""Stochastic variational inference with the mean-field guide, as an
:class:`~spcopyro.inference.protocol.InferenceMethod` (registry: ``svi``).

Each iteration is one ``pyro.infer.SVI`` step: the loss of :mod:`spcopyro.guides.loss` (globals
by reparameterisation, labels in closed form) and one Adam (or ClippedAdam) update of the guide's
``pyro.param`` s (:mod:`spcopyro.guides.mean_field`). The trace is the ELBO estimate of each step
(at the step's coupling while gamma is annealed), so it is noisy where CAVI's is exact; the output
holds the posterior means of pi and phi under the final guide and its q(C) as the marginals, like
CAVI's (:func:`spcopyro.guides.cavi_method.output_from_variational`).

Every fit runs in a fresh ``pyro`` param-store scope (:meth:`pyro.params.ParamStoreDict.scope`):
two fits never share parameters and the caller's param store is left as it was. Pyro's draws
come from the global torch RNG, seeded from ``generator`` inside :func:`torch.random.fork_rng`,
so a seeded generator makes a fit reproducible without disturbing the caller's RNG.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass
from typing import ClassVar, Literal, NamedTuple

import pyro
import pyro.optim
import torch

from spcopyro._util.messages import setting
from spcopyro._util.number_checks import is_finite_number, is_int, is_number, is_positive_number
from spcopyro.config import SpCoConfig
from spcopyro.guides.adam import plain_adam
from spcopyro.guides.cavi_method import output_from_variational
from spcopyro.guides.loss import MeanFieldELBO
from spcopyro.guides.mean_field import (
    GIVEN_START_SMOOTHING,
    RANDOM_START_SMOOTHING,
    MeanFieldGuide,
)
from spcopyro.guides.run import (
    VariationalRun,
    initial_q,
    remaining,
    resumed,
    warn_flat_q,
)
from spcopyro.inference.driver import Trajectory, drive
from spcopyro.inference.protocol import InferenceMethod, InferenceOutput, RunArgs
from spcopyro.inference.schedule import warn_unfinished_annealing
from spcopyro.model import ModelData, spcomapping_model

RANDOM_START_ANNEALING = 100
"""The annealing iterations of a random start (``SVIOptions.anneal_iterations`` None)."""


@dataclass(frozen=True)
class SVIOptions:
    """How stochastic variational inference runs.

    Attributes:
        learning_rate: the optimiser's step size for the labels' logits.
        global_learning_rate: the step size for the unconstrained parameters of q(pi) and
            q(phi) (None: ``learning_rate``). With ``bound="prior"`` these are the logs of the
            expected counts and one step size suits both; with ``bound="zero"`` they are the logs
            of concentrations of up to ~1e6 (the presets' pi), where Adam's first steps of about
            ``learning_rate`` each move a by far more than all the cells' counts: give them a
            step of ~1e-3.
        optimiser: ``"adam"`` or ``"clipped-adam"`` (Pyro's ClippedAdam: gradients clipped to
            ``clip_norm`` per parameter).
        clip_norm: ClippedAdam's clipping norm.
        num_particles: draws of the globals per step (the estimate's variance falls as 1 / this).
        anneal_iterations: gamma rises linearly to the model's value over this many steps
            (0: none), on the schedule of every method
            (:func:`spcopyro.inference.schedule.annealed_gamma`); None (the default) picks it
            by the start (:meth:`start_annealing`): :data:`RANDOM_START_ANNEALING` (100) for a
            random start, 0 for given start labels (as ``label_smoothing``), a value set is
            used for either. From a random start gradient steps move a boundary between two
            concepts' domains by about a cell per step, so a label field that froze into small
            random domains at full coupling coarsens far too slowly; started uncoupled, the
            observations place the concepts first and the domains grow from them. A given
            start is a map already: annealed from gamma 0 its unobserved cells drift to
            uniform (at L = 120 CAVI's labels kept at 95 % were at 0.41 of log L after 10
            steps and 1.000 after 100; at 0.009 without annealing), as Gibbs' refinement from
            a fitted map does not anneal either (until 2026-12-05 the default was 100 for
            every start).
        label_smoothing: s in the starting logits ``log((1 - s) q0 + s / L)``, in (0, 1);
            None (the default) picks it by the start (:meth:`start_smoothing`, as
            :class:`~spcopyro.guides.mean_field.MeanFieldGuide` does): 0.9 for a random start,
            near uniform with a small random tilt (the random one-hot q0 of
            :func:`~spcopyro.guides.run.initial_q`), which is what lets annealing work at
            small L (8); 0.05 for given start labels (``init_labels``, ``fit --init-from``,
            ``--init`` other than random, ``--update``), which keeps 95 % of them. At L = 120
            with sparse observations a start smoothed by 0.9 stays at mean field's disordered
            fixed point (:func:`~spcopyro.guides.run.warn_flat_q`), a fitted warm start's
            included (it kept 10 % of it before 2026-12-05).
        bound: the concentrations' constraint, ``"prior"`` (above the prior's) or ``"zero"``
            (positive): see :class:`~spcopyro.guides.mean_field.MeanFieldGuide`.
        tolerance: stop once the mean ELBO estimate of the last ``window`` steps at full gamma
            differs from that of the ``window`` steps before by less than
            ``tolerance * |ELBO|`` (:func:`spcopyro.inference.schedule.converged`; 0: run
            every step, the steps asked for are then a ceiling). The estimate is noisy, so the
            rule compares means over windows, not single steps.
        window: steps per window of the stopping rule.
    """

    learning_rate: float = 0.1
    global_learning_rate: float | None = None
    optimiser: Literal["adam", "clipped-adam"] = "adam"
    clip_norm: float = 10.0
    num_particles: int = 1
    anneal_iterations: int | None = None
    label_smoothing: float | None = None
    bound: Literal["prior", "zero"] = "prior"
    tolerance: float = 1e-4
    window: int = 50

    RESUME_IGNORES: ClassVar[tuple[str, ...]] = ("label_smoothing",)
    """Fields a resumed run does not read (it goes on from the q reached, smoothed by
    :data:`RESUMED_SMOOTHING` only): a checkpoint's record of them is not compared on resuming
    (:func:`spcopyro.guides.checkpoint.load_variational`, reading it through
    :func:`~spcopyro.inference.protocol.resume_ignores`; checkpoints from before 2026-12-05
    record label_smoothing 0.9, the default then, and were refused against None)."""

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"SVIOptions.{name}={getattr(self, name)!r}: {why}")

        if not is_positive_number(self.learning_rate):
            raise bad("learning_rate", "must be a finite number > 0")
        rate = self.global_learning_rate
        if rate is not None and not is_positive_number(rate):
            raise bad("global_learning_rate", "must be None or a finite number > 0")
        if self.optimiser not in ("adam", "clipped-adam"):
            raise bad("optimiser", "must be 'adam' or 'clipped-adam'")
        if not is_positive_number(self.clip_norm):
            raise bad("clip_norm", "must be a finite number > 0")
        if not is_int(self.num_particles) or self.num_particles < 1:
            raise bad("num_particles", "must be an integer >= 1")
        anneal = self.anneal_iterations
        if anneal is not None and (not is_int(anneal) or anneal < 0):
            raise bad("anneal_iterations", "must be None or an integer >= 0")
        smoothing = self.label_smoothing
        if smoothing is not None and not (is_number(smoothing) and 0 < smoothing < 1):
            raise bad("label_smoothing", "must be None or lie in (0, 1)")
        if self.bound not in ("prior", "zero"):
            raise bad("bound", "must be 'prior' or 'zero'")
        if not (is_finite_number(self.tolerance) and self.tolerance >= 0):
            raise bad("tolerance", "must be a finite number >= 0")
        if not is_int(self.window) or self.window < 1:
            raise bad("window", "must be an integer >= 1")

    def start_smoothing(self, given_start: bool) -> float:
        """The label smoothing a start gets: ``label_smoothing`` where set, else
        :data:`~spcopyro.guides.mean_field.GIVEN_START_SMOOTHING` (0.05) for given start
        labels or q (``given_start``) and
        :data:`~spcopyro.guides.mean_field.RANDOM_START_SMOOTHING` (0.9) for a random one."""
        if self.label_smoothing is not None:
            return float(self.label_smoothing)
        return GIVEN_START_SMOOTHING if given_start else RANDOM_START_SMOOTHING

    def start_annealing(self, given_start: bool) -> int:
        """The annealing iterations a start gets: ``anneal_iterations`` where set, else 0 for
        given start labels or q (``given_start``: annealed from gamma 0 they are lost) and
        :data:`RANDOM_START_ANNEALING` (100) for a random one."""
        if self.anneal_iterations is not None:
            return int(self.anneal_iterations)
        return 0 if given_start else RANDOM_START_ANNEALING

    def for_start(self, given_start: bool) -> SVIOptions:
        """These options with the fields left to the start (None) set to what it gets
        (:meth:`start_smoothing`, :meth:`start_annealing`): what a run ran with."""
        return dataclasses.replace(
            self, label_smoothing=self.start_smoothing(given_start),
            anneal_iterations=self.start_annealing(given_start),
        )  # fmt: skip

    def optimiser_for(self, guide: MeanFieldGuide) -> pyro.optim.PyroOptim:
        """The Pyro optimiser: per-parameter step sizes (logits vs concentrations). ``"adam"``
        is :func:`~spcopyro.guides.adam.plain_adam`, ``pyro.optim.Adam``'s updates bit for bit
        without torch.optim, whose first use imports ``torch._dynamo`` (1.1 s a process)."""
        logits = guide.logits_name
        global_rate = self.global_learning_rate or self.learning_rate

        def per_param(param_name: str) -> dict[str, float]:
            rate = self.learning_rate if param_name == logits else global_rate
            if self.optimiser == "clipped-adam":
                return {"lr": rate, "clip_norm": self.clip_norm}
            return {"lr": rate}

        if self.optimiser == "clipped-adam":
            return pyro.optim.ClippedAdam(per_param)
        return plain_adam(per_param)  # pyro.optim.Adam's updates, without torch._dynamo


class SVIState(NamedTuple):
    """The state of SVI between steps. The guide's parameters live in Pyro's param store (the
    run's own scope) and the optimiser's moments in ``svi``: :func:`step` updates both in
    place."""

    svi: pyro.infer.SVI
    guide: MeanFieldGuide
    configs: dict[float, SpCoConfig]
    """The model config per coupling used so far (made once each)."""


class SVIInfo(NamedTuple):
    """What one SVI step did."""

    objective: float
    """The ELBO estimate of the step (minus its loss), at the step's coupling."""
    num_concepts: int
    """Concepts that are some cell's most probable one under the guide's q(C)."""
    gamma: float
    """The step's coupling."""


RESUMED_SMOOTHING = 1e-9
"""The label smoothing of a resumed run's q: the q reached, kept (only a zero is lifted)."""


def init(
    q: torch.Tensor,
    data: ModelData,
    config: SpCoConfig,
    options: SVIOptions,
    resumed: bool = False,
    given_start: bool = False,
) -> SVIState:
    """The guide started at ``q`` ``[N, L]`` (smoothed per
    ``options.start_smoothing(given_start)``: 0.9 unless set for a random q, 0.05 for given
    start labels or q; a ``resumed`` run's q, the one an interrupted run reached, by
    :data:`RESUMED_SMOOTHING` only: smoothed as a start it went most of the way back to uniform,
    and the ELBO with it), its loss and optimiser. Call inside the param-store scope the run
    uses (:func:`fit_svi`)."""
    smoothing = RESUMED_SMOOTHING if resumed else options.start_smoothing(given_start)
    guide = MeanFieldGuide(data, config, q=q, label_smoothing=smoothing, bound=options.bound)
    loss = MeanFieldELBO(num_particles=options.num_particles)
    svi = pyro.infer.SVI(spcomapping_model, guide, options.optimiser_for(guide), loss)
    return SVIState(svi, guide, {config.gamma: config})


def step(
    state: SVIState, data: ModelData, config: SpCoConfig, gamma: float
) -> tuple[SVIState, SVIInfo]:
    """One SVI step at coupling ``gamma``: the loss's gradient, one optimiser update."""
    if gamma not in state.configs:
        state.configs[gamma] = config.replace(gamma=gamma)
    value = -state.svi.step(data, state.configs[gamma])
    used = int(torch.unique(state.guide.logits().detach().argmax(-1)).numel())
    return state, SVIInfo(value, used, float(gamma))


@contextlib.contextmanager
def _diverged(options: SVIOptions) -> Iterator[None]:
    """A step that took the guide's parameters out of their support (torch's distribution check:
    'Expected parameter ... to satisfy the constraint', a tensor and Pyro's trace shapes, some 30
    lines) as one ValueError naming the step size (learning_rate 10 did it on the synthetic
    house; 1 ran)."""
    try:
        yield
    except ValueError as error:
        if not str(error).startswith("Expected parameter"):
            raise
        rates = f"learning_rate={options.learning_rate:g}"
        if options.global_learning_rate is not None:
            rates += f", global_learning_rate={options.global_learning_rate:g}"
        what = str(error).split(" to satisfy")[0].removeprefix("Expected parameter ")
        where = f"a {what.split('of distribution ')[-1].split('(')[0]}'s {what.split(' (')[0]}"
        raise ValueError(
            f"SVI diverged: an optimiser step ({rates}) left the guide's parameters where the "
            f"model is not defined ({where} out of its support); lower learning_rate (0.1 by "
            "default)"
        ) from None


def fit_svi(
    data: ModelData,
    config: SpCoConfig,
    steps: int,
    *,
    q: torch.Tensor,
    generator: torch.Generator,
    options: SVIOptions | None = None,
    progress: bool | None = None,
    thin: int = 0,
    resume: Trajectory | None = None,
    given_start: bool = False,
) -> VariationalRun:
    """At most ``steps`` SVI steps (:func:`step`) of the mean-field guide started at ``q``
    ``[N, L]``, run by the shared driver: annealed per ``options.anneal_iterations``, stopped
    once the windowed ELBO estimate settles (``options.tolerance``, ``options.window``).

    Runs in a fresh param-store scope (module docstring); the returned
    :class:`~spcopyro.guides.run.VariationalRun` holds the final guide's q(C) and global
    factors and, per step, the ELBO estimate (minus the SVI loss), the concepts in use, the
    seconds and the coupling. ``thin`` > 0 keeps the argmax labels every ``thin`` steps.
    ``resume``: the record of the run ``q`` was reached by (a checkpoint's), continued here
    with a fresh optimiser (its moments are not kept). ``given_start``: ``q`` is given start
    labels or a fitted q, not a random start (``label_smoothing`` None smooths it by 0.05, not
    0.9, and ``anneal_iterations`` None anneals over 0 steps, not 100:
    :meth:`SVIOptions.for_start`).
    """
    options = (SVIOptions() if options is None else options).for_start(given_start)
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    warn_unfinished_annealing(options.anneal_iterations, steps, "anneal_iterations", "step", resume)
    seed = int(torch.randint(0, 2**62, (), generator=generator))
    with torch.random.fork_rng(devices=[]), pyro.get_param_store().scope(), _diverged(options):
        torch.manual_seed(seed)
        run = drive(
            init(q, data, config, options, resumed=resume is not None, given_start=given_start),
            lambda state, gamma: step(state, data, config, gamma), steps, gamma=config.gamma,
            anneal=options.anneal_iterations, tolerance=options.tolerance,
            window=options.window, thin=thin,
            labels=lambda state: state.guide.logits().detach().argmax(-1),
            num_concepts=config.num_concepts, progress=progress, description="SVI",
            unit="step", resume=resume,
            marginals=lambda state: state.guide.marginals().detach(),
        )  # fmt: skip
        guide = run.state.guide
        q = guide.marginals()  # [N, L]
        context, way_out = flat_q_advice(options, resume is not None, given_start)
        warn_flat_q(q, config, "SVI", way_out, context=context)
        return VariationalRun.of(run, q, guide.factors())


def flat_q_advice(options: SVIOptions, resumed: bool, given_start: bool = False) -> tuple[str, str]:
    """SVI's own parts of the flat-q warning (:func:`~spcopyro.guides.run.warn_flat_q`): what
    its parenthesis says of the start (``options`` as given: fields left to the start are read
    as it ran them, :meth:`SVIOptions.for_start`) and the way out, which keeps a given start
    (its own smoothing, no annealing from gamma 0) or names a fitted one, or CAVI."""
    options = options.for_start(given_start)  # what ran (None: the start's)
    smoothing = options.label_smoothing  # set by for_start
    start = ("the resumed q" if resumed else
             f"{'given' if given_start else 'random'} labels, label_smoothing={smoothing:g}"
             + (f", annealed from gamma 0 over {options.anneal_iterations} steps"
                if options.anneal_iterations else ""))  # fmt: skip
    keep = []  # what would keep a given start: its own smoothing, no annealing from gamma 0
    if smoothing > GIVEN_START_SMOOTHING:
        keep.append(f"label_smoothing={GIVEN_START_SMOOTHING:g}, the default for given labels")
    if options.anneal_iterations:
        keep.append("anneal_iterations=0, the default for given labels: annealed from gamma 0 "
                    "a given start falls there too")  # fmt: skip
    cavi = setting("method='cavi'", "--method cavi")
    if given_start and not resumed:
        way_out = (f"Keep the given start ({'; '.join(keep)}) or use {cavi}" if keep
                   else f"Use {cavi}")  # fmt: skip
    else:
        way_out = (f"Start from a fitted map, {setting('init=result', '--init-from OUT')} or "
                   f"init_labels (smoothed by label_smoothing={GIVEN_START_SMOOTHING:g} and not "
                   "annealed, anneal_iterations=0, unless they are set), or use "
                   f"{cavi}")  # fmt: skip
    context = (f"start: {start}; Adam's steps lead there from random labels too: "
               "docs/variational.md")  # fmt: skip
    return context, way_out


class SVIInference(InferenceMethod):
    """Stochastic variational inference (:func:`fit_svi`) behind the common interface: one
    iteration is one SVI step (a ceiling: it stops at ``options.tolerance``), the trace the ELBO
    estimate per step."""

    name = "svi"
    objective_name = "ELBO"
    options_type = SVIOptions
    title = "SVI"
    resumable = True

    def fit(
        self, data: ModelData, config: SpCoConfig, options: SVIOptions, request: RunArgs
    ) -> InferenceOutput:
        q, before = resumed(request) or (
            initial_q(data, config, request.generator, request.init_labels),
            None,
        )
        # given start labels (a resumed run's too: its start's): smoothed by 0.05 and not
        # annealed unless set, recorded as what the start ran with
        given = request.init_labels is not None
        ran = options.for_start(given_start=given)
        run = fit_svi(
            data, config, remaining(request), q=q, generator=request.generator,
            options=ran, progress=request.progress, thin=request.thin, resume=before,
            given_start=given,
        )  # fmt: skip
        record = {"iterations": request.iterations, **dataclasses.asdict(ran)}
        return output_from_variational(run, record)
