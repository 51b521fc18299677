"""A house on the model's grid (``DataPreparation.cell_size``, :mod:`spcopyro.maps.coarse`)."""

from __future__ import annotations

import dataclasses
import logging

from spcopyro.data.dataset import House
from spcopyro.maps.coarse import coarsen_grid, coarsen_labels, coarsening_factor

__all__ = ["model_house"]

_TOLD: set[tuple[object, ...]] = set()
"""The warnings given, by (house, map file, shape, cell size): :func:`_tell_once`."""


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
    # The truth by majority; a model cell its map cells leave unnamed stays -1 (not scored).
    truth = None if house.truth is None else coarsen_labels(house.truth, house.grid, factor,
                                                             fill=False)  # fmt: skip
    return dataclasses.replace(house, grid=grid, truth=truth)
