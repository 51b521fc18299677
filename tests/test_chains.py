"""Chains advancing side by side, on threads or in forked processes (spcopyro.gibbs.chains,
spcopyro.gibbs.chain_processes): each is, bit for bit, the chain its seed gives alone; an
interruption leaves every chain at a completed sweep with its records, from which continuing
gives the uninterrupted chain; an error in one chain stops the others and is raised."""

from __future__ import annotations

import multiprocessing
import os
import re
import signal
import sys
import threading
import time

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem

from spcopyro._util.threads import torch_threads
from spcopyro.gibbs.chain_processes import ChainProcessError, processes_usable
from spcopyro.gibbs.chains import (
    PROCESSES_ENV,
    advance_chains,
    chain_processes,
    resolve_workers,
    uses_processes,
    when_chains_start,
)
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


FORKS = sys.platform.startswith("linux")
"""Whether chains may run in forked processes here (Linux only)."""
linux_only = pytest.mark.skipif(not FORKS, reason="chains run in forked processes on Linux only")


@pytest.fixture(params=["off", "on"], ids=["threads", "processes"])
def mode(request):
    """How the chains run: on threads (``off``) or in forked processes (``on``, which needs one
    torch thread; Linux only)."""
    if request.param == "on" and not FORKS:
        pytest.skip("chains run in forked processes on Linux only")
    with torch_threads(1 if request.param == "on" else None):
        yield request.param


def _backend(name: str) -> str:
    if name == "numba":
        pytest.importorskip("numba")
    return name


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_parallel_chains_equal_the_chains_run_alone(backend, mode):
    backend = _backend(backend)
    cfg = config(num_concepts=6, gamma=1.5)
    _, data = random_problem(seed=11, copies=6)
    seeds = [3, 4, 5]
    alone = _chains(data, cfg, backend, seeds)
    for chain in alone:
        advance(chain, 12, thin=4, progress=False)
    together = _chains(data, cfg, backend, seeds)
    advance_chains(
        [(chain, 12) for chain in together], workers=2, thin=4, progress=False, processes=mode
    )
    for a, b in zip(alone, together, strict=True):
        _same(a, b)
        assert torch.equal(a.generator.get_state(), b.generator.get_state())
        assert a.best_value == b.best_value and a.sample_sweeps == b.sample_sweeps


def test_chains_with_moves_and_sampled_hyperparameters_come_back_whole(mode):
    """Everything a sweep changes comes back from a worker: the moves' draws, the sampled
    hyperparameters' trace, the model config they leave and the log joint's constant."""
    from spcopyro.gibbs.hyper_options import HyperparameterOptions

    cfg = config(num_concepts=6, gamma=1.5)
    _, data = random_problem(seed=11, copies=6)
    hyper = HyperparameterOptions(alpha=True, concentrations=True, gamma="exchange")
    options = GibbsOptions(backend="torch", merge_moves=0.3, region_moves=0.3,
                           cluster_moves=0.2, hyper=hyper)  # fmt: skip
    alone = [start_chain(data, cfg, options=options, seed=seed) for seed in (3, 4, 5)]
    for chain in alone:
        advance(chain, 10, thin=5, progress=False)
    together = [start_chain(data, cfg, options=options, seed=seed) for seed in (3, 4, 5)]
    advance_chains([(chain, 10) for chain in together], workers=2, thin=5, progress=False,
                   processes=mode)  # fmt: skip
    for a, b in zip(alone, together, strict=True):
        _same(a, b)
        ra, rb = a.to_run(), b.to_run()
        for name, values in ra.hyperparameters.items():
            np.testing.assert_array_equal(values, rb.hyperparameters[name])
        assert ra.final_config == rb.final_config and a.constant == b.constant


def test_chains_with_different_sweeps_left_each_get_theirs(mode):
    cfg = config(num_concepts=4)
    _, data = random_problem(seed=12, copies=2)
    chains = _chains(data, cfg, "torch", [0, 1, 2])
    advance(chains[1], 3, progress=False)
    runs = [(chains[0], 5), (chains[1], 2), (chains[2], 0)]
    advance_chains(runs, workers=3, progress=False, processes=mode)
    assert [c.sweeps_done for c in chains] == [5, 5, 0]


def test_the_chains_bar_says_the_first_sweeps_compile(mode, monkeypatch, capsys):
    """While numba's code is not cached yet, the bar names that over the first
    COMPILE_ITERATIONS sweeps (the merge and region moves compile a few sweeps on), with no time
    left shown from their pace (12:55:58 for a default fit of 57 s)."""
    import tqdm.auto

    import spcopyro.gibbs.chains as chains_module
    from spcopyro._util.progress import COMPILE_ITERATIONS

    cfg = config(num_concepts=4)
    _, data = random_problem(seed=12, copies=2)
    chains = _chains(data, cfg, "torch", [0, 1])
    descriptions: list[list[str]] = []
    real = tqdm.auto.tqdm

    class Recording(real):  # type: ignore[misc, valid-type]
        def __init__(self, *args, **kwargs):
            if not kwargs.get("disable"):  # each chain's own run makes a hidden one
                descriptions.append([])  # the lines it draws, the first as it is made
            super().__init__(*args, **kwargs)

        def refresh(self, *args, **kwargs):
            descriptions[-1].append(self.desc)
            return super().refresh(*args, **kwargs)

    monkeypatch.setattr(tqdm.auto, "tqdm", Recording)
    monkeypatch.setattr(chains_module, "compile_note", lambda chains: "compiling")
    capsys.readouterr()
    sweeps = COMPILE_ITERATIONS // 2 + 2  # each chain's: 4 more than the note's
    advance_chains([(c, sweeps) for c in chains], workers=2, progress=True, processes=mode)
    err = capsys.readouterr().err
    (seen,) = descriptions
    assert seen[0] == "Gibbs sweeps (compiling)" and seen[-1] == "Gibbs sweeps"
    assert set(seen) == {"Gibbs sweeps (compiling)", "Gibbs sweeps"}
    noted = [line for line in err.split("\r") if "(compiling)" in line]
    assert noted and not [line for line in noted if re.search(r"<\d", line)]
    if mode == "off":  # sweep by sweep (processes report them in batches)
        assert f"{COMPILE_ITERATIONS - 1}/{2 * sweeps}" in "".join(noted)


def _print_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"{filename}:{lineno}: {category.__name__}: {message}", file=sys.stderr)


def _advance_warning(mode: str, monkeypatch, capfd) -> tuple[list[str], str]:
    """Four chains advanced on two workers (``mode``) while every sweep warns (warnings.warn)
    and logs a warning (logger ``spcopyro``): what recorded_warnings kept, and stderr."""
    import logging
    import warnings

    import spcopyro.gibbs.run as run_module
    from spcopyro.cli.fit_warnings import recorded_warnings

    real = run_module.step

    def step(*args, **kwargs):
        warnings.warn("a sweep's own warning", RuntimeWarning, stacklevel=1)
        logging.getLogger("spcopyro.gibbs.test").warning("a sweep logged %s", "this")
        return real(*args, **kwargs)

    cfg = config(num_concepts=4)
    _, data = random_problem(seed=12, copies=2)
    chains = _chains(data, cfg, "torch", [0, 1, 2, 3])
    capfd.readouterr()
    with monkeypatch.context() as patch, warnings.catch_warnings():
        patch.setattr(run_module, "step", step)
        warnings.simplefilter("default")  # shown once per place, as outside the suite
        warnings.showwarning = _print_warning  # pytest's keeps them off stderr
        with recorded_warnings() as said:
            advance_chains([(c, 3) for c in chains], workers=2, progress=False, processes=mode)
    return said, capfd.readouterr().err


@linux_only
def test_a_chains_warnings_in_a_worker_process_are_shown_once_and_kept_as_on_threads(
    monkeypatch, capfd
):
    """A forked worker's warnings reach this process: printed once here (not once per worker)
    and kept where this thread's warnings go (`spcopyro fit`'s config.json), as on threads."""
    from collections import Counter

    from spcopyro.study.cell_warnings import warnings_text

    on_threads, threads_err = _advance_warning("off", monkeypatch, capfd)
    with torch_threads(1):
        in_processes, processes_err = _advance_warning("on", monkeypatch, capfd)
    assert on_threads[0] == "RuntimeWarning: a sweep's own warning", on_threads
    assert Counter(in_processes) == Counter(on_threads), (in_processes, on_threads)
    assert warnings_text(in_processes) == warnings_text(on_threads)
    for err in (threads_err, processes_err):
        assert err.count("a sweep's own warning") == 1, err
    logged = threads_err.count("a sweep logged this")
    assert processes_err.count("a sweep logged this") == logged, processes_err


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
def test_ctrl_c_leaves_every_chain_at_a_completed_sweep_and_continuing_is_exact(workers, mode):
    cfg = config(num_concepts=5, gamma=1.0)
    _, data = random_problem(seed=13, copies=4)
    seeds = [7, 8]
    reference = _chains(data, cfg, "torch", seeds)
    for chain in reference:
        advance(chain, 10, progress=False)
    chains = _chains(data, cfg, "torch", seeds)
    chains[1].backend = _InterruptingBackend(chains[1].backend, at=4)
    with pytest.raises(KeyboardInterrupt):
        advance_chains(
            [(chain, 10) for chain in chains], workers=workers, progress=False, processes=mode
        )
    assert chains[1].sweeps_done == 3  # the fourth sweep was undone
    for chain in chains:
        assert len(chain.log_joint) == chain.sweeps_done <= 10
    chains[1].backend = chains[1].backend.inner
    runs = [(c, 10 - c.sweeps_done) for c in chains]
    advance_chains(runs, workers=workers, progress=False, processes=mode)
    for a, b in zip(reference, chains, strict=True):
        _same(a, b)


class _SlowBackend:
    """Sleeps before each sweep; at its ``signal_at``-th sends SIGINT to the process that made
    it, as a Ctrl-C at the keyboard does (Python raises it in that process's main thread, not in
    the chain's thread or process); at its ``fail_at``-th raises ``error``."""

    def __init__(self, inner, delay: float, signal_at=None, fail_at=None, error=None) -> None:
        self.inner, self.delay, self.signal_at, self.calls = inner, delay, signal_at, 0
        self.fail_at, self.error, self.name, self.pid = fail_at, error, inner.name, os.getpid()

    def sweep(self, *args):
        self.calls += 1
        time.sleep(self.delay)
        if self.calls == self.signal_at:
            for _ in range(getattr(self, "signals", 1)):
                os.kill(self.pid, signal.SIGINT)
                time.sleep(0.05)
            time.sleep(getattr(self, "after_signals", 0.0))
        if self.calls == self.fail_at:
            if self.error is None:
                os._exit(3)  # the worker process dies
            raise self.error
        return self.inner.sweep(*args)

    def __getattr__(self, name):
        return getattr(self.inner, name)


def test_ctrl_c_at_the_keyboard_keeps_every_chains_completed_sweeps(mode, ctrl_c_raises):
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
        advance_chains(
            [(chain, sweeps) for chain in chains], workers=2, progress=False, processes=mode
        )
    assert chains[0].sweeps_done >= 3  # the chain whose 4th sweep sent the Ctrl-C
    for chain in chains:  # how far the other got is the scheduler's: 2 on a busy machine once
        assert chain.sweeps_done < sweeps
        assert len(chain.log_joint) == len(chain.num_concepts) == chain.sweeps_done
        chain.backend = chain.backend.inner
    runs = [(c, sweeps - c.sweeps_done) for c in chains]
    advance_chains(runs, workers=2, progress=False, processes=mode)
    for a, b in zip(reference, chains, strict=True):
        _same(a, b)


@linux_only
def test_a_second_ctrl_c_stops_waiting_for_the_chains_in_processes(ctrl_c_raises):
    """Two SIGINTs: the command stops waiting, ends the workers, and the chains not yet back
    stay where they were (consistent, with no sweep of this call)."""
    cfg = config(num_concepts=5, gamma=1.0)
    _, data = random_problem(seed=13, copies=4)
    chains = _chains(data, cfg, "torch", [7, 8])
    chains[0].backend = _SlowBackend(chains[0].backend, delay=0.0, signal_at=2)
    chains[0].backend.signals, chains[0].backend.after_signals = 2, 10.0  # then hangs
    chains[1].backend = _SlowBackend(chains[1].backend, delay=1.0)
    start = time.perf_counter()
    with torch_threads(1), pytest.raises(KeyboardInterrupt):
        advance_chains([(chain, 40) for chain in chains], workers=2, progress=False,
                       processes="on")  # fmt: skip
    assert time.perf_counter() - start < 5  # not the 10 s that chain 0 hangs
    assert [chain.sweeps_done for chain in chains] == [0, 0]
    assert all(not chain.log_joint for chain in chains)
    assert multiprocessing.active_children() == []


def test_a_failing_chain_stops_the_others_at_once(mode):
    """A chain's error is raised as soon as it happens: the chains before it in the list do not
    run to their end first."""
    cfg = config(num_concepts=5, gamma=1.0)
    _, data = random_problem(seed=13, copies=4)
    chains = _chains(data, cfg, "torch", [7, 8])
    chains[0].backend = _SlowBackend(chains[0].backend, delay=0.02)
    chains[1].backend = _InterruptingBackend(chains[1].backend, at=4)
    with pytest.raises(KeyboardInterrupt):
        advance_chains([(chain, 200) for chain in chains], workers=2, progress=False,
                       processes=mode)  # fmt: skip
    assert chains[0].sweeps_done < 200
    assert len(chains[0].log_joint) == chains[0].sweeps_done


def test_a_chains_error_is_raised_once_the_others_stopped(mode):
    cfg = config(num_concepts=5, gamma=1.0)
    _, data = random_problem(seed=13, copies=4)
    chains = _chains(data, cfg, "torch", [7, 8, 9])
    chains[0].backend = _SlowBackend(chains[0].backend, delay=0.02)
    chains[1].backend = _SlowBackend(chains[1].backend, delay=0.0, fail_at=3,
                                     error=ValueError("sweep 3 went wrong"))  # fmt: skip
    with pytest.raises(ValueError, match="sweep 3 went wrong") as raised:
        advance_chains([(chain, 200) for chain in chains], workers=2, progress=False,
                       processes=mode)  # fmt: skip
    assert chains[0].sweeps_done < 200 and chains[2].sweeps_done < 200
    if mode == "on":  # chain 2 waits for chain 0 on its worker, and never starts
        assert chains[2].sweeps_done == 0
    for chain in (chains[0], chains[2]):
        assert len(chain.log_joint) == chain.sweeps_done
    if mode == "on":  # the worker's traceback comes with it
        assert any("in the chain's worker process" in note for note in raised.value.__notes__)


@linux_only
def test_a_worker_process_that_dies_is_an_error_naming_its_chains():
    cfg = config(num_concepts=5, gamma=1.0)
    _, data = random_problem(seed=13, copies=4)
    chains = _chains(data, cfg, "torch", [7, 8, 9, 10])
    chains[1].backend = _SlowBackend(chains[1].backend, delay=0.0, fail_at=2)  # os._exit
    with torch_threads(1), pytest.raises(ChainProcessError) as raised:
        advance_chains([(chain, 30) for chain in chains], workers=2, progress=False,
                       processes="on")  # fmt: skip
    assert "chains [1, 3]" in str(raised.value) and "exit code 3" in str(raised.value)
    assert chains[1].sweeps_done == chains[3].sweeps_done == 0  # where they were
    for chain in (chains[0], chains[2]):  # the other worker's: stopped with their records
        assert len(chain.log_joint) == chain.sweeps_done


def test_every_sweep_is_reported_and_the_start_action_runs_once_the_workers_are_forked(mode):
    cfg = config(num_concepts=4)
    _, data = random_problem(seed=12, copies=2)
    chains = _chains(data, cfg, "torch", [0, 1, 2])
    reported: list[int] = []
    started: list[int] = []

    def action() -> None:  # in processes, the workers exist by now
        started.append(len(multiprocessing.active_children()))

    with when_chains_start(action):
        advance_chains([(c, 7) for c in chains], workers=2, progress=False, processes=mode,
                       on_sweep=lambda: reported.append(1))  # fmt: skip
        advance_chains([(c, 2) for c in chains], workers=2, progress=False, processes=mode)
    assert len(reported) == 21
    assert started == ([2] if mode == "on" else [0])  # once, for the first advance
    with when_chains_start(action):
        advance_chains([(chains[0], 0)], workers=2, progress=False)  # no sweep: not called
    assert len(started) == 1


def test_fit_names_a_bad_chain_processes_mode_before_it_prints_anything(
    monkeypatch, tmp_path, capsys
):
    from spcopyro.cli.main import main

    monkeypatch.setenv(PROCESSES_ENV, "sometimes")
    assert main(["fit", "--out", str(tmp_path / "out"), "--sweeps", "2", "--no-figures"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "$SPCOPYRO_CHAIN_PROCESSES must be one of" in captured.err


def test_processes_are_used_only_where_forking_is_safe(monkeypatch):
    monkeypatch.delenv(PROCESSES_ENV, raising=False)
    if not FORKS:
        assert "forking is not used" in processes_usable() and not uses_processes(2)
        return
    with torch_threads(1):
        assert processes_usable() is None  # the suite's process runs no other thread
        assert uses_processes(2) and uses_processes(2, "on")
        assert not uses_processes(1) and not uses_processes(2, "off")
        monkeypatch.setenv(PROCESSES_ENV, "off")
        assert not uses_processes(2)
        monkeypatch.setenv(PROCESSES_ENV, "sometimes")
        with pytest.raises(ValueError, match=r"\$SPCOPYRO_CHAIN_PROCESSES must be one of auto"):
            chain_processes()
        monkeypatch.delenv(PROCESSES_ENV)
        with pytest.raises(ValueError, match="processes must be one of"):
            uses_processes(2, "yes")
        release = threading.Event()
        other = threading.Thread(target=release.wait, name="someone-else", daemon=True)
        other.start()
        try:
            assert not uses_processes(2)
            with pytest.raises(ValueError, match=r"other threads are running \(someone-else\)"):
                uses_processes(2, "on")
        finally:
            release.set()
            other.join()
    with torch_threads(2):
        assert not uses_processes(2)
        with pytest.raises(ValueError, match="torch runs 2 intra-op threads"):
            uses_processes(2, "on")


def test_workers_resolve_to_at_most_one_per_chain():
    assert resolve_workers(8, 3) == 3
    assert resolve_workers(1, 3) == 1
    assert 1 <= resolve_workers("auto", 4) <= 4
    for bad in (0, -1, "two", 1.5, True):
        with pytest.raises(ValueError, match="chain workers"):
            resolve_workers(bad, 2)


def test_fit_with_parallel_chains_gives_the_sequential_fit(monkeypatch):
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house_chains
    from spcopyro.synthetic import HouseSpec, make_house

    house = make_house(seed=2, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=1))
    settings = preset("paper-dp", num_concepts=8)
    kwargs = dict(sweeps=6, seeds=[0, 1, 2], progress=False)
    one = fit_house_chains(house, settings, chain_workers=1, **kwargs)
    for mode in ("off", "on") if FORKS else ("off",):  # threads, processes (one torch thread)
        monkeypatch.setenv(PROCESSES_ENV, mode)
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
