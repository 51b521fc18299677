"""What the robot observed, in world coordinates, and the error raised for malformed data.

A robot takes images (each turned into a K-class place histogram by a CNN) and hears utterances,
each at a world position. :class:`Observations` holds them (world coordinates, free vocabulary:
nothing pre-listed), validated on construction; :class:`DataFormatError` is what the dataset
readers raise for a malformed file or value, naming the file, the 1-based line and column and
the offending value.

Places may be learnt from any number of modalities: besides images and words, an
:class:`Observations` holds further modalities as :class:`ModalityObservations`, each a named
set of count vectors over its own items (for instance the objects a detector saw, or the Wi-Fi
access points heard), observed at world positions.
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from spcopyro._util.context import set_within
from spcopyro._util.messages import echo
from spcopyro.config import HYPERPARAMETER_FIELDS, IMAGES, WORDS
from spcopyro.data.text import _check_tokens, hidden_words_warning, tokenize

logger = logging.getLogger("spcopyro")

__all__ = ["RESERVED_MODALITY_NAMES", "DataFormatError", "ModalityObservations", "Observations"]

_MISSING = object()
_MODALITY_NAME = re.compile(r"[a-z][a-z0-9_]*")  # also the file name modality_<name>.csv
RESERVED_MODALITY_NAMES = (IMAGES, WORDS)  # the two modalities Observations always holds
SITE_NAMES_TAKEN = (
    "labels", "pi", "theta", "w", "potts",  # the model's sites
    "cells", "concepts", "observed_cells",  # its plates
    "log_joint", "num_concepts", *HYPERPARAMETER_FIELDS,  # SpCoGibbs' saved sites
)  # fmt: skip
"""The model's latent sites and plates (spcopyro.model) and the Gibbs kernel's diagnostics and
sampled hyperparameters in ``mcmc.get_samples()``: a modality's observation site ``<name>`` must
not take one of them."""


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
            message += f": {echo(value)}"
        super().__init__(message)


# ---------------------------------------------------------------------------------------------
# Observations
# ---------------------------------------------------------------------------------------------


def _as_xy(
    values: object, name: str, count: int | None = None, counted: str = "observations"
) -> np.ndarray:
    """``[N, 2]`` finite positions; with ``count``, one per row of ``counted`` (which of the two
    is wrong is the caller's to judge: the message names both)."""
    xy = np.array(values, dtype=np.float64)  # [N, 2]
    if xy.size == 0:
        xy = xy.reshape(0, 2)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise ValueError(f"{name} must have shape [N, 2], got {xy.shape}")
    if count is not None and xy.shape[0] != count:
        raise ValueError(
            f"{name} has {xy.shape[0]} rows but {counted} has {count}: one position per observation"
        )
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


def _modality_name_problem(name: object) -> str | None:
    """Why ``name`` cannot name a further modality, or None if it can."""
    if not isinstance(name, str) or _MODALITY_NAME.fullmatch(name) is None:
        return "a modality name must be a lower-case identifier ([a-z][a-z0-9_]*)"
    if name in RESERVED_MODALITY_NAMES:
        return f"a modality name must not be one of {RESERVED_MODALITY_NAMES} (always present)"
    if name in SITE_NAMES_TAKEN or name.endswith(("_probs", "_concentration")):
        return (
            f"a modality name must not be one of {SITE_NAMES_TAKEN} or end in _probs or "
            "_concentration: its "
            "observation site would take the name of a model site or plate, or of a sampler "
            "diagnostic or sampled hyperparameter"
        )
    return None


@dataclass(frozen=True, eq=False)
class ModalityObservations:
    """Observations of one further modality (beyond images and words): count vectors at positions.

    T observations, each a vector of K non-negative counts (or weights) over the modality's
    items, taken at a world position in a trial. Arrays are converted (copied) to the dtypes
    below and validated on construction; a ``ValueError`` names the modality and the field.

    Attributes:
        name: identifier of the modality, a lower-case identifier (``[a-z][a-z0-9_]*``), not
            ``"images"`` or ``"words"``; the dataset file is ``modality_<name>.csv``.
        items: ``[K]`` distinct names of what each count column counts (K >= 1); non-empty,
            without commas, line breaks or surrounding whitespace (they are CSV column names).
        positions: ``[T, 2]`` float64, world metres (x, y) of each observation.
        trials: ``[T]`` int64 >= 0, trial id of each observation.
        counts: ``[T, K]`` float64, finite and >= 0.
    """

    name: str
    items: tuple[str, ...]  # [K]
    positions: np.ndarray  # [T, 2] float64
    trials: np.ndarray  # [T] int64
    counts: np.ndarray  # [T, K] float64

    def __post_init__(self) -> None:
        problem = _modality_name_problem(self.name)
        if problem is not None:
            raise ValueError(f"ModalityObservations.name={self.name!r}: {problem}")
        what = f"modality {self.name!r}"
        if isinstance(self.items, str):
            raise ValueError(f"{what}: items must be a sequence of names, got {self.items!r}")
        items = tuple(self.items)
        if not items:
            raise ValueError(f"{what}: items must name at least one count column")
        for k, item in enumerate(items):
            if (
                not isinstance(item, str)
                or not item
                or item != item.strip()
                or any(char in item for char in ",\r\n")
            ):
                raise ValueError(
                    f"{what}: item {k} must be a non-empty string without commas, line breaks "
                    f"or surrounding whitespace (a CSV column name), got {item!r}"
                )
        if len(set(items)) != len(items):
            seen: set[str] = set()
            dup = next(item for item in items if item in seen or seen.add(item))
            raise ValueError(f"{what}: items list {dup!r} more than once")
        counts = np.array(self.counts, dtype=np.float64)  # [T, K]
        if counts.size == 0 and counts.ndim != 2:
            counts = counts.reshape(0, len(items))
        if counts.ndim != 2 or counts.shape[1] != len(items):
            raise ValueError(
                f"{what}: counts must have shape [T, {len(items)}] (one column per item), "
                f"got {counts.shape}"
            )
        if not np.isfinite(counts).all():
            row, col = np.argwhere(~np.isfinite(counts))[0]
            raise ValueError(f"{what}: counts[{row}, {col}] is not finite: {counts[row, col]}")
        if (counts < 0).any():
            row, col = np.argwhere(counts < 0)[0]
            raise ValueError(f"{what}: counts[{row}, {col}] is negative: {counts[row, col]}")
        num = counts.shape[0]
        set_ = object.__setattr__
        set_(self, "items", items)
        set_(self, "positions", _as_xy(self.positions, f"{what}: positions", num, "counts"))
        set_(self, "trials", _as_trial(self.trials, f"{what}: trials", num))
        set_(self, "counts", counts)

    @property
    def num_observations(self) -> int:
        """T."""
        return int(self.counts.shape[0])

    @property
    def num_items(self) -> int:
        """K."""
        return len(self.items)

    def _select(self, keep: np.ndarray) -> ModalityObservations:
        """The observations where ``keep`` ([T] bool) holds; items and name kept."""
        return ModalityObservations(
            name=self.name,
            items=self.items,
            positions=self.positions[keep],
            trials=self.trials[keep],
            counts=self.counts[keep],
        )


_HIDDEN_WORDS_TOLD: ContextVar[bool] = ContextVar("hidden_words_told", default=False)


@contextmanager
def hidden_words_told() -> Iterator[None]:
    """Within it, :class:`Observations` does not warn of words holding invisible format
    characters: its caller has (the St.csv reader, naming the file and line; a subset of
    observations that warned)."""
    with set_within(_HIDDEN_WORDS_TOLD, True):
        yield


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
        modalities: further modalities (:class:`ModalityObservations`), with distinct names;
            empty by default.
    """

    image_features: np.ndarray  # [T, K] float64
    image_xy: np.ndarray  # [T, 2] float64
    image_trial: np.ndarray  # [T] int64
    utterances: tuple[tuple[str, ...], ...]  # [U]
    word_xy: np.ndarray  # [U, 2] float64
    word_trial: np.ndarray  # [U] int64
    image_yaw: np.ndarray | None = None  # [T] float64
    image_paths: tuple[Path, ...] | None = None  # [T]
    modalities: tuple[ModalityObservations, ...] = ()

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
        if isinstance(self.utterances, str):
            raise ValueError(
                f"utterances must be a sequence of utterances, each its tokens, got the string "
                f"{echo(self.utterances)} (its characters would be utterances)"
            )
        for u, given in enumerate(self.utterances):
            if isinstance(given, str):  # tuple("kitchen") is its letters, each a word
                raise ValueError(
                    f"utterance {u} is a string, {echo(given)}: give its tokens, "
                    f"{tokenize(given)!r} (spcopyro.data.tokenize), not its characters"
                )
        utterances = tuple(tuple(u) for u in self.utterances)
        for u, tokens in enumerate(utterances):
            if not tokens:
                raise ValueError(f"utterance {u} holds no tokens")
            _check_tokens(tokens, u)
        hidden = None if _HIDDEN_WORDS_TOLD.get() else hidden_words_warning(utterances)
        if hidden:  # 'kit\u200bchen' prints as 'kitchen' but is another word
            logger.warning("%s", hidden)
        num_utterances = len(utterances)
        set_ = object.__setattr__
        set_(self, "image_features", features)
        set_(self, "image_xy", _as_xy(self.image_xy, "image_xy", num_images, "image_features"))
        set_(self, "image_trial", _as_trial(self.image_trial, "image_trial", num_images))
        set_(self, "utterances", utterances)
        set_(self, "word_xy", _as_xy(self.word_xy, "word_xy", num_utterances, "utterances"))
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
        if isinstance(self.modalities, ModalityObservations):
            raise TypeError("modalities must be a sequence of ModalityObservations, not one")
        modalities = tuple(self.modalities)
        for m, modality in enumerate(modalities):
            if not isinstance(modality, ModalityObservations):
                raise TypeError(
                    f"modalities[{m}] must be a ModalityObservations, got {type(modality).__name__}"
                )
        names = [modality.name for modality in modalities]
        if len(set(names)) != len(names):
            dup = next(name for n, name in enumerate(names) if name in names[:n])
            raise ValueError(f"modalities: the name {dup!r} is used more than once")
        set_(self, "modalities", modalities)

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
        """Sorted distinct trial ids over images, utterances and the further modalities."""
        ids = np.union1d(self.image_trial, self.word_trial)
        for modality in self.modalities:
            ids = np.union1d(ids, modality.trials)
        return tuple(int(t) for t in ids)

    def modality(self, name: str) -> ModalityObservations:
        """The further modality called ``name``; KeyError (listing the names) if there is none."""
        for modality in self.modalities:
            if modality.name == name:
                return modality
        raise KeyError(f"no modality {name!r}; have {[m.name for m in self.modalities]}")

    @cached_property
    def vocabulary(self) -> tuple[str, ...]:
        """Distinct tokens, in order of first appearance."""
        return tuple(dict.fromkeys(token for tokens in self.utterances for token in tokens))

    def select_trials(self, trials: Iterable[int]) -> Observations:
        """Only the observations of these trials (e.g. for held-out folds), order kept.

        Further modalities are filtered the same way (a modality left with no observation stays,
        with T = 0, so the modalities and their items do not change).

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
        with hidden_words_told():  # this Observations' construction warned of them
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
                modalities=tuple(m._select(np.isin(m.trials, wanted)) for m in self.modalities),
            )
