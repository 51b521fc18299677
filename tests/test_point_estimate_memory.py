"""The point estimate keeps its samples' codes in the narrowest dtype that holds them.

:func:`~spcopyro.results.point_estimate._prepare` renames each kept label map's labels
0..J_s-1 and holds the [S, N] codes through the whole search. They were int64: in a default
``spcopyro fit --sweeps 200`` of a synthetic 2000 x 2000-cell house at 0.05 m (3,868,494 free
cells, 50 kept samples) they were 1475 MiB of the 1883 MiB the point estimate added to the
fit's RSS (to 6866 MiB); with uint8 codes its high-water mark is 5322 MiB. Codes below 256 now
take one byte (uint8), below 65,536 two (uint16); the estimates, losses and joined specks are
the same to the bit.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from spcopyro.results import point_estimate as pe
from spcopyro.results.point_estimate import _prepare, compact, point_estimate


def _rooms(seed: int, cells: int, count: int, labels: int = 120) -> np.ndarray:
    """[count, cells] int16 label maps as a fit keeps them: rooms along a corridor whose walls
    shift by up to 40 cells between samples, each sample naming them its own way out of
    ``labels``, with specks of 2-9 cells of other labels."""
    rng = np.random.default_rng(seed)
    rooms = 20
    edges = np.sort(rng.choice(np.arange(1, cells), rooms - 1, replace=False))
    samples = np.empty((count, cells), dtype=np.int16)
    for row in samples:
        moved = np.sort(np.clip(edges + rng.integers(-40, 41, edges.shape), 1, cells - 1))
        row[:] = rng.permutation(labels)[np.searchsorted(moved, np.arange(cells), "right")]
        for _ in range(10):
            start = rng.integers(cells - 10)
            row[start : start + rng.integers(2, 10)] = rng.integers(labels)
    return samples


@pytest.mark.parametrize(
    ("labels", "cells", "dtype"),
    [
        (120, 500, np.uint8),  # the default preset's L
        (256, 500, np.uint8),
        (257, 500, np.uint16),
        (100_000, 300, np.int64),  # the bound is max label + 1, not the 300 cells
        (100_000, 70_000, np.int64),
    ],
)
def test_codes_take_the_narrowest_dtype_and_keep_their_values(labels, cells, dtype):
    rng = np.random.default_rng(labels + cells)
    samples = rng.integers(0, labels, (3, cells))
    samples[:, 0] = labels - 1  # the largest label occurs
    prepared = _prepare(samples, "vi")
    assert prepared.codes.dtype == dtype
    assert prepared.signatures.dtype == np.int64  # [S, U]: as before
    for codes, size, sample in zip(prepared.codes, prepared.sizes, samples, strict=True):
        expected, k = compact(sample)
        assert size == k
        np.testing.assert_array_equal(codes.astype(np.int64), expected)


AREA = 1e-4
"""m^2 of a cell (0.01 m): 0.5 % of these maps' cells is under SPECK_AREA."""


def test_point_estimate_holds_no_int64_copy_of_the_samples():
    """The search's peak allocation stays below 3/4 of the [S, N] int64 codes it held (S = 50, a
    fit's default: 11.3 MB at the peak, 32.3 MB with int64 codes)."""
    count, cells = 50, 60_000
    samples = _rooms(0, cells, count)
    int64_codes = count * cells * 8  # 24 MB
    cell_words = np.zeros(cells)
    cell_words[::500] = 1.0
    tracemalloc.start()
    try:
        point_estimate(samples, "vi", max_clusters=120, cell_words=cell_words, cell_area=AREA)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 0.75 * int64_codes, f"{peak / 1e6:.1f} MB at the peak"


@pytest.mark.parametrize(
    ("loss", "labels", "max_clusters"),
    [
        ("vi", 120, 120),
        ("binder", 120, 120),
        ("vi", 256, None),  # uint8 codes; the search's spare cluster 256 needs int64
        ("vi", 300, None),  # uint16 codes
    ],
)
def test_narrow_codes_give_the_int64_codes_estimate(monkeypatch, loss, labels, max_clusters):
    samples = _rooms(labels, 4000, 12, labels)
    if labels == 256:
        samples[:, :256] = np.arange(256)  # every row uses all 256 labels: J_s = 256
    cell_words = np.zeros(samples.shape[1])
    cell_words[::97] = 1.0
    found = point_estimate(
        samples, loss, max_clusters=max_clusters, cell_words=cell_words, cell_area=AREA
    )
    assert _prepare(samples, loss).codes.dtype == (np.uint8 if labels <= 256 else np.uint16)
    monkeypatch.setattr(pe, "_radix_dtype", lambda samples: np.int64)  # as before
    wide = point_estimate(
        samples, loss, max_clusters=max_clusters, cell_words=cell_words, cell_area=AREA
    )
    assert found.labels.dtype == wide.labels.dtype == np.int64
    np.testing.assert_array_equal(found.labels, wide.labels)
    assert found[1:] == wide[1:]  # the losses, to the bit, and the specks joined
