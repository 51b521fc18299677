"""Putting observations on free cells of the occupancy grid, with snapping, and the report.

Each observation goes on a free cell of an :class:`~spcopyro.maps.OccupancyGrid`
(:func:`place_observations`: paper eq. 11, ``convert(x) = floor((x - origin) / resolution)``,
with snapping of positions that land just off free space). Nothing is dropped silently:
observations that cannot be placed are listed in a :class:`PlacementReport`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from spcopyro._util.number_checks import is_finite_number
from spcopyro.config import DEFAULT_SNAP_DISTANCE
from spcopyro.data.observations import Observations, _as_xy
from spcopyro.maps.grid import OCCUPIED, OccupancyGrid, cells_on_map

__all__ = [
    "DEFAULT_SNAP_DISTANCE",
    "ModalityPlacement",
    "PlacementReport",
    "count_on_occupied",
    "left_out_and_placed",
    "on_map_text",
    "place_observations",
    "position_hint",
]

# Positions in the public data were recorded by the robot and rounded onto the 5 cm grid; some
# land on wall or unknown pixels (README "Quirks"). In the five public houses 27 images and 8
# utterances (all in room1dk5 and room1ldk4) are off free space, 0.05-0.25 m from the nearest free
# cell; the farthest (0.25 m = 5 cells) are a waypoint in the middle of a thick wall band with an
# unknown core, and one just behind a wall. 0.25 m places all of them, while a position
# deeper inside a wall or farther off the map (a real error) stays unplaced and is reported.

_SNAP_EPS = 1e-9  # cells: tolerance on the snap limit (0.15 / 0.05 == 2.9999999999999996)


def _nearest_free(
    grid: OccupancyGrid, cells: np.ndarray, free_mask: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """For off-free cells ``[N, 2]`` (row, col): nearest free cell ``[N, 2]`` and the Euclidean
    distance to it in cells ``[N]`` (inf when the map has no free cell)."""
    n = cells.shape[0]
    target = np.full((n, 2), -1, dtype=np.int64)  # [N, 2]
    distance = np.full(n, np.inf)  # [N]
    if n == 0 or grid.num_free == 0:
        return target, distance
    height, width = grid.shape
    rows, cols = cells[:, 0], cells[:, 1]
    inside = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)  # [N] bool
    if inside.any():
        from scipy.ndimage import distance_transform_edt  # here: 0.2 s of imports

        # Distance to the nearest zero (= free cell) of the non-free mask, with its indices.
        edt, nearest = distance_transform_edt(~free_mask, return_indices=True)  # [H,W], [2,H,W]
        r, c = rows[inside], cols[inside]
        distance[inside] = edt[r, c]
        target[inside] = nearest[:, r, c].T
    if (~inside).any():
        from scipy.spatial import cKDTree

        # Off the map: exact nearest free cell centre, by a k-d tree over the free cells.
        free_cells = np.argwhere(free_mask)  # [F, 2]
        d, i = cKDTree(free_cells).query(cells[~inside].astype(np.float64))
        distance[~inside] = d
        target[~inside] = free_cells[i]
    return target, distance


def _square_distance(grid: OccupancyGrid, xy: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """``[N]`` metres from each world point ``[N, 2]`` to the square of its cell ``[N, 2]``
    (row, col): 0 inside it."""
    centre = grid.cell_to_world(cells)  # [N, 2]
    gap = np.maximum(np.abs(xy - centre) - 0.5 * grid.resolution, 0.0)  # [N, 2]
    return np.hypot(gap[:, 0], gap[:, 1])


def _nearest_square(
    grid: OccupancyGrid, xy: np.ndarray, cells: np.ndarray, free_mask: np.ndarray, reach: int
) -> tuple[np.ndarray, np.ndarray]:
    """For points ``[N, 2]`` in cells ``[N, 2]`` (on the map or off it): the free cell
    ``[N, 2]`` within ``reach`` cells (per axis) whose square is nearest the point, and that
    distance in metres ``[N]`` (inf and -1 where none is). Ties go to the nearer centre, then
    the first offset in row-major order."""
    n = cells.shape[0]
    height, width = free_mask.shape
    steps = np.arange(-reach, reach + 1)
    offsets = np.stack(np.meshgrid(steps, steps, indexing="ij"), axis=-1).reshape(-1, 2)  # [S, 2]
    candidates = cells[:, None, :] + offsets[None, :, :]  # [N, S, 2]
    rows, cols = candidates[..., 0], candidates[..., 1]
    inside = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)  # [N, S]
    free = np.zeros(inside.shape, dtype=bool)  # [N, S]
    free[inside] = free_mask[rows[inside], cols[inside]]
    flat = candidates.reshape(-1, 2)  # [N * S, 2]
    points = np.repeat(xy, offsets.shape[0], axis=0)  # [N * S, 2]
    square = _square_distance(grid, points, flat).reshape(free.shape)  # [N, S]
    centre = np.hypot(*(points - grid.cell_to_world(flat)).T).reshape(free.shape)  # [N, S]
    square = np.where(free, square, np.inf)
    # lexicographic (square, centre): the centre only breaks exact ties of the square distance
    order = np.lexsort((np.where(free, centre, np.inf), square), axis=1)[:, 0]  # [N]
    best = square[np.arange(n), order]  # [N]
    target = np.where(np.isfinite(best)[:, None], candidates[np.arange(n), order], -1)
    return target, best


def _place(
    grid: OccupancyGrid, xy: np.ndarray, snap_distance: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`place_observations` plus each snapped or unplaced point's distance in metres to
    the nearest free cell's square (0 on free cells, inf when the map has no free cell)."""
    if not is_finite_number(snap_distance):
        raise ValueError(f"snap_distance={snap_distance!r}: must be a finite number of metres")
    if snap_distance < 0:
        raise ValueError(f"snap_distance={snap_distance!r}: must be >= 0 metres")
    xy = _as_xy(xy, "xy")  # [N, 2]
    n = xy.shape[0]
    cells = np.asarray(grid.world_to_cell(xy), dtype=np.int64).reshape(n, 2)  # [N, 2] (row, col)
    free_mask = np.asarray(grid.free, dtype=bool)  # [H, W]
    free_index = np.asarray(grid.free_index, dtype=np.int64)  # [H, W]
    height, width = free_mask.shape
    rows, cols = cells[:, 0], cells[:, 1]
    inside = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)  # [N] bool
    on_free = np.zeros(n, dtype=bool)  # [N]
    on_free[inside] = free_mask[rows[inside], cols[inside]]
    placed = np.full(n, -1, dtype=np.int64)  # [N] free index or -1
    placed[on_free] = free_index[rows[on_free], cols[on_free]]
    distance = np.zeros(n)  # [N] metres
    off = np.flatnonzero(~on_free)  # [n_off]
    through_map = None
    if grid.coarsened_from is not None and off.size:
        through_map = _through_map(grid, xy[off], snap_distance)  # [n_off] free index or -1
    # The nearest free cell by centres (EDT / k-d tree), then, within reach of the limit, the
    # free cell whose square is nearest the point itself.
    target, cell_distance = _nearest_free(grid, cells[off], free_mask)  # [n_off, 2], [n_off]
    square = np.full(off.size, np.inf)  # [n_off] metres
    found = np.isfinite(cell_distance)
    square[found] = _square_distance(grid, xy[off[found]], target[found])
    reach = int(math.ceil(snap_distance / grid.resolution - _SNAP_EPS)) + 1  # cells
    near = cell_distance <= reach * math.sqrt(2.0) + 1.0  # [n_off] bool: may be within reach
    if near.any() and snap_distance > 0:
        local, local_distance = _nearest_square(grid, xy[off[near]], cells[off[near]], free_mask,
                                                reach)  # fmt: skip
        better = local_distance < square[near]
        chosen = np.flatnonzero(near)[better]
        target[chosen] = local[better]
        square[chosen] = local_distance[better]
    distance[off] = square
    within = (square <= snap_distance + _SNAP_EPS * grid.resolution) & (snap_distance > 0)
    if through_map is not None:  # as the map places it; else (a pocket) the model grid's own
        reached = through_map >= 0
        target[reached] = np.asarray(grid.free_cells)[through_map[reached]]
        within |= reached
    snapped = np.zeros(n, dtype=bool)  # [N]
    snapped[off[within]] = True
    placed[off[within]] = free_index[target[within, 0], target[within, 1]]
    unplaced = ~on_free & ~snapped  # [N] bool
    return placed, snapped, unplaced, distance


def _through_map(grid: OccupancyGrid, xy: np.ndarray, snap_distance: float) -> np.ndarray:
    """``[N]`` free index on ``grid``, a model grid coarsened from a map, of points ``[N, 2]``
    placed as the map places them (:func:`place_observations` on ``grid.coarsened_from``), then
    in the free model cell their map cell reaches first through the map's free cells
    (:func:`~spcopyro.maps.coarse.free_block_of_map_cells`); -1 where the map leaves a point
    unplaced or its map cell reaches no free model cell."""
    from spcopyro.maps.coarse import free_block_of_map_cells

    fine = grid.coarsened_from
    assert fine is not None
    on_map, _, _, _ = _place(fine, xy, snap_distance)  # [N] the map's free index or -1
    target = np.full(on_map.shape[0], -1, dtype=np.int64)  # [N]
    found = on_map >= 0
    map_cells = np.asarray(fine.free_cells)[on_map[found]]  # [n_found, 2]
    target[found] = free_block_of_map_cells(grid)[map_cells[:, 0], map_cells[:, 1]]
    return target


def place_observations(
    grid: OccupancyGrid, xy: np.ndarray, snap_distance: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Free cell of each world position (paper eq. 11), snapping points just off free space.

    A point whose cell ``grid.world_to_cell(xy)`` is free stays there. A point off free space
    (on an occupied or unknown cell, or outside the map) moves to the free cell nearest to it
    -- the Euclidean distance from the point to the cell's square, in metres -- when that
    distance is <= ``snap_distance``; otherwise it is unplaced. So a point 2 cm into a wall
    snaps whatever the cell size: on a model grid coarser than the map (:mod:`spcopyro.maps.
    coarse`), whose walls thicken to whole model cells, a position on the map's free space
    inside such a cell still finds the room it was taken in, where a distance between cell
    centres (one model cell, 0.3 m, above the default 0.25 m) would leave it out. (Before
    2026-12-03 the distance was between cell centres; a limit that was met then is met now.)
    Within ``snap_distance`` the free cells are compared exactly (ties to the nearer centre);
    beyond it, for the report, the distance is to the free cell of nearest centre
    (``scipy.ndimage.distance_transform_edt`` inside the map, a k-d tree over the free cells
    outside it, as if the map extended with non-free cells), so a point off the map by more
    than ``snap_distance`` is always unplaced. ``snap_distance = 0`` disables snapping.

    On a model grid coarsened from a map (``grid.coarsened_from``, :func:`spcopyro.maps.coarse.
    coarsen_grid`) a point whose model cell is free stays there, and any other is placed as the
    map places it: on the map, snapping there within ``snap_distance``, then in the free model
    cell that its map cell reaches first through the map's free cells (its own block's unless a
    wall thickened over it; never through a wall). Where that map cell reaches no free model
    cell (a pocket of free map cells inside a thick wall band), the model grid's own snapping
    above decides. (Before 2026-12-03 the
    model grid was snapped to directly: on the public houses' 0.25 m model grids room1dk5 lost
    6 images and room1ldk4 3 images and a word that the map places within 0.07-0.24 m of free
    space, 0.27-0.41 m from a free model cell.)

    Args:
        grid: the occupancy grid.
        xy: ``[N, 2]`` world positions (metres).
        snap_distance: metres, finite, >= 0.

    Returns:
        ``free_index`` ``[N]`` int64 (``grid.free_index`` of the cell, -1 where unplaced),
        ``snapped`` ``[N]`` bool, ``unplaced`` ``[N]`` bool. Points neither snapped nor unplaced
        were on a free cell.
    """
    placed, snapped, unplaced, _ = _place(grid, xy, snap_distance)
    return placed, snapped, unplaced


@dataclass(frozen=True, eq=False)
class ModalityPlacement:
    """Where the observations of one further modality went (see :class:`PlacementReport`).

    ``on_free + snapped + unplaced`` is the modality's number of observations.
    """

    name: str
    on_free: int
    snapped: int
    unplaced: int
    unplaced_indices: np.ndarray  # [*] int64 indices into the modality's observations


def _share_on_free(grid: OccupancyGrid, xy: np.ndarray) -> float:
    """Share of the points ``[n, 2]`` whose cell is free."""
    return float(grid.is_free(grid.world_to_cell(xy)).mean())  # [n] bool -> share


def position_hint(grid: OccupancyGrid, xy: np.ndarray) -> str:
    """When most positions ``[n, 2]`` (metres, the dataset's unit) miss the map's free space but
    would cover it in millimetres or centimetres, a sentence that says so (with a leading
    "; "); else "". "Cover": most of them on free cells, spread over at least
    ``MIN_SPREAD`` of the free space's extent (a wrong scale that squeezes them into the middle
    of a map centred on its origin lands on free space too). A robot's own files in
    millimetres ended in "no observation lands on free space", blaming the map."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    xy = xy[np.isfinite(xy).all(axis=1)]
    if len(xy) < 2 or grid.num_free == 0 or _share_on_free(grid, xy) >= 0.5:
        return ""
    if np.abs(xy).max() >= 2.0**40 * grid.resolution:  # world_to_cell would refuse them
        return ""
    free_spread = grid.cell_to_world(grid.free_cells).std(axis=0).max()  # metres
    for scale, unit in ((1e-3, "millimetres"), (1e-2, "centimetres")):
        scaled = xy * scale  # [n, 2]
        spread = scaled.std(axis=0).max()
        if _share_on_free(grid, scaled) >= 0.5 and spread >= MIN_SPREAD * free_spread:
            return (f"; the positions divided by {round(1 / scale)} land on free space: are "
                    f"they in {unit}? Positions are metres in the map's frame")  # fmt: skip
    return ""


def on_map_text(grid: OccupancyGrid) -> str:
    """``" on map PATH"`` naming the map ``grid`` was read from (its ``source``), the ``where``
    of the placement's messages (:meth:`PlacementReport.off_free_warning`); ``""`` for a grid
    built in memory."""
    return f" on map {grid.source}" if getattr(grid, "source", None) else ""


def count_on_occupied(grid: OccupancyGrid, xy: np.ndarray) -> int:
    """How many of the points ``[n, 2]`` (metres) lie on an occupied cell of ``grid``'s map (the
    map a model grid was coarsened from, whose walls are not thickened), inside its bounds."""
    fine = grid.coarsened_from if grid.coarsened_from is not None else grid
    cells = cells_on_map(grid, xy)  # [n', 2] on fine
    return int(np.count_nonzero(fine.occupancy[cells[:, 0], cells[:, 1]] == OCCUPIED))


MIN_SPREAD = 0.3
""":func:`position_hint`: a rescaled tour must spread over this share of the free space's
extent (standard deviations along the wider axis)."""


@dataclass(frozen=True, eq=False)
class PlacementReport:
    """Where observations went: nothing is dropped silently.

    ``*_on_free + *_snapped + *_unplaced`` is the number of images (words) observed;
    ``modalities`` holds the same for each further modality, in the observations' order.
    """

    images_on_free: int
    images_snapped: int
    images_unplaced: int
    words_on_free: int
    words_snapped: int
    words_unplaced: int
    unplaced_images: np.ndarray  # [*] int64 indices into Observations images
    unplaced_words: np.ndarray  # [*] int64 indices into Observations utterances
    snap_distance: float  # metres
    modalities: tuple[ModalityPlacement, ...] = ()
    hint: str = ""
    """:func:`position_hint`'s sentence, ending both messages about observations off free
    space."""
    images_scaled_away: int = 0
    """Placed or not, the images whose histogram held something but whose scaled row is all
    zero (``floor100`` of a histogram whose every entry is below 0.01, as a 1000-class one can
    be): they add nothing to the counts (:func:`~spcopyro.data.counts.cell_counts` warns)."""
    scaled_away_images: np.ndarray = field(
        default_factory=lambda: np.zeros(0, dtype=np.int64)
    )  # [images_scaled_away] int64 indices into Observations images
    feature_scaling: object = "probability"
    """The feature scaling the counts were made under (named beside ``images_scaled_away``)."""
    unplaced_on_occupied: int = 0
    """Of the observations left out (every modality), those on an occupied cell of the map
    (:func:`count_on_occupied`): with most of them,
    :func:`~spcopyro.data.inverted_map.check_placement` refuses the map."""

    @property
    def num_observations(self) -> int:
        """All observations: images, utterances and every further modality's."""
        return self.num_placed + self.num_unplaced

    @property
    def num_on_free(self) -> int:
        """Observations whose own cell is free (of every modality)."""
        return self.images_on_free + self.words_on_free + sum(m.on_free for m in self.modalities)

    @property
    def num_snapped(self) -> int:
        """Observations moved onto free space (of every modality)."""
        return self.images_snapped + self.words_snapped + sum(m.snapped for m in self.modalities)

    @property
    def num_placed(self) -> int:
        """Observations in the counts (of every modality): on free cells, snapped ones included."""
        return self.num_on_free + self.num_snapped

    @property
    def num_unplaced(self) -> int:
        """Observations left out of the counts (of every modality)."""
        return self.images_unplaced + self.words_unplaced + sum(m.unplaced for m in self.modalities)

    def _off_free(self, where: str) -> str:
        off = self.num_snapped + self.num_unplaced
        return (
            f"{off} of {self.num_observations} observations are not on a free cell{where} "
            f"(but on occupied or unknown cells or outside the map; {self.num_snapped} snapped "
            f"to free space within {self.snap_distance:g} m, {self.num_unplaced} left out)"
            f"{self.hint}"
        )

    def off_free_warning(self, where: str = "") -> str | None:
        """A warning when most observations (more than half) did not land on a free cell, else
        None. ``where`` names the map in the message (e.g. ``" on map PATH"``)."""
        if 2 * (self.num_snapped + self.num_unplaced) <= self.num_observations:
            return None
        return (
            f"{self._off_free(where)}: the sign of a wrong map or origin (check the map yaml's "
            "origin, resolution and negate flag)"
        )

    def free_space_inverted(self) -> bool:
        """More than half of the observations left out, and more than half of those on
        occupied cells of the map: the map's free space reads as occupied (``negate`` or the
        thresholds invert it, or the image is inverted), rather than covering only part of the
        tour (observations off the map or on unknown cells, left out with a warning)."""
        left_out = self.num_unplaced
        return 2 * left_out > self.num_observations and 2 * self.unplaced_on_occupied > left_out

    def check_on_free(self, where: str = "", negate_hint: str = "", negate_line: str = "") -> None:
        """Raise ValueError when observations exist but none landed on a free cell itself (the
        map or its origin is wrong, or ``negate`` inverts free space): a fit would learn every
        concept from the prior alone. ``where`` names the map (``" on map PATH"``);
        ``negate_hint`` (:func:`~spcopyro.maps.free_space.negate_hint`: the other ``negate``
        would place them) blames the yaml's ``negate`` line, else ``negate_line``
        (:func:`~spcopyro.maps.free_space.negate_line`, ``"MAP.yaml:4: negate 1"``) is what to
        check in place of "the map yaml";
        :func:`~spcopyro.data.inverted_map.check_placement` gives both.

        A map whose free space reads as occupied while some observations are on it
        (:meth:`free_space_inverted`) is refused by
        :func:`~spcopyro.data.inverted_map.check_placement`, which says why from the
        observations' positions and the map's yaml, and calls this first."""
        if self.num_observations and not self.num_on_free:
            cause = (
                f"the map's free space reads as occupied: {negate_hint}"
                if negate_hint
                else "the map or its origin is wrong, or its negate flag inverts free space "
                f"(check {negate_line or 'the map yaml'})"
            )
            raise ValueError(
                f"no observation lands on free space: {self._off_free(where)}; {cause}"
            )

    def summary(self) -> str:
        """One human-readable line."""
        further = "".join(
            f"; {m.name}: {m.on_free} on free cells, {m.snapped} snapped, {m.unplaced} unplaced"
            for m in self.modalities
        )
        return (
            f"images: {self.images_on_free} on free cells, {self.images_snapped} snapped, "
            f"{self.images_unplaced} unplaced; words: {self.words_on_free} on free cells, "
            f"{self.words_snapped} snapped, {self.words_unplaced} unplaced{further} "
            f"(snap distance {self.snap_distance:g} m){self.scaled_away_note()}"
        )

    def scaled_away_note(self) -> str:
        """``"; N of T images left out: ..."`` when the feature scaling left images with
        nothing (:attr:`images_scaled_away`), else ``""``: for a summary line's end."""
        if not self.images_scaled_away:
            return ""
        images = self.images_on_free + self.images_snapped + self.images_unplaced
        return (
            f"; {self.images_scaled_away} of {images} images left out: nothing of their "
            f"histogram is left under feature_scaling={self.feature_scaling!r}"
        )


def left_out_and_placed(
    report: PlacementReport, obs: Observations
) -> tuple[np.ndarray, np.ndarray]:
    """(``[n, 2]`` positions of the observations ``report`` leaves out, ``[m, 2]`` of those it
    places), every modality's (images, utterances, then ``report.modalities`` in order), in
    metres: what :func:`count_on_occupied` counts and
    :func:`~spcopyro.data.inverted_map.inverted_free_space_message` weighs."""
    positions = [obs.image_xy, obs.word_xy]  # [T, 2], [U, 2]
    unplaced = [report.unplaced_images, report.unplaced_words]  # indices into each
    for placed in report.modalities:
        positions.append(next(m for m in obs.modalities if m.name == placed.name).positions)
        unplaced.append(placed.unplaced_indices)
    left_out, kept = [], []
    for xy, out in zip(positions, unplaced, strict=True):
        mask = np.zeros(len(xy), dtype=bool)  # [n_j] left out
        mask[np.asarray(out, dtype=np.int64)] = True
        left_out.append(np.asarray(xy, dtype=np.float64).reshape(-1, 2)[mask])
        kept.append(np.asarray(xy, dtype=np.float64).reshape(-1, 2)[~mask])
    return np.concatenate(left_out), np.concatenate(kept)
