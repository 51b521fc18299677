"""Why a loaded map has no free cell: the early refusal of a fit with nothing to label.

A map_server map reads as all unknown (or all occupied) when its thresholds leave no grey free
(``free_thresh: 0``: no ``p`` is below it), when ``negate`` inverts a map drawn with free space
light, or when its image holds only map_saver's unknown grey 205 (nothing explored).
:func:`check_free_cells` refuses such a map before anything else is counted or printed, naming the
yaml's ``negate`` and threshold lines and values and the image's range of greys (and so of the
occupancy ``p`` they give), so the reason can be read off the message. Torch-free: ``spcopyro fit``
calls it right after loading the house.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from spcopyro._util.messages import echo
from spcopyro.maps.grid import OccupancyGrid, cells_on_map
from spcopyro.maps.map_image import _read_levels
from spcopyro.maps.map_server import PGM_UNKNOWN, _occupancy
from spcopyro.maps.map_yaml import MapFormatError, _MapYaml, read_map_yaml

__all__ = [
    "check_free_cells",
    "negate_hint",
    "negate_line",
    "no_free_cell_reason",
    "truth_negate_hint",
]

_GENERIC = "check the map image and its yaml's negate flag and free/occupied thresholds"


def _map_spec(grid: OccupancyGrid) -> _MapYaml | None:
    """The yaml ``grid`` (or the map it was coarsened from) was loaded from, without its image;
    None where it was read from no yaml, or its yaml no longer reads."""
    source = grid.coarsened_from.source if grid.coarsened_from is not None else grid.source
    path = Path(source) if source is not None else None
    if path is None or path.suffix.lower() not in (".yaml", ".yml"):
        return None
    try:
        return read_map_yaml(path, warn=False)  # load_map said its warnings
    except (MapFormatError, OSError):
        return None


def _map_levels(grid: OccupancyGrid) -> tuple[_MapYaml, np.ndarray, float] | None:
    """The yaml ``grid`` (or the map it was coarsened from) was loaded from, its image's levels
    ``[H, W]`` or ``[H, W, C]`` and their full scale; None where it was read from no yaml, or
    its yaml or image no longer reads."""
    spec = _map_spec(grid)
    if spec is None:
        return None
    try:
        levels, full, _ = _read_levels(spec)  # [H, W] or [H, W, C]
    except (MapFormatError, OSError):
        return None
    return spec, levels, full


def _free_under_other_negate(spec: _MapYaml, levels: np.ndarray, full: float) -> np.ndarray:
    """``[H, W]`` bool: the image's cells the other ``negate`` reads free (``p < free_thresh``)."""
    return _occupancy(levels, full, not spec.negate)[1] < spec.free_thresh


def _negate_line(spec: _MapYaml) -> str:
    """``"MAP.yaml:4: negate 1"``: the yaml's ``negate`` line and value as written."""
    return f"{spec.where('negate')}: negate {spec.shown_negate()}"


def negate_line(grid: OccupancyGrid) -> str:
    """``"MAP.yaml:4: negate 1"`` where ``grid`` (or the map it was coarsened from) was read
    from a yaml whose ``negate`` inverts the image (true); "" otherwise. Reads the yaml only."""
    spec = _map_spec(grid)
    return _negate_line(spec) if spec is not None and spec.negate else ""


def negate_hint(
    grid: OccupancyGrid,
    left_out: np.ndarray | None = None,
    placed: np.ndarray | None = None,
    reach: float = 0.0,
) -> str:
    """``"MAP.yaml:4: negate 1 on a map whose free space is drawn white (map_saver's maps need
    negate: 0): with negate 0, 18622 cells would be free, not 1864, and 222 of the 222
    observations left out would lie on them"``: the yaml's ``negate`` line, where the other
    ``negate`` frees more cells than this one; "" otherwise or where ``grid`` was not read from a
    yaml (or its image no longer matches it).

    With ``left_out`` ``[n, 2]`` (metres: the observations left out of the counts), only where
    the other ``negate`` frees the cells more than half of them lie on and, with ``placed``
    ``[m, 2]`` (those in the counts), leaves more than half of those within ``reach`` metres of
    its free cells: a drawing with free space white inside and black outside, where the tour
    went, would trade the observations inside for those outside under the other ``negate`` (its
    free space does not read inverted, the tour left the drawn free space)."""
    read = _map_levels(grid)
    if read is None:
        return ""
    freed = _free_under_other_negate(*read)  # [H, W] bool
    return _read_negate_hint(grid, *read, freed, left_out, placed, reach)


def _read_negate_hint(
    grid: OccupancyGrid,
    spec: _MapYaml,
    levels: np.ndarray,
    full: float,
    freed: np.ndarray,
    left_out: np.ndarray | None = None,
    placed: np.ndarray | None = None,
    reach: float = 0.0,
) -> str:
    """:func:`negate_hint` of the map already read (:func:`_map_levels`: ``spec``, ``levels``
    ``[H, W]`` or ``[H, W, C]``, ``full``) and the cells the other ``negate`` frees, ``freed``
    ``[H, W]`` bool (:func:`_free_under_other_negate`): its tests after the read, and its
    line."""
    now = int(np.count_nonzero(_occupancy(levels, full, spec.negate)[1] < spec.free_thresh))
    flipped = int(np.count_nonzero(freed))
    fine = grid.coarsened_from if grid.coarsened_from is not None else grid
    if flipped <= now or fine.occupancy.shape != freed.shape:
        return ""
    lands = ""
    if left_out is not None:
        cells = cells_on_map(grid, left_out)  # [n', 2] on fine, of freed's shape (above)
        on_freed = int(np.count_nonzero(freed[cells[:, 0], cells[:, 1]]))
        if 2 * on_freed <= len(np.asarray(left_out).reshape(-1, 2)):
            return ""
        lands = f", and {on_freed} of the {len(left_out)} observations left out would lie on them"
    if placed is not None and len(placed):
        from scipy.ndimage import distance_transform_edt

        cells = cells_on_map(grid, placed)  # [m', 2]
        away = distance_transform_edt(~freed) * fine.resolution  # [H, W] metres to a freed cell
        if 2 * int(np.count_nonzero(away[cells[:, 0], cells[:, 1]] <= reach)) <= len(placed):
            return ""
    drawn, need = ("white", "map_saver's maps need negate: 0") if spec.negate else (
        "black", "such a map needs negate: 1")  # fmt: skip
    return (
        f"{_negate_line(spec)} on a map whose free space is "
        f"drawn {drawn} ({need}): with negate {int(not spec.negate)}, {flipped} cells would be "
        f"free, not {now}{lands}"
    )


def truth_negate_hint(grid: OccupancyGrid, labelled: np.ndarray) -> str:
    """:func:`negate_hint`'s line for a house's truth whose labelled cells ``[n, 2]`` (row, col
    of ``grid``) lie off its free space: where the other ``negate`` frees more than half of
    them and they cover more than half of the cells it frees (the truth labels the map read
    with the other ``negate``, not a few cells mislabelled); "" otherwise."""
    read = _map_levels(grid)
    if read is None or not len(labelled):
        return ""
    freed = _free_under_other_negate(*read)  # [H, W] bool, of the map grid was read from
    fine = grid.coarsened_from if grid.coarsened_from is not None else grid
    if fine.occupancy.shape != freed.shape:
        return ""
    cells = cells_on_map(grid, grid.cell_to_world(labelled))  # [n', 2] on fine
    on_freed = int(np.count_nonzero(freed[cells[:, 0], cells[:, 1]]))
    if 2 * on_freed <= len(labelled) or 2 * len(labelled) <= int(np.count_nonzero(freed)):
        return ""
    return _read_negate_hint(grid, *read, freed)  # the map not read again


def no_free_cell_reason(grid: OccupancyGrid) -> str:
    """Why ``grid`` (or the map it was coarsened from), loaded from a map_server yaml, has no free
    cell: the yaml's ``negate``, ``free_thresh`` and ``occupied_thresh`` with their lines, the
    image's greys ``v`` (``[lo, hi]`` of its full scale) and the occupancy they give,
    ``p = (full - v) / full`` (``v / full`` negated), against ``p < free_thresh`` for free; and
    a hint (flipping ``negate`` would free cells; every pixel is the unknown grey 205). A grid
    that was not read from a yaml (or whose yaml no longer reads) gets the generic hint."""
    read = _map_levels(grid)
    if read is None:
        return _GENERIC
    spec, levels, full = read
    grey, p = _occupancy(levels, full, spec.negate)  # [H, W] each, as load_map reads them
    if np.any(p < spec.free_thresh):  # the grid is not the yaml's as it reads now (edited)
        return _GENERIC
    low, high = float(grey.min()), float(grey.max())
    formula = f"grey / {full:g}" if spec.negate else f"({full:g} - grey) / {full:g}"
    reason = (
        f"{_negate_line(spec)}; "
        f"{spec.where('free_thresh')}: free_thresh {echo(spec.free_thresh)}; "
        f"{spec.where('occupied_thresh')}: occupied_thresh {echo(spec.occupied_thresh)}; "
        f"the image {str(spec.image)!r} has greys {low:g}..{high:g} of {full:g}, so "
        f"p = {formula} runs {float(p.min()):.4g}..{float(p.max()):.4g}: none is below "
        f"free_thresh {echo(spec.free_thresh)} (free)"
    )
    rescued = int(np.count_nonzero(_free_under_other_negate(spec, levels, full)))
    if full == 255 and low == high == PGM_UNKNOWN:
        reason += (
            f": every pixel is map_saver's unknown grey {PGM_UNKNOWN}, the map holds no "
            "explored space"
        )
    elif rescued:
        reason += f": with negate {int(not spec.negate)}, {rescued} cells would be free"
    else:
        reason += f": {_GENERIC}"
    return reason


def check_free_cells(
    grid: OccupancyGrid,
    what: str,
    refusal: str = "the map {source} has no free cell, nothing to label",
) -> None:
    """ValueError when ``grid`` has no free cell (nothing to label), saying why
    (:func:`no_free_cell_reason`); ``what`` names the house, e.g. ``"house 'kitchen'"``, and
    ``refusal`` is the words after it, ``{source}`` the map's yaml (``simulate --map``'s: "the
    map has no free cell to tour")."""
    if grid.num_free:
        return
    source = grid.coarsened_from.source if grid.coarsened_from is not None else grid.source
    said = " ".join(refusal.format(source=source or "").split())  # no source: "the map has ..."
    raise ValueError(f"{what}: {said}: {no_free_cell_reason(grid)}")
