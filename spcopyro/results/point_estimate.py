r"""A posterior point estimate of the labels: the partition that minimises an expected loss.

A sampler keeps label maps :math:`c^{(1)}, \dots, c^{(S)}` (thinned, second half of the run).
The state of highest log joint visited (``"map-visited"``, the default report) is one draw that
happened to score well; in a posterior spread over many near-equal states it says little about
what the draws share. Following Dahl, Johnson & Müller (2022, "Search algorithms and loss
functions for Bayesian clustering", JCGS 31:1189), the point estimate is instead

.. math::

    \hat c = \arg\min_{c} \frac1S \sum_{s} \mathcal L(c, c^{(s)}),

a partition of the N cells (labels only matter up to renaming). Both losses are functions of the
contingency table :math:`n_{kj} = \#\{i : c_i = k, c^{(s)}_i = j\}` with margins :math:`a_k, b_j`:

* Binder's loss (Binder 1978; unit costs), the share of ordered cell pairs on which the two
  partitions disagree (together in one, apart in the other):
  :math:`\mathcal L_B = (\sum_k a_k^2 + \sum_j b_j^2 - 2 \sum_{kj} n_{kj}^2) / N^2`;
* the variation of information (Meilă 2007; Wade & Ghahramani 2018), in nats:
  :math:`\mathcal L_{VI} = (\sum_k a_k \log a_k + \sum_j b_j \log b_j
  - 2 \sum_{kj} n_{kj} \log n_{kj}) / N`.

Both are :math:`(F(a) + F(b) - 2 F(n)) / Z` with :math:`F(x) = \sum f(x)`, :math:`f(x) = x^2` or
:math:`x \log x`, so moving one cell i from cluster k to k' changes the expected loss by

.. math::

    \Delta_i(k') = \big[f(a_{k'} + 1) - f(a_{k'}) + f(a_k - 1) - f(a_k)\big]
        - \frac{2}{S} \sum_s \big[f(n^s_{k' j_s} + 1) - f(n^s_{k' j_s})
        + f(n^s_{k j_s} - 1) - f(n^s_{k j_s})\big], \quad j_s = c^{(s)}_i,

(divided by Z), read off the S contingency tables -- never an N x N matrix. The search (SALSO's
greedy sweeps, vectorised): start from the samples of lowest expected loss; in each sweep
compute :math:`\Delta_i(k')` for every cell and every cluster (one spare empty cluster
included) at once, move every cell whose best move lowers the loss, and if the moves taken
together do not lower the exact loss (they interact through the tables), keep only the better
half of them, and so on (one move alone always lowers it); stop when no cell can improve or a
sweep gains less than :data:`RELATIVE_TOLERANCE` of the loss. The search's expected loss
is therefore never above that of the best sample it started from. After its first sweeps a
sweep moves a few cells between a few clusters, so the search keeps, between sweeps, each
cluster's join terms (the first sum of :math:`\Delta_i`) unless a cell left or joined it, works
per (cluster, distinct sample column) pair rather than per cell, and rejects a halving trial
whose loss, summed over the table entries it changes, is clearly not lower without computing
its exact loss: the same moves, estimate and loss, bit for bit, as recomputing everything
(tested), in a fifteenth of the time on a 64,319-cell map (docs/speed.md).

The reported estimates ``vi`` and ``binder`` (:func:`with_point_estimate`) are then made
without specks: under the model every kept sample holds many one-cell droplets of labels that
form and dissolve in corners and doorways, the search keeps such a cell apart where its
co-clustering probability with every neighbouring cluster is below about one half, and a
cluster on fewer than 0.5 % of the cells where fewer than 0.1 words were heard
(:func:`~spcopyro.results.concept_words.is_speck`) is no place. Each such cell is moved, by the
exact :math:`\Delta_i` above, to the cluster that is no speck where it raises the expected loss
least (:mod:`~spcopyro.results.speck_join`), and the estimate's expected loss is recomputed
exactly: it may then exceed the best sample's (the README's fit: 0.1550 with its six specks,
0.1558 without). ``vi-specks`` and ``binder-specks`` report the search's estimate itself (``vi``
and ``binder`` until 2026-12-06).

:func:`agreement_probability` is the uncertainty map: for every sample, its labels matched to
the estimate's clusters by the Hungarian method on their contingency table (the matching that
keeps the most cells), and per cell the share of samples whose matched label equals the
estimate's.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from spcopyro._util.progress import clears_when_done, progress_enabled, setup_bar
from spcopyro._util.timings import timed

# The names live without numpy in estimate_names (the parser reads them there); these re-exports
# keep ``from spcopyro.results.point_estimate import POINT_ESTIMATES`` working.
from spcopyro.results.estimate_names import (
    KEEPS_SPECKS,
    LOSS_LABELS,
    LOSSES,
    POINT_ESTIMATES,
    estimate_loss,
)

# The tables live in estimate_tables. Every name below is used here, and _greedy reads
# _joined_rows, _kept_columns, _pairs and _moved_pairs from this module's names (the tests patch
# the first three here).
from spcopyro.results.estimate_tables import (
    _codes_and_values,
    _departed,
    _f,
    _joined_rows,
    _kept_columns,
    _moved_pairs,
    _moved_tables,
    _Pairs,
    _pairs,
    _radix_dtype,
    _sample_pairs,
    _sample_tables,
    _Samples,
    _signature,
    _Tables,
    _trial_change,
)
from spcopyro.results.speck_join import check_cell_words, join_specks

if TYPE_CHECKING:
    from spcopyro.inference.protocol import InferenceOutput

DEFAULT_STARTS = 3
"""How many of the lowest-loss samples the greedy search starts from."""
MAX_SWEEPS = 30
"""At most this many greedy sweeps per start."""
RELATIVE_TOLERANCE = 1e-5
"""A start's search stops when a sweep lowers the expected loss by less than this share of it
(the long tail of one-cell improvements on maps of ~25,000 cells costs minutes and changes
nothing visible)."""


def _check(samples: np.ndarray, loss: str) -> np.ndarray:
    if loss not in LOSSES:
        raise ValueError(f"loss {loss!r}: choose one of {LOSSES}")
    samples = np.asarray(samples)
    if samples.ndim != 2 or samples.shape[0] < 1 or samples.shape[1] < 1:
        raise ValueError(f"label samples must be [S, N] with S, N >= 1, got {samples.shape}")
    if not np.issubdtype(samples.dtype, np.integer) or samples.min() < 0:
        raise ValueError("label samples must be non-negative integers")
    return samples


def compact(labels: np.ndarray) -> tuple[np.ndarray, int]:
    """([N] labels renamed 0..K-1 in ascending order of their values, K)."""
    codes, values = _codes_and_values(labels)
    return codes, int(values.shape[0])


def contingency(first: np.ndarray, second: np.ndarray, k1: int, k2: int) -> np.ndarray:
    """[k1, k2] the number of cells with label k in ``first`` and j in ``second``."""
    return np.bincount(first * k2 + second, minlength=k1 * k2).reshape(k1, k2)


def pair_loss(first: np.ndarray, second: np.ndarray, loss: str) -> float:
    """The loss between two labelings [N] (symmetric; renaming labels does not change it)."""
    (a, ka), (b, kb) = compact(first), compact(second)
    table = contingency(a, b, ka, kb)
    value = _f(table.sum(1), loss).sum() + _f(table.sum(0), loss).sum() - 2 * _f(table, loss).sum()
    n = a.shape[0]
    return float(value / (n * n if loss == "binder" else n))


def _prepare(samples: np.ndarray, loss: str, bar=None) -> _Samples:
    # [S, N] filled in place (no 2nd copy). Each code is below its row's number of distinct
    # labels, so below max label + 1: _radix_dtype's uint8 to 256, uint16 to 65,536, else int64
    # (a fit's 50 samples of 3.87 million cells, L = 120: 0.19 GB where int64 held 1.55 GB).
    # Codes are read as numbers only in sums with int64 offsets: the same tables and estimate.
    stacked = np.empty(samples.shape, dtype=_radix_dtype(samples))
    sizes, constant = [], 0.0
    for row, sample in zip(stacked, samples, strict=True):
        row[:], k = compact(sample)
        sizes.append(k)
        constant += _f(np.bincount(row), loss).sum()
        if bar is not None:  # 0.2 s per sample at 2.9 million cells: 6 s before the sorts
            bar.update()
    signature = _signature(stacked, tuple(sizes), bar)  # [N] the distinct columns, ranked
    first = np.zeros(int(signature.max()) + 1, dtype=np.int64)  # [U] a cell of each column
    first[signature[::-1]] = np.arange(signature.shape[0])[::-1]
    by_column = np.argsort(signature, kind="stable")  # [N] for _pairs
    # [U] each column's cells for every sample's _sample_pairs: one pass over the N cells
    column_cells = np.bincount(signature, minlength=first.shape[0]).astype(np.float64)
    columns = stacked[:, first].astype(np.int64)  # [S, U] int64, as before the codes narrowed
    prepared = (stacked, tuple(sizes), constant / len(sizes), columns, signature)
    return _Samples(*prepared, by_column, column_cells)


def _expected(
    estimate: np.ndarray, k: int, prepared: _Samples, loss: str, tables: _Tables | None = None
) -> float:
    """The expected loss of ``estimate`` (k clusters); ``tables`` its tables if at hand (their
    first k rows are read: the search's have a spare empty row k)."""
    if tables is None:
        tables = _sample_tables(_pairs(estimate, prepared), k, prepared)
    shared = np.mean([_f(t[:k], loss).sum() for t in tables.tables])
    sizes = np.bincount(estimate, minlength=k)
    value = _f(sizes, loss).sum() + prepared.constant - 2 * shared
    n = estimate.shape[0]
    return float(value / (n * n if loss == "binder" else n))


def expected_loss(estimate: np.ndarray, samples: np.ndarray, loss: str) -> float:
    """(1/S) sum_s loss(estimate, sample s), from the S contingency tables."""
    samples = _check(samples, loss)
    codes, k = compact(estimate)
    return _expected(codes, k, _prepare(samples, loss), loss)


def _pair_changes(
    sizes: np.ndarray,
    pairs: _Pairs,
    departed: np.ndarray,
    joined: np.ndarray,
    samples: int,
    loss: str,
    part: slice = slice(None),
) -> np.ndarray:
    """[p, k + 1] Delta_i(k') of the module doc (times Z) for a cell i of each pair in ``part``:
    cells of a pair (one cluster, one distinct column of the samples) share every term of it.
    ``sizes`` [k + 1] float64 the clusters' sizes, ``departed`` [P] of :func:`_departed`,
    ``joined`` [U, k + 1] of :func:`_joined_rows`, ``samples`` S."""
    cluster = pairs.cluster[part]  # [p]
    own = sizes[cluster]  # [p]
    leave = _f(own - 1, loss) - _f(own, loss)  # [p]
    change = (_f(sizes + 1, loss) - _f(sizes, loss))[None, :] + leave[:, None]  # [p, k + 1]
    shared = joined[pairs.column[part]]  # [p, k + 1]
    shared += departed[part, None]
    shared *= 2.0
    shared /= samples
    change -= shared
    change[np.arange(cluster.shape[0]), cluster] = 0.0  # staying changes nothing
    return change


CHUNK = 1024
"""The search takes the pairs' changes and their best moves this many pairs at a time (arrays
that stay in cache: 25% faster on a 64,319-cell map than all P at once)."""


def _best_moves(
    sizes: np.ndarray,
    pairs: _Pairs,
    tables: list[np.ndarray],
    joined: np.ndarray,
    prepared: _Samples,
    loss: str,
    no_new: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """([P] each pair's best cluster, [P] its Delta (times Z)): the argmin over k' of
    :func:`_pair_changes` (the first of equal ones), the spare cluster k left out if
    ``no_new``."""
    departed = _departed(pairs, tables, prepared, loss)
    count = pairs.cluster.shape[0]  # P
    best = np.empty(count, dtype=np.int64)
    gain = np.empty(count)
    for start in range(0, count, CHUNK):
        part = slice(start, start + CHUNK)
        change = _pair_changes(sizes, pairs, departed, joined, len(prepared.sizes), loss, part)
        if no_new:
            change[:, -1] = np.inf  # no new cluster beyond the cap
        best[part] = change.argmin(1)
        gain[part] = change[np.arange(change.shape[0]), best[part]]
    return best, gain


TRIAL_MARGIN = 1e-9
"""A halving trial whose loss, computed from its changed table entries
(:func:`_trial_change`), is above the bar by more than this share of the loss (plus this much)
is rejected without the exact loss; the two differed by at most 3e-14 of it over every trial of
a search on a 27,832-cell map (both losses), so every decision is the one the exact loss makes."""


class _Start(NamedTuple):
    """Where a greedy search starts: an estimate with its pairs, tables and expected loss."""

    estimate: np.ndarray  # [N] codes 0..k-1
    k: int
    pairs: _Pairs
    tables: _Tables  # S x [k + 1, J_s]: a spare empty row for a new cluster
    value: float  # the expected loss of estimate (from the tables' first k rows)


def _sample_start(row: int, prepared: _Samples, loss: str) -> _Start:
    """Sample ``row`` as a start: its codes (compact already), its pairs its U columns
    (:func:`_sample_pairs`, no sort of the N cells) and its expected loss, which
    :func:`point_estimate` ranks the samples by, so that a search's start is built once."""
    estimate, k = prepared.codes[row], prepared.sizes[row]  # [N], J_s
    pairs = _sample_pairs(row, prepared)
    tables = _sample_tables(pairs, k + 1, prepared)  # S x [J_s + 1, J_s']
    return _Start(estimate, k, pairs, tables, _expected(estimate, k, prepared, loss, tables))


def _greedy(
    start: _Start, prepared: _Samples, loss: str, max_clusters: int | None, bar=None
) -> tuple[np.ndarray, float]:
    """One greedy search from ``start`` (module doc; :func:`_sample_start`). Between sweeps it
    keeps the rows of :func:`_joined_rows` of the clusters no cell left or joined (after the
    first sweep most of them), and rejects halving trials that are clearly no better without
    their exact loss: the same moves, the same estimate and loss to the bit as recomputing
    everything every sweep."""
    estimate, k, pairs, tables, value = start
    estimate = estimate.astype(np.int64)  # [N] a copy, not a view of the samples' (narrow) codes
    n = estimate.shape[0]
    scale = float(n * n if loss == "binder" else n)
    buffer, stale = None, None  # [U, >= k + 1] join terms; the clusters to recompute (None: all)
    sweeps = 0
    while sweeps < MAX_SWEEPS:
        sweeps += 1
        before = value
        sizes = np.bincount(estimate, minlength=k + 1).astype(np.float64)  # [k + 1]
        if stale is None:
            buffer = _joined_rows(tables.tables, None, prepared, loss)  # [U, k + 1]
        else:  # in place, into the buffer's columns stale
            _joined_rows(tables.tables, stale, prepared, loss, buffer[:, : k + 1])
        joined = buffer[:, : k + 1]  # [U, k + 1] a view
        no_new = max_clusters is not None and k >= max_clusters
        best, gain = _best_moves(sizes, pairs, tables.tables, joined, prepared, loss, no_new)
        target = best[pairs.of_cell]  # [N]
        gain = gain[pairs.of_cell]  # [N]
        if bar is not None:
            bar.update(SWEEP_STEPS)
        movers = np.flatnonzero(gain < -1e-9)
        if movers.size == 0:
            break
        movers = movers[np.argsort(gain[movers])]  # best first
        improved = False
        while movers.size:
            guess = value + _trial_change(movers, estimate, target, sizes, tables, prepared,
                                         loss) / scale  # fmt: skip
            if guess >= value - 1e-12 + TRIAL_MARGIN * (1.0 + abs(value)):
                movers = movers[: movers.size // 2]
                continue
            trial = estimate.copy()
            trial[movers] = target[movers]
            kept = np.flatnonzero(np.bincount(trial, minlength=k + 1))  # [kk] old names, in order
            rename = np.full(k + 1, -1, dtype=np.int64)  # [k + 1] old -> new: compact's renaming
            rename[kept] = np.arange(kept.shape[0])
            codes, kk = rename[trial], kept.shape[0]  # as compact(trial), without its sort
            trial_tables = _moved_tables(tables, kept, movers, estimate, target, prepared)
            trial_value = _expected(codes, kk, prepared, loss, trial_tables)
            if trial_value < value - 1e-12:
                trial_pairs = _moved_pairs(pairs, prepared, movers, codes, rename)
                moved = np.zeros(k + 1, dtype=bool)
                moved[estimate[movers]] = moved[target[movers]] = True
                stale = np.append(np.flatnonzero(moved[kept]), kk)  # and the new spare one
                buffer = _kept_columns(buffer, kept)  # in place where it fits
                pairs, tables = trial_pairs, trial_tables
                estimate, k, value, improved = codes, kk, trial_value, True
                break
            movers = movers[: movers.size // 2]
        if not improved or before - value < RELATIVE_TOLERANCE * value:
            break
    if bar is not None:
        bar.update(SWEEP_STEPS * (MAX_SWEEPS - sweeps))  # the sweeps it did not need
    return estimate, value


SWEEP_STEPS = 2
"""A greedy sweep's weight on the progress bar, in the samples' expected losses (one step each):
about its cost (50 samples: a sweep took 2x one sample's loss on a 27,832-cell map, 1.6x on a
64,319-cell one), so the bar's time estimate holds through the searches (it counted a whole
search as one step, and the searches took 90% of the time)."""


class PointEstimate(NamedTuple):
    """What :func:`point_estimate` found."""

    labels: np.ndarray
    """[N] int64 the estimate's clusters, 0..K-1."""
    expected_loss: float
    best_sample_loss: float
    """The lowest expected loss of any single sample (the search's estimate's is never above
    it; joining specks can raise it)."""
    speck_cells: int = 0
    """How many cells of specks were joined to other clusters (:mod:`.speck_join`)."""
    specks: int = 0
    """How many speck clusters those cells made up."""
    loss_with_specks: float | None = None
    """The search's expected loss before the joins (equal to ``expected_loss`` where nothing
    was joined); None where no ``cell_words`` were given (the search's estimate, specks kept)."""


def point_estimate(
    samples: np.ndarray,
    loss: str = "vi",
    starts: int = DEFAULT_STARTS,
    max_clusters: int | None = None,
    progress: bool | None = False,
    cell_words: np.ndarray | None = None,
    cell_area: float | None = None,
) -> PointEstimate:
    """The partition minimising the expected ``loss`` over ``samples`` [S, N] (module doc).

    Args:
        starts: greedy searches from that many samples of lowest expected loss; the best wins.
        max_clusters: open no new cluster once the estimate has this many (e.g. the model's
            L; the samples' labels are below it, so the estimate's clusters stay within it).
        cell_words: [N] the words heard at each cell (the model's counts divided by
            ``word_scaling``, :func:`~spcopyro.results.posterior_means.words_per_cell`): the
            best search's specks are joined to other clusters
            (:func:`~spcopyro.results.speck_join.join_specks`) and the expected loss is that
            of the result; None: specks kept (the search's estimate).
        cell_area: the square metres of one cell (the resolution squared of the samples'
            grid), which a speck's area bound needs: required with ``cell_words``
            (:func:`~spcopyro.results.concept_words.is_speck`).
        progress: a progress bar (and time estimate) over the samples' preparation, expected
            losses and the searches; None: on unless under CI (:mod:`spcopyro._util.progress`).
    """
    from tqdm.auto import tqdm

    samples = _check(samples, loss)
    if cell_words is not None:
        cell_words = check_cell_words(cell_words, samples.shape[1])
        if cell_area is None:
            raise ValueError(
                "cell_words given without cell_area: a speck is also under SPECK_AREA square "
                "metres; pass cell_area, the square metres of one cell (resolution ** 2)"
            )
    order_count = max(1, starts)
    searches = min(order_count, len(samples))  # the bar counts _prepare's 2 S steps too
    with tqdm(
        total=3 * len(samples) + searches * MAX_SWEEPS * SWEEP_STEPS,
        desc=f"point estimate ({LOSS_LABELS[loss]})",
        unit="step",
        disable=not progress_enabled(progress),
        leave=not clears_when_done(),  # a log file gets no line of spaces
    ) as bar:
        prepared = _prepare(samples, loss, bar)
        losses = np.empty(len(samples))  # [S]
        kept: dict[int, _Start] = {}  # the order_count samples of lowest loss so far
        for s in range(len(samples)):
            kept[s] = _sample_start(s, prepared, loss)  # no sort of N
            losses[s] = kept[s].value
            if len(kept) > order_count:  # the highest (loss, row): the last to be searched
                del kept[max(kept, key=lambda row: (losses[row], row))]
            bar.update()
        best, best_value = None, np.inf
        for s in sorted(kept, key=lambda row: (losses[row], row)):  # lowest (loss, row) first
            estimate, value = _greedy(kept.pop(s), prepared, loss, max_clusters, bar)
            if value < best_value:
                best, best_value = estimate, value
        assert best is not None
        if cell_words is None:
            return PointEstimate(compact(best)[0], float(best_value), float(losses.min()))
        codes, k = compact(best)
        joined = join_specks(codes, k, prepared, loss, cell_words, cell_area)
        codes, k = compact(joined.estimate)
        value = _expected(codes, k, prepared, loss) if joined.cells else best_value
    return PointEstimate(codes, float(value), float(losses.min()), joined.cells, joined.specks,
                         float(best_value))  # fmt: skip


def matched_labels(estimate: np.ndarray, sample: np.ndarray) -> np.ndarray:
    """[N] the sample's labels renamed to the estimate's clusters they are matched with (the
    Hungarian matching of most shared cells; -1 for a sample label matched with none)."""
    return _matched(*_codes_and_values(estimate), sample)


def _matched(e: np.ndarray, values: np.ndarray, sample: np.ndarray) -> np.ndarray:
    """:func:`matched_labels` given the estimate's codes ``e`` [N] and its ``values`` [K]
    ascending (:func:`_codes_and_values`; agreement reuses them for every sample)."""
    from scipy.optimize import linear_sum_assignment  # here: a fit without one skips its import

    s, j = compact(sample)
    table = contingency(e, s, values.shape[0], j)  # [K, J]
    rows, cols = linear_sum_assignment(table, maximize=True)
    renamed = np.full(j, -1, dtype=np.int64)
    renamed[cols] = rows
    mapped = renamed[s]  # [N] the estimate's cluster, -1 where matched with none
    return np.where(mapped >= 0, values[np.maximum(mapped, 0)], -1)


def agreement_probability(estimate: np.ndarray, samples: np.ndarray, bar=None) -> np.ndarray:
    """[N] per cell, the share of samples whose (matched) label agrees with ``estimate``;
    ``bar.update()`` after each sample where a ``bar`` is given."""
    samples, estimate = np.asarray(samples), np.asarray(estimate)
    (e, values), agree = _codes_and_values(estimate), np.zeros(estimate.shape[0])  # [K], [N]
    for sample in samples:
        agree += _matched(e, values, sample) == estimate
        if bar is not None:  # 0.1 s per sample at 2.9 million cells
            bar.update()
    return agree / samples.shape[0]


def concept_labels(estimate: np.ndarray, reference: np.ndarray, num_concepts: int) -> np.ndarray:
    """[N] the estimate's clusters named by concepts of ``reference`` [N] (the state whose pi
    and emissions a result reports): the Hungarian matching of most shared cells; clusters left
    over take concepts that ``reference`` does not use."""
    from scipy.optimize import linear_sum_assignment

    e, k = compact(estimate)
    if k > num_concepts:
        raise ValueError(f"the estimate has {k} clusters, more than {num_concepts} concepts")
    table = contingency(e, np.asarray(reference, dtype=np.int64), k, num_concepts)  # [K, L]
    rows, cols = linear_sum_assignment(table, maximize=True)
    name = np.empty(k, dtype=np.int64)
    name[rows] = cols
    return name[e]


def check_point_estimate(name: str) -> str:
    """``name`` if it is one of :data:`POINT_ESTIMATES`, else ValueError listing them."""
    if name not in POINT_ESTIMATES:
        raise ValueError(f"point estimate {name!r}: choose one of {POINT_ESTIMATES}")
    return name


def with_point_estimate(
    output: InferenceOutput,
    samples: np.ndarray,
    name: str,
    num_concepts: int,
    progress: bool | None = False,
    cell_words: np.ndarray | None = None,
    cell_area: float | None = None,
) -> InferenceOutput:
    """``output`` reporting the point estimate ``name`` over ``samples`` [S, N] as its labels
    (unchanged for ``"map-visited"``), with :func:`agreement_probability` as its ``agreement``.

    ``"vi"`` and ``"binder"`` join the specks of the loss's minimiser to other clusters (a speck by
    ``cell_words`` [N], the words heard at each cell, and ``cell_area``, the square metres of one
    cell, which they need: :mod:`~spcopyro.results.speck_join`); ``"vi-specks"`` and
    ``"binder-specks"`` keep them. The estimate's clusters are named by the concepts of
    ``output.labels`` they share most cells with (:func:`concept_labels`), so pi and the emission
    distributions of the reported state describe them; the expected losses (and, joining, the cells
    joined and the loss before) go into ``options``; the agreement is that of the reported labels,
    joined cells included.
    """
    if check_point_estimate(name) == "map-visited":
        return output
    loss, joins = estimate_loss(name)
    if joins and (cell_words is None or cell_area is None):
        raise ValueError(
            f"point estimate {name!r} joins speck clusters, told by the words heard at "
            f"each cell and their area: pass cell_words [N] and cell_area (m^2 of one cell; "
            f"or {loss + KEEPS_SPECKS!r}, which keeps them)"
        )
    with timed("point_estimate"):
        found = point_estimate(samples, loss, max_clusters=num_concepts, progress=progress,
                               cell_words=cell_words if joins else None,
                               cell_area=cell_area)  # fmt: skip
        labels = concept_labels(found.labels, np.asarray(output.labels), num_concepts)
    with timed("agreement"):  # 3 s at 2.9 million cells, 25 samples: a bar on large maps
        bar = setup_bar(samples.shape[1], len(samples), "agreement map", "sample", progress)
        agreement = agreement_probability(labels, samples, bar)
        bar.close()
    joined = {}
    if joins:
        joined = {
            "speck_cells_joined": found.speck_cells,
            "specks_joined": found.specks,
            "loss_with_specks": found.loss_with_specks,
        }
    return dataclasses.replace(
        output,
        labels=labels,
        agreement=agreement,
        options={
            **output.options,
            "point_estimate": name,
            "expected_loss": found.expected_loss,
            "best_sample_loss": found.best_sample_loss,
            **joined,
        },
    )
