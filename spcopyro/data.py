"""Observations of a house, their placement on the occupancy grid, and the dataset files.

A robot takes images (each turned into a K-class place histogram by a CNN) and hears utterances,
each at a world position. This module

* holds them in :class:`Observations` (world coordinates, free vocabulary: nothing pre-listed),
* puts each observation on a free cell of an :class:`~spcopyro.maps.OccupancyGrid`
  (:func:`place_observations`: paper eq. 11, ``convert(x) = floor((x - origin) / resolution)``,
  with snapping of positions that land just off free space),
* sums them per cell into the sparse sufficient statistics the model reads (:func:`cell_counts`),
  with the image-feature scaling and word weighting (counts or tf-idf, paper eq. 20) as options,
* reads and writes the public SpCoMapping dataset layout (:func:`load_house`, :func:`save_house`;
  see the dataset's README.md).

Nothing is dropped silently: observations that cannot be placed are logged (``logging``, logger
``"spcopyro"``) and listed in a :class:`PlacementReport`; malformed files raise
:class:`DataFormatError` naming the file, the 1-based line and the offending value.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import shutil
import string
import unicodedata
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np
from scipy.ndimage import distance_transform_edt
from scipy.spatial import cKDTree

from spcopyro.maps import OccupancyGrid, load_map, save_map

__all__ = [
    "DEFAULT_SNAP_DISTANCE",
    "CellCounts",
    "DataFormatError",
    "FeatureScaling",
    "House",
    "Observations",
    "PlacementReport",
    "cell_counts",
    "find_dataset_root",
    "list_houses",
    "load_house",
    "place_observations",
    "save_house",
    "scale_features",
    "tfidf_weights",
    "tokenize",
    "word_matrix",
]

logger = logging.getLogger("spcopyro")

FeatureScaling = Literal["probability", "floor100"] | float
"""How image histograms become counts: ``"probability"`` (as they are), ``"floor100"``
(``floor(100 f)``, as the released code did) or a positive float ``s`` (``s * f``,
pseudo-counts)."""

WordWeighting = Literal["count", "tfidf"]

# Positions in the public data were recorded by the robot and rounded onto the 5 cm grid; some
# land on wall or unknown pixels (README "Quirks"). In the five public houses 27 images and 8
# utterances (all in room1dk5 and room1ldk4) are off free space, 0.05-0.25 m from the nearest free
# cell; the farthest (0.25 m = 5 cells) are a waypoint in the middle of a thick wall band with an
# unknown core, and one just behind a wall. 0.25 m places all of them, while a position
# deeper inside a wall or farther off the map (a real error) stays unplaced and is reported.
DEFAULT_SNAP_DISTANCE = 0.25  # metres

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")  # camera images looked for in ROOM/img_K/
_POSE_XY_ATOL = 1e-6  # metres: pose_K.csv x, y must agree with Xtx.csv / Xty.csv to this
_SNAP_EPS = 1e-9  # cells: tolerance on the snap limit (0.15 / 0.05 == 2.9999999999999996)
_MISSING = object()


class DataFormatError(ValueError):
    """A data file (or value) is malformed. The message names the file and, where they apply,
    the 1-based line, the 1-based column and the offending value."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        problem: str,
        *,
        line: int | None = None,
        column: int | None = None,
        value: object = _MISSING,
    ) -> None:
        self.path = Path(path)
        self.line = line
        self.column = column
        self.value = None if value is _MISSING else value
        where = str(path)
        if line is not None:
            where += f", line {line}"
        if column is not None:
            where += f", column {column}"
        message = f"{where}: {problem}"
        if value is not _MISSING:
            message += f": {value!r}"
        super().__init__(message)


# ---------------------------------------------------------------------------------------------
# Observations
# ---------------------------------------------------------------------------------------------


def _as_xy(values: object, name: str, count: int | None = None) -> np.ndarray:
    xy = np.array(values, dtype=np.float64)  # [N, 2]
    if xy.size == 0:
        xy = xy.reshape(0, 2)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise ValueError(f"{name} must have shape [N, 2], got {xy.shape}")
    if count is not None and xy.shape[0] != count:
        raise ValueError(f"{name} has {xy.shape[0]} rows, expected {count}")
    bad = np.flatnonzero(~np.isfinite(xy).all(axis=1))
    if bad.size:
        raise ValueError(f"{name} row {bad[0]} is not finite: {xy[bad[0]].tolist()}")
    return xy


def _as_trial(values: object, name: str, count: int) -> np.ndarray:
    raw = np.asarray(values)
    if raw.size == 0:
        raw = raw.astype(np.int64).reshape(0)
    if raw.dtype.kind not in "iu":
        raise ValueError(f"{name} must hold integers, got dtype {raw.dtype}")
    trial = raw.astype(np.int64)  # [N]
    if trial.shape != (count,):
        raise ValueError(f"{name} must have shape [{count}], got {trial.shape}")
    if trial.size and trial.min() < 0:
        raise ValueError(f"{name} holds a negative trial id: {int(trial.min())}")
    return trial


@dataclass(frozen=True, eq=False)
class Observations:
    """What the robot observed, in world coordinates. Words are free vocabulary: nothing pre-listed.

    T images, U utterances, K feature classes. Arrays are converted (copied) to the dtypes below
    and validated on construction; a ``ValueError`` says which field is wrong.

    Attributes:
        image_features: ``[T, K]`` float64 >= 0, place-class histograms (rows sum to about 1).
        image_xy: ``[T, 2]`` float64, world metres where each image was taken.
        image_trial: ``[T]`` int64 >= 0, trial id of each image.
        utterances: ``[U]`` each utterance's tokens (one word, or a tokenised sentence); every
            utterance holds at least one non-empty token.
        word_xy: ``[U, 2]`` float64, world metres where each utterance was heard.
        word_trial: ``[U]`` int64 >= 0.
        image_yaw: ``[T]`` float64 radians (from pose_K.csv quaternions) or None if unknown.
        image_paths: ``[T]`` camera image files in image_features row order, or None.
    """

    image_features: np.ndarray  # [T, K] float64
    image_xy: np.ndarray  # [T, 2] float64
    image_trial: np.ndarray  # [T] int64
    utterances: tuple[tuple[str, ...], ...]  # [U]
    word_xy: np.ndarray  # [U, 2] float64
    word_trial: np.ndarray  # [U] int64
    image_yaw: np.ndarray | None = None  # [T] float64
    image_paths: tuple[Path, ...] | None = None  # [T]

    def __post_init__(self) -> None:
        features = np.array(self.image_features, dtype=np.float64)  # [T, K]
        if features.ndim != 2:
            raise ValueError(f"image_features must have shape [T, K], got {features.shape}")
        if not np.isfinite(features).all():
            row, col = np.argwhere(~np.isfinite(features))[0]
            raise ValueError(f"image_features[{row}, {col}] is not finite: {features[row, col]}")
        if (features < 0).any():
            row, col = np.argwhere(features < 0)[0]
            raise ValueError(f"image_features[{row}, {col}] is negative: {features[row, col]}")
        num_images = features.shape[0]
        utterances = tuple(tuple(u) for u in self.utterances)
        for u, tokens in enumerate(utterances):
            if not tokens:
                raise ValueError(f"utterance {u} holds no tokens")
            for token in tokens:
                if not isinstance(token, str) or not token:
                    raise ValueError(f"utterance {u} holds an invalid token: {token!r}")
        num_utterances = len(utterances)
        set_ = object.__setattr__
        set_(self, "image_features", features)
        set_(self, "image_xy", _as_xy(self.image_xy, "image_xy", num_images))
        set_(self, "image_trial", _as_trial(self.image_trial, "image_trial", num_images))
        set_(self, "utterances", utterances)
        set_(self, "word_xy", _as_xy(self.word_xy, "word_xy", num_utterances))
        set_(self, "word_trial", _as_trial(self.word_trial, "word_trial", num_utterances))
        if self.image_yaw is not None:
            yaw = np.array(self.image_yaw, dtype=np.float64)  # [T]
            if yaw.shape != (num_images,):
                raise ValueError(f"image_yaw must have shape [{num_images}], got {yaw.shape}")
            if not np.isfinite(yaw).all():
                raise ValueError("image_yaw holds a non-finite value")
            set_(self, "image_yaw", yaw)
        if self.image_paths is not None:
            paths = tuple(Path(p) for p in self.image_paths)
            if len(paths) != num_images:
                raise ValueError(f"image_paths has {len(paths)} entries, expected {num_images}")
            set_(self, "image_paths", paths)

    @property
    def num_images(self) -> int:
        """T."""
        return int(self.image_features.shape[0])

    @property
    def num_feature_classes(self) -> int:
        """K."""
        return int(self.image_features.shape[1])

    @property
    def num_utterances(self) -> int:
        """U."""
        return len(self.utterances)

    @cached_property
    def trials(self) -> tuple[int, ...]:
        """Sorted distinct trial ids over images and utterances."""
        ids = np.union1d(self.image_trial, self.word_trial)
        return tuple(int(t) for t in ids)

    @cached_property
    def vocabulary(self) -> tuple[str, ...]:
        """Distinct tokens, in order of first appearance."""
        return tuple(dict.fromkeys(token for tokens in self.utterances for token in tokens))

    def select_trials(self, trials: Iterable[int]) -> Observations:
        """Only the observations of these trials (e.g. for held-out folds), order kept.

        Raises ValueError for a trial id that is not in :attr:`trials`.
        """
        wanted = np.array(sorted({int(t) for t in trials}), dtype=np.int64)  # [S]
        unknown = np.setdiff1d(wanted, np.array(self.trials, dtype=np.int64))
        if unknown.size:
            raise ValueError(
                f"select_trials: unknown trial ids {unknown.tolist()}; have {list(self.trials)}"
            )
        keep_images = np.isin(self.image_trial, wanted)  # [T] bool
        keep_words = np.isin(self.word_trial, wanted)  # [U] bool
        paths = self.image_paths
        return Observations(
            image_features=self.image_features[keep_images],
            image_xy=self.image_xy[keep_images],
            image_trial=self.image_trial[keep_images],
            utterances=tuple(u for u, k in zip(self.utterances, keep_words, strict=True) if k),
            word_xy=self.word_xy[keep_words],
            word_trial=self.word_trial[keep_words],
            image_yaw=None if self.image_yaw is None else self.image_yaw[keep_images],
            image_paths=None
            if paths is None
            else tuple(p for p, k in zip(paths, keep_images, strict=True) if k),
        )


# ---------------------------------------------------------------------------------------------
# Words and features
# ---------------------------------------------------------------------------------------------

_PUNCTUATION = set(string.punctuation)


def _is_punctuation(char: str) -> bool:
    return char in _PUNCTUATION or unicodedata.category(char).startswith("P")


def tokenize(utterance: str) -> tuple[str, ...]:
    """Tokens of an utterance: lower-cased, split on whitespace, punctuation stripped from both
    ends of each token (inner punctuation, as in ``living-room``, stays); empty tokens vanish.

    ``tokenize("Here is the kitchen.") == ("here", "is", "the", "kitchen")``.
    """
    tokens = []
    for raw in utterance.lower().split():
        start, end = 0, len(raw)
        while start < end and _is_punctuation(raw[start]):
            start += 1
        while end > start and _is_punctuation(raw[end - 1]):
            end -= 1
        if start < end:
            tokens.append(raw[start:end])
    return tuple(tokens)


def _vocabulary_index(vocabulary: Sequence[str]) -> dict[str, int]:
    index = {token: v for v, token in enumerate(vocabulary)}
    if len(index) != len(vocabulary):
        seen: set[str] = set()
        dup = next(t for t in vocabulary if t in seen or seen.add(t))
        raise ValueError(f"vocabulary lists {dup!r} more than once")
    return index


def word_matrix(
    utterances: Sequence[Sequence[str]], vocabulary: Sequence[str] | None = None
) -> np.ndarray:
    """``[U, V]`` float64 counts n(t, d) of each vocabulary token t in each utterance d.

    ``vocabulary`` defaults to the distinct tokens in order of first appearance. A token that is
    not in a given vocabulary raises ValueError (naming it): nothing is dropped silently.
    """
    if vocabulary is None:
        vocabulary = tuple(dict.fromkeys(t for u in utterances for t in u))
    index = _vocabulary_index(vocabulary)
    rows, cols, unknown = [], [], {}
    for d, tokens in enumerate(utterances):
        for token in tokens:
            v = index.get(token)
            if v is None:
                unknown.setdefault(token, d)
            else:
                rows.append(d)
                cols.append(v)
    if unknown:
        listed = ", ".join(f"{t!r} (utterance {d})" for t, d in list(unknown.items())[:10])
        raise ValueError(
            f"{len(unknown)} token(s) not in the given vocabulary of {len(index)}: {listed}"
        )
    counts = np.zeros((len(utterances), len(index)), dtype=np.float64)  # [U, V]
    np.add.at(counts, (np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64)), 1.0)
    return counts


def tfidf_weights(
    utterances: Sequence[Sequence[str]], vocabulary: Sequence[str] | None = None
) -> np.ndarray:
    """tf-idf weight of every vocabulary token in every utterance (paper eq. 20).

    Each utterance is a document d; D is the number of utterances::

        tf(t, d)     = n(t, d) / |d|            n(t, d): occurrences of t in d, |d|: tokens in d
        idf(t)       = log(D / df(t))           df(t): number of utterances containing t
        tfidf(t, d)  = tf(t, d) * idf(t)

    (natural log). A token present in *every* utterance gets weight 0 everywhere -- that is the
    point of idf: it carries no information about where it was said. A vocabulary token that
    occurs in no utterance (df = 0) gets weight 0. Each row sums to at most log(D).

    Args:
        utterances: ``[U]`` token sequences (each non-empty).
        vocabulary: ``[V]`` columns; defaults to distinct tokens in order of first appearance.
            A token not in a given vocabulary raises ValueError.

    Returns:
        ``[U, V]`` float64 matrix; row d holds tfidf(t, d) for every vocabulary token t
        (0 for tokens not in d).
    """
    counts = word_matrix(utterances, vocabulary)  # [U, V]
    num_docs = counts.shape[0]
    length = counts.sum(axis=1, keepdims=True)  # [U, 1] |d|
    if (length == 0).any():
        raise ValueError(f"utterance {int(np.flatnonzero(length == 0)[0])} holds no tokens")
    doc_freq = (counts > 0).sum(axis=0)  # [V] df(t)
    idf = np.zeros(counts.shape[1], dtype=np.float64)  # [V]
    seen = doc_freq > 0
    idf[seen] = np.log(num_docs / doc_freq[seen])
    return counts / length * idf  # [U, V]


def scale_features(features: np.ndarray, scaling: FeatureScaling) -> np.ndarray:
    """Image histograms ``[T, K]`` -> counts ``[T, K]`` float64.

    ``"probability"``: f as it is; ``"floor100"``: floor(100 f) (the released code's integer
    pseudo-counts; small probabilities become 0); a positive float s: s * f.
    """
    f = np.asarray(features, dtype=np.float64)
    if isinstance(scaling, str):
        if scaling == "probability":
            return f.copy()
        if scaling == "floor100":
            return np.floor(100.0 * f)
    elif (
        isinstance(scaling, (int, float))
        and not isinstance(scaling, bool)
        and math.isfinite(scaling)
        and scaling > 0
    ):
        return float(scaling) * f
    raise ValueError(
        f"feature_scaling={scaling!r}: must be 'probability', 'floor100' or a positive number"
    )


# ---------------------------------------------------------------------------------------------
# Placement on the grid and per-cell counts
# ---------------------------------------------------------------------------------------------


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
        # Distance to the nearest zero (= free cell) of the non-free mask, with its indices.
        edt, nearest = distance_transform_edt(~free_mask, return_indices=True)  # [H,W], [2,H,W]
        r, c = rows[inside], cols[inside]
        distance[inside] = edt[r, c]
        target[inside] = nearest[:, r, c].T
    if (~inside).any():
        # Off the map: exact nearest free cell centre, by a k-d tree over the free cells.
        free_cells = np.argwhere(free_mask)  # [F, 2]
        d, i = cKDTree(free_cells).query(cells[~inside].astype(np.float64))
        distance[~inside] = d
        target[~inside] = free_cells[i]
    return target, distance


def _place(
    grid: OccupancyGrid, xy: np.ndarray, snap_distance: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`place_observations` plus each snapped or unplaced point's distance in metres to
    the nearest free cell (0 on free cells, inf when the map has no free cell)."""
    if not (isinstance(snap_distance, (int, float)) and math.isfinite(snap_distance)):
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
    off = ~on_free
    target, cell_distance = _nearest_free(grid, cells[off], free_mask)
    distance[off] = cell_distance * grid.resolution
    within = cell_distance <= snap_distance / grid.resolution + _SNAP_EPS  # [n_off] bool
    snapped = np.zeros(n, dtype=bool)  # [N]
    snapped[off] = within
    placed[snapped] = free_index[target[within, 0], target[within, 1]]
    unplaced = off & ~snapped  # [N] bool
    return placed, snapped, unplaced, distance


def place_observations(
    grid: OccupancyGrid, xy: np.ndarray, snap_distance: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Free cell of each world position (paper eq. 11), snapping points just off free space.

    A point whose cell ``grid.world_to_cell(xy)`` is free stays there. A point off free space
    (on an occupied or unknown cell, or outside the map) moves to the nearest free cell --
    Euclidean distance between cell centres, in cells, times the resolution -- when that
    distance is <= ``snap_distance`` metres; otherwise it is unplaced. Inside the map the nearest
    free cell comes from ``scipy.ndimage.distance_transform_edt`` on the non-free mask; outside
    the map it is the exact nearest free cell (a k-d tree over free cell indices, as if the map
    extended with non-free cells), so a point off the map by more than ``snap_distance`` is
    always unplaced. Ties between equally near free cells are broken by the EDT / k-d tree.
    ``snap_distance = 0`` disables snapping.

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
class PlacementReport:
    """Where observations went: nothing is dropped silently.

    ``*_on_free + *_snapped + *_unplaced`` is the number of images (words) observed.
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

    def summary(self) -> str:
        """One human-readable line."""
        return (
            f"images: {self.images_on_free} on free cells, {self.images_snapped} snapped, "
            f"{self.images_unplaced} unplaced; words: {self.words_on_free} on free cells, "
            f"{self.words_snapped} snapped, {self.words_unplaced} unplaced "
            f"(snap distance {self.snap_distance:g} m)"
        )


@dataclass(frozen=True, eq=False)
class CellCounts:
    """Per-cell sufficient statistics for the model: only cells that hold observations (sparse).

    M observed cells, K feature classes, V vocabulary tokens.
    """

    cells: np.ndarray  # [M] int64 free_index of cells with >= 1 placed observation, ascending
    image_counts: np.ndarray  # [M, K] float64 scaled features summed per cell
    word_counts: np.ndarray  # [M, V] float64 word counts (or tf-idf weights) summed per cell
    vocabulary: tuple[str, ...]  # [V]
    num_free: int
    placement: PlacementReport = field(repr=False)


def cell_counts(
    grid: OccupancyGrid,
    obs: Observations,
    *,
    feature_scaling: FeatureScaling = "probability",
    word_weighting: WordWeighting = "count",
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
    vocabulary: Sequence[str] | None = None,
) -> CellCounts:
    """Sum the observations per free cell (the model's sufficient statistics).

    Each observation is placed by :func:`place_observations`; for every cell m holding at least
    one placed observation::

        image_counts[m] = sum over images i in m of scale(f_i)         (scale_features)
        word_counts[m]  = sum over utterances d in m of n(., d)         word_weighting="count"
                        = sum over utterances d in m of tfidf(., d)     word_weighting="tfidf"

    tf-idf (eq. 20) treats all utterances of ``obs`` as the documents, placed or not.

    Vocabulary: ``vocabulary`` given -> its order defines the V columns and a token of ``obs``
    not in it raises ValueError (extend the vocabulary, or select the observations, first);
    ``None`` -> ``obs.vocabulary``. An empty vocabulary is an error, except when ``obs`` holds no
    utterances and the caller passes ``vocabulary=()`` explicitly (then V = 0).

    Unplaced observations are logged (``logger.warning`` with their counts) and listed in
    ``placement``; snapped ones are logged at INFO level.
    """
    if word_weighting not in ("count", "tfidf"):
        raise ValueError(f"word_weighting={word_weighting!r}: must be 'count' or 'tfidf'")
    if vocabulary is None:
        vocab = obs.vocabulary
        if not vocab:
            raise ValueError(
                "cell_counts: the observations hold no words (empty vocabulary); pass "
                "vocabulary=() to build counts without words"
            )
    else:
        vocab = tuple(vocabulary)
        for token in vocab:
            if not isinstance(token, str) or not token:
                raise ValueError(f"vocabulary holds an invalid token: {token!r}")
        if not vocab and obs.num_utterances:
            raise ValueError(
                f"cell_counts: empty vocabulary but the observations hold "
                f"{obs.num_utterances} utterances"
            )
    features = scale_features(obs.image_features, feature_scaling)  # [T, K]
    if word_weighting == "count":
        words = word_matrix(obs.utterances, vocab)  # [U, V]
    else:
        words = tfidf_weights(obs.utterances, vocab)  # [U, V]

    image_cell, image_snapped, image_unplaced = place_observations(
        grid, obs.image_xy, snap_distance
    )  # [T] x3
    word_cell, word_snapped, word_unplaced = place_observations(grid, obs.word_xy, snap_distance)

    image_ok = image_cell >= 0  # [T] bool
    word_ok = word_cell >= 0  # [U] bool
    cells = np.unique(np.concatenate([image_cell[image_ok], word_cell[word_ok]]))  # [M]
    image_counts = np.zeros((cells.size, features.shape[1]), dtype=np.float64)  # [M, K]
    np.add.at(image_counts, np.searchsorted(cells, image_cell[image_ok]), features[image_ok])
    word_counts = np.zeros((cells.size, len(vocab)), dtype=np.float64)  # [M, V]
    np.add.at(word_counts, np.searchsorted(cells, word_cell[word_ok]), words[word_ok])

    report = PlacementReport(
        images_on_free=int(obs.num_images - image_snapped.sum() - image_unplaced.sum()),
        images_snapped=int(image_snapped.sum()),
        images_unplaced=int(image_unplaced.sum()),
        words_on_free=int(obs.num_utterances - word_snapped.sum() - word_unplaced.sum()),
        words_snapped=int(word_snapped.sum()),
        words_unplaced=int(word_unplaced.sum()),
        unplaced_images=np.flatnonzero(image_unplaced).astype(np.int64),
        unplaced_words=np.flatnonzero(word_unplaced).astype(np.int64),
        snap_distance=float(snap_distance),
    )
    where = f" on map {grid.source}" if getattr(grid, "source", None) else ""
    if report.images_unplaced or report.words_unplaced:
        logger.warning(
            "%d image(s) and %d utterance(s) are farther than %g m from free space%s and were "
            "left out of the cell counts (image indices %s, utterance indices %s)",
            report.images_unplaced,
            report.words_unplaced,
            snap_distance,
            where,
            report.unplaced_images.tolist()[:20],
            report.unplaced_words.tolist()[:20],
        )
    if report.images_snapped or report.words_snapped:
        logger.info(
            "%d image(s) and %d utterance(s) snapped to the nearest free cell%s",
            report.images_snapped,
            report.words_snapped,
            where,
        )
    return CellCounts(
        cells=cells.astype(np.int64),
        image_counts=image_counts,
        word_counts=word_counts,
        vocabulary=vocab,
        num_free=int(grid.num_free),
        placement=report,
    )


# ---------------------------------------------------------------------------------------------
# Dataset files
# ---------------------------------------------------------------------------------------------


def find_dataset_root(path: str | os.PathLike[str] | None = None) -> Path | None:
    """The public dataset folder (the one holding ``map/``), resolved.

    Looked for in order: ``path`` if given (FileNotFoundError if it does not exist or holds no
    ``map/``); ``$SPCOPYRO_DATA`` if set (FileNotFoundError likewise);
    ``../shared/data/spcomapping`` relative to the current directory; the same relative to the
    project root (the folder above this package). None if no candidate holds a ``map/`` folder.
    """
    explicit = [(Path(path), "path")] if path is not None else []
    env = os.environ.get("SPCOPYRO_DATA")
    if not explicit and env:
        explicit = [(Path(env), "$SPCOPYRO_DATA")]
    for root, how in explicit:
        if not root.exists():
            raise FileNotFoundError(f"dataset folder {root} (from {how}) does not exist")
        if not (root / "map").is_dir():
            raise FileNotFoundError(f"dataset folder {root} (from {how}) holds no map/ folder")
        return root.resolve()
    relative = Path("..") / "shared" / "data" / "spcomapping"
    for base in (Path.cwd(), Path(__file__).resolve().parents[1]):
        root = base / relative
        if (root / "map").is_dir():
            return root.resolve()
    return None


def list_houses(root: str | os.PathLike[str]) -> list[str]:
    """Names of the room folders under ``root`` that have a map ``root/map/NAME.yaml``, sorted."""
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"dataset folder {root} does not exist")
    return sorted(
        entry.name
        for entry in root.iterdir()
        if entry.is_dir()
        and entry.name != "map"
        and (root / "map" / f"{entry.name}.yaml").is_file()
    )


@dataclass(frozen=True, eq=False)
class House:
    """A house: its map, what the robot observed in it, and optional ground truth.

    ``truth`` is ``[H, W]`` int64, the ground-truth category of each free cell (an index into
    ``category_names`` when given, -1 for unlabelled free cells) and -1 on every non-free cell.
    """

    name: str
    grid: OccupancyGrid
    observations: Observations
    truth: np.ndarray | None = None  # [H, W] int64, -1 off free
    category_names: tuple[str, ...] | None = None
    source: Path | None = None  # the room folder

    def __post_init__(self) -> None:
        if not self.name or self.name in (".", "..", "map") or re.search(r"[/\\]", self.name):
            raise ValueError(f"House.name={self.name!r}: not usable as a room folder name")
        if self.category_names is not None:
            names = tuple(self.category_names)
            if not all(isinstance(n, str) for n in names):
                raise ValueError(f"House.category_names must be strings: {names!r}")
            object.__setattr__(self, "category_names", names)
        if self.truth is not None:
            object.__setattr__(
                self, "truth", _check_truth(self.truth, self.grid, self.category_names, None)
            )
        if self.source is not None:
            object.__setattr__(self, "source", Path(self.source))


def _check_truth(
    truth: np.ndarray,
    grid: OccupancyGrid,
    category_names: tuple[str, ...] | None,
    path: Path | None,
) -> np.ndarray:
    """Validated ``[H, W]`` int64 truth; DataFormatError naming ``path`` (ValueError if None)."""

    def fail(problem: str, value: object = _MISSING) -> Exception:
        if path is not None:
            return DataFormatError(path, problem, value=value)
        suffix = "" if value is _MISSING else f": {value!r}"
        return ValueError(f"truth: {problem}{suffix}")

    raw = np.asarray(truth)
    if raw.dtype.kind not in "iu":
        raise fail("ground truth must hold integers, got dtype", str(raw.dtype))
    labels = raw.astype(np.int64)  # [H, W]
    if labels.shape != tuple(grid.shape):
        raise fail(f"shape differs from the map's {tuple(grid.shape)}", labels.shape)
    if labels.size and labels.min() < -1:
        raise fail("category ids must be >= -1, found", int(labels.min()))
    if category_names is not None and labels.size and labels.max() >= len(category_names):
        raise fail(f"category id out of range for {len(category_names)} names", int(labels.max()))
    off_free = ~np.asarray(grid.free, dtype=bool) & (labels != -1)  # [H, W] bool
    if off_free.any():
        row, col = np.argwhere(off_free)[0]
        raise fail(
            f"{int(off_free.sum())} non-free cell(s) carry a category (must be -1); first at "
            f"(row {row}, col {col})",
            int(labels[row, col]),
        )
    return labels


def _read_lines(path: Path) -> list[str]:
    """The file's lines (no line ends); blank lines at the end are dropped."""
    if not path.is_file():
        raise FileNotFoundError(f"{path}: required file not found")
    lines = [line.rstrip("\r") for line in path.read_text(encoding="utf-8-sig").split("\n")]
    while lines and not lines[-1].strip():
        lines.pop()
    return lines


def _parse_number(path: Path, text: str, line: int, column: int | None) -> float:
    try:
        value = float(text)
    except ValueError:
        raise DataFormatError(
            path, "not a number", line=line, column=column, value=text.strip()
        ) from None
    if not math.isfinite(value):
        raise DataFormatError(path, "not finite", line=line, column=column, value=text.strip())
    return value


def _read_matrix(path: Path, columns: int | None = None) -> np.ndarray:
    """Comma-separated numbers, one row per line; every row the same length -> ``[R, C]``."""
    rows: list[list[float]] = []
    width = columns
    for number, line in enumerate(_read_lines(path), start=1):
        if not line.strip():
            raise DataFormatError(path, "empty line", line=number, value=line)
        fields = line.split(",")
        if width is None:
            width = len(fields)
        if len(fields) != width:
            raise DataFormatError(
                path, f"row has {len(fields)} values, expected {width}", line=number, value=line
            )
        rows.append([_parse_number(path, text, number, c) for c, text in enumerate(fields, 1)])
    return np.array(rows, dtype=np.float64).reshape(len(rows), width or 0)


def _read_column(path: Path, expected: int, data_file: Path) -> np.ndarray:
    """One number per line -> ``[R]``; R must equal ``expected`` (the rows of ``data_file``)."""
    values = _read_matrix(path, columns=1)[:, 0]  # [R]
    if values.shape[0] != expected:
        raise DataFormatError(
            path,
            f"holds {values.shape[0]} values but {data_file.name} holds {expected} entries",
            value=values.shape[0],
        )
    return values


def _read_utterances_line(path: Path) -> tuple[tuple[str, ...], ...]:
    """St.csv: one line of comma-separated utterances, each tokenised."""
    lines = _read_lines(path)
    if len(lines) > 1:
        raise DataFormatError(
            path, "must be one line of comma-separated utterances", line=2, value=lines[1]
        )
    if not lines or not lines[0].strip():
        raise DataFormatError(path, "holds no words (empty vocabulary)")
    utterances = []
    for entry_number, entry in enumerate(lines[0].split(","), start=1):
        tokens = tokenize(entry)
        if not tokens:
            raise DataFormatError(
                path, f"utterance {entry_number} holds no words", line=1, value=entry
            )
        utterances.append(tokens)
    return tuple(utterances)


def _trial_files(room: Path, prefix: str) -> dict[int, Path]:
    pattern = re.compile(rf"{prefix}_(\d+)\.csv")
    found = {}
    for entry in room.iterdir():
        match = pattern.fullmatch(entry.name)
        if match and entry.is_file():
            found[int(match.group(1))] = entry
    return dict(sorted(found.items()))


def _read_trials(
    room: Path,
    image_xy: np.ndarray,
    utterances: tuple[tuple[str, ...], ...],
    files: dict[str, Path],
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, list[int], list[int]]:
    """image_trial [T], word_trial [U], image_yaw [T] or None, trial ids, images per trial."""
    num_images, num_utterances = image_xy.shape[0], len(utterances)
    poses, words = _trial_files(room, "pose"), _trial_files(room, "word")
    if not poses and not words:
        return (
            np.zeros(num_images, dtype=np.int64),
            np.zeros(num_utterances, dtype=np.int64),
            None,
            [0],
            [num_images],
        )
    for have, other, kind in ((poses, words, "word"), (words, poses, "pose")):
        missing = sorted(set(have) - set(other))
        if missing:
            raise DataFormatError(
                room / f"{kind}_{missing[0]}.csv",
                f"missing: trials {sorted(have)} have {'pose' if kind == 'word' else 'word'} "
                f"files but not {kind} files",
            )
    trials = list(poses)
    pose_rows = [_read_matrix(poses[k], columns=4) for k in trials]  # [n_k, 4] each
    image_counts = [p.shape[0] for p in pose_rows]
    if sum(image_counts) != num_images:
        raise DataFormatError(
            files["Ft"],
            f"holds {num_images} rows but the pose files hold {sum(image_counts)} ("
            + ", ".join(f"{poses[k].name}: {n}" for k, n in zip(trials, image_counts, strict=True))
            + ")",
            value=num_images,
        )
    pose = np.concatenate(pose_rows, axis=0)  # [T, 4] x, y, qz, qw
    first_row = np.cumsum([0, *image_counts])  # [n_trials + 1] first image of each trial

    def locate(i: int) -> tuple[Path, int]:
        """Pose file and 1-based line of image i."""
        k = int(np.searchsorted(first_row, i, side="right")) - 1
        return poses[trials[k]], i - int(first_row[k]) + 1

    mismatch = ~np.isclose(pose[:, :2], image_xy, rtol=0.0, atol=_POSE_XY_ATOL).all(axis=1)
    if mismatch.any():
        i = int(np.flatnonzero(mismatch)[0])
        path, line = locate(i)
        raise DataFormatError(
            path,
            f"x, y differ from {files['Xtx'].name}/{files['Xty'].name} line {i + 1} "
            f"({image_xy[i].tolist()})",
            line=line,
            value=pose[i, :2].tolist(),
        )
    zero = (pose[:, 2] == 0) & (pose[:, 3] == 0)
    if zero.any():
        i = int(np.flatnonzero(zero)[0])
        path, line = locate(i)
        raise DataFormatError(
            path,
            "quaternion (qz, qw) is zero",
            line=line,
            value=pose[i].tolist(),
        )
    yaw = 2.0 * np.arctan2(pose[:, 2], pose[:, 3])  # [T] planar rotation about z

    word_counts = []
    position = 0
    for k in trials:
        lines = _read_lines(words[k])
        for number, line in enumerate(lines, start=1):
            tokens = tokenize(line)
            if not tokens:
                raise DataFormatError(words[k], "utterance holds no words", line=number, value=line)
            if position < num_utterances and tokens != utterances[position]:
                raise DataFormatError(
                    words[k],
                    f"differs from {files['St'].name} utterance {position + 1} "
                    f"({' '.join(utterances[position])!r})",
                    line=number,
                    value=line,
                )
            position += 1
        word_counts.append(len(lines))
    if sum(word_counts) != num_utterances:
        raise DataFormatError(
            files["St"],
            f"holds {num_utterances} utterances but the word files hold {sum(word_counts)} ("
            + ", ".join(f"{words[k].name}: {n}" for k, n in zip(trials, word_counts, strict=True))
            + ")",
            value=num_utterances,
        )
    trial_ids = np.array(trials, dtype=np.int64)  # [n_trials]
    return (
        np.repeat(trial_ids, image_counts),
        np.repeat(trial_ids, word_counts),
        yaw,
        trials,
        image_counts,
    )


def _image_paths(
    room: Path, trials: Sequence[int], counts: Sequence[int]
) -> tuple[Path, ...] | None:
    """Camera images ROOM/img_K/* (sorted by name) for every trial, or None (logged) if absent
    or inconsistent with the rows of Ft.csv."""
    folders = {
        int(m.group(1)): entry
        for entry in room.iterdir()
        if entry.is_dir() and (m := re.fullmatch(r"img_(\d+)", entry.name))
    }
    if not folders:
        return None
    paths: list[Path] = []
    for k, n in zip(trials, counts, strict=True):
        folder = folders.get(k)
        if folder is None:
            if n == 0:
                continue
            logger.warning("%s: no folder img_%d for trial %d; image_paths left None", room, k, k)
            return None
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if len(files) != n:
            logger.warning(
                "%s holds %d images but trial %d has %d rows in Ft.csv; image_paths left None",
                folder,
                len(files),
                k,
                n,
            )
            return None
        paths.extend(files)
    extra = sorted(set(folders) - set(trials))
    if extra:
        logger.warning("%s: img_%d has no trial; image_paths left None", room, extra[0])
        return None
    return tuple(paths)


def load_house(
    room_dir: str | os.PathLike[str], map_yaml: str | os.PathLike[str] | None = None
) -> House:
    """Read a house in the public SpCoMapping dataset layout (see the dataset's README.md).

    ``room_dir`` = ``ROOT/NAME``; the map is ``ROOT/map/NAME.yaml`` unless ``map_yaml`` is given.
    Files (ROOM/...):

    * ``Ft.csv`` (required): one image per row, K comma-separated features >= 0, K the same in
      every row; ``Xtx.csv``, ``Xty.csv`` (required): world x / y of each row, one per line.
    * ``St.csv`` (required): one line of comma-separated utterances (trailing newline optional),
      each tokenised with :func:`tokenize` (an entry may be a sentence); ``StXtx.csv``,
      ``StXty.csv`` (required): world x / y of each utterance, one per line.
    * ``pose_K.csv`` / ``word_K.csv`` (optional, K = trial id, in pairs): their row / line counts
      split images / utterances into trials in order of K, and must add up to the Ft.csv rows /
      St.csv utterances; pose rows are ``x, y, qz, qw`` (x, y equal to Xtx/Xty), giving
      ``image_yaw = 2 atan2(qz, qw)``; word lines must repeat St.csv's utterances. Absent: all
      observations are trial 0 and ``image_yaw`` is None.
    * ``img_K/`` (optional): camera images, sorted by name, one per Ft row of trial K
      (:data:`IMAGE_SUFFIXES`); a count mismatch logs a warning and leaves ``image_paths`` None.
    * ``truth.npy`` ``[H, W]`` int and ``categories.json`` (list of names) (optional, written by
      the synthetic generator): ground-truth category per cell, -1 off free.

    Raises:
        FileNotFoundError: a required file (or the map) is missing; the message names it.
        DataFormatError: a malformed file: non-numeric, NaN / inf or negative features, rows of
            different lengths, empty Ft.csv or St.csv, position files whose length differs from
            their data file, pose / word files inconsistent with Ft.csv / St.csv, truth.npy
            whose shape differs from the map; the message names file, 1-based line and value.
    """
    room = Path(room_dir)
    if not room.is_dir():
        raise FileNotFoundError(f"room folder {room} does not exist")
    name = room.resolve().name
    yaml_path = Path(map_yaml) if map_yaml is not None else room.parent / "map" / f"{name}.yaml"
    if not yaml_path.is_file():
        raise FileNotFoundError(f"{yaml_path}: map of house {name!r} not found")
    grid = load_map(yaml_path)

    files = {key: room / f"{key}.csv" for key in ("Ft", "Xtx", "Xty", "St", "StXtx", "StXty")}
    features = _read_matrix(files["Ft"])  # [T, K]
    if features.shape[0] == 0:
        raise DataFormatError(files["Ft"], "holds no image features (empty file)")
    if (features < 0).any():
        row, col = np.argwhere(features < 0)[0]
        raise DataFormatError(
            files["Ft"],
            "negative image feature",
            line=int(row) + 1,
            column=int(col) + 1,
            value=float(features[row, col]),
        )
    num_images = features.shape[0]
    image_xy = np.stack(
        [
            _read_column(files["Xtx"], num_images, files["Ft"]),
            _read_column(files["Xty"], num_images, files["Ft"]),
        ],
        axis=1,
    )  # [T, 2]
    utterances = _read_utterances_line(files["St"])
    word_xy = np.stack(
        [
            _read_column(files["StXtx"], len(utterances), files["St"]),
            _read_column(files["StXty"], len(utterances), files["St"]),
        ],
        axis=1,
    )  # [U, 2]
    image_trial, word_trial, image_yaw, trial_ids, images_per_trial = _read_trials(
        room, image_xy, utterances, files
    )
    image_paths = _image_paths(room, trial_ids, images_per_trial)
    observations = Observations(
        image_features=features,
        image_xy=image_xy,
        image_trial=image_trial,
        utterances=utterances,
        word_xy=word_xy,
        word_trial=word_trial,
        image_yaw=image_yaw,
        image_paths=image_paths,
    )

    category_names = None
    categories_path = room / "categories.json"
    if categories_path.is_file():
        try:
            names = json.loads(categories_path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as error:
            raise DataFormatError(
                categories_path, f"not valid JSON ({error.msg})", line=error.lineno
            ) from None
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise DataFormatError(categories_path, "must be a JSON list of strings", value=names)
        category_names = tuple(names)
    truth = None
    truth_path = room / "truth.npy"
    if truth_path.is_file():
        try:
            raw = np.load(truth_path, allow_pickle=False)
        except ValueError as error:
            raise DataFormatError(truth_path, f"not a numeric .npy array ({error})") from None
        truth = _check_truth(raw, grid, category_names, truth_path)
    return House(
        name=name,
        grid=grid,
        observations=observations,
        truth=truth,
        category_names=category_names,
        source=room.resolve(),
    )


def _format_float(value: float) -> str:
    return repr(float(value))  # shortest string that reads back to the same float


def _write_lines(path: Path, lines: Iterable[str], trailing_newline: bool = True) -> None:
    text = "\n".join(lines)
    if trailing_newline and text:
        text += "\n"
    path.write_text(text, encoding="utf-8")


_MANAGED_FILES = (
    "Ft.csv",
    "Xtx.csv",
    "Xty.csv",
    "St.csv",
    "StXtx.csv",
    "StXty.csv",
    "truth.npy",
    "categories.json",
)


def save_house(house: House, root: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
    """Write ``house`` in the dataset layout under ``root``; the inverse of :func:`load_house`.

    Writes ``root/map/NAME.{pgm,yaml}`` (:func:`spcopyro.maps.save_map`) and ``root/NAME/`` with
    Ft.csv, Xtx.csv, Xty.csv, St.csv (tokens joined by single spaces, utterances comma separated,
    no trailing newline, like the original), StXtx.csv, StXty.csv, one ``pose_K.csv``
    (``x, y, qz, qw``; yaw 0 when unknown) and ``word_K.csv`` per trial K, copies of the camera
    images as ``img_K/NNNNN.ext`` when ``image_paths`` is known, and truth.npy + categories.json
    when present. Floats are written with ``repr`` (they read back exactly); yaw goes through
    the quaternion, so it reads back to within rounding, wrapped to (-pi, pi].

    Raises:
        ValueError: no images or no utterances (load_house would reject the files); observations
            not grouped by trial in ascending order; a token that would not read back as itself
            (a comma, whitespace, upper case or edge punctuation).
        FileExistsError: ``root/NAME`` is not empty or the map exists, and ``overwrite`` is
            False. With ``overwrite`` the files this function writes (and stale pose_K, word_K,
            img_K) are replaced; other files are left alone.

    Returns:
        The room folder ``root/NAME``.
    """
    obs = house.observations
    if obs.num_images == 0 or obs.num_feature_classes == 0:
        raise ValueError(f"save_house({house.name!r}): no images (Ft.csv would be empty)")
    if obs.num_utterances == 0:
        raise ValueError(f"save_house({house.name!r}): no utterances (St.csv would be empty)")
    for name, trial in (("image_trial", obs.image_trial), ("word_trial", obs.word_trial)):
        if (np.diff(trial) < 0).any():
            raise ValueError(
                f"save_house({house.name!r}): {name} is not in ascending order; the files store "
                "observations trial after trial"
            )
    for u, tokens in enumerate(obs.utterances):
        for token in tokens:
            if "," in token:
                raise ValueError(
                    f"save_house({house.name!r}): utterance {u} token {token!r} contains a comma "
                    "(St.csv separates utterances with commas)"
                )
            if tokenize(token) != (token,):
                raise ValueError(
                    f"save_house({house.name!r}): utterance {u} token {token!r} would read back "
                    f"as {tokenize(token)!r}"
                )

    for source in obs.image_paths or ():
        if source.suffix.lower() not in IMAGE_SUFFIXES:
            raise ValueError(
                f"save_house({house.name!r}): image {source} is not one of {IMAGE_SUFFIXES}"
            )

    root = Path(root)
    room = root / house.name
    map_yaml = root / "map" / f"{house.name}.yaml"
    if (room.exists() and any(room.iterdir())) or map_yaml.exists():
        if not overwrite:
            raise FileExistsError(f"{room} (or {map_yaml}) already exists; pass overwrite=True")
        sources = obs.image_paths or ()
        if any(room.resolve() in p.resolve().parents for p in sources):
            raise ValueError(
                f"save_house: cannot overwrite {room}, the house's images are read from it"
            )
        for entry in room.iterdir() if room.exists() else ():
            if entry.name in _MANAGED_FILES or re.fullmatch(r"(pose|word)_\d+\.csv", entry.name):
                entry.unlink()
            elif entry.is_dir() and re.fullmatch(r"img_\d+", entry.name):
                shutil.rmtree(entry)
    room.mkdir(parents=True, exist_ok=True)
    (root / "map").mkdir(parents=True, exist_ok=True)
    save_map(house.grid, map_yaml)

    fmt = _format_float
    _write_lines(room / "Ft.csv", (",".join(map(fmt, row)) for row in obs.image_features.tolist()))
    _write_lines(room / "Xtx.csv", map(fmt, obs.image_xy[:, 0].tolist()))
    _write_lines(room / "Xty.csv", map(fmt, obs.image_xy[:, 1].tolist()))
    sentences = [" ".join(tokens) for tokens in obs.utterances]
    _write_lines(room / "St.csv", [",".join(sentences)], trailing_newline=False)
    _write_lines(room / "StXtx.csv", map(fmt, obs.word_xy[:, 0].tolist()))
    _write_lines(room / "StXty.csv", map(fmt, obs.word_xy[:, 1].tolist()))

    yaw = obs.image_yaw if obs.image_yaw is not None else np.zeros(obs.num_images)  # [T]
    pose = np.stack(
        [obs.image_xy[:, 0], obs.image_xy[:, 1], np.sin(yaw / 2), np.cos(yaw / 2)], axis=1
    )  # [T, 4]
    for k in obs.trials:
        in_trial = np.flatnonzero(obs.image_trial == k)  # [n_k]
        _write_lines(
            room / f"pose_{k}.csv", (",".join(map(fmt, row)) for row in pose[in_trial].tolist())
        )
        _write_lines(
            room / f"word_{k}.csv",
            (s for s, t in zip(sentences, obs.word_trial, strict=True) if t == k),
        )
        if obs.image_paths is not None and in_trial.size:
            folder = room / f"img_{k}"
            folder.mkdir()
            for number, i in enumerate(in_trial, start=1):
                source = obs.image_paths[i]
                shutil.copyfile(source, folder / f"{number:05d}{source.suffix.lower()}")

    if house.truth is not None:
        np.save(room / "truth.npy", np.asarray(house.truth, dtype=np.int64))
    if house.category_names is not None:
        (room / "categories.json").write_text(
            json.dumps(list(house.category_names), indent=1) + "\n", encoding="utf-8"
        )
    return room
