"""The per-cell passes over a fit's [N, L] marginals keep no whole-map float64 copy.

On a 100 m x 100 m warehouse map at 0.05 m (2.9 million free cells, L = 120) the fit's float32
label frequencies are 1.4 GB; the passes over them (counting the frequencies, the entropy that
``fit`` saves, ``where``'s probability and unmapped mass) made float64 copies and temporaries of
the whole [N, L] array: a peak of 11.3 GB for ``spcopyro fit --sweeps 50`` and 5.4 GB for
``spcopyro where``. They now work a block of cells at a time, with the same values.
"""

from __future__ import annotations

import tracemalloc
from types import SimpleNamespace

import numpy as np

from spcopyro.results import uncertainty
from spcopyro.results.uncertainty import (
    cell_entropy,
    label_frequencies,
    unmapped_mass,
    where_probability,
)

N, L, S = 200_000, 120, 4


def _peak(function, *args):
    """(the result, the bytes numpy allocated at the peak of ``function(*args)``)."""
    tracemalloc.start()
    try:
        value = function(*args)
        return value, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _result(marginals: np.ndarray) -> SimpleNamespace:
    """A stand-in for an SpCoResult with these marginals (what the passes read of one)."""
    concept_given_word = np.linspace(0.0, 1.0, L) / np.linspace(0.0, 1.0, L).sum()
    sizes = np.zeros(L, dtype=np.int64)
    sizes[:30] = 1  # concepts 30.. label no cell of the map
    return SimpleNamespace(
        marginals=marginals,
        labels=marginals.argmax(1),
        computed_once=lambda name, compute: compute(),
        concept_given_word=lambda word, prior: concept_given_word,
        concept_sizes=lambda: sizes,
    )


def test_passes_over_the_marginals_allocate_less_than_a_copy_of_them(monkeypatch):
    monkeypatch.setattr(uncertainty, "BLOCK_CELLS", 4096, raising=False)  # 15.7 MB of float64
    rng = np.random.default_rng(0)
    base = rng.integers(0, 30, N)
    samples = np.where(rng.random((S, N)) < 0.2, rng.integers(0, L, (S, N)), base)  # [S, N]
    float32_copy = N * L * 4  # bytes of the marginals themselves (96 MB here)

    marginals, peak = _peak(label_frequencies, samples, L)  # [N, L]
    assert marginals.dtype == np.float32 and marginals.shape == (N, L)
    assert peak < 1.5 * float32_copy  # the result and a block's counts (was 3 x: int64 counts)
    np.testing.assert_array_equal(marginals.sum(1), np.ones(N, dtype=np.float32))

    result = _result(marginals)
    for name, function, args in (
        ("cell_entropy", cell_entropy, (result,)),
        ("where_probability", where_probability, (result, "kitchen")),
        ("unmapped_mass", unmapped_mass, (result,)),
    ):
        value, peak = _peak(function, *args)
        assert value.shape == (N,)
        assert peak < 0.5 * float32_copy, f"{name} allocated {peak / 1e6:.0f} MB"


def test_the_blocked_passes_compute_the_whole_array_formulas_exactly():
    rng = np.random.default_rng(1)
    n = 40_000  # more than two blocks
    samples = rng.integers(0, L, (S, n))
    flat = np.arange(n, dtype=np.int64) * L + samples
    expected = np.bincount(flat.ravel(), minlength=n * L).reshape(n, L).astype(np.float32) / S
    marginals = label_frequencies(samples, L)
    np.testing.assert_array_equal(marginals, expected)

    result = _result(marginals)
    p = marginals.astype(np.float64)
    np.testing.assert_array_equal(
        cell_entropy(result), -(p * np.log(np.where(p > 0, p, 1.0))).sum(-1)
    )
    concept_given_word = result.concept_given_word("kitchen", "area")
    np.testing.assert_array_equal(
        where_probability(result, "kitchen"), (p * concept_given_word).sum(-1)
    )
    np.testing.assert_array_equal(unmapped_mass(result), p[:, 30:].sum(-1))
    result.marginals = None  # a point estimate: the cell's concept's probability
    np.testing.assert_array_equal(
        where_probability(result, "kitchen"), concept_given_word[result.labels]
    )


def test_where_probability_does_not_depend_on_the_block_size(monkeypatch):
    """Each cell's sum is its own: a BLAS product of a block (``block @ concept_given_word``)
    groups rows and splits them across threads, so rows at those boundaries came out 1 ulp
    apart from the whole-array product (one thread, 16,385 cells: row 16,384 differed)."""
    rng = np.random.default_rng(2)
    n = 16_385
    marginals = label_frequencies(rng.integers(0, L, (S, n)), L)  # [n, L]
    result = _result(marginals)
    monkeypatch.setattr(uncertainty, "BLOCK_CELLS", n)
    whole = where_probability(result, "kitchen")  # [n] one block
    for block_cells in (1, 7, 4096, 1 << 14):
        monkeypatch.setattr(uncertainty, "BLOCK_CELLS", block_cells)
        np.testing.assert_array_equal(where_probability(result, "kitchen"), whole)
    product = marginals.astype(np.float64) @ result.concept_given_word("kitchen", "area")
    np.testing.assert_allclose(whole, product, rtol=1e-15)


def test_label_frequencies_advance_a_bar_per_million_cells(monkeypatch):
    """The count was one step of the fit's 'label frequencies' bar that sat still for 8 s on a
    3.07-million-cell map; it now advances once per COUNT_STEP_CELLS cells counted, with the
    same frequencies as without a bar."""
    monkeypatch.setattr(uncertainty, "BLOCK_CELLS", 7)
    monkeypatch.setattr(uncertainty, "COUNT_STEP_CELLS", 50)
    samples = np.random.default_rng(4).integers(0, 5, (3, 201))
    expected = label_frequencies(samples, 5)
    # The cells counted so far, seen through the count's bincount of each block's [S * n] keys.
    counted = [0]
    bincount = np.bincount

    def counting_bincount(keys, minlength=0):
        counted[0] += keys.size // samples.shape[0]
        return bincount(keys, minlength=minlength)

    monkeypatch.setattr(np, "bincount", counting_bincount)
    steps = []  # (steps credited by this update, cells counted when it came)
    bar = SimpleNamespace(update=lambda k=1: steps.append((k, counted[0])))
    frequencies = label_frequencies(samples, 5, bar)
    np.testing.assert_array_equal(frequencies, expected)
    assert counted[0] == 201
    assert sum(k for k, _ in steps) == uncertainty.count_steps(201) == 5 and len(steps) == 5
    # No step is credited before its cells are counted: the k-th step when 50 k cells (or all,
    # for the last, partial one) have been; it was credited when its first block began.
    credited = np.cumsum([k for k, _ in steps])
    for total, (_, cells) in zip(credited, steps, strict=True):
        assert cells >= min(50 * total, 201), steps
    assert uncertainty.count_steps(0) == uncertainty.count_steps(1) == 1
    # A map of no cells still gives its one step.
    empty = []
    label_frequencies(np.zeros((2, 0), dtype=np.int64), 5, SimpleNamespace(update=empty.append))
    assert empty == [1]
