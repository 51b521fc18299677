"""Ctrl-C or SIGTERM landing inside a numba call: the call ends with ``SystemError: ...
returned a result with an exception set`` caused by the KeyboardInterrupt
(:mod:`spcopyro._util.interrupts`). It is an interrupt like any other: the chain stops at its
last completed sweep and continues exactly, ``fit`` keeps its checkpoint and exits with 130, a
study's cell in flight is not stored as failed.

Before, ``fit`` ended with a traceback and exit code 1 and lost its checkpoint (seen with
``timeout -s TERM``-like signals in ``grow_region``), and a study stored the cell as a failed
one, not run again without ``--retry-failed``, and went on."""

from __future__ import annotations

import signal

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem

import spcopyro.gibbs.chains
from spcopyro._util.interrupts import caused_by_interrupt
from spcopyro._util.outputs import checkpoint_path
from spcopyro.cli.main import main
from spcopyro.gibbs.checkpoint import read_record
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import advance, run_gibbs, start_chain
from spcopyro.study import evaluate
from spcopyro.study.run import run_study
from spcopyro.study.spec import study_from_dict
from spcopyro.study.table import read_table


def _compiled_call_interrupted() -> SystemError:
    """What a numba dispatcher raises when the signal's handler ran inside it (as CPython makes
    it: a SystemError whose cause is the handler's exception)."""
    try:
        try:
            raise KeyboardInterrupt(f"signal {int(signal.SIGTERM)}")
        except KeyboardInterrupt as stop:
            raise SystemError(
                "CPUDispatcher(<function grow_region>) returned a result with an exception set"
            ) from stop
    except SystemError as error:
        return error


def test_only_a_system_error_caused_by_an_interrupt_is_one():
    assert caused_by_interrupt(_compiled_call_interrupted())
    twice = SystemError("outer")
    twice.__cause__ = _compiled_call_interrupted()
    assert caused_by_interrupt(twice) and caused_by_interrupt(KeyboardInterrupt())
    assert not caused_by_interrupt(SystemError("a bug of its own"))
    during = ValueError("raised while handling Ctrl-C")
    during.__cause__ = KeyboardInterrupt()
    assert not caused_by_interrupt(during) and not caused_by_interrupt(None)


class _InterruptedBackend:
    """The backend whose ``sweep`` number ``at`` ends as an interrupted numba call would, after
    it drew its random numbers."""

    def __init__(self, inner, at: int) -> None:
        self.inner, self.at, self.calls, self.name = inner, at, 0, inner.name

    def sweep(self, state, data, cfg, generator, plan, refresh):
        new = self.inner.sweep(state, data, cfg, generator, plan, refresh)
        self.calls += 1
        if self.calls == self.at:
            raise _compiled_call_interrupted()
        return new

    def __getattr__(self, name):
        return getattr(self.inner, name)


def test_a_chain_interrupted_inside_a_compiled_call_is_undone_and_continues_exactly():
    cfg = config()
    _, data = random_problem(seed=3)
    options = GibbsOptions(cluster_moves=0.5, unobserved_refresh=0.5)
    whole = run_gibbs(data, cfg, 10, options=options, seed=2, thin=2, progress=False)
    chain = start_chain(data, cfg, options=options, seed=2)
    advance(chain, 4, thin=2, progress=False)
    real = chain.backend
    chain.backend = _InterruptedBackend(real, at=2)
    with pytest.raises(KeyboardInterrupt):  # was: the SystemError, the chain mid-sweep
        advance(chain, 6, thin=2, progress=False)
    chain.backend = real
    assert chain.sweeps_done == 5 and len(chain.log_joint) == 5  # sweep 6, cut short: undone
    advance(chain, 5, thin=2, progress=False)
    run = chain.to_run()
    assert torch.equal(run.final_state.labels, whole.final_state.labels)
    np.testing.assert_array_equal(run.log_joint, whole.log_joint)


def test_fit_keeps_its_checkpoint_and_exits_130(home, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"

    def interrupted_advance(gibbs_chain, num_sweeps, callback=None, **kwargs):
        def stop(s, state):
            if callback is not None:
                callback(s, state)
            if s == 3:
                raise _compiled_call_interrupted()

        return advance(gibbs_chain, num_sweeps, callback=stop, **kwargs)

    monkeypatch.setattr(spcopyro.gibbs.chains, "advance", interrupted_advance)
    argv = ["fit", str(home), "--out", str(out), "--sweeps", "12", "--preset", "original-code",
            "--gamma", "3", "--concepts", "8", "--no-figures"]  # fmt: skip
    assert main(argv) == 130  # was 1, with a traceback
    err = capsys.readouterr().err
    assert "\ninterrupted (chain 1 of 1, 4 of 12 sweeps done)" in f"\n{err.split(chr(13))[-1]}"
    assert "Traceback" not in err and not out.exists()
    assert [c["sweeps_done"] for c in read_record(checkpoint_path(out))["chains"]] == [4]


def test_main_says_interrupted_for_an_interrupt_outside_a_fit(monkeypatch, capsys):
    import argparse

    from spcopyro.cli import main as main_module

    def command(error):
        def func(args):
            raise error

        class Parser(argparse.ArgumentParser):  # no commands: main's checks of them pass
            def parse_args(self, argv):
                return argparse.Namespace(func=func, verbose=False)

        monkeypatch.setattr(main_module, "build_parser", Parser)

    command(_compiled_call_interrupted())
    assert main_module.main(["study"]) == 130  # was: the SystemError's traceback
    assert capsys.readouterr().err == "interrupted\n"
    command(SystemError("a bug of its own"))
    with pytest.raises(SystemError, match="a bug of its own"):
        main_module.main(["study"])


TINY = {
    "study": {"name": "tiny", "seeds": 2, "sweeps": 4},
    "variants": {"og3": {"preset": "original-code", "gamma": 3.0}},
    "data": {"small": {"synthetic": "default", "height": 36, "width": 44, "num_rooms": 2}},
}


def test_a_study_cell_interrupted_inside_a_compiled_call_is_not_stored_as_failed(
    tmp_path, monkeypatch
):
    study = study_from_dict(TINY)
    real = evaluate._fit_and_score
    calls: list[int] = []

    def second_interrupted(cell):
        calls.append(1)
        if len(calls) == 2:
            raise _compiled_call_interrupted()
        return real(cell)

    monkeypatch.setattr(evaluate, "_fit_and_score", second_interrupted)
    with pytest.raises(KeyboardInterrupt):  # was: stored as failed, and the study went on
        run_study(study, tmp_path / "out", workers=1, progress=False)
    rows = read_table(tmp_path / "out" / "results.csv")
    assert [r["status"] for r in rows] == ["ok"]
    monkeypatch.setattr(evaluate, "_fit_and_score", real)
    again = run_study(study, tmp_path / "out", workers=1, progress=False)
    assert (again.cached, again.ran, again.failed, again.failed_before) == (1, 1, 0, 0)
