"""The methods of the comparison (paper Table 4), each fitted to one house the same way.

Rows, in order (:data:`METHODS`):

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

import time
from dataclasses import dataclass, field

import numpy as np
import torch

from spcopyro.baselines.cnn import cnn_semantic_map
from spcopyro.baselines.geometry import DEFAULT_DOOR_WIDTH, geometry_semantic_map
from spcopyro.baselines.nearest import nearest_word_map
from spcopyro.baselines.spcoa import fit_spcoa
from spcopyro.config import SpCoConfig, preset
from spcopyro.data import DEFAULT_SNAP_DISTANCE, House
from spcopyro.fit import prepare_model_data
from spcopyro.gibbs.api import run_gibbs
from spcopyro.metrics import SemanticMapModel, SpCoSemanticMap, adjusted_rand_index
from spcopyro.results import SpCoResult

SPCO_METHODS = ("A-dp", "A-orig-g3", "B-dirichlet")
METHODS = (*SPCO_METHODS, "C-spcoa", "D-cnn", "E-nearest", "F-geometry")
METHOD_LABELS = {
    "A-dp": "(A) SpCoMapping DP [paper-dp: gamma 4, L 120]",
    "A-orig-g3": "(A') SpCoMapping DP [original-code values, gamma 3]",
    "B-dirichlet": "(B) SpCoMapping Dirichlet [paper-dirichlet, L = #categories]",
    "C-spcoa": "(C) SpCoA (spatial concepts over observations)",
    "D-cnn": "(D) CNN place classes, nearest-filled",
    "E-nearest": "(E) nearest utterance's word",
    "F-geometry": "(F) geometry only (room segmentation)",
}
SPCOA_CONCEPTS = 20
"""L of the SpCoA baseline (an upper bound: its weak-limit DP leaves unneeded concepts empty)."""
PUBLIC_DOOR_WIDTH = 2.0
"""Door width (m) of the geometry baseline on the public houses, whose rooms open through gaps
of about 1.7 m (a 1 m door width merges them)."""


@dataclass(frozen=True)
class RunSettings:
    """How long each method runs."""

    sweeps: int = 5000
    """Gibbs sweeps of SpCoMapping (paper: 5000)."""
    spcoa_iterations: int = 200
    trace_every: int = 50
    """Keep a label map every this many sweeps for the ARI-per-sweep figure (synthetic only)."""


def spco_config(method: str, num_categories: int | None) -> SpCoConfig:
    """The :class:`SpCoConfig` of an SpCoMapping row (see the module docstring)."""
    if method == "A-dp":
        return preset("paper-dp")
    if method == "A-orig-g3":
        return preset("original-code", gamma=3.0)
    if method == "B-dirichlet":
        if not num_categories:
            raise ValueError("B-dirichlet needs the number of categories of the house (L)")
        return preset("paper-dirichlet", num_concepts=int(num_categories))
    raise ValueError(f"{method!r} is not an SpCoMapping method; choose one of {SPCO_METHODS}")


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


def fit_spco(
    house: House,
    config: SpCoConfig,
    *,
    sweeps: int,
    seed: int,
    thin: int = 0,
    backend: str = "auto",
) -> tuple[SpCoResult, tuple[np.ndarray, np.ndarray] | None]:
    """SpCoMapping from random labels (as :func:`spcopyro.fit.fit_house` with ``init="random"``),
    keeping a label map every ``thin`` sweeps; with a truth, their ARI per sweep (paper Fig. 5).
    """
    counts, data = prepare_model_data(house, config, DEFAULT_SNAP_DISTANCE)
    generator = torch.Generator().manual_seed(int(seed))
    run = run_gibbs(
        data, config, sweeps, generator=generator, thin=thin, backend=backend, progress=False
    )
    result = SpCoResult.from_run(run, house.grid, counts.vocabulary, config, name=house.name)
    trace = None
    if house.truth is not None and run.label_samples is not None:
        image = np.full(house.grid.shape, -1, dtype=np.int64)  # [H, W]
        aris = []
        for sample in run.label_samples:  # [N] int16 each
            image[house.grid.free] = sample  # free cells in raster = free-index order
            aris.append(adjusted_rand_index(image, house.truth))
        trace = (run.sample_sweeps + 1, np.asarray(aris))
    return result, trace


def fit_method(
    method: str,
    house: House,
    settings: RunSettings,
    *,
    seed: int = 0,
    num_categories: int | None = None,
    public: bool = False,
) -> Fitted:
    """Fit ``method`` (one of :data:`METHODS`) to ``house``.

    ``num_categories``: L of ``B-dirichlet``. ``public``: the house is one of the public dataset
    (the geometry baseline then uses :data:`PUBLIC_DOOR_WIDTH`).
    """
    start = time.perf_counter()
    if method in SPCO_METHODS:
        config = spco_config(method, num_categories)
        thin = settings.trace_every if house.truth is not None else 0
        result, trace = fit_spco(house, config, sweeps=settings.sweeps, seed=seed, thin=thin)
        fitted = Fitted(method, SpCoSemanticMap(result), 0.0, result=result, ari_trace=trace)
    elif method == "C-spcoa":
        model = fit_spcoa(
            house, num_concepts=SPCOA_CONCEPTS, iterations=settings.spcoa_iterations, seed=seed
        )
        fitted = Fitted(method, model, 0.0)
    elif method == "D-cnn":
        fitted = Fitted(method, cnn_semantic_map(house.grid, house.observations), 0.0)
    elif method == "E-nearest":
        fitted = Fitted(method, nearest_word_map(house.grid, house.observations), 0.0)
    elif method == "F-geometry":
        door = PUBLIC_DOOR_WIDTH if public else DEFAULT_DOOR_WIDTH
        model = geometry_semantic_map(house.grid, house.observations, door_width=door)
        fitted = Fitted(method, model, 0.0)
    else:
        raise ValueError(f"unknown method {method!r}; choose one of {METHODS}")
    fitted.seconds = time.perf_counter() - start
    return fitted
