"""The compiled gamma fill's loop for rows without statistics (spcopyro.gibbs.numba_random)
draws exactly what its general loop draws for the same shapes."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from spcopyro.gibbs.numba_random import (  # noqa: E402
    _fill_gamma_linear,
    dirichlet_log_rows,
    rng_state,
)


def _fill(base: float, statistics: np.ndarray, seed: int) -> tuple[np.ndarray, ...]:
    R, C = statistics.shape
    out, boost, sums = np.zeros((R, C)), np.zeros((R, C)), np.zeros(R)
    boosted, state = np.zeros(R, dtype=np.bool_), rng_state(seed)
    bad = _fill_gamma_linear(base, statistics, out, boost, sums, boosted, state)
    return np.array([bad]), out, boost, sums, boosted, state


@pytest.mark.parametrize("base", [1.0, 1.5, 500.0, 10000.0, 1e8 / 120])
def test_rows_without_statistics_draw_what_the_general_loop_draws(base):
    """A statistic too small to change the shape (base + 1e-300 == base) sends a row through the
    general loop with the same shapes: every number must be the same to the bit."""
    rng = np.random.default_rng(0)
    statistics = np.zeros((12, 40))  # [R, C]
    statistics[2] = rng.integers(0, 9, 40)  # a row with counts: the general loop either way
    plain_path = statistics.copy()
    general_path = statistics.copy()
    general_path[[0, 5, 11], 0] = 1e-300
    assert base + 1e-300 == base
    for seed in range(3):
        expected = _fill(base, general_path, seed)
        got = _fill(base, plain_path, seed)
        for a, b in zip(expected, got, strict=True):
            assert np.array_equal(a, b), (base, seed)
        log_plain, _ = dirichlet_log_rows(base, plain_path, rng_state(seed))
        log_general, _ = dirichlet_log_rows(base, general_path, rng_state(seed))
        assert np.array_equal(log_plain.view(np.uint64), log_general.view(np.uint64))


def test_bad_or_small_shapes_keep_the_general_loop():
    zeros = np.zeros((3, 4))
    for base in (0.0, -1.0, np.inf, np.nan):
        assert _fill(base, zeros, 1)[0][0] == 0  # the first entry named
    bad, out, boost, _, boosted, _ = _fill(0.5, zeros, 1)  # below 1: boosted, log(U) / a
    assert bad[0] == -1 and boosted.all() and (boost < 0).all() and (out > 0).all()
