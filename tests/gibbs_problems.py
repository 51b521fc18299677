"""Tiny SpCoMapping problems for the sampler's tests (exactly enumerable where needed)."""

from __future__ import annotations

import itertools
import types

import numpy as np
import torch

from spcopyro.config import SpCoConfig
from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
from spcopyro.model import DTYPE, ModelData, make_model_data


def tiny_grid(occupancy_rows: list[str]) -> OccupancyGrid:
    """A grid from strings: '.' free, '#' occupied."""
    occ = np.array([[FREE if ch == "." else OCCUPIED for ch in row] for row in occupancy_rows])
    return OccupancyGrid(occ.astype(np.int8), 0.1, (0.0, 0.0, 0.0))


def model_data(
    grid: OccupancyGrid,
    obs_cells: np.ndarray,
    image_counts: np.ndarray,
    word_counts: np.ndarray,
    connectivity: int = 4,
) -> ModelData:
    counts = types.SimpleNamespace(
        num_free=grid.num_free,
        cells=np.asarray(obs_cells, dtype=np.int64),
        image_counts=np.asarray(image_counts, dtype=np.float64),
        word_counts=np.asarray(word_counts, dtype=np.float64),
    )
    return make_model_data(grid, counts, connectivity)


def without_words(data: ModelData) -> ModelData:
    """The data with a words modality of V = 0 items (a house of images only, 001ba82)."""
    return data.with_counts("words", torch.zeros((data.obs_cells.shape[0], 0), dtype=DTYPE))


def with_connectivity(grid: OccupancyGrid, data: ModelData, connectivity: int) -> ModelData:
    """The same observations on ``grid`` (the data's own map), rebuilt with another
    neighbourhood (4 or 8)."""
    return model_data(grid, data.obs_cells.numpy(), data.image_counts.numpy(),
                      data.word_counts.numpy(), connectivity)  # fmt: skip


PROBLEM_ROWS = ["......", "..#...", "..#...", "......", "....#."]


def random_problem(
    seed: int,
    connectivity: int = 4,
    K: int = 3,
    V: int = 4,
    num_observed: int = 5,
    copies: int = 1,
) -> tuple[OccupancyGrid, ModelData]:
    """A 5 x 6 map with wall stubs and real-valued counts in a few cells.

    With ``copies`` > 1 the map and its observations are repeated, separated by walls, so one
    label sweep advances ``copies`` independent chains (see :func:`replicate_grid`).
    """
    grid, n = replicate_grid(PROBLEM_ROWS, copies)
    rng = np.random.default_rng(seed)
    cells = np.sort(rng.choice(n, num_observed, replace=False))
    images = rng.gamma(1.0, 2.0, (num_observed, K))
    words = rng.poisson(1.0, (num_observed, V)).astype(float) + rng.uniform(0, 0.5, (1, V))
    offsets = (np.arange(copies) * n)[:, None]
    return grid, model_data(
        grid,
        (offsets + cells).ravel(),
        np.tile(images, (copies, 1)),
        np.tile(words, (copies, 1)),
        connectivity,
    )


def replicate_grid(rows: list[str], copies: int) -> tuple[OccupancyGrid, int]:
    """``copies`` copies of a small map side by side, separated by walls: independent chains.

    Returns the grid and the number of free cells of one copy. Free indices of copy r are
    r * n + (0..n-1) in the small map's raster order (copies are stacked vertically).
    """
    width = len(rows[0])
    block = rows + ["#" * width]
    grid = tiny_grid((block * copies)[:-1])
    return grid, sum(row.count(".") for row in rows)


def all_labelings(num_cells: int, num_concepts: int) -> torch.Tensor:
    """[L^n, n] every label assignment of n cells."""
    return torch.tensor(list(itertools.product(range(num_concepts), repeat=num_cells)))


def state_index(labels: torch.Tensor, num_concepts: int) -> torch.Tensor:
    """[..., n] labelings -> [...] their row in :func:`all_labelings`."""
    n = labels.shape[-1]
    weights = num_concepts ** torch.arange(n - 1, -1, -1)
    return (labels * weights).sum(-1)


def config(**kw: object) -> SpCoConfig:
    base = dict(num_concepts=3, prior="dp", alpha=3.0, beta=1.0, chi=1.0, gamma=0.9)
    base.update(kw)
    return SpCoConfig(**base)  # type: ignore[arg-type]
