"""What every inference method of SpCoMapping offers, and what it hands back.

An inference method (Gibbs sampling in :mod:`spcopyro.gibbs`; variational methods beside it)
is an object with a ``name``, the name of the objective it traces, its options' type and a
:meth:`InferenceMethod.run` that fits the model to :class:`~spcopyro.model.ModelData` and returns
an :class:`InferenceOutput`: a point estimate of the labels (and, where the method has them,
per-cell marginals), point estimates or posterior means of pi and of each modality's
distributions, and a per-iteration :class:`Trace`. :mod:`spcopyro.fit.registry` lists the methods by
name; :class:`spcopyro.results.result.SpCoResult` turns an output into what users query (the
semantic
map, words per concept, "where is X?"), the same way for every method. The model's per-cell math
that a method needs is in :mod:`spcopyro.likelihood`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import (
    TYPE_CHECKING,
    ClassVar,
    NamedTuple,
    Protocol,
    TypeVar,
    get_args,
    get_type_hints,
    runtime_checkable,
)

import numpy as np

from spcopyro._util.number_checks import is_integer
from spcopyro.config import SpCoConfig

if (
    TYPE_CHECKING
):  # annotations only: a saved result is read without torch (spcopyro.results.result)
    import torch

    from spcopyro.inference.driver import Trajectory
    from spcopyro.model import ModelData


@dataclass(frozen=True)
class Trace:
    """A fit's per-iteration record. S iterations (Gibbs sweeps or variational updates)."""

    objective: np.ndarray
    """[S] float64: the log joint after each sweep (Gibbs) or the ELBO (variational)."""
    num_concepts: np.ndarray
    """[S] int64: concepts in use after each iteration."""
    seconds: np.ndarray
    """[S] float64: cumulative wall-clock seconds."""
    objective_name: str = "log joint"


@dataclass(frozen=True)
class InferenceOutput:
    """What an inference method returns, before the map and item names are attached."""

    labels: np.ndarray
    """[N] int64 point estimate of every free cell's concept."""
    pi: np.ndarray
    """[L] point estimate or posterior mean of pi."""
    emissions: tuple[np.ndarray, ...]
    """Per modality of the model data, [L, K_m] point estimates or posterior means."""
    trace: Trace
    best_iteration: int
    """The iteration (0-based) whose state ``labels`` and the globals are."""
    marginals: np.ndarray | None = None
    """[N, L] p(C_i = l) where the method has it (a variational q(C))."""
    labels_final: np.ndarray | None = None
    """[N] the last state's labels, for a sampler."""
    options: dict[str, object] = field(default_factory=dict)
    """The method's options (and seed, iterations), as JSON values: recorded with the result."""
    label_samples: np.ndarray | None = None
    """[S', N] int16 label maps kept along the way (a sampler with thinning), else None."""
    sample_iterations: np.ndarray | None = None
    """[S'] the 0-based iterations of ``label_samples``."""
    parameters_drawn: bool = False
    """True when ``pi`` and ``emissions`` are one posterior draw (a sampler's state), not means:
    :func:`spcopyro.fit.house.result_of` then reports their posterior means given the labels
    (:mod:`spcopyro.results.posterior_means`)."""
    agreement: np.ndarray | None = None
    """[N] where ``labels`` is a posterior point estimate over label samples
    (:mod:`spcopyro.results.point_estimate`): each cell's share of samples agreeing with it."""


OptionsT = TypeVar("OptionsT")


def method_options(options: object | None, kind: type[OptionsT], method: str) -> OptionsT:
    """A method's options: ``kind()`` (its defaults) for None, ``options`` when it is a ``kind``,
    else TypeError naming the method and the type it takes."""
    if options is None:
        return kind()
    if not isinstance(options, kind):
        raise TypeError(f"{method} takes {kind.__name__}, got {type(options).__name__}")
    return options


@runtime_checkable
class StartDependentOptions(Protocol):
    """A method's options whose defaults depend on the start (svi's
    :class:`~spcopyro.guides.svi_method.SVIOptions`: ``label_smoothing`` and
    ``anneal_iterations`` left None get one value for a random start, another for given start
    labels). What an options object may offer beside its fields; every other method's options
    run as given, whatever the start. Read through :func:`options_for_start`."""

    def for_start(self, given_start: bool) -> object:
        """These options with the fields left to the start set to what a run from a random
        start (``given_start`` False) or from given start labels or q (True) runs with."""
        ...


def options_for_start(options: OptionsT, given_start: bool) -> OptionsT:
    """``options`` as a run from that start runs them: the fields left to the start set
    (:class:`StartDependentOptions`), ``options`` itself where nothing depends on the start.
    What a fit records, a checkpoint compares and a report counts."""
    if isinstance(options, StartDependentOptions):
        return options.for_start(given_start)  # type: ignore[return-value]
    return options


def start_filled(given: object, ran: object) -> dict[str, object]:
    """The fields of dataclass options ``given`` left to the start (None) that ``ran``
    (:func:`options_for_start` of them) sets: name -> the value run, in field order. What fit's
    options line notes and a checkpoint refusal names as unset."""
    if not (dataclasses.is_dataclass(given) and dataclasses.is_dataclass(ran)):
        return {}
    return {f.name: getattr(ran, f.name) for f in dataclasses.fields(ran)  # type: ignore[arg-type]
            if getattr(given, f.name) is None and getattr(ran, f.name) is not None}  # fmt: skip


@runtime_checkable
class ResumeIgnoringOptions(Protocol):
    """A method's options with fields a resumed run does not read (svi's
    :class:`~spcopyro.guides.svi_method.SVIOptions`: ``label_smoothing``, which smooths the
    start only; a resumed run goes on from the q it had reached). A checkpoint's record of those
    fields is not compared on resuming (:mod:`spcopyro.guides.checkpoint`); every other
    method's options are compared whole. Read through :func:`resume_ignores`."""

    RESUME_IGNORES: ClassVar[tuple[str, ...]]
    """The names of the fields a resumed run does not read."""


def resume_ignores(options: object) -> tuple[str, ...]:
    """The fields of ``options`` that a resumed run does not read
    (:class:`ResumeIgnoringOptions`; none where the options' class declares none)."""
    if isinstance(options, ResumeIgnoringOptions):
        return tuple(type(options).RESUME_IGNORES)
    return ()


class Resumption(NamedTuple):
    """Where a variational fit that was interrupted goes on (a checkpoint's content,
    :mod:`spcopyro.guides.checkpoint`): the q(C) it had reached and the record of its
    iterations so far."""

    marginals: torch.Tensor
    """[N, L] float64 q(C_i = l) after the last completed iteration."""
    trajectory: Trajectory
    """The driver's record of those iterations (the new ones are numbered on from it)."""


class RunArgs(NamedTuple):
    """The arguments of :meth:`InferenceMethod.run` other than the data, config and options,
    as :meth:`InferenceMethod.fit` receives them."""

    iterations: int
    generator: torch.Generator
    init_labels: torch.Tensor | None = None
    progress: bool | None = None
    thin: int = 0
    resume: Resumption | None = None
    """A variational method: go on from here (``iterations`` stays the whole run's ceiling)."""


class InferenceMethod(Protocol):
    """An inference method for :func:`~spcopyro.model.spcomapping_model` (see the module doc).

    A method may implement :meth:`run` itself (the protocol), or subclass this class, set
    ``options_type`` and ``title`` and implement :meth:`fit`: the :meth:`run` below then checks the
    options and hands the rest to :meth:`fit` (every method of spcopyro does so).
    """

    name: str
    """The registry's key, e.g. ``"gibbs"``."""
    objective_name: str
    """What :attr:`Trace.objective` holds, e.g. ``"log joint"`` or ``"ELBO"``."""
    options_type: type = type(None)
    """The type of the method's options (for subclasses: :meth:`run` checks it)."""
    title: str = ""
    """The method's name in messages, e.g. ``"Gibbs sampling"``."""
    resumable: bool = False
    """Whether :meth:`run` takes ``resume`` (a variational checkpoint's q(C) and record; Gibbs
    chains resume through :mod:`spcopyro.gibbs.checkpoint`)."""

    def default_options(self) -> object:
        """The method's options object with its defaults."""
        return self.options_type()

    def run(
        self,
        data: ModelData,
        config: SpCoConfig,
        *,
        iterations: int,
        generator: torch.Generator,
        init_labels: torch.Tensor | None = None,
        options: object | None = None,
        progress: bool | None = None,
        thin: int = 0,
        resume: Resumption | None = None,
    ) -> InferenceOutput:
        """Fit the model to ``data`` with ``iterations`` iterations (a ceiling for a method that
        stops at convergence), drawing from ``generator`` (a seeded generator makes the fit
        reproducible); ``thin`` > 0 keeps a label map every ``thin`` iterations where the method
        has such maps. ``resume``: a variational method (:attr:`resumable`) goes on from an
        interrupted run's q(C) and record instead of starting at ``init_labels``."""
        from spcopyro._util.random_draws import check_generator  # torch: not at import
        from spcopyro.model import check_model_data

        options = method_options(options, self.options_type, self.title or self.name)
        check_model_data(data, config)
        # before a resumed run's count ("nothing left of the 0 asked for") or a draw names them
        if not is_integer(iterations) or iterations < 1:
            raise ValueError(f"iterations must be an integer >= 1, got {iterations!r}")
        check_generator(generator)
        if resume is not None and not self.resumable:
            raise ValueError(f"{self.title or self.name} does not resume from a checkpoint")
        request = RunArgs(iterations, generator, init_labels, progress, thin, resume)
        return self.fit(data, config, options, request)

    def fit(
        self, data: ModelData, config: SpCoConfig, options: object, request: RunArgs
    ) -> InferenceOutput:
        """:meth:`run` with its options checked (for subclasses)."""
        raise NotImplementedError(f"{type(self).__name__} implements neither run nor fit")


def _parse_value(text: str, current: object, where: str) -> object:
    """``text`` as a value of ``current``'s type (bool, int, float or str)."""
    if isinstance(current, bool):
        if text.lower() in ("true", "1", "yes", "on"):
            return True
        if text.lower() in ("false", "0", "no", "off"):
            return False
        raise ValueError(f"{where}: expected true or false, got {text!r}")
    for kind in (int, float):
        if isinstance(current, kind):
            try:
                return kind(text)
            except ValueError:
                wanted = "an integer" if kind is int else "a number"
                raise ValueError(f"{where}: expected {wanted}, got {text!r}") from None
    return text


def with_options(options: object, assignments: Sequence[str]) -> object:
    """A copy of a method's options dataclass with ``NAME=VALUE`` assignments applied (each
    value parsed as its field's current type; ``outer.inner=VALUE`` reaches a nested options
    object, e.g. vi-gibbs' ``variational.anneal_iterations``). The dataclass validates the
    result; an unknown name is a ValueError listing the known ones."""
    for assignment in assignments:
        name, sep, text = assignment.partition("=")
        if not sep or not name:
            raise ValueError(f"method option {assignment!r}: expected NAME=VALUE")
        options = _assign(options, name.strip().split("."), text.strip(), assignment)
    return options


def _assign(options: object, path: list[str], text: str, assignment: str) -> object:
    if not dataclasses.is_dataclass(options):
        raise ValueError(f"method option {assignment!r}: {type(options).__name__} has no fields")
    fields = {f.name for f in dataclasses.fields(options)}
    if path[0] not in fields:
        raise ValueError(
            f"method option {assignment!r}: {type(options).__name__} has no field "
            f"{path[0]!r}; it has {sorted(fields)}"
        )
    current = getattr(options, path[0])
    if len(path) > 1:
        value = _assign(current, path[1:], text, assignment)
    else:  # a field that may be None (svi's global_learning_rate): parsed as its declared type
        kind, optional = _declared(options, path[0])
        if optional and text.lower() in ("none", "null"):
            value = None
        else:
            like = kind() if current is None and kind is not None else current
            value = _parse_value(text, like, f"method option {assignment!r}")
    return dataclasses.replace(options, **{path[0]: value})


def _declared(options: object, name: str) -> tuple[type | None, bool]:
    """The scalar type (bool, int, float or str) a field of ``options`` is declared with (None:
    none of those) and whether it may be None."""
    try:
        hint = get_type_hints(type(options))[name]
    except Exception:  # an annotation that does not resolve: the current value's type decides
        return None, False
    kinds = get_args(hint) or (hint,)
    scalars = [kind for kind in kinds if kind in (bool, int, float, str)]
    return (scalars[0] if scalars else None), type(None) in kinds
