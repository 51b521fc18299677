"""The compiled loopy-BP backend's cached beliefs (spcopyro.guides.numba_lbp_beliefs): the running
sizes, observed beliefs, labels and Bethe terms equal a from-scratch recomputation
(``_summaries``) when no belief is left stale, and stay within the documented bound of it, cell
by cell, pair by pair and in total, when the active set leaves some stale."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from spcopyro.config import preset
from spcopyro.fit.house import prepare_model_data
from spcopyro.guides.lbp_method import LBPOptions, init, step
from spcopyro.guides.run import initial_q
from spcopyro.synthetic import HouseSpec, make_house

numba_lbp = pytest.importorskip("spcopyro.guides.numba_lbp")

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # small tensors


@pytest.fixture(scope="module")
def house():
    """A 40 x 50 three-room house at L = 6 (1,299 free cells, observed ones in every room)."""
    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=3))
    settings = preset("original-code", gamma=2.0, num_concepts=6)
    return prepare_model_data(house, settings)[1], settings.model


def states(data, cfg, options: LBPOptions, iterations: int):
    """The compiled state after each of ``iterations`` outer iterations from a soft random
    start, gamma annealed over the first 3 (the coupling changes between passes)."""
    q = initial_q(data, cfg, torch.Generator().manual_seed(0), init="soft")
    state = init(q, data, cfg, options)
    for k in range(iterations):
        state, _ = step(state, data, cfg, cfg.gamma * min(1.0, (k + 1) / 3), options)
        yield state


@pytest.mark.parametrize("options", [
    dict(support=0, threshold=0.0, active_tolerance=0.0),
    dict(support=3, threshold=1e-3, active_tolerance=0.0),
])  # fmt: skip
def test_without_stale_beliefs_the_cached_summaries_are_the_recomputed_ones(house, options):
    """Tolerance 0 (every belief whose inputs changed is recomputed): after each iteration the
    running sizes, observed q, labels and Bethe totals equal ``_summaries`` of all the messages
    to rounding, and the bound is 0."""
    data, cfg = house
    for state in states(data, cfg, LBPOptions(backend="numba", **options), 8):
        bp = state.bp
        sizes, observed, labels, totals = bp.exact_summaries()
        np.testing.assert_allclose(bp.sizes, sizes, rtol=1e-11, atol=1e-9)
        np.testing.assert_allclose(bp.observed_q, observed, rtol=1e-11, atol=1e-12)
        np.testing.assert_array_equal(bp._labels, labels)
        np.testing.assert_allclose(bp.totals, totals, rtol=1e-11, atol=1e-9)
        assert (bp.cache_bound() == 0).all()


def test_stale_beliefs_stay_within_the_documented_bound(house):
    """Tolerance 0.05 (so that many beliefs are kept stale): every cached belief within a
    factor e^(+-2 drift) of the exact one, every cached pair term within its bound (against
    the same state recomputed from scratch), the totals and sizes within :meth:`cache_bound`
    of ``_summaries``; and then :meth:`refresh_all` makes them exact."""
    data, cfg = house
    options = LBPOptions(backend="numba", support=0, threshold=0.0, active_tolerance=0.05)
    stale = 0
    for k, state in enumerate(states(data, cfg, options, 14)):
        bp = state.bp
        N = bp.nb.shape[0]
        stale = max(stale, N - bp.refreshed_cells)
        if k < 4:
            continue
        exact_q = bp.beliefs().numpy()  # [N, L] from the messages (the dense path)
        ratio = np.abs(np.log(bp.cached_beliefs()) - np.log(exact_q)).max(1)  # [N]
        assert (ratio <= 2 * bp.belief_drift + 1e-9).all()
        assert (2 * bp.belief_drift <= options.active_tolerance).all()
        fresh = copy.deepcopy(bp)
        fresh.refresh_all()
        delta = 2 * (bp.belief_drift[bp.pair_a] + bp.belief_drift[bp.pair_b])  # [P]
        assert (np.abs(bp.pair_agree - fresh.pair_agree) <= np.expm1(delta) + 1e-12).all()
        pair_bound = delta + np.expm1(delta) * 2 * np.log(cfg.num_concepts)
        assert (np.abs(bp.pair_entropy - fresh.pair_entropy) <= pair_bound + 1e-12).all()
        sizes, observed, labels, totals = bp.exact_summaries()
        bound = bp.cache_bound()
        assert np.abs(bp.sizes - sizes).sum() <= bound[0] + 1e-9
        assert (np.abs(bp.totals - totals) <= bound[1:] + 1e-9).all()
        np.testing.assert_allclose(fresh.sizes, sizes, rtol=1e-11, atol=1e-9)
        np.testing.assert_allclose(fresh.totals, totals, rtol=1e-11, atol=1e-9)
        np.testing.assert_array_equal(fresh._labels, labels)
        assert (fresh.cache_bound() == 0).all()
    assert stale > N // 4  # the test kept many beliefs stale


def test_the_running_sums_match_their_recount(house):
    """After 60 iterations (past a recount) the running sums equal the sums of the cached
    values, and the epochs in use hold exactly the background cells."""
    data, cfg = house
    options = LBPOptions(backend="numba", active_tolerance=0.05)
    *_, last = states(data, cfg, options, 60)
    bp = last.bp
    before = bp.sizes.copy(), bp.totals.copy()
    bp._recount()
    np.testing.assert_allclose(bp.sizes_rest + bp.epoch_invz @ bp.epoch_beta, before[0],
                               rtol=1e-11, atol=1e-9)  # fmt: skip
    np.testing.assert_allclose(bp.totals, before[1], rtol=1e-11, atol=1e-9)
    M = bp.observed_q.shape[0]
    assert bp.epoch_count.sum() == (bp.rows == M).sum()
    assert bp.sizes.sum() == pytest.approx(bp.nb.shape[0], rel=1e-12)
