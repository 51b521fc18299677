r"""A fitted SpCoMapping for its user, whatever method fitted it: the semantic map, each
concept's words (and items of any further modality), "where is X?".

:class:`SpCoResult` holds a *point estimate* of every cell's concept (``labels``: Gibbs'
MAP-visited state, or the most probable concept under a variational posterior), optionally the
per-cell marginals ``[N, L]`` (a variational q(C), or label frequencies over samples), point
estimates or posterior means of pi and of every modality's distributions, and a per-iteration
:class:`~spcopyro.inference.protocol.Trace` (the log joint for Gibbs, the ELBO for variational
methods). An inference method hands it an :class:`~spcopyro.inference.protocol.InferenceOutput`;
:meth:`SpCoResult.from_output` adds the map, the item names and the settings.

"Where is X?" (the paper's eq. 19, with the area prior by default) and the warnings of an answer
to treat with care are in :mod:`spcopyro.results.where`.
"""

from __future__ import annotations

import csv
import functools
import json
import os
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from spcopyro._util.messages import with_article
from spcopyro._util.npz import write_npz
from spcopyro._util.number_checks import is_integer
from spcopyro._util.outputs import DAMAGED_FILE_ERRORS, read_npz
from spcopyro.config import IMAGES, WORDS, DataPreparation, SpCoConfig
from spcopyro.inference.protocol import InferenceOutput, Trace
from spcopyro.maps import OccupancyGrid, load_map, save_map
from spcopyro.results.concept_names import concept_names
from spcopyro.results.concept_words import (
    lift,
    listed_distinctive_words,
    listed_top_words,
    ranked,
    words_modelled,
    words_note,
)
from spcopyro.results.semantic_map import UnknownWordError, word_index, word_key
from spcopyro.results.specks import with_speck_fields
from spcopyro.results.where import (
    DEFAULT_WHERE_PRIOR,
    WHERE_PRIORS,
    WhereAnswer,
    answer_warnings,
    bayes_factor,
    concept_given_words,
    shared_answers,
)

__all__ = [
    "EmissionTable",
    "InferenceOutput",
    "SpCoResult",
    "Trace",
    "UnknownWordError",
    "word_index",
]

RESULT_FILE = "result.npz"
_SETTINGS = ("model", "data", "method", "inference")
"""The entries of ``config.json`` that are settings (the others are the provenance)."""

_COUNTED = DataPreparation(word_weighting="count")
"""The preparation of a result built without one (a library caller's, a test's): words counted,
as :func:`~spcopyro.data.counts.cell_counts` counts them unless told otherwise, recorded
resolved, never ``"auto"``, which an update would resolve for its own data."""
MAP_FILE = "map.yaml"
_OPTIONAL_ARRAYS = (
    "marginals", "labels_final", "concept_totals", "word_totals", "agreement", "word_counts"
)  # fmt: skip
"""The parts of a result that may be None, saved in ``result.npz`` under their own names."""


def _count(n: int) -> int:
    """How many items a list asks for, an integer >= 0, or ValueError (``n=-1`` gave every
    item but the last, a slice's reading of it)."""
    if not is_integer(n) or n < 0:
        raise ValueError(f"n must be an integer >= 0, got {n!r}")
    return int(n)


@dataclass(frozen=True)
class EmissionTable:
    """One modality's per-concept distributions, with the names of what they are over."""

    name: str
    """The modality (``"images"``, ``"words"``, or a further one)."""
    items: tuple[str, ...]
    """[K_m] the names of the items (the vocabulary for words; class numbers for images)."""
    probabilities: np.ndarray
    """[L, K_m] each concept's distribution over the items."""


@dataclass(frozen=True)
class SpCoResult:
    """A fitted semantic map with its map, vocabulary, settings and trace.

    ``labels`` is ``[N]``: the concepts of the free cells in the grid's ``free_index`` order;
    :meth:`label_image` gives them as an ``[H, W]`` image (-1 off free space).
    """

    grid: OccupancyGrid
    config: SpCoConfig
    labels: np.ndarray  # [N] int64
    pi: np.ndarray  # [L]
    emissions: tuple[EmissionTable, ...]
    trace: Trace
    best_iteration: int
    method: str = "gibbs"
    marginals: np.ndarray | None = None  # [N, L]
    labels_final: np.ndarray | None = None  # [N]
    agreement: np.ndarray | None = None  # [N] p(sample agrees with a point estimate's labels)
    preparation: DataPreparation = _COUNTED  # a fit's: fit_house's, resolved
    inference: dict[str, object] = field(default_factory=dict)
    name: str = ""
    provenance: dict[str, object] = field(default_factory=dict)
    """Where the data came from, the software's versions, ...
    (:func:`spcopyro.fit.house.provenance`):
    top-level entries of ``config.json`` beside the settings."""
    concept_totals: np.ndarray | None = None
    """[L, 1 + n_modalities] per concept under ``labels``: its observed cells, then each
    modality's total count there (emissions' order); None when unknown (an old result)."""
    word_totals: np.ndarray | None = None
    """[V] each vocabulary word's total count over the map's observed cells (the model's
    counts): 0 for a word heard only off the map's free space, whose where-answer is the prior's
    alone (:meth:`where` warns); None when unknown (an old result)."""
    word_counts: np.ndarray | None = None
    """[L, V] each word's count in each concept's region under ``labels`` (the model's counts), 0
    for a word never heard there: the word lists keep a heard word, the rest out
    (:func:`~spcopyro.results.concept_words.shown_top_words`); None when unknown (an old
    result, whose lists read the unheard words from ``w`` alone)."""

    @classmethod
    def from_output(
        cls,
        output: InferenceOutput,
        grid: OccupancyGrid,
        items: dict[str, tuple[str, ...]],
        config: SpCoConfig,
        *,
        modalities: tuple[str, ...] = (IMAGES, WORDS),
        method: str = "gibbs",
        preparation: DataPreparation = _COUNTED,
        name: str = "",
        provenance: dict[str, object] | None = None,
        concept_totals: np.ndarray | None = None,
        word_totals: np.ndarray | None = None,
        word_counts: np.ndarray | None = None,
    ) -> SpCoResult:
        """The result of ``output`` on ``grid``. ``modalities``: the names of the model data's
        modalities in order; ``items``: the item names of each (class numbers are used for a
        modality without names, e.g. images)."""
        tables = []
        for modality, table in zip(modalities, output.emissions, strict=True):
            table = np.asarray(table)
            names = tuple(items.get(modality, ())) or tuple(str(k) for k in range(table.shape[1]))
            if len(names) != table.shape[1]:
                raise ValueError(
                    f"{len(names)} item names for the {table.shape[1]} items of {modality!r}"
                )
            tables.append(EmissionTable(modality, names, table))
        return cls(
            grid=grid,
            config=config,
            labels=np.asarray(output.labels, dtype=np.int64),
            pi=np.asarray(output.pi),
            emissions=tuple(tables),
            trace=output.trace,
            best_iteration=int(output.best_iteration),
            method=method,
            marginals=output.marginals,
            labels_final=output.labels_final,
            agreement=output.agreement,
            preparation=preparation,
            inference=dict(output.options),
            name=name,
            provenance=dict(provenance or {}),
            concept_totals=concept_totals,
            word_totals=word_totals,
            word_counts=word_counts,
        )

    # -- the parts --------------------------------------------------------------------------------

    @functools.cached_property
    def _computed(self) -> dict[Hashable, object]:
        """What :meth:`computed_once` kept (a new result, :func:`dataclasses.replace`'s too,
        starts with nothing kept)."""
        return {}

    def computed_once(self, key: Hashable, compute: Callable[[], object]) -> object:
        """``compute()``, called only the first time ``key`` is asked for on this result and
        kept with it (the result is frozen: what is derived from it alone stays true). An array
        is kept read-only, so that no caller changes what the next one gets. ``where --out``
        asks for :func:`~spcopyro.results.uncertainty.unmapped_note` three times (the printed
        line and both figures), ``navigate`` for :meth:`word_posteriors` once per place."""
        kept = self._computed
        if key not in kept:
            value = compute()
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
            kept[key] = value
        return kept[key]

    def emission(self, modality: str) -> EmissionTable:
        """The :class:`EmissionTable` of ``modality`` (KeyError naming the known ones)."""
        for table in self.emissions:
            if table.name == modality:
                return table
        raise KeyError(
            f"no modality {modality!r} in this result; it has {[t.name for t in self.emissions]}"
        )

    @property
    def theta(self) -> np.ndarray:
        """[L, K] the image-feature distributions."""
        return self.emission(IMAGES).probabilities

    @property
    def w(self) -> np.ndarray:
        """[L, V] the word distributions."""
        return self.emission(WORDS).probabilities

    @property
    def vocabulary(self) -> tuple[str, ...]:
        """[V] the words, in the columns' order of :attr:`w`."""
        return self.emission(WORDS).items

    @property
    def best_objective(self) -> float:
        """The objective (log joint or ELBO) of the state the point estimate comes from."""
        return float(self.trace.objective[self.best_iteration])

    # -- the semantic map -------------------------------------------------------------------------

    def labels_of(self, which: str = "best") -> np.ndarray:
        """[N] labels of the point estimate (``"best"``) or of a sampler's last state
        (``"final"``)."""
        if which not in ("best", "final"):
            raise ValueError(f"which must be 'best' or 'final', got {which!r}")
        if which == "final":
            if self.labels_final is None:
                raise ValueError(f"{with_article(self.method)} result has no final state's labels")
            return self.labels_final
        return self.labels

    def label_image(self, which: str = "best") -> np.ndarray:
        """[H, W] int64 concept of every free cell, -1 elsewhere (map image row order)."""
        image = np.full(self.grid.shape, -1, dtype=np.int64)
        image[self.grid.free] = self.labels_of(which)  # free cells in raster = free_index order
        return image

    def concept_sizes(self) -> np.ndarray:
        """[L] the number of cells of each concept in the point estimate."""
        return np.bincount(self.labels, minlength=self.config.num_concepts)

    def concepts_in_use(self, which: str = "best") -> np.ndarray:
        """Concept ids labelling at least one cell, largest region first."""
        sizes = np.bincount(self.labels_of(which), minlength=self.config.num_concepts)
        used = np.flatnonzero(sizes)
        return used[np.argsort(-sizes[used], kind="stable")]

    def top_items(self, modality: str, concept: int, n: int = 3) -> list[tuple[str, float]]:
        """The ``n`` most probable items of a concept under a modality, with probabilities."""
        table = self.emission(modality)
        concept, n = self._concept(concept), _count(n)
        if not table.items:
            return []
        row = table.probabilities[concept]
        order = ranked(row)[:n]  # ties (to the last bits) in item order, on any CPU
        return [(table.items[k], float(row[k])) for k in order]

    def top_words(self, concept: int, n: int = 3) -> list[tuple[str, float]]:
        """The ``n`` most probable words of a concept under w_concept, with their probabilities."""
        return self.top_items(WORDS, concept, n)

    def _concept(self, concept: int) -> int:
        """``concept`` as an index 0..L-1, or ValueError (-1 read the last concept's row)."""
        count = self.config.num_concepts
        if not is_integer(concept) or not 0 <= concept < count:
            raise ValueError(f"concept must be an integer in 0..{count - 1}, got {concept!r}")
        return int(concept)

    def heard(self, concept: int, modality: str = WORDS) -> float | None:
        """The total count of ``modality`` observed in the concept's region (words: how many
        were heard there, tf-idf weighted if so prepared, in words: the model's counts
        divided by ``word_scaling``); None when the result does not know."""
        concept = self._concept(concept)
        if self.concept_totals is None:
            return None
        names = [t.name for t in self.emissions]
        total = float(self.concept_totals[concept, 1 + names.index(modality)])
        scaling = getattr(self.preparation, "word_scaling", 1.0) if modality == WORDS else 1.0
        return total / scaling

    def lift(self, modality: str = WORDS) -> np.ndarray:
        """[L, K_m] p(item | concept) / p(item), p(item) the area-weighted mixture over the
        concepts in use (:func:`spcopyro.results.concept_words.lift`)."""
        return lift(self.emission(modality).probabilities, self.concept_sizes())

    def distinctive_words(self, concept: int, n: int = 3) -> list[tuple[str, float, float]]:
        """The ``n`` words of largest lift above ``MIN_LIFT`` (1.1) for a concept, as
        ``(word, lift, p)`` (:func:`~spcopyro.results.concept_words.listed_distinctive_words`):
        of the words heard in its region where known; none where none was, or the fit did not
        model its words."""
        return listed_distinctive_words(self, self._concept(concept), _count(n))

    def concepts(self, n_words: int = 3) -> list[dict[str, object]]:
        """Per concept in use: id, its region's ``name`` (the word ``where`` answers with it,
        :func:`~spcopyro.results.concept_names.concept_name`), cell count, pi, top words (and
        the top items of every further modality) with probabilities; the observed cells and
        words heard in its region (``observed_cells``, ``words_heard``; None when unknown), its
        distinctive words ``[word, lift, p]``, and no word lists but a ``words_note`` where no
        word was heard or the fit did not model its words
        (:func:`~spcopyro.results.concept_words.words_note`)."""
        sizes = self.concept_sizes()
        further = [t.name for t in self.emissions if t.name not in (IMAGES, WORDS)]
        summaries = []
        names = concept_names(self)
        for c in self.concepts_in_use():
            heard = self.heard(int(c))
            top = listed_top_words(self, int(c), n_words)  # none: not heard or not modelled
            distinctive = self.distinctive_words(int(c), n_words)
            cells = None if self.concept_totals is None else int(self.concept_totals[c, 0])
            summary: dict[str, object] = {
                "concept": int(c),
                "name": names[int(c)],
                "cells": int(sizes[c]),
                "pi": float(self.pi[c]),
                "top_words": [[word, p] for word, p in top],
                "observed_cells": cells,
                "words_heard": heard,
                "distinctive_words": [[w, r, p] for w, r, p in distinctive],
                "words_note": words_note(self, heard),
            }
            for modality in further:
                summary[f"top_{modality}"] = [
                    [item, p] for item, p in self.top_items(modality, int(c), n_words)
                ]
            summaries.append(summary)
        return summaries

    # -- "where is X?" (eq. 19) ------------------------------------------------------------------

    def concept_prior(self, prior: str = DEFAULT_WHERE_PRIOR) -> np.ndarray:
        """[L] p(C = l) of eq. (19) over the concepts in use (0 elsewhere), summing to 1:
        ``"area"`` the share of the map's cells labelled l, ``"pi"`` the fitted pi."""
        if prior not in WHERE_PRIORS:
            raise ValueError(f"prior must be 'area' or 'pi', got {prior!r}")
        sizes = self.concept_sizes()
        weight = np.where(sizes > 0, self.pi if prior == "pi" else sizes / sizes.sum(), 0.0)
        return weight / weight.sum()

    def concept_given_word(self, word: str, prior: str = DEFAULT_WHERE_PRIOR) -> np.ndarray:
        """[L] p(C = l | word) proportional to w_{l,word} p(C = l) over concepts in use (eq. 19).

        ``prior``: ``"area"`` (share of cells labelled l; the default) or ``"pi"`` (eq. 19 as in
        the paper); see the module docstring for why area is the default.
        """
        v = word_index(self.vocabulary, word)
        score = self.w[:, v] * self.concept_prior(prior)  # [L]
        return score / score.sum()

    def word_posteriors(self, prior: str = DEFAULT_WHERE_PRIOR) -> np.ndarray:
        """[L, V] p(C = l | word) of every word of the vocabulary (eq. 19,
        :func:`~spcopyro.results.where.concept_given_words`; ``prior`` as in
        :meth:`concept_given_word`), computed once per prior (:meth:`computed_once`) and
        read-only: :meth:`where` reads the other words' answers from it."""
        table = self.computed_once(
            ("word_posteriors", prior),
            lambda: concept_given_words(self.w, self.concept_prior(prior)),
        )
        return np.asarray(table)

    def where(self, word: str, prior: str = DEFAULT_WHERE_PRIOR) -> WhereAnswer:
        """The concept argmax_C p(C | word) (eq. 19), its region, the runner-up and the
        warnings of an answer to treat with care (:func:`answer_warnings`), the other words the
        same concept answers (:func:`~spcopyro.results.where.shared_answers`); ``prior`` as in
        :meth:`concept_given_word` (default ``"area"``; ``"pi"`` is the paper's eq. 19)."""
        posterior = self.concept_given_word(word, prior)  # [L]
        weights = self.concept_prior(prior)  # [L]
        sizes = self.concept_sizes()  # [L]
        order = np.argsort(-posterior, kind="stable")
        concept = int(order[0])
        runner_up = int(order[1]) if (sizes > 0).sum() > 1 else None
        key = word_key(self.vocabulary, word)  # as looked up: 'Kitchen?' is 'kitchen'
        region = self.label_image() == concept  # [H, W]
        warnings = answer_warnings(
            posterior, weights, sizes, word=key, prior_name=prior,
            cell_area=self.grid.cell_area, region=region,
            connectivity=self.config.connectivity, words_modelled=words_modelled(self),
            heard=self.heard(concept),  # None: unknown, a speck judged by its size alone
        )  # fmt: skip
        if self.word_totals is not None and self.word_totals[word_index(self.vocabulary, key)] == 0:
            warnings = (
                f"{key!r} was never heard on the map's free space (fit warned of its "
                "utterances off the map): no observation ties it to a place, so this answer "
                "(the concept whose few words leave most room for an unheard one) says nothing "
                "about where it is",
                *warnings,
            )
        return WhereAnswer(
            word=key,
            concept=concept,
            probability=float(posterior[concept]),
            region=region,
            prior=prior,
            runner_up=runner_up,
            runner_up_probability=0.0 if runner_up is None else float(posterior[runner_up]),
            evidence=bayes_factor(float(posterior[concept]), float(weights[concept])),
            warnings=warnings,
            shared_with=()  # one concept for the whole map: warned above, every word is its
            if runner_up is None
            else shared_answers(self.w, weights, concept, self.vocabulary, key,
                                posterior=self.word_posteriors(prior)),
        )  # fmt: skip

    # -- saving and loading ----------------------------------------------------------------------

    def settings_json(self) -> dict[str, object]:
        """The settings of the fit: model, data preparation, inference method and its options,
        then the :attr:`provenance` entries (data source, software versions)."""
        settings = {
            "model": self.config.to_json(),
            "data": self.preparation.to_json(),
            "method": self.method,
            "inference": self.inference,
        }
        return {**settings, **{k: v for k, v in self.provenance.items() if k not in settings}}

    def save(self, out_dir: str | os.PathLike[str], *, with_config: bool = True) -> Path:
        """Write the result into ``out_dir``; ``with_config=False``: all but ``config.json``,
        which the caller writes (``spcopyro fit``: last, with the warnings the whole fit gave,
        :func:`spcopyro.cli.fit_warnings.write_config`).

        Files: ``labels.npy`` ([H, W] int64, -1 off free space, concept ids >= 0, map image row
        order; the point estimate), ``concepts.json`` (per concept: cells, pi, top words,
        whether it is a speck and the posterior's support, :mod:`spcopyro.results.specks`),
        ``trace.csv`` (iteration, objective, concepts in use, seconds), ``map.yaml``/``map.pgm``
        (the occupancy grid), ``result.npz`` (everything needed by :meth:`load`),
        ``config.json`` (:meth:`settings_json`). Figures are written by
        :mod:`spcopyro.figures.plotting`.
        Labels outside ``[0, L)`` (or not one per free cell) raise ValueError before any file
        is written.
        """
        labels, num_free, num_l = np.asarray(self.labels), self.grid.num_free, len(self.pi)
        in_range = labels.size == 0 or 0 <= labels.min() <= labels.max() < num_l
        if labels.shape != (num_free,) or not in_range:
            values = f"{labels.min()}..{labels.max()}" if labels.size else "none"
            raise ValueError(
                f"not saving a corrupt result: labels must be {num_free} concepts in "
                f"0..{num_l - 1}, got shape {labels.shape}, values {values}"
            )
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        np.save(out / "labels.npy", self.label_image())
        concepts = with_speck_fields(self, self.concepts(n_words=10))  # + speck, support
        (out / "concepts.json").write_text(json.dumps(concepts, indent=2) + "\n")
        if with_config:
            (out / "config.json").write_text(json.dumps(self.settings_json(), indent=2) + "\n")
        trace = self.trace
        with open(out / "trace.csv", "w", newline="") as f:
            writer = csv.writer(f)
            objective = trace.objective_name.replace(" ", "_").lower()
            writer.writerow(["iteration", objective, "num_concepts", "seconds"])
            for s in range(len(trace.objective)):
                writer.writerow(
                    [s + 1, repr(float(trace.objective[s])), int(trace.num_concepts[s]),
                     f"{trace.seconds[s]:.6f}"]
                )  # fmt: skip
        save_map(self.grid, out / MAP_FILE)
        write_npz(out / RESULT_FILE, self._arrays())  # np.savez_compressed's file, faster
        return out

    def _arrays(self) -> dict[str, np.ndarray]:
        """``result.npz``'s arrays (:meth:`load` reads them back with ``config.json``)."""
        trace = self.trace
        arrays: dict[str, np.ndarray] = {
            "labels": self.labels,
            "pi": self.pi,
            "objective": trace.objective,
            "num_concepts": trace.num_concepts,
            "seconds": trace.seconds,
            "objective_name": np.array(trace.objective_name),
            "best_iteration": np.array(self.best_iteration),
            "modalities": np.array([t.name for t in self.emissions], dtype=str),
            "method": np.array(self.method),
            "name": np.array(self.name),
        }
        for table in self.emissions:
            arrays[f"emission_{table.name}"] = table.probabilities
            arrays[f"items_{table.name}"] = np.array(table.items, dtype=str)
        for key in _OPTIONAL_ARRAYS:  # a part the result does not know is not written
            if getattr(self, key) is not None:
                arrays[key] = getattr(self, key)
        return arrays

    @classmethod
    def load(cls, out_dir: str | os.PathLike[str]) -> SpCoResult:
        """Read a result written by :meth:`save`."""
        out = Path(out_dir)
        path = out / RESULT_FILE
        if out.is_file():  # result.npz itself, or another file: not "<file>/result.npz"
            folder = out.parent if out.name == RESULT_FILE else None
            hint = f" (here {folder})" if folder is not None else ""
            raise FileNotFoundError(
                f"{out} is a file, not the output folder of `spcopyro fit`: give the folder "
                f"that holds {RESULT_FILE}{hint}"
            )
        if not path.is_file():
            from spcopyro.data.dataset import is_house_folder  # only on this error's path

            if is_house_folder(out):  # data, not a fit
                raise FileNotFoundError(
                    f"{out} is a house folder (data), not a fitted result: fit it first, "
                    f"`spcopyro fit {out} --out OUT`, and give OUT here"
                )
            raise FileNotFoundError(
                f"{path}: no fitted result here (run `spcopyro fit DATA --out {out}` first)"
            )
        try:
            with read_npz(path) as z:
                arrays = {k: z[k] for k in z.files}
        except DAMAGED_FILE_ERRORS as error:
            raise ValueError(
                f"{path}: not a readable spcopyro result ({type(error).__name__}: {error}); "
                "the file is damaged or truncated: fit again"
            ) from None
        config_path = out / "config.json"
        try:
            settings = json.loads(config_path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as error:
            raise ValueError(
                f"{config_path}: line {error.lineno}, column {error.colno}: {error.msg} "
                "(a damaged config.json: fit again)"
            ) from None
        except UnicodeDecodeError as error:
            raise ValueError(f"{config_path}: not UTF-8 text ({error.reason})") from None
        except FileNotFoundError:
            raise FileNotFoundError(
                f"{config_path}: missing beside {RESULT_FILE} (the fit's settings, which `fit` "
                "writes with it; copied without it? copy the whole folder, or fit again)"
            ) from None
        try:
            return cls._from_saved(out, path, arrays, settings)
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as error:
            raise ValueError(
                f"{path} and {config_path} do not form a spcopyro result "
                f"({type(error).__name__}: {error}); the files are damaged: fit again"
            ) from None

    @classmethod
    def _from_saved(
        cls, out: Path, path: Path, arrays: dict[str, np.ndarray], settings: dict, grid=None
    ) -> SpCoResult:
        """The result from ``result.npz``'s arrays and ``config.json``'s settings (``grid``:
        its map, else ``out``'s ``map.yaml``)."""
        if not isinstance(settings, dict):
            raise TypeError(f"config.json holds a {type(settings).__name__}, not an object")
        if "labels_best" in arrays:
            raise ValueError(
                f"{path} was written by spcopyro before its results became method-neutral "
                "(labels_best/theta/w); fit again to read it with this version"
            )
        model = dict(settings["model"])
        model["concentrations"] = tuple(dict(model.get("concentrations", {})).items())
        emissions = tuple(
            EmissionTable(
                str(name),
                tuple(str(v) for v in arrays[f"items_{name}"]),
                arrays[f"emission_{name}"],
            )
            for name in arrays["modalities"]
        )
        return cls(
            grid=load_map(out / MAP_FILE) if grid is None else grid,
            config=SpCoConfig(**model),
            labels=arrays["labels"],
            pi=arrays["pi"],
            emissions=emissions,
            trace=Trace(
                objective=arrays["objective"],
                num_concepts=arrays["num_concepts"],
                seconds=arrays["seconds"],
                objective_name=str(arrays["objective_name"]),
            ),
            best_iteration=int(arrays["best_iteration"]),
            method=str(arrays["method"]),
            preparation=DataPreparation(**settings["data"]),
            inference=dict(settings.get("inference", {})),
            name=str(arrays["name"]),
            provenance={k: v for k, v in settings.items() if k not in _SETTINGS},
            **{key: arrays.get(key) for key in _OPTIONAL_ARRAYS},  # None: not saved (an old fit)
        )
