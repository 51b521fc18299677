"""The methods of the comparison (paper Table 4), each fitted to one house the same way.

Rows, in order (:data:`REGISTRY`; a new row -- e.g. SpCoMapping fitted by another inference
method of :mod:`spcopyro.fit.registry` -- is one :func:`register` call):

* ``A-dp``: SpCoMapping with the weak-limit DP prior, the ``paper-dp`` preset (Section 4.1:
  alpha 1e8, beta 500, chi 1e4, gamma 4, L 120), random initial labels.
* ``A-orig-g3``: SpCoMapping DP with the released code's values (``original-code``: alpha 1e7,
  beta 0.1, chi 1, floor(100 f) features, L 120) but gamma 3 instead of 2.1 (2.1 lies below the
  Potts critical coupling ln(1 + sqrt(120)) = 2.48 and forms no regions).
* ``B-dirichlet``: SpCoMapping with the finite Dirichlet prior, ``paper-dirichlet`` (alpha 5e7,
  beta 100, chi 1e4, gamma 3), L = the number of ground-truth categories of the house.
* ``C-spcoa``: spatial concepts over observations (:mod:`spcopyro.baselines.spcoa`).
* ``D-cnn``: each image's most probable place class, nearest-filled (:mod:`~.baselines.cnn`).
* ``E-nearest``: the word of the nearest utterance (:mod:`spcopyro.baselines.nearest`).
* ``F-geometry``: room segmentation of the occupancy map, no words or images
  (:mod:`spcopyro.baselines.geometry`).
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
import torch

from spcopyro._util.threads import AUTO, resolve_threads, torch_threads
from spcopyro.baselines.cnn import cnn_semantic_map
from spcopyro.baselines.geometry import DEFAULT_DOOR_WIDTH, geometry_semantic_map
from spcopyro.baselines.nearest import nearest_word_map
from spcopyro.baselines.spcoa import fit_spcoa
from spcopyro.config import SpCoSettings, preset
from spcopyro.data import House
from spcopyro.fit.house import log_degenerate_map, prepare_model_data, result_of
from spcopyro.fit.registry import get_method
from spcopyro.metrics import adjusted_rand_index
from spcopyro.results.result import SpCoResult
from spcopyro.results.semantic_map import SemanticMapModel, SpCoSemanticMap


def _spcoa_options() -> dict[str, object]:
    """Every keyword of :func:`~spcopyro.baselines.spcoa.fit_spcoa` but ``iterations`` and
    ``seed``, at its defaults, with the baseline's own L and word weighting."""
    keywords = inspect.signature(fit_spcoa).parameters.values()
    own = {"iterations", "seed"}  # the run's (RunSettings.spcoa_iterations, FitContext.seed)
    defaults = {k.name: k.default for k in keywords if k.kind is k.KEYWORD_ONLY}
    options = {name: value for name, value in defaults.items() if name not in own}
    return {**options, "num_concepts": 20, "word_weighting": "auto"}


SPCOA_OPTIONS: Mapping[str, object] = MappingProxyType(_spcoa_options())
"""What the SpCoA baseline (``C-spcoa``) is fitted with besides its iterations and seed: every
keyword of :func:`~spcopyro.baselines.spcoa.fit_spcoa`, resolved -- ``num_concepts`` 20 (L, an
upper bound: its weak-limit DP leaves unneeded concepts empty), ``word_weighting`` ``"auto"``
(as SpCoMapping's fit by default: tf-idf on a house of sentences,
:mod:`spcopyro.data.word_weighting`), the others fit_spcoa's defaults. The row's fit passes
these, and a study cell's key holds them (:func:`spcopyro.study.cells.cell_key`), so a change
of any of them runs the cached C-spcoa cells again."""
PUBLIC_DOOR_WIDTH = 2.0
"""Door width (m) of the geometry baseline on the public houses, whose rooms open through gaps
of about 1.7 m (a 1 m door width merges them)."""


@dataclass(frozen=True)
class RunSettings:
    """How long each method runs."""

    sweeps: int = 5000
    """Iterations of SpCoMapping's inference (Gibbs sweeps; paper: 5000)."""
    spcoa_iterations: int = 200
    trace_every: int = 50
    """Keep a label map every this many sweeps for the ARI-per-sweep figure (synthetic only)."""


@dataclass
class Fitted:
    """One method fitted to one house."""

    method: str
    model: SemanticMapModel
    seconds: float
    result: SpCoResult | None = None
    """SpCoMapping's result (None for the baselines)."""
    ari_trace: tuple[np.ndarray, np.ndarray] | None = None
    """(sweeps [S'], ARI [S']) of the sampled label maps against the truth (synthetic only)."""
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class FitContext:
    """What a row's fit may read besides the house."""

    settings: RunSettings
    seed: int = 0
    num_categories: int | None = None
    """The number of ground-truth categories (L of ``B-dirichlet``)."""
    public: bool = False
    """The house is one of the public dataset."""


@dataclass(frozen=True)
class Method:
    """One row of the comparison: a label for the table and how to fit it to a house."""

    key: str
    label: str
    fit: Callable[[House, FitContext], Fitted]
    settings: Callable[[int | None], SpCoSettings] | None = None
    """For a fit of SpCoMapping itself (any inference method): its settings given the house's
    number of categories; None for a baseline."""

    @property
    def spcomapping(self) -> bool:
        """Whether the row fits SpCoMapping (rather than a baseline)."""
        return self.settings is not None


REGISTRY: dict[str, Method] = {}
"""Every row, in table order. A new row is one :func:`register` call."""


def register(method: Method) -> Method:
    """Add a row to :data:`REGISTRY` (ValueError if the key is taken)."""
    if method.key in REGISTRY:
        raise ValueError(f"method {method.key!r} is registered already")
    REGISTRY[method.key] = method
    return method


def fit_spco(
    house: House,
    settings: SpCoSettings,
    *,
    sweeps: int,
    seed: int,
    thin: int = 0,
    method: str = "gibbs",
    options: object | None = None,
    threads: int | str | None = AUTO,
) -> tuple[SpCoResult, tuple[np.ndarray, np.ndarray] | None]:
    """SpCoMapping by the inference method ``method`` (:mod:`spcopyro.fit.registry`) from random
    labels (as :func:`spcopyro.fit.house.fit_house` with ``init="random"``), keeping a label map
    every
    ``thin`` iterations; with a truth, their ARI per iteration (paper Fig. 5). ``threads``: torch
    intra-op threads during the run (:mod:`spcopyro._util.threads`; default: its policy). The
    map is checked as ``fit_house`` checks its own (:func:`log_degenerate_map`, with the
    caller's :func:`~spcopyro.results.map_checks.degenerate_map_advice`: a study cell's is the
    study's).
    """
    counts, data = prepare_model_data(house, settings, method=method)
    generator = torch.Generator().manual_seed(int(seed))
    with torch_threads(resolve_threads(threads, house.grid.num_free)):
        output = get_method(method).run(
            data, settings.model, iterations=sweeps, generator=generator, options=options,
            progress=False, thin=thin,
        )  # fmt: skip
    result = result_of(output, house, counts, data, settings, method)
    trace = None
    if house.truth is not None and output.label_samples is not None:
        image = np.full(house.grid.shape, -1, dtype=np.int64)  # [H, W]
        aris = []
        for sample in output.label_samples:  # [N] int16 each
            image[house.grid.free] = sample  # free cells in raster = free-index order
            aris.append(adjusted_rand_index(image, house.truth))
        trace = (output.sample_iterations + 1, np.asarray(aris))
    log_degenerate_map(result, house)
    return result, trace


def spcomapping_row(
    key: str, label: str, settings: Callable[[int | None], SpCoSettings], method: str = "gibbs"
) -> Method:
    """A row fitting SpCoMapping with ``settings(num_categories)`` by the inference ``method``."""

    def fit(house: House, context: FitContext) -> Fitted:
        thin = context.settings.trace_every if house.truth is not None else 0
        result, trace = fit_spco(
            house, settings(context.num_categories), sweeps=context.settings.sweeps,
            seed=context.seed, thin=thin, method=method,
        )  # fmt: skip
        return Fitted(key, SpCoSemanticMap(result), 0.0, result=result, ari_trace=trace)

    return Method(key, label, fit, settings=settings)


def _dirichlet_settings(num_categories: int | None) -> SpCoSettings:
    if not num_categories:
        raise ValueError("B-dirichlet needs the number of categories of the house (L)")
    return preset("paper-dirichlet", num_concepts=int(num_categories))


def _fit_spcoa(house: House, context: FitContext) -> Fitted:
    model = fit_spcoa(
        house, iterations=context.settings.spcoa_iterations, seed=context.seed, **SPCOA_OPTIONS
    )
    return Fitted("C-spcoa", model, 0.0)


def _fit_geometry(house: House, context: FitContext) -> Fitted:
    door = PUBLIC_DOOR_WIDTH if context.public else DEFAULT_DOOR_WIDTH
    model = geometry_semantic_map(house.grid, house.observations, door_width=door)
    return Fitted("F-geometry", model, 0.0)


register(spcomapping_row(
    "A-dp", "(A) SpCoMapping DP [paper-dp: gamma 4, L 120]", lambda _: preset("paper-dp"),
))  # fmt: skip
register(spcomapping_row(
    "A-orig-g3", "(A') SpCoMapping DP [original-code values, gamma 3]",
    lambda _: preset("original-code", gamma=3.0),
))  # fmt: skip
register(spcomapping_row(
    "B-dirichlet", "(B) SpCoMapping Dirichlet [paper-dirichlet, L = #categories]",
    _dirichlet_settings,
))  # fmt: skip
register(Method("C-spcoa", "(C) SpCoA (spatial concepts over observations)", _fit_spcoa))
register(Method(
    "D-cnn", "(D) CNN place classes, nearest-filled",
    lambda house, _: Fitted("D-cnn", cnn_semantic_map(house.grid, house.observations), 0.0),
))  # fmt: skip
register(Method(
    "E-nearest", "(E) nearest utterance's word",
    lambda house, _: Fitted("E-nearest", nearest_word_map(house.grid, house.observations), 0.0),
))  # fmt: skip
register(Method("F-geometry", "(F) geometry only (room segmentation)", _fit_geometry))

METHODS = tuple(REGISTRY)
"""The rows' keys in table order."""
SPCO_METHODS = tuple(key for key, method in REGISTRY.items() if method.spcomapping)
METHOD_LABELS = {key: method.label for key, method in REGISTRY.items()}


def spco_settings(method: str, num_categories: int | None) -> SpCoSettings:
    """The settings of an SpCoMapping row (see the module docstring)."""
    row = REGISTRY.get(method)
    if row is None or row.settings is None:
        raise ValueError(f"{method!r} is not an SpCoMapping method; choose one of {SPCO_METHODS}")
    return row.settings(num_categories)


def fit_method(
    method: str,
    house: House,
    settings: RunSettings,
    *,
    seed: int = 0,
    num_categories: int | None = None,
    public: bool = False,
) -> Fitted:
    """Fit ``method`` (a key of :data:`REGISTRY`) to ``house``.

    ``num_categories``: L of ``B-dirichlet``. ``public``: the house is one of the public dataset
    (the geometry baseline then uses :data:`PUBLIC_DOOR_WIDTH`). Every method runs with the
    torch threads of the fit's policy (:mod:`spcopyro._util.threads`), baselines too: SpCoA with
    torch's default of one thread a core took 9.2 s on room1dk5 beside another process, 1.1 s
    with one.
    """
    if method not in REGISTRY:
        raise ValueError(f"unknown method {method!r}; choose one of {METHODS}")
    start = time.perf_counter()
    context = FitContext(settings, seed=seed, num_categories=num_categories, public=public)
    with torch_threads(resolve_threads(AUTO, house.grid.num_free)):
        fitted = REGISTRY[method].fit(house, context)
    fitted.seconds = time.perf_counter() - start
    return fitted
