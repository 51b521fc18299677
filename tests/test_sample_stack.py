"""A chain's kept label maps are held once: :meth:`GibbsChain.to_run` hands out the stack the
chain's rows live in (read-only), and a fit's second half of them is a view, not a copy.

At 3.87 million free cells a default fit kept 100 maps (0.77 GB) twice -- the chain's rows, views
of the driver's stack, and to_run's np.stack of them -- and copied the 50 of the second half
again before renaming them: 1.16 GB more than the maps themselves at the label-frequency step.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from gibbs_problems import config, random_problem

from spcopyro.fit.gibbs_chains import second_half
from spcopyro.gibbs.checkpoint import load_chain, save_chain
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import advance, start_chain

SWEEPS, THIN = 12, 2


def _chain(copies: int = 1):
    _, data = random_problem(0, copies=copies)
    return data, start_chain(data, config(), options=GibbsOptions(backend="torch"), seed=3)


def _shares_every_row(stack: np.ndarray, rows: list[np.ndarray]) -> bool:
    return all(np.shares_memory(stack[s], row) for s, row in enumerate(rows))


def test_one_advance_hands_out_the_chains_own_rows():
    _, chain = _chain()
    advance(chain, SWEEPS, thin=THIN, progress=False)
    run = chain.to_run()
    assert run.label_samples.shape == (SWEEPS // THIN, chain.state.labels.numel())
    assert _shares_every_row(run.label_samples, chain.label_samples)
    assert not run.label_samples.flags.writeable  # the chain's maps: not to be written into
    with pytest.raises(ValueError, match="read-only"):
        run.label_samples[0, 0] = 1
    again = chain.to_run().label_samples
    assert np.shares_memory(again, run.label_samples)
    np.testing.assert_array_equal(run.sample_sweeps, np.arange(THIN - 1, SWEEPS, THIN))


def test_rows_of_several_advances_are_stacked_once_and_the_chain_keeps_that_stack():
    _, chain = _chain()
    advance(chain, SWEEPS // 2, thin=THIN, progress=False)
    advance(chain, SWEEPS // 2, thin=THIN, progress=False)  # a second driver stack
    before = [row.copy() for row in chain.label_samples]
    run = chain.to_run()
    np.testing.assert_array_equal(run.label_samples, np.stack(before))
    assert _shares_every_row(run.label_samples, chain.label_samples)  # the old rows let go
    np.testing.assert_array_equal(np.stack(chain.label_samples), np.stack(before))
    assert np.shares_memory(chain.to_run().label_samples, run.label_samples)
    # and the chain goes on as one never stacked: its later maps are those of a fresh chain
    advance(chain, 4, thin=THIN, progress=False)
    _, fresh = _chain()
    advance(fresh, SWEEPS + 4, thin=THIN, progress=False)
    np.testing.assert_array_equal(chain.to_run().label_samples, fresh.to_run().label_samples)


def test_a_resumed_chain_saves_and_continues_the_same_after_to_run(tmp_path):
    data, chain = _chain()
    advance(chain, SWEEPS // 2, thin=THIN, progress=False)
    save_chain(chain, tmp_path / "c.npz")
    resumed = load_chain(tmp_path / "c.npz", data, config(), GibbsOptions(backend="torch"))
    advance(resumed, SWEEPS // 2, thin=THIN, progress=False)
    first = resumed.to_run().label_samples  # the loaded rows and the new ones, stacked once
    save_chain(resumed, tmp_path / "d.npz")  # saved from the stack's rows
    advance(chain, SWEEPS // 2, thin=THIN, progress=False)
    np.testing.assert_array_equal(first, chain.to_run().label_samples)
    again = load_chain(tmp_path / "d.npz", data, config(), GibbsOptions(backend="torch"))
    np.testing.assert_array_equal(again.to_run().label_samples, first)


def test_to_run_allocates_no_second_copy_of_the_maps():
    """A tracemalloc bound: to_run's allocations stay far below the maps' S N 2 bytes (the old
    np.stack allocated all of them)."""
    _, chain = _chain(copies=400)  # 12,000 cells
    advance(chain, 40, thin=1, progress=False)
    maps = sum(row.nbytes for row in chain.label_samples)  # S N 2 bytes: 960 kB
    tracemalloc.start()
    try:
        run = chain.to_run()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert run.label_samples.nbytes == maps
    assert peak < 0.25 * maps, (peak, maps)


def test_second_half_is_the_view_from_the_first_late_sample():
    """``samples[first:]``, the samples at sweeps ``>= sweeps // 2`` (the old boolean mask's),
    also where ``sweeps // 2`` is itself a kept sweep (it is in) or falls between two."""
    samples = np.arange(24, dtype=np.int16).reshape(6, 4)  # [S, N]
    samples.flags.writeable = False
    iterations = np.array([1, 3, 5, 7, 9, 11])  # thin 2, ascending
    for sweeps in range(0, 26):
        half = second_half(samples, iterations, sweeps)
        np.testing.assert_array_equal(half, samples[iterations >= sweeps // 2])
        assert half.base is samples or half.base is samples.base  # a view, no copy
        assert not half.flags.writeable
    assert second_half(samples, iterations, 14).shape == (3, 4)  # 7 kept: 7, 9, 11
    assert second_half(samples, iterations, 24).shape == (0, 4)  # none late
    with pytest.raises(ValueError, match="ascend"):
        second_half(samples, iterations[::-1], 12)


def test_save_writes_the_chains_stack_without_stacking_it_again(tmp_path, monkeypatch):
    """A checkpoint saved after a fit (Ctrl-C while its outputs are written) reads the stack the
    chain's rows live in: no second S N copy of the maps while they are all held."""
    data, chain = _chain()
    advance(chain, SWEEPS, thin=THIN, progress=False)
    expected = np.stack(chain.label_samples)

    def no_stack(*args, **kwargs):
        raise AssertionError("np.stack of rows that are one stack's rows already")

    with monkeypatch.context() as patch:
        patch.setattr(np, "stack", no_stack)
        stack = chain.sample_stack()
        assert _shares_every_row(stack, chain.label_samples) and not stack.flags.writeable
        save_chain(chain, tmp_path / "c.npz")
    with np.load(tmp_path / "c.npz") as saved:
        np.testing.assert_array_equal(saved["chain0.label_samples"], expected)
        assert saved["chain0.label_samples"].dtype == expected.dtype


def test_a_checkpoint_saved_before_and_after_stacking_is_the_same_file(tmp_path):
    """Rows of two advances: saved as they are, and again once sample_stack has made the chain's
    rows one stack's rows -- the same bytes (and so the same as the old np.stack's)."""
    _, chain = _chain()
    advance(chain, SWEEPS // 2, thin=THIN, progress=False)
    advance(chain, SWEEPS // 2, thin=THIN, progress=False)
    save_chain(chain, tmp_path / "before.npz")
    chain.sample_stack()
    save_chain(chain, tmp_path / "after.npz")
    assert (tmp_path / "before.npz").read_bytes() == (tmp_path / "after.npz").read_bytes()
