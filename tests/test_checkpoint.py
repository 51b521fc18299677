"""Ctrl-C and resuming: a chain stops at its last completed sweep, is saved
(:mod:`spcopyro.gibbs.checkpoint`) and continues exactly; ``spcopyro fit`` keeps a checkpoint
beside OUT, exits with 130, and ``--resume`` gives what a fit that never stopped gives."""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch
from fit_interrupts import interrupt_fit_at, interrupted
from gibbs_problems import config, random_problem

import spcopyro.fit.house
import spcopyro.gibbs.chains
import spcopyro.gibbs.run
import spcopyro.inference.driver as driver_module
from spcopyro._util.outputs import StagedOutput, checkpoint_path
from spcopyro.cli.main import main
from spcopyro.gibbs.checkpoint import (
    data_fingerprint,
    load_chain,
    load_chains,
    read_record,
    save_chain,
    save_chains,
)
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import GibbsRun, advance, run_gibbs, start_chain
from spcopyro.guides.checkpoint import is_variational_checkpoint

FIT = ["--sweeps", "12", "--preset", "original-code", "--gamma", "3", "--concepts", "8",
       "--anneal-sweeps", "3", "--cluster-moves", "0.3"]  # fmt: skip


def _options(backend) -> GibbsOptions:
    return GibbsOptions(backend=backend.name, cluster_moves=0.5, unobserved_refresh=0.5,
                        anneal_sweeps=3)  # fmt: skip


def _assert_same_run(mine: GibbsRun, theirs: GibbsRun) -> None:
    for a, b in ((mine.final_state, theirs.final_state), (mine.best_state, theirs.best_state)):
        assert torch.equal(a.labels, b.labels)  # [N]
        assert torch.equal(a.log_pi, b.log_pi)  # [L]
        for x, y in zip(a.log_emissions, b.log_emissions, strict=True):
            assert torch.equal(x, y)  # [L, K_m]
    np.testing.assert_array_equal(mine.log_joint, theirs.log_joint)  # [S]
    np.testing.assert_array_equal(mine.num_concepts, theirs.num_concepts)  # [S]
    np.testing.assert_array_equal(mine.label_samples, theirs.label_samples)  # [S', N]
    np.testing.assert_array_equal(mine.sample_sweeps, theirs.sample_sweeps)
    assert mine.best_sweep == theirs.best_sweep and mine.backend == theirs.backend
    assert len(mine.seconds) == len(theirs.seconds) and np.all(np.diff(mine.seconds) >= 0)


# -- the run loop and the checkpoint file ------------------------------------------------------


def test_a_chain_interrupted_saved_and_loaded_continues_exactly(backend, tmp_path):
    """Ctrl-C through the run loop's callback after sweep 8 (of 20): the chain holds 9 sweeps;
    saved, loaded and advanced to 20 it is run_gibbs(20) bit for bit, best state and thinned maps
    included."""
    cfg = config()
    _, data = random_problem(seed=7)
    options = _options(backend)
    whole = run_gibbs(data, cfg, 20, options=options, seed=4, thin=3, progress=False)

    def stop_after_8(sweep, state):
        if sweep == 8:
            raise KeyboardInterrupt

    chain = start_chain(data, cfg, options=options, seed=4)
    with pytest.raises(KeyboardInterrupt):
        advance(chain, 20, thin=3, progress=False, callback=stop_after_8)
    assert chain.sweeps_done == 9 and len(chain.log_joint) == 9
    path = save_chain(chain, tmp_path / "c.checkpoint.npz", record={"note": "x"})
    resumed = load_chain(path, data, cfg, options, record={"note": "x"})
    assert resumed.sweeps_done == 9 and resumed.generator is not chain.generator
    advance(resumed, 11, thin=3, progress=False)
    _assert_same_run(resumed.to_run(), whole)
    record = read_record(path)
    assert "not a result" in record["what"] and record["chains"] == [
        {"sweeps_done": 9, "best_sweep": chain.best_sweep}
    ]


class _Interrupting:
    """A backend that raises KeyboardInterrupt in the middle of its ``at``-th call of ``method``
    (after drawing from the generator, where the method draws)."""

    def __init__(self, backend, method: str, at: int) -> None:
        self.inner, self.method, self.at, self.calls = backend, method, at, 0
        self.name = backend.name

    def _maybe_stop(self, method: str) -> None:
        if method == self.method:
            self.calls += 1
            if self.calls == self.at:
                raise KeyboardInterrupt

    def sweep(self, state, data, config, generator, plan, refresh):
        new = self.inner.sweep(state, data, config, generator, plan, refresh)
        self._maybe_stop("sweep")
        return new

    def trace(self, state, data, config):
        self._maybe_stop("trace")
        return self.inner.trace(state, data, config)

    def __getattr__(self, name):  # the rest as the backend's
        return getattr(self.inner, name)


class _Clock:
    """``time`` for the run loop whose ``perf_counter`` raises KeyboardInterrupt at call
    ``at`` (call 1 is advance's start; call 2 comes after the first sweep's log joint and
    number of concepts were appended)."""

    def __init__(self, at: int) -> None:
        self.at, self.calls = at, 0

    def perf_counter(self) -> float:
        self.calls += 1
        if self.calls == self.at:
            raise KeyboardInterrupt
        return time.perf_counter()


@pytest.mark.parametrize("where", ["sweep", "trace", "records"])
def test_an_interrupt_inside_a_sweep_is_undone(backend, where, monkeypatch):
    """Ctrl-C in sweep 6 after it drew its random numbers (in the backend's sweep), after the
    new state was taken (in the trace's log joint), or after part of the trace was appended: the
    chain is back at 5 sweeps, generator included, and continues exactly."""
    cfg = config()
    _, data = random_problem(seed=3)
    options = _options(backend)
    whole = run_gibbs(data, cfg, 14, options=options, seed=2, thin=2, progress=False)
    chain = start_chain(data, cfg, options=options, seed=2)
    advance(chain, 5, thin=2, progress=False)
    generator_state = chain.generator.get_state()
    labels, best, samples = chain.state.labels, chain.best_sweep, len(chain.label_samples)
    real = chain.backend
    if where == "records":
        monkeypatch.setattr(driver_module, "time", _Clock(at=2))
    else:
        chain.backend = _Interrupting(real, where, at=1)
    with pytest.raises(KeyboardInterrupt):
        advance(chain, 9, thin=2, progress=False)
    monkeypatch.setattr(driver_module, "time", time)
    chain.backend = real
    assert chain.sweeps_done == 5
    assert len(chain.log_joint) == len(chain.num_concepts) == len(chain.seconds) == 5
    assert torch.equal(chain.generator.get_state(), generator_state)
    assert chain.state.labels is labels and chain.best_sweep == best
    assert len(chain.label_samples) == len(chain.sample_sweeps) == samples
    advance(chain, 9, thin=2, progress=False)
    _assert_same_run(chain.to_run(), whole)


def test_a_checkpoint_refuses_other_data_settings_and_backend(tmp_path):
    cfg = config()
    _, data = random_problem(seed=7)
    torch_options = GibbsOptions(backend="torch")
    chain = advance(start_chain(data, cfg, options=torch_options, seed=1), 3, progress=False)
    path = save_chain(chain, tmp_path / "c.npz", record={"sweeps": 10})
    _, other_data = random_problem(seed=8)
    with pytest.raises(ValueError, match="other data or settings: the data differ"):
        load_chain(path, other_data, cfg, torch_options)
    with pytest.raises(ValueError, match=r"gamma: 0\.9 in the checkpoint, 2\.0 here"):
        load_chain(path, data, cfg.replace(gamma=2.0), torch_options)
    with pytest.raises(ValueError, match="cluster_moves: 0.0 in the checkpoint, 0.5 here"):
        load_chain(path, data, cfg, torch_options.replace(cluster_moves=0.5))
    with pytest.raises(ValueError, match="sweeps: 10 in the checkpoint, 20 here"):
        load_chain(path, data, cfg, torch_options, record={"sweeps": 20})
    pytest.importorskip("numba")
    said = r"'torch' ran the checkpoint's chains.*pass backend='torch' \(fit's --backend torch\)"
    with pytest.raises(ValueError, match=said):
        load_chain(path, data, cfg, GibbsOptions(backend="numba"))
    assert data_fingerprint(data) == data_fingerprint(random_problem(seed=7)[1])


def test_a_variational_checkpoint_refuses_a_gibbs_one_and_other_data(tmp_path):
    """load_variational reads the record as load_chain does (one reader): a Gibbs checkpoint is
    not a variational one, and other data are named."""
    from spcopyro.gibbs.run import SweepInfo
    from spcopyro.guides.checkpoint import load_variational, save_variational
    from spcopyro.inference.driver import drive

    cfg = config()
    _, data = random_problem(seed=7)
    chain = advance(start_chain(data, cfg, seed=1), 2, progress=False)
    gibbs = save_chain(chain, tmp_path / "gibbs.npz")
    kwargs = dict(method="cavi", options=None)
    with pytest.raises(ValueError, match="interrupted 'gibbs' fit.*--method gibbs"):
        load_variational(gibbs, data, cfg, **kwargs)
    assert not is_variational_checkpoint(gibbs)
    record = drive(0, lambda s, g: (s + 1, SweepInfo(-1.0, 1, g)), 2, gamma=cfg.gamma,
                   progress=False)  # fmt: skip
    q = torch.full((data.num_free, cfg.num_concepts), 1.0 / cfg.num_concepts)
    path = save_variational(tmp_path / "q.npz", q, record, config=cfg, data=data, **kwargs)
    assert is_variational_checkpoint(path)
    _, other_data = random_problem(seed=8)
    with pytest.raises(ValueError, match="other data or settings: the data differ"):
        load_variational(path, other_data, cfg, **kwargs)
    with pytest.raises(ValueError, match="method: 'cavi' in the checkpoint, 'lbp' here"):
        load_variational(path, data, cfg, method="lbp", options=None)
    resumed = load_variational(path, data, cfg, **kwargs)
    assert torch.equal(resumed.marginals, q.double())
    np.testing.assert_array_equal(resumed.trajectory.objective, record.objective)


def test_a_variational_checkpoint_names_the_backend_that_ran_not_auto(tmp_path):
    """A cavi fit run with backend auto (numba, where it imports) was refused on resume with
    backend=numba ('backend: auto in the checkpoint, numba here'), the backend that had run."""
    from spcopyro.gibbs.run import SweepInfo
    from spcopyro.guides.checkpoint import load_variational, save_variational
    from spcopyro.guides.options import VariationalOptions
    from spcopyro.guides.run import resolve_backend
    from spcopyro.inference.driver import drive

    ran = resolve_backend("auto")  # numba where it imports, else torch
    other = "torch" if ran == "numba" else "numba"
    cfg = config()
    _, data = random_problem(seed=7)
    record = drive(0, lambda s, g: (s + 1, SweepInfo(-1.0, 1, g)), 2, gamma=cfg.gamma,
                   progress=False)  # fmt: skip
    q = torch.full((data.num_free, cfg.num_concepts), 1.0 / cfg.num_concepts)
    auto = VariationalOptions(backend="auto")
    path = save_variational(tmp_path / "q.npz", q, record, config=cfg, data=data, method="cavi",
                            options=auto)  # fmt: skip
    for options in (auto, VariationalOptions(backend=ran)):
        load_variational(path, data, cfg, method="cavi", options=options)
    with pytest.raises(ValueError, match=rf"backend: '{ran}' in the checkpoint, '{other}' here"):
        load_variational(path, data, cfg, method="cavi", options=VariationalOptions(backend=other))


def test_an_lbp_checkpoint_names_the_backend_auto_ran_at_a_large_coupling(tmp_path):
    """LBP's auto runs torch where gamma D > 300 (numba's products would overflow); its
    checkpoint named numba (CAVI's auto), so resuming with backend=torch, the backend that ran,
    was refused ('numba' in the checkpoint, 'torch' here) and backend=numba accepted."""
    from spcopyro.gibbs.run import SweepInfo
    from spcopyro.guides.checkpoint import load_variational, save_variational
    from spcopyro.guides.lbp_method import LBPOptions, resolve_lbp_backend
    from spcopyro.inference.driver import drive

    cfg = config(gamma=100.0)
    _, data = random_problem(seed=7)
    assert resolve_lbp_backend(LBPOptions(), data, cfg) == "torch"
    record = drive(0, lambda s, g: (s + 1, SweepInfo(-1.0, 1, g)), 2, gamma=cfg.gamma,
                   progress=False)  # fmt: skip
    q = torch.full((data.num_free, cfg.num_concepts), 1.0 / cfg.num_concepts)
    path = save_variational(tmp_path / "q.npz", q, record, config=cfg, data=data, method="lbp",
                            options=LBPOptions())  # fmt: skip
    for options in (LBPOptions(), LBPOptions(backend="torch")):
        load_variational(path, data, cfg, method="lbp", options=options)
    with pytest.raises(ValueError, match="backend: 'torch' in the checkpoint, 'numba' here"):
        load_variational(path, data, cfg, method="lbp", options=LBPOptions(backend="numba"))


def test_a_file_that_is_no_checkpoint_is_refused(tmp_path):
    cfg = config()
    _, data = random_problem(seed=7)
    np.savez(tmp_path / "other.npz", labels=np.zeros(3))
    with pytest.raises(ValueError, match="not a spcopyro checkpoint"):
        load_chain(tmp_path / "other.npz", data, cfg)
    (tmp_path / "text.npz").write_text("hello")
    with pytest.raises(ValueError, match="not a spcopyro checkpoint"):
        load_chain(tmp_path / "text.npz", data, cfg)
    with pytest.raises(FileNotFoundError, match="no such checkpoint"):
        load_chain(tmp_path / "missing.npz", data, cfg)


def test_resume_of_out_or_a_folder_names_the_checkpoint_beside_it(home, tmp_path, capsys):
    out = tmp_path / "out"
    checkpoint = checkpoint_path(out)

    def refusal() -> str:
        assert main(["fit", str(home), "--out", str(out), *FIT, "--resume", str(out)]) == 2
        return capsys.readouterr().err

    assert "no such checkpoint file: a fit stopped by Ctrl-C keeps its state in" in refusal()
    checkpoint.write_bytes(b"")  # an interrupted fit into OUT leaves only OUT.checkpoint.npz
    kept = f"the fit interrupted into it kept its state in {checkpoint}"
    assert f"no such checkpoint file: {kept}; --resume {checkpoint}" in refusal()
    out.mkdir()
    assert f"is a folder, not a checkpoint file: {kept}" in refusal()
    (out / "result.npz").write_bytes(b"")
    finished = "is a finished fit, not a checkpoint: to continue it with new observations use"
    assert f"{finished} --update {out}" in refusal()


def test_chains_not_started_are_saved_as_such(tmp_path):
    cfg = config()
    _, data = random_problem(seed=7)
    options = GibbsOptions(backend="torch")
    chain = advance(start_chain(data, cfg, options=options, seed=1), 2, progress=False)
    path = save_chains([chain, None], tmp_path / "c.npz")
    first, second = load_chains(path, data, cfg, options)
    assert first.sweeps_done == 2 and second is None
    with pytest.raises(ValueError, match="holds 2 chains, not one"):
        load_chain(path, data, cfg, options)
    with pytest.raises(ValueError, match="at least one started chain"):
        save_chains([None], tmp_path / "d.npz")


def test_checkpoints_are_written_by_write_npz(monkeypatch, tmp_path):
    """A checkpoint's [N, L] marginals or [K, N] label samples are written on Ctrl-C while the
    user waits: through _util.npz.write_npz (level 1 for large arrays), not np.savez_compressed
    (level 6: 3.9-4.1 s against 2.3 s of CPU for a 2.9-million-cell map's result.npz); np.load
    reads them."""
    from spcopyro._util import npz
    from spcopyro.gibbs.run import SweepInfo
    from spcopyro.guides.checkpoint import load_variational, save_variational
    from spcopyro.inference.driver import drive

    written: list[str] = []
    write_member = npz._write_member

    def spy(archive, name, array):
        written.append(name)
        write_member(archive, name, array)

    monkeypatch.setattr(npz, "_write_member", spy)
    cfg = config()
    _, data = random_problem(seed=7)
    chain = advance(start_chain(data, cfg, seed=1), 2, progress=False)
    gibbs = save_chains([chain], tmp_path / "gibbs.npz")
    with np.load(gibbs) as loaded:
        assert written == loaded.files and "chain0.labels" in written
    assert load_chain(gibbs, data, cfg, chain.options).sweeps_done == 2
    written.clear()
    record = drive(0, lambda s, g: (s + 1, SweepInfo(-1.0, 1, g)), 2, gamma=cfg.gamma,
                   progress=False)  # fmt: skip
    q = torch.full((data.num_free, cfg.num_concepts), 1.0 / cfg.num_concepts)
    path = save_variational(tmp_path / "q.npz", q, record, config=cfg, data=data, method="cavi",
                            options=None)  # fmt: skip
    with np.load(path) as loaded:
        assert written == loaded.files and "marginals" in written
    resumed = load_variational(path, data, cfg, method="cavi", options=None)
    assert torch.equal(resumed.marginals, q.double())


# -- spcopyro fit: Ctrl-C and --resume -----------------------------------------------------------


@pytest.fixture(autouse=True)
def _no_progress_bars(monkeypatch):
    monkeypatch.setenv("CI", "1")  # stderr holds only what the command says


def _same_outputs(mine, theirs) -> None:
    """Two fit folders hold the same result (wall-clock seconds aside)."""
    with np.load(mine / "result.npz") as a, np.load(theirs / "result.npz") as b:  # closed
        assert set(a.files) == set(b.files)
        for name in a.files:
            if name != "seconds":
                np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    np.testing.assert_array_equal(np.load(mine / "labels.npy"), np.load(theirs / "labels.npy"))


@pytest.mark.parametrize(("chains", "chain", "sweep"), [(1, 0, 6), (2, 0, 4), (2, 1, 8)])
def test_ctrl_c_keeps_a_checkpoint_and_resume_gives_the_unbroken_fit(
    home, tmp_path, capsys, monkeypatch, chains, chain, sweep
):
    out = tmp_path / "out"
    # One chain after another, so that chain k's interruption leaves those after it unstarted
    # (test_chains.py interrupts chains advancing side by side).
    argv = ["fit", str(home), "--out", str(out), *FIT, "--chains", str(chains),
            "--chain-workers", "1"]  # fmt: skip
    with monkeypatch.context() as patch:
        interrupt_fit_at(patch, chain, sweep)
        assert main(argv) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("interrupted (")  # one line, no traceback
    assert f"chain {chain + 1} of {chains}, {sweep + 1} of 12 sweeps done" in err
    checkpoint = checkpoint_path(out)
    assert f"saved in {checkpoint}" in err
    assert {p.name for p in tmp_path.iterdir()} == {checkpoint.name}  # no OUT, no staging
    record = read_record(checkpoint)
    assert [c and c["sweeps_done"] for c in record["chains"]] == (
        [sweep + 1] if chains == 1 else [12, sweep + 1] if chain == 1 else [sweep + 1, 0]
    )  # every chain is started (its sweep 0 saved) before any advances
    assert record["caller"]["seeds"] == list(range(chains))

    again = shlex.split(err.split("continue with: ")[1])
    assert again[0] == "spcopyro" and again[-2:] == ["--resume", str(checkpoint)]
    asked: list[tuple[int, int]] = []  # (sweeps done, sweeps asked) of each chain advanced

    def recording_advance(gibbs_chain, num_sweeps, **kwargs):
        asked.append((gibbs_chain.sweeps_done, num_sweeps))
        return advance(gibbs_chain, num_sweeps, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.gibbs.chains, "advance", recording_advance)
        assert main(again[1:]) == 0
    assert asked[0] == (sweep + 1, 11 - sweep)  # the interrupted chain goes on where it stopped
    assert asked[1:] == ([(0, 12)] if chains == 2 and chain == 0 else [])  # then any not begun
    assert f"removed {checkpoint}" in capsys.readouterr().out
    assert not checkpoint.exists()
    assert main(["fit", str(home), "--out", str(tmp_path / "unbroken"), *FIT, "--chains",
                 str(chains)]) == 0  # fmt: skip
    _same_outputs(out, tmp_path / "unbroken")
    # config.json's command runs the fit again: not with the checkpoint, removed once written
    config = json.loads((out / "config.json").read_text())
    assert config["command"] == shlex.join(["spcopyro", *argv])
    assert config["resumed_from"] == str(checkpoint)
    assert "resumed_from" not in json.loads((tmp_path / "unbroken" / "config.json").read_text())


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forked chains: Linux only")
def test_ctrl_c_at_the_keyboard_with_chains_in_processes_resumes_to_the_unbroken_fit(
    home, tmp_path, capsys, monkeypatch, ctrl_c_raises
):
    """``fit --chains 2`` with its chains in forked processes: a SIGINT to the command (what a
    Ctrl-C at the keyboard sends; the workers ignore theirs) stops both chains after their
    sweep, saves them with their records, and ``--resume`` gives the unbroken fit."""
    monkeypatch.setenv(spcopyro.gibbs.chains.PROCESSES_ENV, "on")
    command, sweep = os.getpid(), spcopyro.gibbs.run._sweep

    def slow_sweep(chain):  # looked up at each sweep, so the forked workers run it too
        # 0.5 s a sweep once the SIGINT is sent: 0.05 s left the command 0.35 s to pass the stop
        # on before chain 0 ran its 12 sweeps, which a busy machine (the whole suite) exceeded
        time.sleep(0.05 if chain.sweeps_done < 5 else 0.5)
        info = sweep(chain)
        if chain.generator.initial_seed() == 0 and chain.sweeps_done == 5:
            os.kill(command, signal.SIGINT)
        return info

    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT, "--chains", "2", "--chain-workers", "2"]
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.gibbs.run, "_sweep", slow_sweep)
        assert main(argv) == 130
    err = capsys.readouterr().err
    assert err.startswith("interrupted (") and err.count("\n") == 1
    checkpoint = checkpoint_path(out)
    done = [chain["sweeps_done"] for chain in read_record(checkpoint)["chains"]]
    assert 5 <= done[0] < 12 and 1 <= done[1] < 12
    with np.load(checkpoint) as saved:  # each chain's records match its sweeps
        for k in range(2):
            assert len(saved[f"chain{k}.log_joint"]) == len(saved[f"chain{k}.num_concepts"])
            assert len(saved[f"chain{k}.log_joint"]) == done[k]
    again = shlex.split(err.split("continue with: ")[1])
    assert main(again[1:]) == 0
    assert main(["fit", str(home), "--out", str(tmp_path / "unbroken"), *FIT, "--chains", "2",
                 "--chain-workers", "1"]) == 0  # fmt: skip
    _same_outputs(out, tmp_path / "unbroken")


def test_the_printed_resume_command_works_for_a_default_fit(home, tmp_path, capsys, monkeypatch):
    """Issue 22 item 6: the default preset starts from the rooms; --resume used to force a
    random start and fail ("init: 'rooms' in the checkpoint, 'random' here")."""
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), "--sweeps", "12", "--no-figures"]
    with monkeypatch.context() as patch:
        interrupt_fit_at(patch, 0, 5)
        assert main(argv) == 130
    err = capsys.readouterr().err
    again = shlex.split(err.split("continue with: ")[1])
    assert main(again[1:]) == 0, capsys.readouterr().err
    assert main([*argv[:3], str(tmp_path / "unbroken"), *argv[4:]]) == 0
    _same_outputs(out, tmp_path / "unbroken")


def _interrupt_cavi_at(monkeypatch, call: int) -> None:
    """Make CAVI's torch step raise KeyboardInterrupt at its ``call``-th call."""
    import spcopyro.guides.cavi as cavi

    calls: list[int] = []
    real = cavi.step

    def interrupting(state, *args, **kwargs):
        calls.append(1)
        if len(calls) == call:
            raise KeyboardInterrupt
        return real(state, *args, **kwargs)

    monkeypatch.setattr(cavi, "step", interrupting)


def _variational_argv(home, out, method: str) -> list[str]:
    prefix = "" if method == "cavi" else "variational."
    sampler = FIT if method == "vi-gibbs" else FIT[:8]  # cavi refuses the Gibbs flags
    return ["fit", str(home), "--out", str(out), *sampler, "--method", method, "--method-option",
            f"{prefix}backend=torch", "--method-option", f"{prefix}tolerance=0"]  # fmt: skip


def test_ctrl_c_in_a_vi_gibbs_fit_says_how_far_it_got(home, tmp_path, capsys, monkeypatch):
    """The driver's record of an interrupted run reaches the command's one line: which fit,
    how many iterations were done (vi-gibbs: its VI stage, through the same driver)."""
    _interrupt_cavi_at(monkeypatch, 4)
    out = tmp_path / "out"
    assert main(_variational_argv(home, out, "vi-gibbs")) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(
        "interrupted (vi-gibbs fit 1 of 1, in its CAVI start, 3 of at most 100 iterations done)"
    )
    assert "no checkpoint kept (the 'vi-gibbs' method)" in err and not out.exists()
    assert main([*_variational_argv(home, out, "vi-gibbs"), "--resume", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "one fit (--chains 1) of cavi" in err and "--method vi-gibbs keeps no checkpoint" in err


def test_resume_with_several_variational_fits_names_chains(home, tmp_path, capsys):
    """--resume with --chains 2 of a method that resumes one fit: the refusal named "--sweeps N
    --method cavi" as what keeps no checkpoint, which does keep one; the --chains is why."""
    argv = _variational_argv(home, tmp_path / "out", "cavi")
    assert main([*argv, "--chains", "2", "--resume", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err
    assert "; --method cavi --chains 2 keeps no checkpoint" in err


def test_ctrl_c_in_vi_gibbs_names_the_stage_it_stopped_in(home, tmp_path, capsys, monkeypatch):
    """vi-gibbs runs CAVI, then Gibbs sweeps: Ctrl-C said "k of S iterations done" with S its
    --sweeps in either stage, k CAVI's iterations in the first (of at most vi_iterations)."""
    import spcopyro.gibbs.run as gibbs_run

    real = gibbs_run.advance

    def interrupting(chain, num_sweeps, callback=None, **kwargs):
        def stop(s, state):
            if s == 4:
                raise KeyboardInterrupt

        return real(chain, num_sweeps, callback=stop, **kwargs)

    monkeypatch.setattr(gibbs_run, "advance", interrupting)
    out = tmp_path / "out"
    argv = _variational_argv(home, out, "vi-gibbs")
    assert main([*argv, "--method-option", "vi_iterations=3"]) == 130
    err = capsys.readouterr().err
    assert "(vi-gibbs fit 1 of 1, 5 of 12 Gibbs sweeps done after its CAVI start)" in err
    assert not out.exists()


def test_ctrl_c_in_a_variational_fit_of_several_chains_says_why_none_is_kept(
    home, tmp_path, capsys, monkeypatch
):
    _interrupt_cavi_at(monkeypatch, 2)
    out = tmp_path / "out"
    assert main([*_variational_argv(home, out, "cavi"), "--chains", "2"]) == 130
    err = capsys.readouterr().err
    assert err.rstrip().endswith("no checkpoint kept (--chains 2: a cavi checkpoint holds one fit)")
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_in_a_cavi_fit_keeps_its_q_and_resume_gives_the_unbroken_fit(
    home, tmp_path, capsys, monkeypatch
):
    """A variational fit interrupted after 3 iterations is saved (its q(C) and record); the
    printed command goes on from there, and with CAVI's torch backend the result is the fit that
    never stopped, trace and kept maps included (issue 23 item 1)."""
    out = tmp_path / "out"
    argv = _variational_argv(home, out, "cavi")
    with monkeypatch.context() as patch:
        _interrupt_cavi_at(patch, 4)
        assert main(argv) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("interrupted (cavi fit 1 of 1, 3 of 12 ")
    checkpoint = checkpoint_path(out)
    assert f"saved in {checkpoint}" in err and not out.exists()
    assert is_variational_checkpoint(checkpoint) and not is_variational_checkpoint(home / "x")
    again = shlex.split(err.split("continue with: ")[1])
    assert again[-2:] == ["--resume", str(checkpoint)]
    assert main([*again[1:], "--gamma", "4"]) == 2  # other settings: refused, naming them
    assert "gamma: 3.0 in the checkpoint, 4.0 here" in capsys.readouterr().err
    assert main(again[1:]) == 0
    assert "resuming         the fit saved in" in capsys.readouterr().out
    assert not checkpoint.exists()
    assert main([*argv[:3], str(tmp_path / "unbroken"), *argv[4:]]) == 0
    _same_outputs(out, tmp_path / "unbroken")


@pytest.mark.parametrize("method", ["svi", "cavi-numba", "lbp-torch", "lbp-numba", "stochastic-vi"])
def test_other_variational_fits_resume_from_the_q_reached(home, tmp_path, monkeypatch, method):
    """SVI, CAVI's compiled backend, LBP and memoized VI go on from the saved q(C) (a warm
    start): the trace continues the saved one and the fit completes its iterations."""
    import spcopyro.guides.lbp_method
    import spcopyro.guides.memoized
    import spcopyro.guides.run
    import spcopyro.guides.svi_method
    from spcopyro.data import load_house
    from spcopyro.fit.gibbs_chains import FitInterrupted
    from spcopyro.fit.house import fit_house_chains
    from spcopyro.guides.lbp_method import LBPOptions
    from spcopyro.guides.memoized import StochasticOptions
    from spcopyro.guides.options import VariationalOptions
    from spcopyro.guides.svi_method import SVIOptions

    if method.endswith("numba"):
        pytest.importorskip("numba")
    if method == "svi":
        name, module, options = "svi", spcopyro.guides.svi_method, SVIOptions(tolerance=0.0)
    elif method == "stochastic-vi":
        name, module = method, spcopyro.guides.memoized
        options = StochasticOptions(block_size=4, tolerance=0.0)
    elif method == "cavi-numba":
        name, module = "cavi", spcopyro.guides.run
        options = VariationalOptions(backend="numba", tolerance=0.0)
    else:
        name, module = "lbp", spcopyro.guides.lbp_method
        options = LBPOptions(backend=method.split("-")[1], tolerance=0.0)
    house = load_house(home)
    path = tmp_path / "fit.checkpoint.npz"
    kwargs = dict(method=name, options=options, sweeps=12, progress=False)
    real = driver_module.drive

    def drive_stopped_at_6(state, step, iterations, **more):
        steps = 0

        def stopping(state, gamma):
            nonlocal steps
            steps += 1
            if steps == 6:
                raise KeyboardInterrupt
            return step(state, gamma)

        return real(state, stopping, iterations, **more)

    with monkeypatch.context() as patch:
        patch.setattr(module, "drive", drive_stopped_at_6)
        with pytest.raises(FitInterrupted) as caught:
            fit_house_chains(house, checkpoint=path, **kwargs)
    assert caught.value.checkpoint == path and "5 of 12 iterations done" in caught.value.where
    (result,) = fit_house_chains(house, resume=path, **kwargs)
    assert len(result.trace.objective) == 12
    with np.load(path) as saved:
        np.testing.assert_array_equal(result.trace.objective[:5], saved["objective"])
        np.testing.assert_allclose(saved["marginals"].sum(-1), 1.0)  # a q(C) per free cell


def test_a_fit_into_out_with_a_checkpoint_must_resume_or_overwrite(
    home, tmp_path, capsys, monkeypatch
):
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT]
    with monkeypatch.context() as patch:
        interrupt_fit_at(patch, 0, 2)
        assert main(argv) == 130
    checkpoint = checkpoint_path(out)
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{checkpoint} holds an interrupted fit" in err and "--resume" in err
    assert main([*argv, "--gamma", "4", "--resume", str(checkpoint)]) == 2
    err = capsys.readouterr().err
    assert "made for other data or settings" in err and "gamma: 3.0 in the checkpoint, 4.0" in err
    assert main([*argv[:5], "20", *argv[6:], "--resume", str(checkpoint)]) == 2  # --sweeps 20
    assert "sweeps: 12 in the checkpoint, 20 here" in capsys.readouterr().err
    assert not out.exists() and checkpoint.is_file()
    assert main([*argv, "--overwrite"]) == 0  # starts afresh; the old checkpoint goes
    assert not checkpoint.exists() and (out / "result.npz").is_file()


def test_the_command_recorded_and_printed_leaves_out_resume_however_it_was_typed():
    from spcopyro.cli.fit_resume import (
        RESUME_PREFIX,
        again_command,
        resume_command,
        without_resume,
    )
    from spcopyro.cli.main import build_parser

    fit = build_parser()._subparsers._group_actions[0].choices["fit"]
    flags = [f for a in fit._actions for f in a.option_strings if f.startswith(RESUME_PREFIX)]
    assert flags == ["--resume"]  # the prefix is argparse's: no other flag shares it
    for typed in (["--resume", "A"], ["--resume=A"], ["--resu", "A"], ["--res=A"]):
        args = argparse.Namespace(argv=["fit", "--out", "o", *typed, "--sweeps", "9"])
        assert without_resume(args) == ["fit", "--out", "o", "--sweeps", "9"]
        assert resume_command(args, Path("B")) == "spcopyro fit --out o --sweeps 9 --resume B"
    kept = argparse.Namespace(argv=["fit", "--refine", "never", "--region-moves", "0"])
    assert without_resume(kept) == kept.argv
    # the resume command is the again command and --resume, each word quoted as the shell reads
    spaced = argparse.Namespace(argv=["fit", "--out", "my fit", "--resume", "old one"])
    again = "spcopyro fit --out 'my fit'"
    assert again_command(spaced) == again
    assert resume_command(spaced, Path("a b/c")) == f"{again} --resume 'a b/c'"


def test_ctrl_c_right_after_out_is_written_leaves_no_stale_checkpoint(
    home, tmp_path, capsys, monkeypatch
):
    """Ctrl-C between moving the resumed fit into OUT and removing its checkpoint left the
    checkpoint of a finished fit beside it."""
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT, "--no-figures"]
    with monkeypatch.context() as patch:
        interrupt_fit_at(patch, 0, 4)
        assert main(argv) == 130
    checkpoint = checkpoint_path(out)
    assert checkpoint.is_file()
    commit = StagedOutput.commit

    def commit_then_ctrl_c(self):
        commit(self)
        raise KeyboardInterrupt

    monkeypatch.setattr(StagedOutput, "commit", commit_then_ctrl_c)
    capsys.readouterr()
    assert main([*argv, "--resume", str(checkpoint)]) == 130
    assert f"interrupted after {out} was written" in capsys.readouterr().err
    assert (out / "result.npz").is_file() and not checkpoint.exists()


def test_ctrl_c_while_writing_keeps_the_finished_chains(home, tmp_path, capsys, monkeypatch):
    import spcopyro.figures.plotting

    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT]

    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.figures.plotting, "plot_semantic_map", interrupted)
        assert main(argv) == 130
    err = capsys.readouterr().err
    assert err.startswith("interrupted while writing the outputs: nothing written to")
    assert not out.exists()

    def no_sampling(*args, **kwargs):
        raise AssertionError("the finished chains were sampled again")

    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.gibbs.chains, "advance", no_sampling)
        assert main([*argv, "--resume", str(checkpoint_path(out))]) == 0
    assert main(["fit", str(home), "--out", str(tmp_path / "unbroken"), *FIT]) == 0
    _same_outputs(out, tmp_path / "unbroken")


def test_ctrl_c_under_sweeps_auto_stops_cleanly(home, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(spcopyro.gibbs.chains, "advance", interrupted)
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), "--sweeps", "auto", "--chains", "2",
            "--max-sweeps", "10", "--concepts", "4"]  # fmt: skip
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert err == (  # how far it got, as every fit's interruption says (it said nothing)
        "interrupted (2 chains at 0, 0 of at most 10 sweeps, not yet converged after 0 "
        f"check(s)): nothing written to {out}; no checkpoint kept (--sweeps auto)\n"
    )
    assert list(tmp_path.iterdir()) == []
    assert main([*argv, "--resume", str(tmp_path / "x.npz")]) == 2
    assert "--resume continues Gibbs chains" in capsys.readouterr().err


def _default_sigint() -> None:
    """In the child: SIGINT back to its default, so that Python installs its KeyboardInterrupt
    handler even when the test runner was started with SIGINT ignored (a background job of a
    shell without job control, ``nohup``: children inherit the ignore)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupted_fit_process(out: Path, home: Path, chains: int, send) -> tuple[str, int]:
    """Run ``python -m spcopyro fit`` of ``chains`` chains of a million sweeps on ``home``
    (in a process group of its own), ``send(process)`` once it has swept some, and return its
    stderr and process group after asserting exit 130 and no traceback."""
    env = {k: v for k, v in os.environ.items() if k != "CI"}  # the progress bar shows sweeping
    env["PYTHONPATH"] = str(Path(spcopyro.fit.house.__file__).parents[1])
    env[spcopyro.gibbs.chains.PROCESSES_ENV] = "on" if chains > 1 else "auto"
    env["PYTHONFAULTHANDLER"] = "1"  # SIGABRT prints the stacks of a hung fit
    argv = ["fit", str(home), "--out", str(out), "--sweeps", "1000000", "--concepts", "8",
            "--chains", str(chains), "--chain-workers", str(chains)]  # fmt: skip
    process = subprocess.Popen([sys.executable, "-m", "spcopyro", *argv], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               preexec_fn=_default_sigint, process_group=0)  # fmt: skip
    seen, total = b"", str(chains * 1000000).encode()
    while not re.search(rb"Gibbs sweeps.*?: .*?\b[1-9][0-9]*/" + total + rb" \[", seen):
        chunk = os.read(process.stderr.fileno(), 4096)  # swept some
        if not chunk:
            break
        seen += chunk
    send(process)
    try:
        _, rest = process.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # a hang: every thread's stack (faulthandler), then fail
        os.killpg(process.pid, signal.SIGABRT)
        _, rest = process.communicate(timeout=30)
        pytest.fail(f"no exit 120 s after the signal:\n{(seen + rest).decode()[-8000:]}")
    err = (seen + rest).decode()
    assert process.returncode == 130, err
    assert "Traceback" not in err
    return err, process.pid


@pytest.mark.slow  # a fresh process: ~5 s of imports
@pytest.mark.parametrize("sent", [signal.SIGINT, signal.SIGTERM])
def test_a_real_ctrl_c_in_a_fit_process(home, tmp_path, sent):
    """SIGINT (Ctrl-C) or SIGTERM (timeout, systemd, docker, Slurm: issue 22 item 7) to a
    ``python -m spcopyro fit`` process once it has done some sweeps: exit 130, no traceback,
    the last line says where the checkpoint is, which holds the sweeps done."""
    out = tmp_path / "out"
    err, _ = _interrupted_fit_process(out, home, 1, lambda process: process.send_signal(sent))
    last = err.strip().splitlines()[-1].split("\r")[-1]
    assert last.startswith("interrupted (chain 1 of 1, ") and "continue with: spcopyro" in last
    record = read_record(checkpoint_path(out))
    assert 0 < record["chains"][0]["sweeps_done"] < 1000000 and not out.exists()


@pytest.mark.slow  # a fresh process: ~5 s of imports
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forked chains: Linux only")
@pytest.mark.parametrize("sent", [signal.SIGINT, signal.SIGTERM])
def test_a_real_ctrl_c_in_a_fit_whose_chains_run_in_processes(home, tmp_path, sent):
    """SIGINT to the whole process group (a Ctrl-C at the terminal: the chains' worker
    processes get it too, and ignore it) or SIGTERM to the command alone, during ``fit --chains
    2`` with its chains in forked processes: exit 130, no traceback, every chain saved with the
    records of its sweeps, no worker left running."""
    out = tmp_path / "out"

    def send(process: subprocess.Popen) -> None:
        if sent == signal.SIGINT:
            os.killpg(process.pid, sent)
        else:
            process.send_signal(sent)

    err, group = _interrupted_fit_process(out, home, 2, send)
    last = err.strip().splitlines()[-1].split("\r")[-1]
    assert last.startswith("interrupted (") and "continue with: spcopyro" in last
    checkpoint = checkpoint_path(out)
    done = [chain["sweeps_done"] for chain in read_record(checkpoint)["chains"]]
    assert all(0 < d < 1000000 for d in done) and not out.exists()
    with np.load(checkpoint) as saved:
        assert [len(saved[f"chain{k}.log_joint"]) for k in range(2)] == done
    time.sleep(0.5)
    assert _processes_in_group(group) == []  # the workers ended with the command


def _processes_in_group(group: int) -> list[int]:
    """The pids of the live processes of process group ``group`` (Linux's /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            state, _, pgrp = stat.read_text().rsplit(")", 1)[1].split()[:3]
        except (OSError, IndexError, ValueError):  # gone meanwhile
            continue
        if int(pgrp) == group and state != "Z":
            found.append(int(stat.parent.name))
    return found


def test_a_killed_runs_staging_folder_is_removed_by_the_next_run_into_out(home, tmp_path):
    """Issue 22 item 7: ``kill -9`` leaves ``OUT.partial-PID-*``; the next fit into the same
    OUT removes it (its process is gone) and leaves a live process's staging alone."""
    from spcopyro._util.outputs import remove_stale_stagings, staging_prefix

    out = tmp_path / "out"
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f"out.partial-{dead.pid}-abc123"
    stale.mkdir()
    (stale / "labels.npy").write_bytes(b"half written")
    live = tmp_path / f"{staging_prefix(out)}xyz"  # this process: alive
    live.mkdir()
    other = tmp_path / "out.partial-oldstyle"  # no pid: not ours to judge
    other.mkdir()
    assert main(["fit", str(home), "--out", str(out), *FIT]) == 0
    assert not stale.exists() and live.exists() and other.exists()
    assert remove_stale_stagings(out) == []


def test_chains_stopped_side_by_side_say_how_far_each_got():
    """`--chains 2` interrupted said "chain 1 of 2, 45 of 200 sweeps done" while the second
    chain, advancing beside it, had 46."""
    from types import SimpleNamespace

    from spcopyro.fit.gibbs_chains import _where_stopped

    def at(*done):
        return [SimpleNamespace(sweeps_done=d) for d in done]

    assert _where_stopped(at(45, 46), 200) == "2 chains at 45, 46 of 200 sweeps done"
    assert _where_stopped(at(200, 9), 200) == "chain 2 of 2, 9 of 200 sweeps done"  # in turn
    assert _where_stopped([*at(7), None], 12) == "chain 1 of 2, 7 of 12 sweeps done"
    assert _where_stopped(at(12, 12), 12) == "all 2 chain(s) done (12 sweeps each)"


def test_a_patch_of_with_sample_marginals_reaches_a_vi_gibbs_fit(
    home, tmp_path, capsys, monkeypatch
):
    """fit.house calls gibbs_chains.with_sample_marginals through its module: a test's patch
    there reaches a vi-gibbs fit's call (house bound the name when first imported, so such a
    patch was missed, or kept for every later fit where house was first imported under it).
    Ctrl-C there: the iterations were done, while their result was made."""
    import spcopyro.fit.gibbs_chains as gibbs_chains
    import spcopyro.fit.house  # noqa: F401 -- imported before the patch, as by any earlier fit

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(gibbs_chains, "with_sample_marginals", interrupted)
    argv = _variational_argv(home, tmp_path / "out", "vi-gibbs")
    assert main([*argv, "--method-option", "vi_iterations=3"]) == 130
    err = capsys.readouterr().err
    assert "(vi-gibbs fit 1 of 1, after its " in err
    assert "while their result was made" in err
