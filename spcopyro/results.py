r"""A fitted SpCoMapping for its user: the semantic map, each concept's words, "where is X?".

:class:`SpCoResult` wraps a Gibbs run (:class:`~spcopyro.gibbs.api.GibbsRun`) with the map and the
vocabulary. Its answers are computed from the *MAP-visited* state (the visited state of highest
log joint) unless ``which="final"`` is asked for. Place estimation from a word is the paper's
eq. (19):

.. math::

    \hat C = \arg\max_l p(C = l \mid S) = \arg\max_l \; w_{l,S} \, \pi_l ,

taken over the concepts that label at least one cell (a concept that labels no cell has no
region to point at). With the presets' huge alpha (1e7-1e8), pi is nearly uniform, so eq. (19)
weighs a concept of three cells like one of a thousand and can point at a speck whose few
observed cells hold the word. ``prior="area"`` replaces pi_l by the share of the map's cells
labelled l (the probability that a uniformly chosen free cell has concept l), which answers
"which region would a word uttered somewhere on this map come from?".
"""

from __future__ import annotations

import csv
import difflib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.api import GibbsRun
from spcopyro.gibbs.state import GibbsState
from spcopyro.maps import OccupancyGrid, load_map, save_map

RESULT_FILE = "result.npz"
MAP_FILE = "map.yaml"


@dataclass(frozen=True)
class WhereAnswer:
    """The answer to "where is WORD?"."""

    word: str
    concept: int
    probability: float
    """p(C = concept | word) (eq. 19), normalised over the concepts in use."""
    region: np.ndarray
    """[H, W] bool: the cells labelled with ``concept``."""


class UnknownWordError(KeyError):
    """A word that is not in the fitted vocabulary."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0])


def word_index(vocabulary: tuple[str, ...], word: str) -> int:
    """The column of ``word`` (lower-cased) in ``vocabulary``; :class:`UnknownWordError` with
    the closest known words when it is not there."""
    try:
        return vocabulary.index(word.lower())
    except ValueError:
        close = difflib.get_close_matches(word.lower(), vocabulary, n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise UnknownWordError(
            f"word {word!r} is not in the vocabulary of {len(vocabulary)} words{hint}"
        ) from None


@dataclass(frozen=True)
class SpCoResult:
    """A fitted semantic map (labels, pi, theta, w) with its map and vocabulary.

    ``labels_best``/``labels_final`` are ``[N]`` concepts of the free cells in the grid's
    ``free_index`` order; :meth:`label_image` gives them as an ``[H, W]`` image (-1 off free space).
    """

    grid: OccupancyGrid
    vocabulary: tuple[str, ...]
    config: SpCoConfig
    labels_best: np.ndarray  # [N] int64
    labels_final: np.ndarray  # [N] int64
    pi: np.ndarray  # [L] of the MAP-visited state
    theta: np.ndarray  # [L, K]
    w: np.ndarray  # [L, V]
    log_joint: np.ndarray  # [S]
    num_concepts: np.ndarray  # [S]
    seconds: np.ndarray  # [S]
    best_sweep: int
    name: str = ""

    @classmethod
    def from_run(
        cls,
        run: GibbsRun,
        grid: OccupancyGrid,
        vocabulary: tuple[str, ...],
        config: SpCoConfig,
        name: str = "",
    ) -> SpCoResult:
        best: GibbsState = run.best_state
        return cls(
            grid=grid,
            vocabulary=tuple(vocabulary),
            config=config,
            labels_best=best.labels.numpy().astype(np.int64),
            labels_final=run.final_state.labels.numpy().astype(np.int64),
            pi=best.log_pi.exp().numpy(),
            theta=best.log_theta.exp().numpy(),
            w=best.log_w.exp().numpy(),
            log_joint=run.log_joint,
            num_concepts=run.num_concepts,
            seconds=run.seconds,
            best_sweep=run.best_sweep,
            name=name,
        )

    @property
    def best_log_joint(self) -> float:
        """The log joint of the MAP-visited state (``log_joint[best_sweep]``)."""
        return float(self.log_joint[self.best_sweep])

    # -- the semantic map ------------------------------------------------------------------------

    def labels(self, which: str = "best") -> np.ndarray:
        """[N] labels of the MAP-visited (``"best"``) or the last (``"final"``) state."""
        if which not in ("best", "final"):
            raise ValueError(f"which must be 'best' or 'final', got {which!r}")
        return self.labels_best if which == "best" else self.labels_final

    def label_image(self, which: str = "best") -> np.ndarray:
        """[H, W] int64 concept of every free cell, -1 elsewhere (map image row order)."""
        image = np.full(self.grid.shape, -1, dtype=np.int64)
        image[self.grid.free] = self.labels(which)  # free cells in raster = free_index order
        return image

    def concepts_in_use(self, which: str = "best") -> np.ndarray:
        """Concept ids labelling at least one cell, largest region first."""
        sizes = np.bincount(self.labels(which), minlength=self.config.num_concepts)
        used = np.flatnonzero(sizes)
        return used[np.argsort(-sizes[used], kind="stable")]

    def top_words(self, concept: int, n: int = 3) -> list[tuple[str, float]]:
        """The ``n`` most probable words of a concept under w_concept, with their probabilities."""
        if not self.vocabulary:
            return []
        order = np.argsort(-self.w[concept], kind="stable")[:n]
        return [(self.vocabulary[v], float(self.w[concept, v])) for v in order]

    def concepts(self, n_words: int = 3) -> list[dict[str, object]]:
        """Per concept in use: id, cell count, pi, top words with probabilities."""
        sizes = np.bincount(self.labels_best, minlength=self.config.num_concepts)
        return [
            {
                "concept": int(c),
                "cells": int(sizes[c]),
                "pi": float(self.pi[c]),
                "top_words": [[word, p] for word, p in self.top_words(int(c), n_words)],
            }
            for c in self.concepts_in_use()
        ]

    # -- "where is X?" (eq. 19) ----------------------------------------------------------------

    def concept_given_word(self, word: str, prior: str = "pi") -> np.ndarray:
        """[L] p(C = l | word) proportional to w_{l,word} p(C = l) over concepts in use (eq. 19).

        ``prior``: ``"pi"`` (eq. 19 as in the paper) or ``"area"`` (share of cells labelled l).
        """
        if prior not in ("pi", "area"):
            raise ValueError(f"prior must be 'pi' or 'area', got {prior!r}")
        v = word_index(self.vocabulary, word)
        sizes = np.bincount(self.labels_best, minlength=self.config.num_concepts)
        weight = self.pi if prior == "pi" else sizes / sizes.sum()
        score = np.where(sizes > 0, self.w[:, v] * weight, 0.0)
        return score / score.sum()

    def where(self, word: str, prior: str = "pi") -> WhereAnswer:
        """The concept argmax_C p(C | word) (eq. 19) and its region; ``prior`` as above."""
        posterior = self.concept_given_word(word, prior)
        concept = int(np.argmax(posterior))
        return WhereAnswer(
            word=word.lower(),
            concept=concept,
            probability=float(posterior[concept]),
            region=self.label_image() == concept,
        )

    # -- saving and loading ----------------------------------------------------------------------

    def save(self, out_dir: str | os.PathLike[str]) -> Path:
        """Write the result into ``out_dir``.

        Files: ``labels.npy`` ([H, W] int64, -1 off free space, concept ids >= 0, map image row
        order; the MAP-visited state), ``concepts.json`` (per concept: cells, pi, top words),
        ``trace.csv`` (sweep, log joint, concepts in use, seconds), ``map.yaml``/``map.pgm`` (the
        occupancy grid), ``result.npz`` (everything needed by :meth:`load`), ``config.json``.
        Figures are written by :mod:`spcopyro.plotting`.
        """
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        np.save(out / "labels.npy", self.label_image())
        (out / "concepts.json").write_text(json.dumps(self.concepts(n_words=10), indent=2) + "\n")
        (out / "config.json").write_text(json.dumps(self.config.__dict__, indent=2) + "\n")
        with open(out / "trace.csv", "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["sweep", "log_joint", "num_concepts", "seconds"])
            for s in range(len(self.log_joint)):
                writer.writerow(
                    [s + 1, repr(float(self.log_joint[s])), int(self.num_concepts[s]),
                     f"{self.seconds[s]:.6f}"]
                )  # fmt: skip
        save_map(self.grid, out / MAP_FILE)
        np.savez_compressed(
            out / RESULT_FILE,
            labels_best=self.labels_best,
            labels_final=self.labels_final,
            pi=self.pi,
            theta=self.theta,
            w=self.w,
            log_joint=self.log_joint,
            num_concepts=self.num_concepts,
            seconds=self.seconds,
            best_sweep=self.best_sweep,
            vocabulary=np.array(self.vocabulary, dtype=str),
            name=np.array(self.name),
        )
        return out

    @classmethod
    def load(cls, out_dir: str | os.PathLike[str]) -> SpCoResult:
        """Read a result written by :meth:`save`."""
        out = Path(out_dir)
        path = out / RESULT_FILE
        if not path.is_file():
            raise FileNotFoundError(
                f"{path}: no fitted result here (run `spcopyro fit DATA --out {out}` first)"
            )
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        config = SpCoConfig(**json.loads((out / "config.json").read_text()))
        return cls(
            grid=load_map(out / MAP_FILE),
            vocabulary=tuple(str(v) for v in arrays["vocabulary"]),
            config=config,
            labels_best=arrays["labels_best"],
            labels_final=arrays["labels_final"],
            pi=arrays["pi"],
            theta=arrays["theta"],
            w=arrays["w"],
            log_joint=arrays["log_joint"],
            num_concepts=arrays["num_concepts"],
            seconds=arrays["seconds"],
            best_sweep=int(arrays["best_sweep"]),
            name=str(arrays["name"]),
        )
