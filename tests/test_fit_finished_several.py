"""A finished fit of several fits (``--chains K`` of a method other than Gibbs) or an
``--update`` (of any method), stopped while ``spcopyro fit`` writes its outputs: kept in
OUT.checkpoint.npz (:mod:`spcopyro.cli.fit_finished`), and ``--resume`` writes the outputs of an
unbroken run from it without fitting again. Both were lost ("the finished fit is lost -- run it
again"), where Gibbs chains of ``--chains K`` keep their finished chains."""

from __future__ import annotations

import shlex

import numpy as np
import pytest
from fit_interrupts import interrupted
from test_fit_resume_gaps import FIT, _failing_print_concepts, _same_outputs

import spcopyro.cli.fit_write
import spcopyro.fit.house
import spcopyro.robot.online
from spcopyro._util.outputs import checkpoint_path
from spcopyro.cli.main import main


def _no_fit(*args, **kwargs):
    raise AssertionError("the finished fit was run again")


def _prior_fit(home, tmp_path) -> str:
    """A Gibbs fit of ``home`` for ``--update`` to continue: its folder."""
    prior = tmp_path / "prior"
    assert main(["fit", str(home), "--out", str(prior), *FIT]) == 0
    return str(prior)


@pytest.mark.parametrize(
    ("method", "extra"),
    [("lbp", ["--chains", "2"]), ("vi-gibbs", ["--chains", "2"]), ("gibbs", ["--update"]),
     ("cavi", ["--chains", "2", "--update"])],
)  # fmt: skip
def test_ctrl_c_while_writing_several_fits_or_an_update_keeps_them_for_resume_to_write(
    method, extra, home, tmp_path, capsys, monkeypatch
):
    """Ctrl-C while the outputs of two finished fits, or of an update, are written keeps every
    fit in OUT.checkpoint.npz with the one kept; the command the line gives writes the files an
    unbroken run writes (chains.json comparing both fits, byte for byte), but for the timings,
    without fitting again."""
    if extra[-1] == "--update":
        extra = [*extra, _prior_fit(home, tmp_path)]
    argv = ["fit", str(home), "--out", "out", *FIT, "--method", method, *extra]
    for folder in ("stopped", "unbroken"):  # the same --out: config.json records the command
        (tmp_path / folder).mkdir()
    monkeypatch.chdir(tmp_path / "unbroken")
    assert main(argv) == 0
    monkeypatch.chdir(tmp_path / "stopped")
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.cli.fit_write, "print_concepts", interrupted)
        assert main(argv) == 130
    err = capsys.readouterr().err.splitlines()[-1]
    out, checkpoint = tmp_path / "stopped" / "out", checkpoint_path("out")
    command = shlex.join(["spcopyro", *argv, "--resume", str(checkpoint)])
    assert err == (
        f"interrupted while writing the outputs: nothing written to {out}; the finished fit is "
        f"saved in {checkpoint} -- write its outputs (without fitting again) with: {command}"
    )
    assert not out.exists() and checkpoint.is_file()
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.fit.house, "fit_house_chains", _no_fit)
        patch.setattr(spcopyro.robot.online, "fit_update", _no_fit)
        assert main(shlex.split(command)[1:]) == 0
    printed = capsys.readouterr().out
    assert f"resuming         the fit saved in {checkpoint}" in printed
    assert f"removed {checkpoint}" in printed and not checkpoint.exists()
    unbroken = tmp_path / "unbroken" / "out"
    _same_outputs(out, unbroken)
    if "--chains" in extra:
        assert (out / "chains.json").read_bytes() == (unbroken / "chains.json").read_bytes()


def test_an_error_while_writing_several_fits_keeps_them_for_resume_to_write(
    home, tmp_path, capsys, monkeypatch
):
    """An error (a full disk) while the outputs of two lbp fits are written keeps both in
    OUT.checkpoint.npz, as Ctrl-C does (the note said they were lost: "a finished fit's file
    holds one fit"); the note gives the command that writes OUT once the error is fixed."""
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT, "--method", "lbp", "--chains", "2"]
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.cli.fit_write, "print_concepts", _failing_print_concepts)
        assert main(argv) == 2
    err = capsys.readouterr().err
    checkpoint = checkpoint_path(out)
    command = shlex.join(["spcopyro", *argv, "--resume", str(checkpoint)])
    assert (
        f"note: nothing written to {out}; the finished fit is saved in {checkpoint} -- once "
        f"fixed, write its outputs (without fitting again) with: {command}"
    ) in err.splitlines(), err
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.fit.house, "fit_house_chains", _no_fit)
        assert main(shlex.split(command)[1:]) == 0
    assert (out / "chains.json").is_file() and not checkpoint.exists()


def test_a_finished_fit_kept_for_other_chains_or_another_update_is_refused(
    home, tmp_path, capsys, monkeypatch
):
    """The kept fits are those of the command that kept them: ``--resume`` with another
    ``--chains``, or of an update whose saved fit has changed since, names the difference."""
    prior = _prior_fit(home, tmp_path)
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT, "--method", "cavi", "--update", prior]
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.cli.fit_write, "print_concepts", interrupted)
        assert main([*argv, "--chains", "2"]) == 130
    checkpoint = checkpoint_path(out)
    capsys.readouterr()
    assert main([*argv, "--chains", "3", "--resume", str(checkpoint)]) == 2
    assert "chains: 2 in the checkpoint, 3 here" in capsys.readouterr().err
    with np.load(f"{prior}/result.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["labels"] = arrays["labels"][::-1].copy()  # another state to update
    np.savez_compressed(f"{prior}/result.npz", **arrays)
    assert main([*argv, "--chains", "2", "--resume", str(checkpoint)]) == 2
    err = capsys.readouterr().err
    assert "a finished fit made for other data or settings: update.result_sha256: " in err, err
    assert checkpoint.is_file()


def test_a_file_of_one_fit_as_first_written_still_resumes(home, tmp_path, capsys, monkeypatch):
    """A finished fit's file written before it kept several fits (no ``fits`` or ``kept`` in
    its record, no ``chains`` or ``update`` in its request) is one fit: its
    ``--resume`` writes OUT without fitting again."""
    import json

    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT, "--method", "cavi"]
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.cli.fit_write, "print_concepts", interrupted)
        assert main(argv) == 130
    checkpoint = checkpoint_path(out)
    with np.load(checkpoint) as z:
        arrays = {k: z[k] for k in z.files}
    record = json.loads(str(arrays["record"]))
    for key in ("fits", "kept"):
        del record[key]
    for key in ("chains", "update"):
        del record["request"][key]
    arrays["record"] = np.array(json.dumps(record))
    with open(checkpoint, "wb") as file:
        np.savez_compressed(file, **arrays)
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.fit.house, "fit_house_chains", _no_fit)
        assert main([*argv, "--resume", str(checkpoint)]) == 0
    assert (out / "result.npz").is_file() and not checkpoint.exists()
