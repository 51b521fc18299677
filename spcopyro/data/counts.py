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
count would otherwise turn every sweep's log joint into NaN or rounding noise. Those checks, the
feature scaling and the warnings about what is left out live in
:mod:`~spcopyro.data.count_checks` (re-exported here).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from spcopyro.config import (
    IMAGES,
    WORDS,
    DataPreparation,
    FeatureScaling,
    FootprintKernel,
    WordWeightingSetting,
    footprint_spreads,
    words_footprint_radius,
)
from spcopyro.data.count_checks import (
    KEEPS,
    MAX_COUNT_TOTAL,
    check_count_totals,
    say_placement_warnings,
    scale_features,
    scaled_away,
)
from spcopyro.data.footprint import (
    SpreadSources,
    footprint_weights,
    free_cell_graph,
    shared,
    spread_counts,
    spread_sources,
)
from spcopyro.data.observations import Observations
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
    (:class:`~spcopyro.data.factored_counts.SpreadSources`). Empty without a footprint."""


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
    footprint_reach_door_width: float | None = None,
) -> CellCounts:
    """Sum the observations per free cell (the model's sufficient statistics).

    Each observation is placed by :func:`place_observations`; for every cell m holding at least
    one placed observation::

        image_counts[m] = sum over images i in m of scale(f_i)         (scale_features)
        word_counts[m]  = sum over utterances d in m of n(., d)         word_weighting="count"
                        = sum over utterances d in m of tfidf(., d)     word_weighting="tfidf"
        modalities[j].counts[m] = sum over observations o of modality j in m of counts_o

    (``"auto"``, the default of a fit's :class:`~spcopyro.config.preparation.DataPreparation`:
    tf-idf when at least 30% of the utterances of ``obs`` have more than one token, else counts,
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
    ``footprint_reach_radius`` metres from its cell (None: no limit) and drawn within the room
    segments at doorways up to ``footprint_reach_door_width`` metres (None: no cut). All 0 leave the
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
               footprint_reach_share, footprint_reach_radius,
               footprint_reach_door_width)  # fmt: skip
        return shared((grid, obs), key, lambda: _with_footprint(
            plain, grid, obs, features, words, placed, (footprint_radius, words_radius),
            footprint_kernel, footprint_fov,
            (footprint_reach_share, footprint_reach_radius, footprint_reach_door_width),
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
    """:func:`cell_counts` under a :class:`~spcopyro.config.preparation.DataPreparation` (its
    feature scaling, word weighting and scaling, snap distance and footprint): the counts a fit with
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
        footprint_reach_door_width=preparation.footprint_reach_door_width,
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
    reach: tuple[float, float | None, float | None] = (0.0, None, None),
) -> CellCounts:
    """``plain`` (the counts without footprint: placement report, vocabulary) with every
    observation spread over its footprint (:func:`~spcopyro.data.footprint.footprint_weights`):
    ``radii`` (metres) the images' and further modalities', then the utterances' (0: own cell);
    ``reach`` (share, radius, door width) of each over its Voronoi cell among its modality's,
    cut at the radius and drawn within the rooms at that door width (the reach share).
    ``features`` [T, K] and ``words`` [U, V] are the scaled / weighted rows per observation,
    ``placed`` the free index of each image, utterance and further observation (-1: unplaced)."""
    fov = fov if radii[0] else None  # images at their own cell (words' footprint only): unread
    if fov is not None and obs.num_images and obs.image_yaw is None:
        raise ValueError("footprint_fov needs each image's yaw (pose_K.csv gives it); these "
                         "observations hold none: leave it unset for the whole disc")  # fmt: skip
    image_cell, word_cell, further_cells = placed
    bar = _footprint_bar(grid, max(radii), (image_cell, word_cell, *further_cells))
    graph = free_cell_graph(grid)
    each = dict(graph=graph, advance=bar.update, reach_share=reach[0], reach_radius=reach[1],
                reach_door_width=reach[2])  # fmt: skip
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
