"""Where a fit's labels start: the paper's Gaussians over the observed cells (eqs. 21-22), a
SpCoA fit's Gaussians, one concept per geometric room, or a previous fit's labels (a warm start).

:func:`initial_labels` picks one by name (:data:`~spcopyro.inference.initialisation.INITS`);
``"random"`` leaves the start to the inference method.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from spcopyro.config import SpCoConfig, SpCoSettings
from spcopyro.data import CellCounts, House
from spcopyro.inference.initialisation import (
    INITS,
    kmeans_gaussians,
    labels_from_gaussians,
    more_concepts_remedy,
)
from spcopyro.maps.grid import describe_map, same_free_cells
from spcopyro.model import DTYPE
from spcopyro.results.result import SpCoResult


def free_cell_positions(house: House) -> torch.Tensor:
    """[N, 2] world (x, y) of every free cell's centre, in free-index order."""
    grid = house.grid
    return torch.as_tensor(grid.cell_to_world(grid.free_cells), dtype=DTYPE)


def gaussian_initial_labels(
    house: House, counts: CellCounts, config: SpCoConfig, generator: torch.Generator
) -> torch.Tensor:
    """[N] labels from Gaussians over the positions of the observed cells (eqs. 21-22).

    A stand-in for spatial-concept pre-learning: k-means with k = L on the observed cells'
    centres, then each free cell takes its most probable Gaussian.
    """
    cell_xy = free_cell_positions(house)  # [N, 2]
    points = cell_xy[torch.as_tensor(counts.cells)]  # [M, 2]
    means, covariances, log_weights = kmeans_gaussians(points, config.num_concepts, generator)
    return labels_from_gaussians(cell_xy, means, covariances, log_weights)


def spcoa_initial_labels(house: House, settings: SpCoSettings, seed: int) -> torch.Tensor:
    """[N] labels from spatial-concept pre-learning (paper Section 5, eqs. 21-22): the Gaussians
    of a SpCoA fit (:func:`spcopyro.baselines.spcoa.spcoa_gaussians`), at most L of them."""
    from spcopyro.baselines.spcoa import spcoa_gaussians

    cell_xy = free_cell_positions(house)  # [N, 2]
    means, covariances, log_weights = spcoa_gaussians(
        house, num_concepts=settings.model.num_concepts, seed=seed,
        word_weighting=settings.data.word_weighting,
    )  # fmt: skip
    return labels_from_gaussians(cell_xy, means, covariances, log_weights)


Init = str | SpCoResult
"""A start: a name of :data:`INITS`, or a previous fit's :class:`SpCoResult` (a warm start)."""


def check_init(init: object) -> None:
    """ValueError unless ``init`` is one of :data:`INITS` or an :class:`SpCoResult`."""
    if isinstance(init, SpCoResult) or (isinstance(init, str) and init in INITS):
        return
    got = repr(init) if isinstance(init, str) else f"a {type(init).__name__}"
    raise ValueError(
        f"init must be one of {INITS} or a previous fit's SpCoResult on the same map, got "
        f"{got} (labels of your own start run_gibbs or an inference method's run through "
        "init_labels)"
    )


def init_name(init: Init) -> str:
    """``init`` as ``config.json`` records it: the name, or ``"result of METHOD"``."""
    check_init(init)
    return init if isinstance(init, str) else f"result of {init.method}"


RENUMBER_RESULT = "spcopyro.results.renumber.renumbered(result, perm)"
"""How a previous fit starting another is renumbered to fewer concepts (:func:`result_labels`)."""


def result_labels(result: SpCoResult, house: House, config: SpCoConfig) -> torch.Tensor:
    """[N] a previous fit's point labels as the start of a new one (a warm start: a Gibbs fit
    starting variational inference, or the other way round). A fit on a coarsening of this
    house's map (``--cell-size``; its grid's ``coarsened_from`` is this map) starts it with its
    labels refined to the map's cells (:func:`~spcopyro.maps.coarse.refine_labels`: each free
    map cell takes its model cell's label, or the nearest one's); a fit on this house's map
    starts a fit on its coarsening with each model cell's most frequent label
    (:func:`~spcopyro.maps.coarse.coarsen_labels`; e.g. a refined fit, on the map's cells,
    starting a default fit on the model grid). ValueError if it was made on another map or with
    more concepts than ``config`` has."""
    coarse_of = result.grid.coarsened_from
    if coarse_of is not None and same_free_cells(coarse_of, house.grid):
        from spcopyro.maps.coarse import refine_labels

        factor = round(result.grid.resolution / house.grid.resolution)
        image = refine_labels(result.label_image(), house.grid, factor)  # [H, W]
        cells = np.asarray(house.grid.free_cells)  # [N, 2]
        result = dataclasses.replace(
            result, grid=house.grid, labels=image[cells[:, 0], cells[:, 1]].astype(np.int64)
        )
    fine_of = house.grid.coarsened_from  # this fit on a coarsening of the result's map
    if fine_of is not None and same_free_cells(fine_of, result.grid) and coarse_of is None:
        from spcopyro.maps.coarse import coarsen_labels

        factor = round(house.grid.resolution / result.grid.resolution)
        image = coarsen_labels(result.label_image(), result.grid, factor)  # [h, w]
        cells = np.asarray(house.grid.free_cells)  # [N, 2]
        result = dataclasses.replace(
            result, grid=house.grid, labels=image[cells[:, 0], cells[:, 1]].astype(np.int64)
        )
    if not same_free_cells(result.grid, house.grid):  # labels are indexed by free cell
        old, grid = result.grid, house.grid
        moved = ""
        if old.shape == grid.shape and not np.array_equal(old.free, grid.free):
            moved = f" ({int((old.free != grid.free).sum())} cells differ in being free)"
        raise ValueError(
            f"the starting result was fitted on {describe_map(old)}; this house's map is "
            f"{describe_map(grid)}{moved}"
        )
    labels = np.asarray(result.labels)
    if labels.max() >= config.num_concepts:
        remedy = more_concepts_remedy(labels, config.num_concepts, RENUMBER_RESULT)
        raise ValueError(
            f"the starting result uses concept {labels.max()}, beyond this fit's "
            f"num_concepts = {config.num_concepts} (concepts 0..{config.num_concepts - 1}): "
            f"{remedy}"
        )
    return torch.as_tensor(labels, dtype=torch.long)


def rooms_initial_labels(
    house: House, config: SpCoConfig, generator: torch.Generator, door_width: float | None = None
) -> torch.Tensor:
    """[N] labels from the map alone: one concept per room of a geometric room segmentation
    (:func:`spcopyro.maps.rooms.room_segments`, the (F) baseline's; doorways up to
    ``door_width`` metres, default its own, separate rooms), rooms beyond L sharing concepts
    (room r gets r mod L). The segmentation labels every free cell (cut-off pieces are segments
    of their own); the [N] uniform draw beside it is kept so that the generator's stream, and
    with it every seeded fit, is as before, though no cell takes it. A start, not a prior: the
    sampler then lets the observations move, merge (merge moves) and split the regions; only the
    speed at which it gets there depends on the start."""
    from spcopyro.maps.rooms import DEFAULT_DOOR_WIDTH, free_cell_rooms

    width = DEFAULT_DOOR_WIDTH if door_width is None else door_width
    room = torch.as_tensor(free_cell_rooms(house.grid, width), dtype=torch.long)  # [N] >= 0
    L = config.num_concepts
    torch.randint(L, (len(room),), generator=generator)  # [N] drawn for the stream alone
    return room % L


def initial_labels(
    house: House,
    counts: CellCounts,
    settings: SpCoSettings,
    init: Init,
    seed: int,
    generator: torch.Generator,
) -> torch.Tensor | None:
    """[N] starting labels: None for ``"random"`` (the method draws them), else ``"gaussian"``
    (k-means Gaussians over the observed cells), ``"spcoa"`` (a SpCoA fit's Gaussians),
    ``"rooms"`` (one concept per geometric room: :func:`rooms_initial_labels`) or a previous
    :class:`SpCoResult`'s labels (:func:`result_labels`)."""
    if isinstance(init, SpCoResult):
        return result_labels(init, house, settings.model)
    check_init(init)
    if init == "gaussian":
        return gaussian_initial_labels(house, counts, settings.model, generator)
    if init == "spcoa":
        return spcoa_initial_labels(house, settings, seed)
    if init == "rooms":
        return rooms_initial_labels(house, settings.model, generator)
    return None
