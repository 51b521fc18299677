"""Ctrl-C before ``spcopyro fit`` began fitting (importing, checking, loading the data, staging
OUT): the one line says what was interrupted, that nothing was changed (OUT not written, the
checkpoint ``--resume`` names left as it was) and the command that starts it again; no staging
folder is left. It said only 'interrupted'."""

from __future__ import annotations

import shlex

import pytest
from fit_interrupts import interrupt_cavi_at, interrupted

import spcopyro._util.collector
import spcopyro.cli.fit
import spcopyro.fit.gibbs_chains
from spcopyro._util.outputs import checkpoint_path
from spcopyro.cli.main import main

FIT = ["--sweeps", "12", "--preset", "original-code", "--gamma", "3", "--concepts", "8",
       "--no-figures", "--method", "cavi", "--method-option", "backend=torch"]  # fmt: skip


@pytest.fixture
def interrupted_cavi(home, tmp_path, capsys, monkeypatch):
    """(argv, checkpoint): a cavi fit into ``tmp_path/out`` stopped after 3 iterations."""
    argv = ["fit", str(home), "--out", str(tmp_path / "out"), *FIT]
    with monkeypatch.context() as patch:
        interrupt_cavi_at(patch, 4)
        assert main(argv) == 130
    capsys.readouterr()
    checkpoint = checkpoint_path(tmp_path / "out")
    assert checkpoint.is_file()
    return argv, checkpoint


@pytest.mark.parametrize(
    ("module", "name", "stage"),
    [(spcopyro._util.collector, "import_frozen", "importing spcopyro's fit"),
     (spcopyro.cli.fit, "_load", "loading the data"),
     (spcopyro.cli.fit, "check_resume_file", "checking the checkpoint {checkpoint}")],
)  # fmt: skip
def test_ctrl_c_while_a_resume_loads_says_what_and_that_nothing_changed(
    module, name, stage, interrupted_cavi, tmp_path, capsys, monkeypatch
):
    argv, checkpoint = interrupted_cavi
    before = checkpoint.read_bytes()
    resume = [*argv, "--resume", str(checkpoint)]
    with monkeypatch.context() as patch:
        patch.setattr(module, name, interrupted)
        assert main(resume) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    stage = stage.format(checkpoint=checkpoint)
    assert err == (
        f"interrupted while {stage}, before the fit began: nothing was changed "
        f"({tmp_path / 'out'} not written, {checkpoint} left as it was) -- continue with: "
        f"{shlex.join(['spcopyro', *resume])}\n"
    )
    assert checkpoint.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [checkpoint.name]
    assert main(shlex.split(err.split("continue with: ")[1])[1:]) == 0
    assert (tmp_path / "out" / "result.npz").is_file() and not checkpoint.exists()


def test_ctrl_c_once_out_is_staged_removes_the_staging_folder(home, tmp_path, capsys, monkeypatch):
    """A Ctrl-C between staging OUT and the fit's own handler (here: as the checkpoint keeper is
    made) left OUT.partial-* behind; the line gives the command to run it again."""
    argv = ["fit", str(home), "--out", str(tmp_path / "out"), *FIT]
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.fit.gibbs_chains, "FitCheckpoint", interrupted)
        assert main(argv) == 130
    err = capsys.readouterr().err
    assert err == (
        "interrupted while preparing the output folder, before the fit began: nothing was "
        f"changed ({tmp_path / 'out'} not written) -- run it again with: "
        f"{shlex.join(['spcopyro', *argv])}\n"
    )
    assert list(tmp_path.iterdir()) == []
