"""Concept labels are renamed 0..K-1 by a table lookup, not a sort of the map's cells.

On a 2.9-million-cell warehouse map (``spcopyro fit --sweeps 50``, 25 kept samples) agreement
took 20 s: per sample three np.unique sorts of the N cells (the estimate's codes and values,
again for every sample, and the sample's codes), 0.34 s each where a bincount lookup takes
0.02 s. The point estimate's preparation renames every sample the same way.
"""

from __future__ import annotations

import numpy as np
import pytest

from spcopyro.results import point_estimate as pe


def _count_unique(monkeypatch) -> list[int]:
    calls = [0]
    unique = np.unique

    def counted(*args, **kwargs):
        calls[0] += 1
        return unique(*args, **kwargs)

    monkeypatch.setattr(np, "unique", counted)
    return calls


def test_agreement_sorts_no_labelling(monkeypatch):
    rng = np.random.default_rng(0)
    estimate = rng.integers(0, 8, 5000) * 3  # concept ids with gaps
    samples = np.where(rng.random((12, 5000)) < 0.1, rng.integers(0, 40, (12, 5000)), estimate)
    calls = _count_unique(monkeypatch)
    agree = pe.agreement_probability(estimate, samples)
    assert calls[0] == 0  # was 3 per sample
    monkeypatch.undo()
    expected = np.mean([pe.matched_labels(estimate, s) == estimate for s in samples], axis=0)
    np.testing.assert_array_equal(agree, expected)


def test_labels_outside_small_ids_are_sorted_once_per_labelling(monkeypatch):
    """The fallback sorted twice per compact (the values, then the codes) and agreement three
    times for the estimate: one np.unique(return_inverse=True) now gives both."""
    rng = np.random.default_rng(3)
    estimate = rng.integers(0, 8, 2000) * 10**9  # ids past the lookup's range
    samples = np.where(
        rng.random((5, 2000)) < 0.1, rng.integers(0, 12, (5, 2000)) * 10**9, estimate
    )
    calls = _count_unique(monkeypatch)
    codes, k = pe.compact(estimate)
    assert calls[0] == 1  # was 2
    agree = pe.agreement_probability(estimate, samples)
    assert calls[0] == 1 + 1 + samples.shape[0]  # was 3 for the estimate and 2 per sample
    monkeypatch.undo()
    values, inverse = np.unique(estimate, return_inverse=True)
    assert k == values.size
    np.testing.assert_array_equal(codes, inverse)
    expected = np.mean([pe.matched_labels(estimate, s) == estimate for s in samples], axis=0)
    np.testing.assert_array_equal(agree, expected)


@pytest.mark.parametrize("dtype", [np.int64, np.int32, np.int16, np.uint8, np.uint32])
def test_compact_equals_numpy_unique(dtype):
    rng = np.random.default_rng(1)
    for high in (1, 3, 120):
        labels = (rng.integers(0, high, 1000) * 2).astype(dtype)
        values, inverse = np.unique(labels, return_inverse=True)
        codes, k = pe.compact(labels)
        assert k == values.size and codes.dtype == np.int64
        np.testing.assert_array_equal(codes, inverse)
        found_codes, found = pe._codes_and_values(labels)
        assert found.dtype == values.dtype
        np.testing.assert_array_equal(found, values)
        np.testing.assert_array_equal(found_codes, inverse)


@pytest.mark.parametrize(
    "labels",
    [
        np.array([], dtype=np.int64),
        np.array([-3, 5, -3]),
        np.array([2**40, 3]),
        np.array([1.5, 0.5]),
    ],
)
def test_compact_falls_back_to_a_sort_outside_small_ids(labels):
    values, inverse = np.unique(labels, return_inverse=True)
    codes, k = pe.compact(labels)
    assert k == values.size
    np.testing.assert_array_equal(codes, inverse.astype(np.int64))


def test_the_point_estimate_bar_is_open_while_the_samples_are_prepared(monkeypatch):
    """The preparation (a sort of the N cells per sample) ran before the bar opened: 16.5 s of
    a silent terminal between the sweeps and the point estimate's bar on the warehouse map."""
    from tqdm.auto import tqdm

    prepare, open_bars = pe._prepare, []

    def watched(*args, **kwargs):
        open_bars.append(len(tqdm._instances))
        return prepare(*args, **kwargs)

    monkeypatch.setattr(pe, "_prepare", watched)
    rng = np.random.default_rng(2)
    samples = rng.integers(0, 4, (6, 300))
    found = pe.point_estimate(samples, "vi", max_clusters=10, progress=True)
    assert open_bars and open_bars[0] >= 1
    assert found.labels.shape == (300,)
