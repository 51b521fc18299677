"""A house on the model's grid (``DataPreparation.cell_size``, :mod:`spcopyro.maps.coarse`)."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from spcopyro.data.dataset import House
from spcopyro.maps.coarse import coarsen_grid, coarsening_factor, model_cell_of

__all__ = ["model_house"]

_TOLD: set[tuple[object, ...]] = set()
"""The warnings given, by (house, map file, shape, cell size): :func:`_tell_once`."""


def _coarsen_truth(house: House, factor: int, coarse_free: np.ndarray) -> np.ndarray:
    """``[h, w]`` truth: each free model cell's most frequent category among its map cells'
    (the smallest on ties), -1 where none is labelled or off free."""
    truth = np.asarray(house.truth)  # [H, W]
    rows, cols = model_cell_of(house.grid, factor)
    labelled = truth >= 0
    block = rows[:, None] * coarse_free.shape[1] + cols[None, :]  # [H, W] model cell id
    num_categories = int(truth.max()) + 1 if labelled.any() else 1
    votes = np.zeros((coarse_free.size, num_categories), dtype=np.int64)  # [h*w, K]
    np.add.at(votes, (block[labelled], truth[labelled]), 1)
    best = np.where(votes.any(axis=1), votes.argmax(axis=1), -1).reshape(coarse_free.shape)
    return np.where(coarse_free, best, -1).astype(np.int64)


def _tell_once(key: tuple[object, ...], message: str, *args: object) -> None:
    """Warn (logger ``"spcopyro"``) once per ``key`` (a map and a cell size): a fit asks for its
    model grid more than once (the command, the refinement's check)."""
    if key in _TOLD:
        return
    _TOLD.add(key)
    logging.getLogger("spcopyro").warning(message, *args)


def model_house(house: House, cell_size: float | None) -> House:
    """The house with its map coarsened to the model's cells of about ``cell_size`` metres
    (:func:`~spcopyro.maps.coarse.coarsen_grid`; the observations are world positions and stay
    as they are; a ground truth is coarsened by majority). ``None``, or a cell size that rounds
    to the map's own cells, returns the house itself, so applying it twice changes nothing;
    so does a map whose free space is too thin to leave a free model cell (with a warning)."""
    factor = coarsening_factor(house.grid.resolution, cell_size)
    if factor == 1:
        if cell_size is not None and cell_size < house.grid.resolution / 2:
            _tell_once(
                (house.name, str(house.grid.source), house.grid.shape, cell_size),
                "house %r: cells of %g m are finer than map %s's own %g m cells, which the "
                "model uses (a model cell is made of whole map cells)",
                house.name, cell_size, house.grid.source or "", house.grid.resolution,
            )  # fmt: skip
        return house
    grid = coarsen_grid(house.grid, factor)
    if grid.num_free == 0:  # thin free space only (or an inverted map): the map's own cells
        _tell_once(
            (house.name, str(house.grid.source), house.grid.shape, grid.resolution),
            "house %r: cells of %g m leave no free cell of map %s (%d free cells of %g m); "
            "fitting on the map's own cells",
            house.name,
            grid.resolution,
            house.grid.source or "",
            house.grid.num_free,
            house.grid.resolution,
        )
        return house
    truth = None if house.truth is None else _coarsen_truth(house, factor, grid.free)
    return dataclasses.replace(house, grid=grid, truth=truth)
