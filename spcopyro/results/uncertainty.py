r"""Per-cell uncertainty of a fit, and "where is X?" as a probability per cell.

Every inference method can give per-cell label probabilities :math:`p(C_i = l)`: a variational
method's q(C_i) (:attr:`SpCoResult.marginals <spcopyro.results.result.SpCoResult.marginals>`), or a
Gibbs chain's label frequencies over the samples it kept (:func:`label_frequencies`, stored as
the result's marginals by ``spcopyro fit``). From them:

* the **uncertainty map** :math:`H_i = -\sum_l p(C_i = l) \log p(C_i = l)` (nats; 0 where every
  sample or all of q agrees, log L at most) -- :func:`cell_entropy`;
* the **probability that a cell belongs to the word's place** (eq. 19 spread over the cells):

  .. math::

      p(i \in \text{place}(S)) = \sum_l p(C_i = l)\, p(C = l \mid S),

  the chance that the cell's concept is the word's, with both uncertain and independent --
  :func:`where_probability`. With a point estimate only (no marginals) it is
  :math:`p(C = C_i \mid S)`, constant over each concept's region.

  p(C = l | S) is known only for the concepts that label cells of the reported map (the others
  have no region, and no word table fitted to one), so the sum runs over those: a cell's
  probability on other concepts (:func:`unmapped_mass`) is not counted, as if they were never
  the word's. Such mass is real: a Gibbs chain's kept samples each hold a few extra concepts,
  and the ones :func:`align_samples` matches with none of the map's take the ids the map leaves
  free (in room2ldk4's default fit 25 such ids, each about one cell's worth of mass: 1.7% of a
  cell's mass on average, 44% at most, at region borders), and a CAVI q(C_i) can hold mass on
  concepts no cell takes as its most probable. So the value is that of the map's concepts only,
  and a cell's probability could be higher by at most its unmapped mass; ``where`` prints that
  mass's mean and largest value (:func:`unmapped_note`) and the figures' colour bar and title
  say so.

A mean-field q is over-confident near region borders and in regions no observation reaches
(its entropy there is lower than the posterior's); Gibbs frequencies from a few dozen samples of
one chain miss modes the chain never visited. Compare the two maps with that in mind.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from spcopyro.inference.names import SAMPLERS

if TYPE_CHECKING:
    from spcopyro.results.result import SpCoResult


def marginals_source(result: SpCoResult) -> str:
    """What a result's per-cell probabilities are, as ``where``'s threshold line and its
    probability figure name them: "q(C) of cavi" (a variational method's marginals), "Gibbs
    label frequencies over 50 kept samples" (a sampler's; vi-gibbs's say so), or "point
    estimate" for a result without marginals. Both said "marginals" of every method, a CAVI
    fit's q and a Gibbs fit's frequencies in steps of 1/50 alike."""
    if result.marginals is None:
        return "point estimate"
    if result.method not in SAMPLERS:
        return f"q(C) of {result.method}"
    kept = result.inference.get("marginal_samples")
    over = f" over {int(kept)} kept samples" if isinstance(kept, int) and kept > 0 else ""
    return f"Gibbs label frequencies{over}" + ("" if result.method == "gibbs" else " (vi-gibbs)")


def label_frequencies(samples: np.ndarray, num_concepts: int, bar: Any = None) -> np.ndarray:
    """[N, L] float32 the fraction of the ``[S, N]`` label ``samples`` in which each cell has each
    concept (the Monte Carlo estimate of p(C_i = l)); ``bar.update()`` once per
    :data:`COUNT_STEP_CELLS` cells counted (:func:`count_steps` in all) where a ``bar`` is given."""
    samples = np.asarray(samples)
    if samples.ndim != 2 or samples.shape[0] == 0:
        raise ValueError(f"samples must be [S >= 1, N], got shape {samples.shape}")
    _check_labels(samples, num_concepts)
    S, N = samples.shape
    frequencies = np.empty((N, num_concepts), dtype=np.float32)  # [N, L]
    # A block of cells at a time: the whole map's int64 counts and keys would be N L 8 and
    # S N 8 bytes besides the result (2.8 GB and 0.6 GB at 2.9 million cells, L = 120, S = 25).
    done = 0  # the bar's steps so far
    for start, stop in _blocks(N):
        keys = np.arange(stop - start, dtype=np.int64) * num_concepts + samples[:, start:stop]
        counts = np.bincount(keys.ravel(), minlength=(stop - start) * num_concepts)  # [n * L]
        frequencies[start:stop] = counts.reshape(-1, num_concepts).astype(np.float32) / S
        reached = stop // COUNT_STEP_CELLS  # whole steps of cells counted (none before its end)
        if bar is not None and reached > done:
            bar.update(reached - done)
            done = reached
    if bar is not None and count_steps(N) > done:  # the last, partial step: all cells counted
        bar.update(count_steps(N) - done)
    return frequencies


COUNT_STEP_CELLS = 1 << 20
"""Cells per progress step of :func:`label_frequencies`. At 2.9 million cells, L = 120, S = 25
the count is ~1 s of user CPU, but the [N, L] float32 result's first writes fault in 1.4 GB:
0.2-3.7 s of system time more (numpy asks for huge pages, which the kernel may compact memory
for), so the step that counted them all sat still for up to 8 s in a loaded fit."""


def count_steps(num_cells: int) -> int:
    """The steps :func:`label_frequencies` gives a bar for ``num_cells`` cells (1 at least)."""
    return max(1, -(-num_cells // COUNT_STEP_CELLS))


BLOCK_CELLS = 1 << 14
"""Cells per block of the [N, L] passes over a result's marginals (:func:`_blocks`)."""


def _blocks(num_cells: int) -> list[tuple[int, int]]:
    """``(start, stop)`` of consecutive blocks of :data:`BLOCK_CELLS` cells covering
    ``num_cells``: each [N, L] pass works on one block's rows at a time, so its temporaries are
    a block's, not the map's (per row the arithmetic, and so every value, is the same)."""
    return [(a, min(a + BLOCK_CELLS, num_cells)) for a in range(0, num_cells, BLOCK_CELLS)]


def _check_labels(samples: np.ndarray, num_concepts: int) -> None:
    """ValueError unless every label of ``samples`` is a concept id in [0, num_concepts)."""
    if samples.size and (samples.min() < 0 or samples.max() >= num_concepts):
        raise ValueError(
            f"labels must lie in [0, {num_concepts}), got {samples.min()}..{samples.max()}"
        )


def align_samples(
    samples: np.ndarray, reference: np.ndarray, num_concepts: int, bar: Any = None
) -> np.ndarray:
    """``[S, N]`` the label ``samples`` renamed to the ``[N]`` ``reference`` map's concepts.

    A sampler's concept ids are arbitrary and change along a chain (a merge move, a relabelling),
    so the concept called 3 in a kept sample need not be the reported map's concept 3. Each
    sample is renamed by the one-to-one map of its ids onto the reference's ids that maximises
    the cells on which the two agree (the assignment problem on the contingency table of the
    labels each uses, ``scipy.optimize.linear_sum_assignment``); a sample's concept matched
    with none of the reference's takes an id the reference does not use. Per-cell frequencies
    over the renamed samples then speak of the reported concepts. A sample that equals the
    reference up to names becomes the reference exactly. Cost per sample: O(N + K^3) for the
    K concepts in use (not L); ``bar.update()`` after each sample where a ``bar`` is given."""
    from scipy.optimize import linear_sum_assignment  # here, not on the fit's import path

    samples = np.asarray(samples)
    reference = np.asarray(reference)
    _check_labels(samples, num_concepts)
    ref_ids, ref_codes = np.unique(reference, return_inverse=True)  # [K_r], [N]
    free_ids = np.setdiff1d(np.arange(num_concepts), ref_ids)  # ids the reference leaves free
    aligned = np.empty_like(samples)
    rename_all = np.empty(num_concepts, dtype=np.int64)  # [L] a sample's id -> reported id
    for s, labels in enumerate(samples):
        pairs = labels.astype(np.int64) * ref_ids.size + ref_codes  # [N] (label, ref) pair
        table = np.bincount(pairs, minlength=num_concepts * ref_ids.size)  # [L * K_r]
        table = table.reshape(num_concepts, ref_ids.size)  # [L, K_r]
        ids = np.flatnonzero(table.any(axis=1))  # [K_s] the ids it uses, ascending
        overlap = table[ids]  # [K_s, K_r]
        rows, cols = linear_sum_assignment(overlap, maximize=True)
        rename = np.full(ids.size, -1, dtype=np.int64)
        rename[rows] = ref_ids[cols]
        unmatched = np.flatnonzero(rename < 0)
        rename[unmatched] = free_ids[: unmatched.size]
        rename_all[ids] = rename
        aligned[s] = rename_all[labels]
        if bar is not None:
            bar.update()
    return aligned


def cell_probabilities(result: SpCoResult) -> np.ndarray:
    """[N, L] p(C_i = l): the result's marginals, or one-hot point labels if it has none."""
    if result.marginals is not None:
        return np.asarray(result.marginals, dtype=np.float64)
    one_hot = np.zeros((result.grid.num_free, len(result.pi)))
    one_hot[np.arange(result.grid.num_free), result.labels] = 1.0
    return one_hot


def cell_entropy(result: SpCoResult) -> np.ndarray | None:
    """[N] each free cell's entropy of p(C_i) in nats, or None when the result holds a point
    estimate only (no marginals: nothing to say about uncertainty). Computed once per result
    (:meth:`SpCoResult.computed_once <spcopyro.results.result.SpCoResult.computed_once>`, which
    keeps it read-only): ``spcopyro fit`` writes it to ``uncertainty.npy`` and
    :func:`~spcopyro.figures.plotting.plot_uncertainty` draws the same values (a child process
    that draws the figures inherits them through the fork). Each call returns a writable copy
    of the kept array (``h[mask] = 0`` raised "assignment destination is read-only"; the copy is
    N floats, the entropy an [N, L] pass), so no caller changes what the next one gets."""
    if result.marginals is None:
        return None

    def entropy() -> np.ndarray:
        marginals = np.asarray(result.marginals)  # [N, L]
        h = np.empty(marginals.shape[0])  # [N]
        for start, stop in _blocks(marginals.shape[0]):  # float64 copies of a block only
            p = marginals[start:stop].astype(np.float64)  # [n, L]
            logs = np.log(np.where(p > 0, p, 1.0))
            h[start:stop] = -(p * logs).sum(-1)
        return h

    kept: np.ndarray = result.computed_once("cell_entropy", entropy)  # type: ignore[assignment]
    return kept.copy()  # [N]


def where_probability(result: SpCoResult, word: str, prior: str = "area") -> np.ndarray:
    """[N] p(cell i belongs to the place of ``word``), summed over the concepts of the reported
    map only (module docstring: the mass :func:`unmapped_mass` is not counted; ``prior`` as in
    :meth:`SpCoResult.concept_given_word
    <spcopyro.results.result.SpCoResult.concept_given_word>`)."""
    concept_given_word = np.asarray(result.concept_given_word(word, prior), dtype=np.float64)
    if result.marginals is None:  # one-hot point labels: the cell's concept's p, no [N, L]
        return concept_given_word[np.asarray(result.labels)]  # [N]
    marginals = np.asarray(result.marginals)  # [N, L]
    probability = np.empty(marginals.shape[0])  # [N]
    for start, stop in _blocks(marginals.shape[0]):  # a block's float64 copy, not the map's
        block = marginals[start:stop].astype(np.float64)  # [n, L]
        block *= concept_given_word
        # Each row summed on its own, in one order (numpy's pairwise sum along the contiguous
        # last axis), so a cell's value does not depend on the block size or on threads: a
        # BLAS product (block @ concept_given_word) groups rows and splits them across
        # threads, and rows at those boundaries came out 1 ulp apart.
        probability[start:stop] = block.sum(-1)
    return probability


def unmapped_mass(result: SpCoResult) -> np.ndarray | None:
    """[N] each free cell's probability on concepts that label no cell of the reported map,
    which :func:`where_probability` does not count (module docstring); None without marginals.
    Computed once per result, read-only (:meth:`SpCoResult.computed_once
    <spcopyro.results.result.SpCoResult.computed_once>`)."""
    if result.marginals is None:
        return None

    def mass() -> np.ndarray:
        unmapped = result.concept_sizes() == 0  # [L]
        marginals = np.asarray(result.marginals)  # [N, L]
        total = np.empty(marginals.shape[0])  # [N]
        for start, stop in _blocks(marginals.shape[0]):
            total[start:stop] = marginals[start:stop][:, unmapped].astype(np.float64).sum(-1)
        return total

    return result.computed_once("unmapped_mass", mass)  # type: ignore[return-value]


def unmapped_note(result: SpCoResult) -> str | None:
    """``"not counted: ..."``, the cells' mass on concepts absent from the map (mean and
    largest, :func:`unmapped_mass`), or None when there is none. Computed once per result:
    ``where --out`` prints it and both its figures say it."""

    def note() -> str | None:
        mass = unmapped_mass(result)
        if mass is None or not mass.max() > 0:
            return None
        return (
            f"not counted: {mass.mean():.1%} of a cell's probability on average, up to "
            f"{mass.max():.0%}, lies on concepts absent from the map"
        )

    return result.computed_once("unmapped_note", note)  # type: ignore[return-value]


def cell_probability_label(word: str, off_map: bool = False) -> str:
    """The name of a cell's :func:`where_probability` of ``word`` on a figure's colour bar:
    ``"p(cell is the place) for 'bath'"``, as ``where`` and ``navigate`` print it, with
    ``"; the map's concepts only"`` where ``off_map`` (some mass lies on concepts absent from
    the map, :func:`unmapped_note`). One name for the where, where-probability and navigate
    figures."""
    return f"p(cell is the place) for '{word}'" + ("; the map's concepts only" if off_map else "")


def free_cells_image(result: SpCoResult, values: np.ndarray) -> np.ndarray:
    """[H, W] float64 ``values`` ``[N]`` of the free cells drawn on the map, NaN elsewhere."""
    image = np.full(result.grid.shape, np.nan)  # [H, W]
    image[result.grid.free] = values  # free cells in raster = free_index order
    return image


def threshold_line(probability: np.ndarray, region: np.ndarray, source: str) -> str:
    """``where``'s line "cells whose probability of being the place exceeds 0.5: N (source)",
    given ``probability`` [N] (:func:`where_probability`) and ``region`` [N] bool (the answer's
    region over the free cells). Where some of the region's cells are not above 0.5 it says so
    and what their probability is: beside a 64-cell region, "exceeds 0.5: 0" read as a
    contradiction when the word's p was 0.500 (a tie between two concepts, so every cell of
    the region had p = 0.500 under a point estimate)."""
    probability = np.asarray(probability, dtype=np.float64)  # [N]
    inside = probability[np.asarray(region, dtype=bool)]  # [n] the region's cells
    line = (
        f"cells whose probability of being the place exceeds 0.5: "
        f"{int((probability > 0.5).sum())} ({source})"
    )
    if inside.size == 0 or inside.min() > 0.5:
        return line
    low, high = f"{inside.min():.3f}", f"{inside.max():.3f}"
    share = low if low == high else f"{low}-{high}"
    above = int((inside > 0.5).sum())
    cells = f"{inside.size} cell" + ("" if inside.size == 1 else "s")
    held = "none of them" if not above else f"{above} of them"
    return (
        f"{line}; the region is the cells of the word's most probable concept, not those above "
        f"0.5: its {cells} have p(cell is the place) {share}, {held} above 0.5"
    )
