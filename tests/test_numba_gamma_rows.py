"""The compiled gamma fill (spcopyro.gibbs.numba_random._fill_gamma_linear), the hot loop of
every Gibbs sweep's globals: its draws pinned, so that a change of the loop that alters any draw,
its order or the number of random bits it takes fails here."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from spcopyro.gibbs.numba_random import _fill_gamma_linear, rng_state  # noqa: E402


def _fill(base: float, statistics: np.ndarray, seed: int) -> tuple[np.ndarray, ...]:
    R, C = statistics.shape
    out, boost, sums = np.zeros((R, C)), np.zeros((R, C)), np.zeros(R)
    boosted, state = np.zeros(R, dtype=np.bool_), rng_state(seed)
    bad = _fill_gamma_linear(base, statistics, out, boost, sums, boosted, state)
    return np.array([bad]), out, boost, sums, boosted, state


# [6, 8]: rows without statistics (0, 3), with counts, with fractions, all ones.
STATISTICS = np.array(
    [
        [0, 0, 0, 0, 0, 0, 0, 0],
        [3, 0, 1, 0, 0, 7, 0, 2],
        [0.4, 0, 0.25, 0, 0, 0, 0, 0.05],
        [0, 0, 0, 0, 0, 0, 0, 0],
        [120, 45, 0, 0, 300, 0, 9, 0],
        [1, 1, 1, 1, 1, 1, 1, 1],
    ],
    dtype=float,
)
WITH_NAN = STATISTICS.copy()
WITH_NAN[4, 2] = np.nan

# (base, statistics, seed): (bad index, the RNG state after, boosted rows, sum of w * out, sum of
# w * boost, sum of row_sums), w = 1..48 in row-major order. Recorded at 4cb051b (before the
# loop for rows without statistics was folded into the general one); the state is exact (it
# counts the random bits taken), the sums follow libm's last bits, so they compare to 1e-12.
PINNED = [
    (1.0, STATISTICS, 0, -1,
     [3149401891484456212, 13039160981685256520, 15401258220711718302, 296005906514685948],
     [], 17198.761944752787, 0.0, 492.6739023244164),
    (0.3, STATISTICS, 1, -1,
     [1136691936596536892, 15419019959977758744, 5447365994532926738, 12659179912379181402],
     [0, 1, 2, 3, 4], 18609.42212836761, -1312.472486240004, 547.4123787359806),
    (1e-20, STATISTICS, 2, -1,  # a + 1 == 1 after the boost: the exponential
     [17844290733342989979, 11884481269038762969, 18034983125395756595, 10790006051901499679],
     [0, 1, 2, 3, 4], 17514.705534235953, -4.725224863628773e22, 512.0424031293846),
    (1.5, STATISTICS, 3, -1,
     [15963143039433025486, 6616366819069004050, 454539505589824621, 3779135711994275021],
     [], 18815.639037604524, 0.0, 552.0198874186145),
    (500.0, STATISTICS, 4, -1,
     [869117966903181588, 17188226896332862296, 12642114189232462596, 9026025616835655524],
     [], 606196.326752326, 0.0, 24421.584539532632),
    (1e8 / 120, STATISTICS, 5, -1,
     [391425099664171161, 14361652873856214661, 10296769017900764585, 13620805313923857192],
     [], 979751837.927986, 0.0, 39997179.51237051),
    (1.0, WITH_NAN, 7, 34,  # stops at [4, 2], the state as it was there
     [9466372666329871066, 11235145887622028885, 14917016949087276353, 4934825874872372777],
     [], 6374.869923589765, 0.0, 34.52084614284096),
]  # fmt: skip


@pytest.mark.parametrize("case", PINNED, ids=lambda case: f"base={case[0]:g}-seed={case[2]}")
def test_gamma_fill_draws_are_pinned(case):
    base, statistics, seed, bad, state, boosted, out_w, boost_w, sums = case
    got_bad, out, boost, row_sums, got_boosted, got_state = _fill(base, statistics, seed)
    w = np.arange(1, statistics.size + 1, dtype=float).reshape(statistics.shape)  # [R, C]
    assert got_bad[0] == bad
    assert got_state.tolist() == state
    assert np.flatnonzero(got_boosted).tolist() == boosted
    assert float((out * w).sum()) == pytest.approx(out_w, rel=1e-12)
    assert float((boost * w).sum()) == pytest.approx(boost_w, rel=1e-12)
    assert float(row_sums.sum()) == pytest.approx(sums, rel=1e-12)


def test_bad_shapes_are_named_and_small_ones_boosted():
    zeros = np.zeros((3, 4))
    for base in (0.0, -1.0, np.inf, np.nan):
        assert _fill(base, zeros, 1)[0][0] == 0  # the first entry named
    bad, out, boost, _, boosted, _ = _fill(0.5, zeros, 1)  # below 1: boosted, log(U) / a
    assert bad[0] == -1 and boosted.all() and (boost < 0).all() and (out > 0).all()
