"""Chains advancing side by side on threads (spcopyro.gibbs.chains): each is, bit for bit, the
chain its seed gives alone; an interruption leaves every chain at a completed sweep, from which
continuing gives the uninterrupted chain."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem

from spcopyro.gibbs.chains import advance_chains, resolve_workers
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import advance, start_chain


def _chains(data, cfg, backend, seeds):
    options = GibbsOptions(backend=backend)
    return [start_chain(data, cfg, options=options, seed=seed) for seed in seeds]


def _same(a, b) -> None:
    ra, rb = a.to_run(), b.to_run()
    torch.testing.assert_close(ra.final_state.labels, rb.final_state.labels, rtol=0, atol=0)
    torch.testing.assert_close(ra.final_state.log_pi, rb.final_state.log_pi, rtol=0, atol=0)
    np.testing.assert_array_equal(ra.log_joint, rb.log_joint)
    assert ra.best_sweep == rb.best_sweep
    if ra.label_samples is not None:
        np.testing.assert_array_equal(ra.label_samples, rb.label_samples)


def _backend(name: str) -> str:
    if name == "numba":
        pytest.importorskip("numba")
    return name


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_parallel_chains_equal_the_chains_run_alone(backend):
    backend = _backend(backend)
    cfg = config(num_concepts=6, gamma=1.5)
    _, data = random_problem(seed=11, copies=6)
    seeds = [3, 4, 5]
    alone = _chains(data, cfg, backend, seeds)
    for chain in alone:
        advance(chain, 12, thin=4, progress=False)
    together = _chains(data, cfg, backend, seeds)
    advance_chains([(chain, 12) for chain in together], workers=2, thin=4, progress=False)
    for a, b in zip(alone, together, strict=True):
        _same(a, b)


def test_chains_with_different_sweeps_left_each_get_theirs():
    cfg = config(num_concepts=4)
    _, data = random_problem(seed=12, copies=2)
    chains = _chains(data, cfg, "torch", [0, 1, 2])
    advance(chains[1], 3, progress=False)
    advance_chains([(chains[0], 5), (chains[1], 2), (chains[2], 0)], workers=3, progress=False)
    assert [c.sweeps_done for c in chains] == [5, 5, 0]


class _InterruptingBackend:
    """Raises KeyboardInterrupt at the ``at``-th sweep of the chain it belongs to."""

    def __init__(self, inner, at: int) -> None:
        self.inner, self.at, self.calls, self.name = inner, at, 0, inner.name

    def sweep(self, *args):
        self.calls += 1
        if self.calls == self.at:
            raise KeyboardInterrupt
        return self.inner.sweep(*args)

    def __getattr__(self, name):
        return getattr(self.inner, name)


@pytest.mark.parametrize("workers", [1, 2])
def test_ctrl_c_leaves_every_chain_at_a_completed_sweep_and_continuing_is_exact(workers):
    cfg = config(num_concepts=5, gamma=1.0)
    _, data = random_problem(seed=13, copies=4)
    seeds = [7, 8]
    reference = _chains(data, cfg, "torch", seeds)
    for chain in reference:
        advance(chain, 10, progress=False)
    chains = _chains(data, cfg, "torch", seeds)
    chains[1].backend = _InterruptingBackend(chains[1].backend, at=4)
    with pytest.raises(KeyboardInterrupt):
        advance_chains([(chain, 10) for chain in chains], workers=workers, progress=False)
    assert chains[1].sweeps_done == 3  # the fourth sweep was undone
    for chain in chains:
        assert len(chain.log_joint) == chain.sweeps_done <= 10
    chains[1].backend = chains[1].backend.inner
    advance_chains([(c, 10 - c.sweeps_done) for c in chains], workers=workers, progress=False)
    for a, b in zip(reference, chains, strict=True):
        _same(a, b)


class _SlowBackend:
    """Sleeps before each sweep; at its ``signal_at``-th sends SIGINT to the process, as a
    Ctrl-C at the keyboard does (Python raises it in the main thread, not in the chain's)."""

    def __init__(self, inner, delay: float, signal_at: int | None = None) -> None:
        self.inner, self.delay, self.signal_at, self.calls = inner, delay, signal_at, 0
        self.name = inner.name

    def sweep(self, *args):
        self.calls += 1
        time.sleep(self.delay)
        if self.calls == self.signal_at:
            os.kill(os.getpid(), signal.SIGINT)
        return self.inner.sweep(*args)

    def __getattr__(self, name):
        return getattr(self.inner, name)


def test_ctrl_c_at_the_keyboard_keeps_every_chains_completed_sweeps():
    """The chains on worker threads stop at their next completed sweep *with its record*: the
    records (log joint, concepts) match the sweeps done, and continuing is exact."""
    cfg = config(num_concepts=5, gamma=1.0)
    _, data = random_problem(seed=13, copies=4)
    seeds, sweeps = [7, 8], 40
    reference = _chains(data, cfg, "torch", seeds)
    for chain in reference:
        advance(chain, sweeps, progress=False)
    chains = _chains(data, cfg, "torch", seeds)
    chains[0].backend = _SlowBackend(chains[0].backend, delay=0.02, signal_at=4)
    chains[1].backend = _SlowBackend(chains[1].backend, delay=0.02)
    with pytest.raises(KeyboardInterrupt):
        advance_chains([(chain, sweeps) for chain in chains], workers=2, progress=False)
    for chain in chains:
        assert 3 <= chain.sweeps_done < sweeps
        assert len(chain.log_joint) == len(chain.num_concepts) == chain.sweeps_done
        chain.backend = chain.backend.inner
    advance_chains([(c, sweeps - c.sweeps_done) for c in chains], workers=2, progress=False)
    for a, b in zip(reference, chains, strict=True):
        _same(a, b)


def test_a_failing_chain_stops_the_others_at_once():
    """A chain's error is raised as soon as it happens: the chains before it in the list do not
    run to their end first."""
    cfg = config(num_concepts=5, gamma=1.0)
    _, data = random_problem(seed=13, copies=4)
    chains = _chains(data, cfg, "torch", [7, 8])
    chains[0].backend = _SlowBackend(chains[0].backend, delay=0.02)
    chains[1].backend = _InterruptingBackend(chains[1].backend, at=4)
    with pytest.raises(KeyboardInterrupt):
        advance_chains([(chain, 200) for chain in chains], workers=2, progress=False)
    assert chains[0].sweeps_done < 200
    assert len(chains[0].log_joint) == chains[0].sweeps_done


def test_workers_resolve_to_at_most_one_per_chain():
    assert resolve_workers(8, 3) == 3
    assert resolve_workers(1, 3) == 1
    assert 1 <= resolve_workers("auto", 4) <= 4
    for bad in (0, -1, "two", 1.5, True):
        with pytest.raises(ValueError, match="chain workers"):
            resolve_workers(bad, 2)


def test_fit_with_parallel_chains_gives_the_sequential_fit():
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house_chains
    from spcopyro.synthetic import HouseSpec, make_house

    house = make_house(seed=2, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=1))
    settings = preset("paper-dp", num_concepts=8)
    kwargs = dict(sweeps=6, seeds=[0, 1, 2], progress=False)
    one = fit_house_chains(house, settings, chain_workers=1, **kwargs)
    two = fit_house_chains(house, settings, chain_workers=2, **kwargs)
    for a, b in zip(one, two, strict=True):
        np.testing.assert_array_equal(a.labels, b.labels)
        np.testing.assert_array_equal(a.trace.objective, b.trace.objective)


def test_fit_command_line_chain_workers_option(capsys):
    from spcopyro.cli.main import build_parser

    parse = build_parser().parse_args
    assert parse(["fit", "--out", "x"]).chain_workers == "auto"
    assert parse(["fit", "--out", "x", "--chain-workers", "3"]).chain_workers == 3
    for bad in ("0", "-1", "two", "1.5"):
        with pytest.raises(SystemExit):
            parse(["fit", "--out", "x", "--chain-workers", bad])
        assert "argument --chain-workers: must be 'auto' or an integer >= 1" in (
            capsys.readouterr().err
        )
