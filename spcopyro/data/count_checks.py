"""The observations' values checked, and what the counts leave out said.

:func:`~spcopyro.data.counts.cell_counts` reads these before it sums anything: the image-feature
scaling (:func:`scale_features`) and the images it empties (:func:`scaled_away`), every count
total finite and at most :data:`MAX_COUNT_TOTAL` (:func:`check_count_totals`, naming the file,
line and value), and the warnings about observations left out of the counts
(:func:`say_placement_warnings`: logger ``"spcopyro"``, with their lines in the house folder).
Moved from :mod:`spcopyro.data.counts`, which re-exports every public name.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from spcopyro._util.messages import setting
from spcopyro._util.number_checks import is_positive_number
from spcopyro.config import IMAGES, WORDS, FeatureScaling
from spcopyro.data.observations import DataFormatError, Observations
from spcopyro.data.placement import PlacementReport, on_map_text
from spcopyro.maps.grid import OccupancyGrid

__all__ = [
    "KEEPS", "MAX_COUNT_TOTAL", "check_count_totals", "say_placement_warnings",
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
    elif is_positive_number(scaling):
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
