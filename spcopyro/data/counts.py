"""Per-cell sums of the observations: the sparse sufficient statistics the model reads.

:func:`cell_counts` places every observation (:func:`~spcopyro.data.placement.place_observations`)
and sums them per cell into a :class:`CellCounts`, with the image-feature scaling
(:func:`scale_features`) and the word weighting (counts or tf-idf, paper eq. 20) as options.
Further modalities (:class:`~spcopyro.data.observations.ModalityObservations`) are placed like
images and their raw counts summed per cell (:class:`CellModalityCounts`).
Observations that cannot be placed are logged (``logging``, logger ``"spcopyro"``) and listed in
the counts' :class:`~spcopyro.data.placement.PlacementReport`; so is a placement where most
observations fall off free space (the sign of a wrong map or origin).

Every count total must be finite and at most :data:`MAX_COUNT_TOTAL` (:func:`check_count_totals`):
a value that scaling makes infinite (``floor100`` of 1e308) or a total far beyond any real
count would otherwise turn every sweep's log joint into NaN or rounding noise.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from spcopyro._util.messages import setting
from spcopyro.config import (
    IMAGES,
    WORDS,
    DataPreparation,
    FeatureScaling,
    FootprintKernel,
    WordWeightingSetting,
    footprint_spreads,
    is_number,
    words_footprint_radius,
)
from spcopyro.data.footprint import (
    SpreadSources,
    footprint_weights,
    free_cell_graph,
    shared,
    spread_counts,
    spread_sources,
)
from spcopyro.data.observations import DataFormatError, Observations
from spcopyro.data.placement import (
    DEFAULT_SNAP_DISTANCE,
    ModalityPlacement,
    PlacementReport,
    count_on_occupied,
    left_out_and_placed,
    on_map_text,
    place_observations,
    position_hint,
)
from spcopyro.data.text import tfidf_weights, word_matrix
from spcopyro.data.word_weighting import resolve_word_weighting
from spcopyro.maps.grid import OccupancyGrid

__all__ = [
    "KEEPS", "MAX_COUNT_TOTAL", "CellCounts", "CellModalityCounts", "FeatureScaling",
    "cell_counts", "check_count_totals", "prepared_cell_counts", "say_placement_warnings",
    "scale_features", "scaled_away",
]  # fmt: skip

logger = logging.getLogger("spcopyro")

MAX_COUNT_TOTAL = 1e15
"""The largest total of a modality's counts (one observation's, and all observations' together)
that :func:`cell_counts` accepts. The log joint holds each modality's data term
sum_i x_i . log phi_{C_i}, of magnitude about total * log K nats; float64 resolves it to
2^-52 of that, so at a total of 1e15 over K = 205 image classes (5.3e15 nats) its rounding step
reaches 1 nat and comparing the log joints of two sweeps (the best-sweep choice) becomes
rounding noise; float64 also stops holding every integer count exactly at 2^53 = 9.0e15. Real
data are far below it: a histogram sums to 1 (``floor100``: at most 100) per image."""


def scale_features(features: np.ndarray, scaling: FeatureScaling) -> np.ndarray:
    """Image histograms ``[T, K]`` -> counts ``[T, K]`` float64.

    ``"probability"``: f as it is; ``"floor100"``: floor(100 f) (the released code's integer
    pseudo-counts; small probabilities become 0); a positive float s: s * f.
    A huge feature can overflow to inf (``floor100`` of 1e308): :func:`cell_counts` checks the
    result (:func:`check_count_totals`).
    """
    f = np.asarray(features, dtype=np.float64)
    if isinstance(scaling, str):
        if scaling == "probability":
            return f.copy()
        if scaling == "floor100":
            with np.errstate(over="ignore"):  # inf is reported by check_count_totals
                return np.floor(100.0 * f)
    elif is_number(scaling) and math.isfinite(scaling) and scaling > 0:
        with np.errstate(over="ignore"):
            return float(scaling) * f
    raise ValueError(
        f"feature_scaling={scaling!r}: must be 'probability', 'floor100' or a positive number"
    )


KEEPS = 0.5
"""``fit --refine auto`` (:func:`spcopyro.fit.refine.refine_decision`) does not refine when
floor(100 f), the refinement's counting of the images, leaves nothing of more than this share of
them (every feature of a row below 0.01: a histogram over the 1000 ImageNet classes of
``spcopyro features``, all of them with ``--weights random``): the decision was measured on the
images, and the refinement would fit without them (the README's rosbag walk: the coarse fit's six
rooms became four on the map's cells, every image left out). ``spcopyro features`` says so of the
rows it writes (``floor100_note``)."""


def scaled_away(raw: np.ndarray, scaled: np.ndarray) -> np.ndarray:
    """[n] int64 indices of the images whose histogram ``raw`` ``[T, K]`` holds something but
    whose ``scaled`` row ``[T, K]`` (:func:`scale_features` of it) is all zero: ``floor100`` of
    a histogram over many classes (1000 ImageNet classes, every probability below 0.01) leaves
    nothing of it. The one test of it: :func:`cell_counts` leaves these images out (and warns),
    ``fit --refine auto`` does not refine where floor(100 f) would leave out most of them
    (:func:`spcopyro.fit.refine.refine_decision`), and ``spcopyro features`` names them."""
    raw = np.asarray(raw, dtype=np.float64).reshape(scaled.shape)  # [T, K]
    return np.flatnonzero((scaled.sum(axis=1) == 0) & (raw.sum(axis=1) > 0)).astype(np.int64)


def _warn_scaled_away(
    raw: np.ndarray,
    lost: np.ndarray,
    scaling: FeatureScaling,
    source: str | os.PathLike[str] | None,
) -> None:
    """Warn (logger ``"spcopyro"``) about the images ``lost`` (:func:`scaled_away` of the
    histograms ``raw`` ``[T, K]``), which would else be lost silently."""
    if not lost.size:
        return
    first = 1 if source is not None else 0  # Ft.csv's lines count from 1, indices from 0
    listed = ", ".join(str(i + first) for i in lost[:5].tolist()) + (
        ", ..." if lost.size > 5 else ""
    )
    where = f"lines {listed} of {Path(source) / 'Ft.csv'}" if source else f"images {listed}"
    probability = setting("feature_scaling='probability'", "--feature-scaling probability")
    never = setting("refine='never'", "--refine never")
    logger.warning(
        "%d of %d image(s) carry no information under feature_scaling=%r, left out of the "
        "counts: every feature of their row is below 0.01, which floor(100 f) makes 0 (%s); a "
        "histogram over many classes (the 1000 ImageNet classes of spcopyro features) needs "
        "%s or a number; the refinement of preset coarse counts images so too: %s",
        lost.size, raw.shape[0], scaling, where, probability, never,
    )  # fmt: skip


def _location(modality: str, index: int, source: Path | None) -> tuple[Path | None, int, str]:
    """(file, 1-based line, words) naming observation ``index`` of a modality as load_house
    reads it from the house folder ``source``: Ft.csv row i is line i + 1, St.csv holds all
    utterances on line 1, a modality_<name>.csv has a header line before its observations."""
    if modality == IMAGES:
        return (source / "Ft.csv" if source else None), index + 1, f"image {index}"
    if modality == WORDS:
        return (source / "St.csv" if source else None), 1, f"utterance {index} (entry {index + 1})"
    file = source / f"modality_{modality}.csv" if source else None
    return file, index + 2, f"observation {index} of modality {modality!r}"


def _left_out(
    xy: np.ndarray,
    indices: np.ndarray,
    files: str | None,
    what: str,
    tokens: Sequence[Sequence[str]] | None = None,
    first_line: int = 1,
) -> str:
    """The observations ``indices`` (of positions ``xy`` ``[N, 2]``) left out, named by the
    lines of ``files`` (the files in the house folder that give their positions, observation i
    on line i + ``first_line``) or, without a house folder, by index; the first five, with
    their position (and words)."""
    shown = []
    for i in indices.tolist()[:5]:
        said = f"{' '.join(tokens[i])!r} at " if tokens is not None else ""
        number = i + first_line if files else i
        shown.append(f"{number} ({said}x {xy[i, 0]:.2f}, y {xy[i, 1]:.2f})")
    more = f", ... ({indices.size} in all)" if indices.size > 5 else ""
    if files:
        return f"{what} at line(s) {', '.join(shown)}{more} of {files}"
    return f"{what} of index {', '.join(shown)}{more}"


def say_placement_warnings(
    report: PlacementReport,
    grid: OccupancyGrid,
    obs: Observations,
    source: str | os.PathLike[str] | None = None,
) -> None:
    """Warn (logger ``"spcopyro"``) of what :func:`cell_counts`' ``report`` of ``obs`` on ``grid``
    leaves out: the images scaled away, the observations farther than the snap distance from
    free space (with their lines in the house folder ``source``), and most of them off free
    space. ``cell_counts`` says them unless ``warn=False``; a fit counts with ``warn=False`` and
    says them once its placement is not refused for the map
    (:func:`~spcopyro.data.inverted_map.check_placement`)."""
    _warn_scaled_away(obs.image_features, report.scaled_away_images, report.feature_scaling,
                      source)  # fmt: skip
    where = on_map_text(grid)
    farther = f"farther than {report.snap_distance:g} m from free space{where}"
    if getattr(grid, "coarsened_from", None) is not None:  # placed through the map
        farther += (
            f", or on the map only in free space that reaches no free {grid.resolution:g} m "
            "model cell"
        )
    folder = Path(source) if source is not None else None
    if report.images_unplaced or report.words_unplaced:
        named = []
        if report.images_unplaced:
            files = folder and f"{folder / 'Xtx.csv'} and Xty.csv"
            named.append(_left_out(obs.image_xy, report.unplaced_images, files, "images"))
        if report.words_unplaced:
            files = folder and f"{folder / 'StXtx.csv'} and StXty.csv"
            named.append(
                _left_out(obs.word_xy, report.unplaced_words, files, "utterances", obs.utterances)
            )
        logger.warning(
            "%d image(s) and %d utterance(s) are %s and were left out of the cell counts: %s",
            report.images_unplaced,
            report.words_unplaced,
            farther,
            "; ".join(named),
        )
    off_free = report.off_free_warning(where)
    if off_free:
        logger.warning("%s", off_free)
    for placed in report.modalities:
        if placed.unplaced:
            file = folder / f"modality_{placed.name}.csv" if folder else None
            logger.warning(
                "%d observation(s) of modality %r are %s and were left out of the cell counts: %s",
                placed.unplaced,
                placed.name,
                farther,
                _left_out(
                    next(m for m in obs.modalities if m.name == placed.name).positions,
                    placed.unplaced_indices,
                    file and str(file),
                    "observations",
                    first_line=2,
                ),
            )


def check_count_totals(
    counts: np.ndarray,
    modality: str,
    *,
    raw: np.ndarray | None = None,
    scaling: FeatureScaling | None = None,
    source: str | os.PathLike[str] | None = None,
) -> None:
    """Reject counts that would make the log joint NaN or meaningless.

    ``counts`` ``[T, K]``: one row per observation of ``modality`` (``"images"`` after
    :func:`scale_features` with ``scaling``, whose input ``raw`` ``[T, K]`` names the value read;
    ``"words"``; or a further modality's name). Every entry must be finite and, with
    ``n_t = sum_k counts[t, k]``, every ``n_t`` and ``sum_t n_t`` at most :data:`MAX_COUNT_TOTAL`.

    Raises:
        DataFormatError: ``source`` (the house folder) given: names the file (Ft.csv, St.csv,
            modality_<name>.csv), the line, the column and the value.
        ValueError: else, naming the observation by its index, and the value.
    """
    counts = np.asarray(counts, dtype=np.float64)  # [T, K]
    if counts.size == 0:
        return
    folder = Path(source) if source is not None else None
    read = counts if raw is None else np.asarray(raw, dtype=np.float64)  # [T, K]
    scaled = "" if scaling is None else f" under feature_scaling={scaling!r}"
    limit = (
        f"above MAX_COUNT_TOTAL = {MAX_COUNT_TOTAL:g} (beyond it the log joint's data term "
        "outgrows float64's resolution of 1 nat: no real histogram or count comes near)"
    )

    def fail(index: int, column: int, problem: str) -> ValueError:
        file, line, what = _location(modality, index, folder)
        value = float(read[index, column])
        if file is not None:
            return DataFormatError(file, f"{what}: {problem}", line=line, column=column + 1,
                                   value=value)  # fmt: skip
        return ValueError(f"{what}, column {column}: {problem}: {value!r}")

    finite = np.isfinite(counts)  # [T, K] bool
    if not finite.all():
        index, column = np.argwhere(~finite)[0]
        raise fail(int(index), int(column), f"the count becomes {counts[index, column]}{scaled}")
    with np.errstate(over="ignore"):
        totals = counts.sum(axis=1)  # [T] n_t (inf where a row overflows)
        grand = totals.sum()
    largest = int(np.argmax(totals))
    column = int(np.argmax(counts[largest]))
    if totals[largest] > MAX_COUNT_TOTAL:
        raise fail(largest, column, f"its counts total {totals[largest]:.4g}{scaled}, {limit}")
    if grand > MAX_COUNT_TOTAL:
        raise fail(
            largest, column,
            f"the {counts.shape[0]} observations of {modality!r} total {grand:.4g}{scaled}, "
            f"{limit}; this one has the largest total, {totals[largest]:.4g}",
        )  # fmt: skip


@dataclass(frozen=True, eq=False)
class CellModalityCounts:
    """One further modality's counts summed per observed cell (rows follow ``CellCounts.cells``).

    M observed cells, K items of the modality.
    """

    name: str
    items: tuple[str, ...]  # [K]
    counts: np.ndarray  # [M, K] float64 raw counts summed per cell


@dataclass(frozen=True, eq=False)
class CellCounts:
    """Per-cell sufficient statistics for the model: only cells that hold observations (sparse).

    M observed cells, K feature classes, V vocabulary tokens. The rows of every count matrix
    (``image_counts``, ``word_counts``, each of ``modalities``) follow ``cells``.
    """

    cells: np.ndarray  # [M] int64 free_index of cells with >= 1 placed observation, ascending
    image_counts: np.ndarray  # [M, K] float64 scaled features summed per cell
    word_counts: np.ndarray  # [M, V] float64 word counts (or tf-idf weights) summed per cell
    vocabulary: tuple[str, ...]  # [V]
    num_free: int
    placement: PlacementReport = field(repr=False)
    modalities: tuple[CellModalityCounts, ...] = ()  # further modalities, in the obs' order
    spread: dict[str, SpreadSources] = field(default_factory=dict, repr=False)
    """With a footprint: each modality's counts in factored form (by modality name; equal to
    its count matrix to rounding), which a sampler's products may use
    (:class:`~spcopyro.data.footprint.SpreadSources`). Empty without a footprint."""


def cell_counts(
    grid: OccupancyGrid,
    obs: Observations,
    *,
    feature_scaling: FeatureScaling = "probability",
    word_weighting: WordWeightingSetting = "count",
    snap_distance: float = DEFAULT_SNAP_DISTANCE,
    vocabulary: Sequence[str] | None = None,
    source: str | os.PathLike[str] | None = None,
    footprint_radius: float = 0.0,
    footprint_kernel: FootprintKernel = "uniform",
    footprint_fov: float | None = None,
    word_scaling: float = 1.0,
    warn: bool = True,
    word_footprint_radius: float | None = None,
    footprint_reach_share: float = 0.0,
    footprint_reach_radius: float | None = None,
) -> CellCounts:
    """Sum the observations per free cell (the model's sufficient statistics).

    Each observation is placed by :func:`place_observations`; for every cell m holding at least
    one placed observation::

        image_counts[m] = sum over images i in m of scale(f_i)         (scale_features)
        word_counts[m]  = sum over utterances d in m of n(., d)         word_weighting="count"
                        = sum over utterances d in m of tfidf(., d)     word_weighting="tfidf"
        modalities[j].counts[m] = sum over observations o of modality j in m of counts_o

    (``"auto"``, the default of a fit's :class:`~spcopyro.config.DataPreparation`: tf-idf when
    at least 30% of the utterances of ``obs`` have more than one token, else counts,
    :mod:`spcopyro.data.word_weighting`. This function counts unless told otherwise.)

    Further modalities are placed exactly like images (same snapping) and summed as they are
    (no scaling or weighting). The observed cells are those holding at least one placed image,
    utterance or observation of a further modality, so a row may be zero in some of the
    matrices. tf-idf (eq. 20) treats all utterances of ``obs`` as the documents, placed or not.

    Vocabulary: ``vocabulary`` given -> its order defines the V columns and a token of ``obs``
    not in it raises ValueError (extend the vocabulary, or select the observations, first);
    ``None`` -> ``obs.vocabulary``; observations without utterances (a house of images only)
    give V = 0 (the model's words then explain nothing), and an empty ``vocabulary`` is an
    error only when ``obs`` holds utterances.

    Unplaced observations are logged (``logger.warning`` with their counts) and listed in
    ``placement``; snapped ones are logged at INFO level; more than half of all observations
    off free space is logged as a warning (:meth:`PlacementReport.off_free_warning`).

    Observation footprint (``footprint_radius`` > 0, :mod:`spcopyro.data.footprint`): every placed
    observation o is spread over the free cells within that geodesic distance of its cell with
    weights w_oc summing to 1 (``footprint_kernel``; ``footprint_fov`` degrees around
    ``obs.image_yaw`` for images), so each sum above becomes sum_o w_oc counts_o and the observed
    cells are every cell with a positive weight; ``word_footprint_radius``, if not None, is the
    utterances' own (0: their cell; the fov is read only where ``footprint_radius`` > 0);
    ``footprint_reach_share`` e > 0 moves a share e of each observation's weight to its geodesic
    Voronoi cell among its modality's observed cells (with both radii 0 too), cut at
    ``footprint_reach_radius`` metres from its cell (None: no limit). All 0 leave the
    counts as without them. ``warn=False``: no warnings about observations left out
    (:func:`say_placement_warnings`: a caller counting the same observations twice says them once,
    a fit after its placement check). ``word_scaling`` s multiplies every utterance's word counts
    (or tf-idf weights) by s before they are placed (``DataPreparation.word_scaling``).

    Counts are checked by :func:`check_count_totals` (finite, totals at most
    :data:`MAX_COUNT_TOTAL`): ``source``, the house folder the observations were read from
    (``House.source``), lets its errors name the file and line; else they name the index.
    """
    word_weighting = resolve_word_weighting(word_weighting, obs)  # ValueError naming a bad one
    if vocabulary is None:
        vocab = obs.vocabulary  # () when no utterance was heard: V = 0
    else:
        vocab = tuple(vocabulary)  # a blank word: word_matrix's ValueError, naming its column
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
    if word_scaling != 1.0:
        words = words * float(word_scaling)  # [U, V]: each utterance counted s times
    check_count_totals(features, IMAGES, raw=obs.image_features, scaling=feature_scaling,
                       source=source)  # fmt: skip
    check_count_totals(words, WORDS, source=source)
    for modality in obs.modalities:
        check_count_totals(modality.counts, modality.name, source=source)

    image_cell, image_snapped, image_unplaced = place_observations(
        grid, obs.image_xy, snap_distance
    )  # [T] x3
    word_cell, word_snapped, word_unplaced = place_observations(grid, obs.word_xy, snap_distance)
    further = [place_observations(grid, m.positions, snap_distance) for m in obs.modalities]

    words_radius = words_footprint_radius(footprint_radius, word_footprint_radius)
    if footprint_spreads(footprint_radius, words_radius, footprint_reach_share):
        plain = cell_counts(grid, obs, feature_scaling=feature_scaling,
                            word_weighting=word_weighting, snap_distance=snap_distance,
                            vocabulary=vocab, source=source, word_scaling=word_scaling,
                            warn=warn)  # fmt: skip
        placed = (image_cell, word_cell, [cell for cell, _, _ in further])
        # within shared_footprints (spcopyro fit), spread once for its summary and model data
        key = (feature_scaling, word_weighting, snap_distance, vocab, word_scaling,
               footprint_radius, footprint_kernel, footprint_fov, words_radius,
               footprint_reach_share, footprint_reach_radius)  # fmt: skip
        return shared((grid, obs), key, lambda: _with_footprint(
            plain, grid, obs, features, words, placed, (footprint_radius, words_radius),
            footprint_kernel, footprint_fov, (footprint_reach_share, footprint_reach_radius),
        ))  # fmt: skip
    lost = scaled_away(obs.image_features, features)  # [n] images left with nothing
    image_ok = image_cell >= 0  # [T] bool
    word_ok = word_cell >= 0  # [U] bool
    further_cells = [cell[cell >= 0] for cell, _, _ in further]  # [T_j] each
    cells = np.unique(np.concatenate([image_cell[image_ok], word_cell[word_ok], *further_cells]))
    image_counts = np.zeros((cells.size, features.shape[1]), dtype=np.float64)  # [M, K]
    np.add.at(image_counts, np.searchsorted(cells, image_cell[image_ok]), features[image_ok])
    word_counts = np.zeros((cells.size, len(vocab)), dtype=np.float64)  # [M, V]
    np.add.at(word_counts, np.searchsorted(cells, word_cell[word_ok]), words[word_ok])
    modality_counts = []
    for modality, (cell, _, _) in zip(obs.modalities, further, strict=True):
        ok = cell >= 0  # [T_j] bool
        summed = np.zeros((cells.size, modality.num_items), dtype=np.float64)  # [M, K_j]
        np.add.at(summed, np.searchsorted(cells, cell[ok]), modality.counts[ok])
        modality_counts.append(CellModalityCounts(modality.name, modality.items, summed))

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
        hint=position_hint(grid, np.concatenate([obs.image_xy, obs.word_xy])),  # [T + U, 2]
        images_scaled_away=int(lost.size),
        scaled_away_images=lost,
        feature_scaling=feature_scaling,
        modalities=tuple(
            ModalityPlacement(
                name=modality.name,
                on_free=int(modality.num_observations - snapped.sum() - unplaced.sum()),
                snapped=int(snapped.sum()),
                unplaced=int(unplaced.sum()),
                unplaced_indices=np.flatnonzero(unplaced).astype(np.int64),
            )
            for modality, (_, snapped, unplaced) in zip(obs.modalities, further, strict=True)
        ),
    )
    left_out = left_out_and_placed(report, obs)[0]  # [n, 2] every modality's
    report = replace(report, unplaced_on_occupied=count_on_occupied(grid, left_out))
    if warn:
        say_placement_warnings(report, grid, obs, source)
    where = on_map_text(grid)
    if report.images_snapped or report.words_snapped:
        logger.info("%d image(s) and %d utterance(s) snapped to the nearest free cell%s",
                    report.images_snapped, report.words_snapped, where)  # fmt: skip
    for placed in report.modalities:
        if placed.snapped:
            logger.info("%d observation(s) of modality %r snapped to the nearest free cell%s",
                        placed.snapped, placed.name, where)  # fmt: skip
    return CellCounts(
        cells=cells.astype(np.int64),
        image_counts=image_counts,
        word_counts=word_counts,
        vocabulary=vocab,
        num_free=int(grid.num_free),
        placement=report,
        modalities=tuple(modality_counts),
    )


def prepared_cell_counts(
    grid: OccupancyGrid,
    obs: Observations,
    preparation: DataPreparation,
    *,
    vocabulary: Sequence[str] | None = None,
    source: str | os.PathLike[str] | None = None,
    warn: bool = True,
) -> CellCounts:
    """:func:`cell_counts` under a :class:`~spcopyro.config.DataPreparation` (its feature
    scaling, word weighting and scaling, snap distance and footprint): the counts a fit with
    that preparation reads (its model grid is ``grid``; ``cell_size`` is applied to the map
    before, not here)."""
    return cell_counts(
        grid, obs, word_scaling=preparation.word_scaling, source=source, warn=warn,
        feature_scaling=preparation.feature_scaling, word_weighting=preparation.word_weighting,
        footprint_radius=preparation.footprint_radius, footprint_fov=preparation.footprint_fov,
        footprint_kernel=preparation.footprint_kernel, snap_distance=preparation.snap_distance,
        word_footprint_radius=preparation.word_footprint_radius, vocabulary=vocabulary,
        footprint_reach_share=preparation.footprint_reach_share,
        footprint_reach_radius=preparation.footprint_reach_radius,
    )  # fmt: skip


def _with_footprint(
    plain: CellCounts,
    grid: OccupancyGrid,
    obs: Observations,
    features: np.ndarray,
    words: np.ndarray,
    placed: tuple[np.ndarray, np.ndarray, list[np.ndarray]],
    radii: tuple[float, float],
    kernel: FootprintKernel,
    fov: float | None,
    reach: tuple[float, float | None] = (0.0, None),
) -> CellCounts:
    """``plain`` (the counts without footprint: placement report, vocabulary) with every
    observation spread over its footprint (:func:`~spcopyro.data.footprint.footprint_weights`):
    ``radii`` (metres) the images' and further modalities', then the utterances' (0: own cell);
    ``reach`` (share, radius) of each over its Voronoi cell among its modality's, cut at the
    radius (the reach share).
    ``features`` [T, K] and ``words`` [U, V] are the scaled / weighted rows per observation,
    ``placed`` the free index of each image, utterance and further observation (-1: unplaced)."""
    fov = fov if radii[0] else None  # images at their own cell (words' footprint only): unread
    if fov is not None and obs.num_images and obs.image_yaw is None:
        raise ValueError("footprint_fov needs each image's yaw (pose_K.csv gives it); these "
                         "observations hold none: leave it unset for the whole disc")  # fmt: skip
    image_cell, word_cell, further_cells = placed
    bar = _footprint_bar(grid, max(radii), (image_cell, word_cell, *further_cells))
    graph = free_cell_graph(grid)
    each = dict(graph=graph, advance=bar.update, reach_share=reach[0], reach_radius=reach[1])
    image_w = footprint_weights(grid, image_cell, radii[0], kernel, yaw=obs.image_yaw, fov=fov,
                                **each)  # fmt: skip  # [T, N]
    word_w = footprint_weights(grid, word_cell, radii[1], kernel, **each)  # [U, N]
    further_w = [footprint_weights(grid, c, radii[0], kernel, **each) for c in further_cells]
    reached = [np.unique(w.indices) for w in (image_w, word_w, *further_w)]
    cells = np.unique(np.concatenate(reached)).astype(np.int64)  # [M]
    bar.set_postfix_str(f"summing the counts on the {cells.size:,} cells they reach")
    rows = {IMAGES: (image_w, features), WORDS: (word_w, words)}
    for m, w in zip(plain.modalities, further_w, strict=True):
        rows[m.name] = (w, obs.modality(m.name).counts)
    modalities = tuple(
        CellModalityCounts(m.name, m.items, spread_counts(w, obs.modality(m.name).counts, cells))
        for m, w in zip(plain.modalities, further_w, strict=True)
    )
    counts = CellCounts(
        cells=cells,
        image_counts=spread_counts(image_w, features, cells),  # [M, K]
        word_counts=spread_counts(word_w, words, cells),  # [M, V]
        vocabulary=plain.vocabulary,
        num_free=plain.num_free,
        placement=plain.placement,
        modalities=modalities,
        spread={name: spread_sources(w, x, cells) for name, (w, x) in rows.items()},
    )
    bar.close()
    return counts


def _footprint_bar(grid: OccupancyGrid, radius: float, placed: tuple[np.ndarray, ...]):
    """The progress bar of spreading the footprints (:func:`~spcopyro._util.progress.setup_bar`,
    on a large map) over the distinct observed cells (``placed``: each modality's [T_j] free
    indices, -1 unplaced)."""
    from spcopyro._util.progress import setup_bar

    total = sum(int(np.unique(cell[cell >= 0]).size) for cell in placed)
    return setup_bar(grid.num_free, total, f"{radius:g} m footprints on {grid.num_free:,} free "
                     "cells", "source")  # fmt: skip
