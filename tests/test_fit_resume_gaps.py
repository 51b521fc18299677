"""``spcopyro fit``'s checkpoint between the sweeps and the outputs, and what a resume must
match: a Ctrl-C after the chains finished (while their point estimate is made) keeps them, and
``--resume`` with another ``--marginal-samples`` is refused (it would mix two spacings of the
kept label maps)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fit_interrupts import interrupt_cavi_at, interrupt_fit_at, interrupted

import spcopyro.fit.gibbs_chains
import spcopyro.gibbs.chains
from spcopyro._util.outputs import checkpoint_path
from spcopyro.cli.main import main
from spcopyro.gibbs.checkpoint import read_record

FIT = ["--sweeps", "12", "--preset", "original-code", "--gamma", "3", "--concepts", "8",
       "--no-figures"]  # fmt: skip


def _ctrl_c_in(monkeypatch, capsys, module, name: str, argv: list[str]) -> str:
    """``spcopyro fit`` run with ``module.name`` stopped by Ctrl-C: it exits with 130; the last
    line of its stderr (after the progress bars)."""
    with monkeypatch.context() as patch:
        patch.setattr(module, name, interrupted)
        assert main(argv) == 130
    return capsys.readouterr().err.splitlines()[-1]


def _stopped_gibbs_fit(home, out, monkeypatch, capsys, sweep: int) -> list[str]:
    """The argv of a Gibbs fit (one chain) into ``out``, run and stopped by Ctrl-C after its
    ``sweep``-th sweep (0: the first): it exits with 130 and keeps a checkpoint."""
    argv = ["fit", str(home), "--out", str(out), *FIT]
    with monkeypatch.context() as patch:
        interrupt_fit_at(patch, 0, sweep)
        assert main(argv) == 130
    capsys.readouterr()
    return argv


def _stopped_cavi_fit(home, out, monkeypatch, capsys) -> list[str]:
    """The argv of a cavi fit (torch backend) into ``out``, run and stopped by Ctrl-C at its
    torch step's third call: it exits with 130 and keeps a checkpoint."""
    argv = ["fit", str(home), "--out", str(out), *FIT, "--method", "cavi",
            "--method-option", "backend=torch"]  # fmt: skip
    with monkeypatch.context() as patch:
        interrupt_cavi_at(patch, 3)
        assert main(argv) == 130
    capsys.readouterr()
    return argv


def test_ctrl_c_after_the_sweeps_keeps_the_finished_chains(home, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT]
    # Ctrl-C while the point estimate is made
    err = _ctrl_c_in(monkeypatch, capsys, spcopyro.fit.gibbs_chains, "with_sample_marginals", argv)
    checkpoint = checkpoint_path(out)
    assert err.startswith("interrupted after the sweeps: nothing written to")
    assert "no sweep was done" not in err and f"saved in {checkpoint}" in err
    assert [c["sweeps_done"] for c in read_record(checkpoint)["chains"]] == [12]

    def no_sampling(*args, **kwargs):
        raise AssertionError("the finished chains were sampled again")

    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.gibbs.chains, "advance", no_sampling)
        assert main([*argv, "--resume", str(checkpoint)]) == 0
    assert main(["fit", str(home), "--out", str(tmp_path / "unbroken"), *FIT]) == 0
    np.testing.assert_array_equal(
        np.load(out / "labels.npy"), np.load(tmp_path / "unbroken" / "labels.npy")
    )


def test_resume_with_other_marginal_samples_is_refused(home, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    # stopped past the middle: label maps kept every sweep
    argv = _stopped_gibbs_fit(home, out, monkeypatch, capsys, 8)
    checkpoint = checkpoint_path(out)
    assert main([*argv, "--marginal-samples", "2", "--resume", str(checkpoint)]) == 2
    err = capsys.readouterr().err
    assert "marginal_samples: 50 in the checkpoint, 2 here" in err
    assert not out.exists() and checkpoint.is_file()
    assert main([*argv, "--resume", str(checkpoint)]) == 0


def test_a_checkpoint_resumed_with_another_method_names_the_method(
    home, tmp_path, capsys, monkeypatch
):
    """A Gibbs checkpoint given to --method cavi (or the reverse, or another variational
    method) names the method it was made with, not only its file format or every option."""

    gibbs_out, cavi_out = tmp_path / "gibbs", tmp_path / "cavi"
    _stopped_gibbs_fit(home, gibbs_out, monkeypatch, capsys, 4)
    cavi_argv = _stopped_cavi_fit(home, cavi_out, monkeypatch, capsys)
    gibbs_checkpoint, cavi_checkpoint = checkpoint_path(gibbs_out), checkpoint_path(cavi_out)
    assert gibbs_checkpoint.is_file() and cavi_checkpoint.is_file()
    out = str(tmp_path / "other")
    assert main(["fit", str(home), "--out", out, *FIT, "--resume", str(cavi_checkpoint)]) == 2
    assert "interrupted 'cavi' fit" in capsys.readouterr().err
    assert main([*cavi_argv[:3], out, *cavi_argv[4:], "--resume", str(gibbs_checkpoint)]) == 2
    assert "interrupted 'gibbs' fit, which this method cannot continue: resume it with " \
        "method='gibbs' (fit's --method gibbs)" in capsys.readouterr().err  # fmt: skip
    lbp = [*cavi_argv[:3], out, *FIT, "--method", "lbp", "--resume", str(cavi_checkpoint)]
    assert main(lbp) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.endswith(
        "method: 'cavi' in the checkpoint, 'lbp' here: resume it with method='cavi' (fit's "
        "--method cavi)"
    )


def test_sweeps_auto_with_anneal_sweeps_is_refined(home, tmp_path, capsys):
    """--sweeps auto runs its --anneal-sweeps before the checked blocks; the refinement, which
    runs the same options (but does not anneal again), runs as many sweeps as the chains did,
    anneal included: it stopped after all the sampling with 'anneal_sweeps (10) must not exceed
    num_sweeps (5)', a number the user never gave."""
    from spcopyro.data import load_house
    from spcopyro.fit.house import fit_house
    from spcopyro.gibbs.options import GibbsOptions

    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), "--no-figures", "--sweeps", "auto",
            "--max-sweeps", "5", "--chains", "2", "--anneal-sweeps", "10", "--refine", "always",
            "--marginal-samples", "0"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "fitted 2 chains x 15 sweeps on 0.3 m cells (" in printed
    assert "), then 2 chains x 15 on the map's 0.1 m cells (" in printed
    # only the coarse stage anneals: the refinement starts from its map
    inference = json.loads((out / "config.json").read_text())["inference"]
    assert inference["anneal_sweeps"] == 0 and inference["refine"]["coarse"]["anneal_sweeps"] == 10
    result = fit_house(load_house(home), sweeps="auto", chains=2, refine="always",
                       options=GibbsOptions(anneal_sweeps=10), progress=False,
                       marginal_samples=0)  # fmt: skip
    assert len(result.trace.objective) >= 10 + 250  # the library's block: 250 sweeps
    assert result.inference["refine"]["refine"]


def test_max_sweeps_without_sweeps_auto_is_refused(home, tmp_path, capsys):
    """--max-sweeps caps --sweeps auto alone: with a number of --sweeps (or none) it was ignored
    silently, a fit of 5000 sweeps for one asked to stop at 300."""
    out = tmp_path / "out"
    assert main(["fit", str(home), "--out", str(out), "--max-sweeps", "300"]) == 2
    assert "--max-sweeps caps --sweeps auto, not --sweeps 5000" in capsys.readouterr().err
    assert main(["fit", str(home), "--out", str(out), "--sweeps", "9", "--max-sweeps", "9"]) == 2
    assert "not --sweeps 9: leave it out" in capsys.readouterr().err
    assert not out.exists()


def test_a_refused_resume_names_the_field_that_differs_within_a_group(
    home, tmp_path, capsys, monkeypatch
):
    """--cell-size or a hyperparameter-sampling option differing: the message names that field
    (it printed the checkpoint's and this run's whole data preparation, or sampler options)."""
    from spcopyro.gibbs.checkpoint import differences

    saved = {"sweeps": 12, "data_preparation": {"cell_size": 0.25, "word_scaling": 10.0}}
    here = {"sweeps": 12, "data_preparation": {"cell_size": 0.5, "word_scaling": 10.0}}
    assert differences(saved, here) == [
        "data_preparation.cell_size: 0.25 in the checkpoint, 0.5 here"
    ]
    assert differences({"a": {"b": 1}}, {"a": 2}) == ["a: {'b': 1} in the checkpoint, 2 here"]
    out = tmp_path / "out"
    argv = _stopped_gibbs_fit(home, out, monkeypatch, capsys, 1)
    other = [*argv, "--cell-size", "0.5", "--method-option", "hyper.gamma=exchange",
             "--resume", str(checkpoint_path(out))]  # fmt: skip
    assert main(other) == 2
    err = capsys.readouterr().err
    assert "data_preparation.cell_size: None in the checkpoint, 0.5 here" in err
    assert "hyper.gamma: 'fixed' in the checkpoint, 'exchange' here" in err
    assert "{" not in err  # no whole group printed


def test_ctrl_c_before_a_resumed_fit_loads_its_chains_says_the_checkpoint_still_holds(
    home, tmp_path, capsys, monkeypatch
):
    """A resumed fit stopped before its chains are loaded (here while it prints what it fits):
    the checkpoint it resumes is left as it was, and the line says so (it said 'no checkpoint
    kept (no sweep was done)')."""
    import spcopyro.cli.fit

    out = tmp_path / "out"
    argv = _stopped_gibbs_fit(home, out, monkeypatch, capsys, 5)
    checkpoint = checkpoint_path(out)
    before = checkpoint.read_bytes()

    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.cli.fit, "_summary", interrupted)
        assert main([*argv, "--resume", str(checkpoint)]) == 130
    err = capsys.readouterr().err
    assert "no checkpoint kept" not in err
    assert f"{checkpoint} is left as it was, with the state this run resumed from" in err
    assert err.rstrip().endswith(f"--resume {checkpoint}")
    assert checkpoint.read_bytes() == before
    assert main([*argv, "--resume", str(checkpoint)]) == 0


def test_ctrl_c_while_writing_a_refined_fit_says_the_refinement_runs_again(
    home, tmp_path, capsys, monkeypatch
):
    """The checkpoint keeps the first stage's chains, not the refinement's: the line says so
    (it said only that the state reached is saved)."""
    import spcopyro.cli.fit_write

    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), "--sweeps", "6", "--no-figures",
            "--refine", "always", "--chain-workers", "1"]  # fmt: skip

    err = _ctrl_c_in(monkeypatch, capsys, spcopyro.cli.fit_write, "print_concepts", argv)
    assert err.startswith("interrupted while writing the outputs (only the first stage is "
                          "kept: resuming refines again): nothing written to")  # fmt: skip
    assert main([*argv, "--resume", str(checkpoint_path(out))]) == 0
    assert "refining         refine='always'" in capsys.readouterr().out


def test_a_second_ctrl_c_while_saving_the_chains_still_keeps_them(
    home, tmp_path, capsys, monkeypatch
):
    """A second Ctrl-C while the first one's checkpoint is written: the command saves the
    chains again, and does not claim they had finished their sweeps."""
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT]
    save = spcopyro.fit.gibbs_chains.save_chains
    calls = []

    def interrupted_once(*args, **kwargs):
        calls.append(1)
        if len(calls) == 1:
            raise KeyboardInterrupt
        return save(*args, **kwargs)

    with monkeypatch.context() as patch:
        interrupt_fit_at(patch, 0, 4)
        patch.setattr(spcopyro.fit.gibbs_chains, "save_chains", interrupted_once)
        assert main(argv) == 130
    err = capsys.readouterr().err.splitlines()[-1]
    checkpoint = checkpoint_path(out)
    assert err.startswith(f"interrupted: nothing written to {out}; the state reached is saved in")
    assert [c["sweeps_done"] for c in read_record(checkpoint)["chains"]] == [5]


def test_an_error_after_the_sweeps_keeps_the_finished_chains(home, tmp_path, capsys, monkeypatch):
    """An error in the point estimate (after every sweep was run) keeps the chains, as one while
    the outputs are written does: they were lost."""
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT]

    def failing(*args, **kwargs):
        raise MemoryError("the point estimate")

    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.fit.gibbs_chains, "with_sample_marginals", failing)
        with pytest.raises(MemoryError):  # main shows an unexpected error's traceback
            main(argv)
    err = capsys.readouterr().err
    checkpoint = checkpoint_path(out)
    assert f"the finished chains are saved in {checkpoint}" in err
    assert [c["sweeps_done"] for c in read_record(checkpoint)["chains"]] == [12]
    assert main([*argv, "--resume", str(checkpoint)]) == 0


def test_ctrl_c_after_a_variational_fit_s_iterations_says_so(home, tmp_path, capsys, monkeypatch):
    """Ctrl-C once CAVI's iterations are done, while their result is made: the line says the
    iterations were done (it said 'no checkpoint kept (no iteration was done)')."""
    import spcopyro.fit.house

    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT, "--method", "cavi"]
    err = _ctrl_c_in(monkeypatch, capsys, spcopyro.fit.house, "result_of", argv)
    assert err.startswith("interrupted (cavi fit 1 of 1, after its ")
    assert err.endswith("no checkpoint kept (it stopped after the iterations, while their "
                        "result was made)")  # fmt: skip
    assert "no iteration was done" not in err and not out.exists()
    import spcopyro.guides.cavi_method  # inside the method, once its driver has returned

    err = _ctrl_c_in(
        monkeypatch, capsys, spcopyro.guides.cavi_method, "output_from_variational", argv
    )
    assert err.startswith("interrupted (cavi fit 1 of 1): nothing written")
    assert err.endswith("(it stopped outside the iterations: while the method set up or made "
                        "their result)")  # fmt: skip


def _without_timings(value):
    """A JSON value without the entries that are timings (``seconds``, ``vi_seconds``, ...) and
    without ``resumed_from``, which a resumed run records."""
    if isinstance(value, dict):
        return {k: _without_timings(v) for k, v in value.items()
                if "seconds" not in k and k != "resumed_from"}  # fmt: skip
    return [_without_timings(v) for v in value] if isinstance(value, list) else value


def _same_outputs(out, unbroken) -> None:
    """``out`` holds the files ``unbroken`` does, byte for byte but for the timings: the seconds
    of trace.csv and result.npz, config.json's timing entries (and ``resumed_from``)."""
    files = sorted(p.relative_to(unbroken) for p in unbroken.rglob("*") if p.is_file())
    assert sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file()) == files
    for name in files:
        a, b = out / name, unbroken / name
        if name.name == "trace.csv":
            rows = [[line.rsplit(",", 1)[0] for line in f.read_text().splitlines()] for f in (a, b)]
            assert rows[0] == rows[1]
        elif name.name == "result.npz":
            with np.load(a) as x, np.load(b) as y:
                assert x.files == y.files
                for key in x.files:
                    if key != "seconds":
                        assert x[key].dtype == y[key].dtype, key
                        np.testing.assert_array_equal(x[key], y[key], err_msg=key)
        elif name.name == "config.json":
            read = [_without_timings(json.loads(f.read_text())) for f in (a, b)]
            assert read[0] == read[1]
        else:
            assert a.read_bytes() == b.read_bytes(), name


@pytest.mark.parametrize("method", ["cavi", "lbp", "svi", "stochastic-vi", "vi-gibbs"])
def test_ctrl_c_while_writing_a_variational_fit_keeps_it_for_resume_to_write(
    method, home, tmp_path, capsys, monkeypatch
):
    """Ctrl-C while a finished variational fit's outputs are written (found sending SIGINT to
    ``spcopyro fit --method cavi`` while its figures were drawn): the finished fit is kept in
    OUT.checkpoint.npz (it was lost: "run it again"), no half OUT is left, and the command the
    line gives (``--resume`` it) writes OUT without fitting again: the files an unbroken run
    writes, but for the timings. vi-gibbs, which keeps no checkpoint of its sweeps, keeps this
    one too."""
    import shlex

    import spcopyro.cli.fit_write
    import spcopyro.fit.house

    argv = ["fit", str(home), "--out", "out", *FIT, "--method", method]
    for folder in ("stopped", "unbroken"):  # the same --out: config.json records the command
        (tmp_path / folder).mkdir()
    monkeypatch.chdir(tmp_path / "unbroken")
    assert main(argv) == 0
    monkeypatch.chdir(tmp_path / "stopped")
    err = _ctrl_c_in(monkeypatch, capsys, spcopyro.cli.fit_write, "print_concepts", argv)
    out, checkpoint = tmp_path / "stopped" / "out", checkpoint_path("out")
    command = shlex.join(["spcopyro", *argv, "--resume", str(checkpoint)])
    assert err == (
        f"interrupted while writing the outputs: nothing written to {out}; the finished fit is "
        f"saved in {checkpoint} -- write its outputs (without fitting again) with: {command}"
    )
    assert not out.exists() and not list(tmp_path.glob("stopped/out.partial*"))

    def no_fit(*args, **kwargs):
        raise AssertionError("the finished fit was run again")

    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.fit.house, "fit_house_chains", no_fit)
        assert main(shlex.split(command)[1:]) == 0
    assert f"removed {checkpoint}" in capsys.readouterr().out and not checkpoint.exists()
    _same_outputs(out, tmp_path / "unbroken" / "out")


def test_ctrl_c_from_a_terminal_while_cavi_s_outputs_are_written(tmp_path):
    """The same through a real ``spcopyro fit --method cavi`` process: SIGINT to its process
    group (a terminal's Ctrl-C) once its staging folder holds ``result.npz`` (written first of
    the outputs, before the figures), waited for by polling, not a fixed sleep. Exit 130, the
    line above, nothing left beside OUT, no process of the run left. A run the signal reached
    only once OUT was committed (a very fast machine) is tried again."""
    import glob
    import os
    import signal
    import subprocess
    import sys
    import time

    env = {k: v for k, v in os.environ.items() if k != "SPCOPYRO_TIMINGS"}
    for attempt in range(3):
        out = tmp_path / f"out{attempt}"
        argv = [sys.executable, "-m", "spcopyro", "fit", "--method", "cavi", "--sweeps", "20",
                "--out", str(out)]  # fmt: skip
        errors = tmp_path / f"stderr{attempt}.txt"
        with errors.open("w") as sink:  # a file: a pipe unread while polling could fill
            process = subprocess.Popen(
                argv, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=sink,
                start_new_session=True,
            )  # fmt: skip
        try:
            deadline = time.monotonic() + 120
            while process.poll() is None and time.monotonic() < deadline:
                if glob.glob(str(tmp_path / f"out{attempt}.partial-*" / "result.npz")):
                    os.killpg(process.pid, signal.SIGINT)
                    break
                time.sleep(0.005)
            process.wait(timeout=60)
        finally:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
        err = errors.read_text()
        if process.returncode == 0 or "was written" in err:
            continue  # the signal came after the commit: again
        break
    else:
        pytest.skip("the fit's outputs were written before the signal reached it, 3 times")
    line = err.splitlines()[-1]
    assert process.returncode == 130, err
    assert line.startswith(f"interrupted while writing the outputs: nothing written to {out}")
    checkpoint = checkpoint_path(out)
    assert line.endswith(
        f"the finished fit is saved in {checkpoint} -- write its outputs (without fitting "
        f"again) with: spcopyro fit --method cavi --sweeps 20 --out {out} --resume {checkpoint}"
    ), line
    assert list(tmp_path.glob(f"out{attempt}*")) == [checkpoint]  # no OUT or staging folder
    time.sleep(0.5)  # the figures' child, stopped by the fit, has been reaped by then
    ps = subprocess.run(["ps", "-eo", "pid,sid,stat"], capture_output=True, text=True).stdout
    left = [row for row in ps.splitlines()[1:] if row.split()[1] == str(process.pid)]
    assert not [row for row in left if not row.split()[2].startswith("Z")], left


@pytest.mark.parametrize(
    ("method", "article"),
    [("cavi", "a"), ("lbp", "an"), ("svi", "an"), ("stochastic-vi", "a")],
)
def test_the_interrupt_message_gives_each_method_its_article(method, article, tmp_path):
    """'an lbp checkpoint', 'an svi checkpoint' (was 'a lbp', 'a svi'), in the line that names
    a variational method's checkpoint."""
    import argparse

    from spcopyro._util.messages import with_article
    from spcopyro.cli.fit_resume import interrupted_message, resumable_methods

    assert method in resumable_methods()
    args = argparse.Namespace(method=method, sweeps=10, update=None, chains=3)
    line = interrupted_message(args, "", None, tmp_path / "out", finished=False)
    assert f"{article} {method} checkpoint holds one fit" in line, line
    spoken = {"gibbs": "a", "vi-gibbs": "a", "em": "an", "mcmc": "an", "ep": "an", "map": "a",
              "'svi'": "an", "'cavi'": "a", '"lbp"': "an"}  # fmt: skip
    for name, article in spoken.items():
        assert with_article(name) == f"{article} {name}"


def test_a_variational_checkpoint_of_several_seeds_is_refused_with_its_article(tmp_path):
    """fit_house_chains says "an 'lbp' checkpoint holds one fit" (was "a 'lbp'")."""
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house_chains
    from spcopyro.synthetic import make_house

    with pytest.raises(ValueError, match="^an 'lbp' checkpoint holds one fit; 2 seeds asked$"):
        fit_house_chains(make_house(seed=0), preset("original-code"), seeds=[0, 1],
                         method="lbp", checkpoint=tmp_path / "ck", progress=False)  # fmt: skip


def test_ctrl_c_while_writing_a_resumed_variational_fit_keeps_the_finished_fit(
    home, tmp_path, capsys, monkeypatch
):
    """A resumed cavi fit (``--resume CK``) stopped by Ctrl-C while its outputs are written:
    the finished fit replaces CK (the line said the iterations this run added were lost and CK
    was left as it was), and ``--resume CK`` writes OUT."""
    import shlex

    import spcopyro.cli.fit_write

    out = tmp_path / "out"
    argv = _stopped_cavi_fit(home, out, monkeypatch, capsys)
    checkpoint = checkpoint_path(out)

    resumed = [*argv, "--resume", str(checkpoint)]
    err = _ctrl_c_in(monkeypatch, capsys, spcopyro.cli.fit_write, "print_concepts", resumed)
    assert err == (
        f"interrupted while writing the outputs: nothing written to {out}; the finished fit is "
        f"saved in {checkpoint} -- write its outputs (without fitting again) with: "
        f"{shlex.join(['spcopyro', *resumed])}"
    )
    assert not out.exists()
    assert main(resumed) == 0 and (out / "result.npz").is_file() and not checkpoint.exists()


def test_a_resumed_finished_fit_that_cannot_be_saved_leaves_the_resumed_checkpoint(
    home, tmp_path, capsys, monkeypatch
):
    """A resumed cavi fit (``--resume CK``) stopped while writing, its finished fit not saved
    (a full disk): CK still holds the state the run resumed from, and the line says so. It said
    "the finished fit is saved in CK -- write its outputs (without fitting again)", which CK,
    a checkpoint of iterations, cannot do."""
    import shlex

    import spcopyro.cli.fit_finished
    import spcopyro.cli.fit_write

    def full_disk(path, *args, **kwargs):
        raise OSError(28, "No space left on device", str(path))

    out = tmp_path / "out"
    argv = _stopped_cavi_fit(home, out, monkeypatch, capsys)
    checkpoint = checkpoint_path(out)
    resumed = [*argv, "--resume", str(checkpoint)]
    monkeypatch.setattr(spcopyro.cli.fit_finished, "save_finished_fit", full_disk)
    err = _ctrl_c_in(monkeypatch, capsys, spcopyro.cli.fit_write, "print_concepts", resumed)
    assert err == (
        f"interrupted while writing the outputs: nothing written to {out}; the iterations this "
        f"run added are lost; {checkpoint} is left as it was, with the state this run resumed "
        f"from -- continue from there with: {shlex.join(['spcopyro', *resumed])}"
    ), err
    assert checkpoint.is_file() and not out.exists()


@pytest.mark.parametrize("method", ["cavi", "vi-gibbs"])
def test_a_finished_fit_that_cannot_be_saved_names_its_file(
    method, home, tmp_path, capsys, monkeypatch
):
    """Ctrl-C while a finished fit's outputs are written, and its file cannot be written
    (a full disk): the line names the file it could not save, OUT.checkpoint.npz (it named OUT,
    where nothing was to be saved), and says the fit is lost. vi-gibbs keeps no checkpoint of
    its sweeps but does keep its finished fit: it said "no checkpoint kept (the 'vi-gibbs'
    method)", as if none were ever kept."""
    import spcopyro.cli.fit_finished
    import spcopyro.cli.fit_write

    def full_disk(path, *args, **kwargs):
        raise OSError(28, "No space left on device", str(path))

    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT, "--method", method]
    monkeypatch.setattr(spcopyro.cli.fit_finished, "save_finished_fit", full_disk)
    err = _ctrl_c_in(monkeypatch, capsys, spcopyro.cli.fit_write, "print_concepts", argv)
    assert err.startswith(
        f"interrupted while writing the outputs: nothing written to {out}; no checkpoint kept "
        "(its iterations had all run; the finished fit could not be saved in "
        f"{checkpoint_path(out)}): the finished fit is lost -- run it again with: "
    ), err
    assert not out.exists() and not checkpoint_path(out).exists()


def _failing_print_concepts(*args, **kwargs):
    """``print_concepts`` failing as a full disk does, while a fit's outputs are written."""
    raise OSError(28, "No space left on device")


@pytest.mark.parametrize("method", ["cavi", "vi-gibbs"])
def test_an_error_while_writing_a_finished_fit_keeps_it_for_resume_to_write(
    method, home, tmp_path, capsys, monkeypatch
):
    """An error (not Ctrl-C: a full disk) while a finished cavi or vi-gibbs fit's outputs are
    written keeps the finished fit in OUT.checkpoint.npz, as Ctrl-C there does (it was lost
    without a word, where Gibbs kept its finished chains); the note names the file and the
    command, which writes OUT without fitting again."""
    import shlex

    import spcopyro.cli.fit_write
    import spcopyro.fit.house

    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), *FIT, "--method", method]
    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.cli.fit_write, "print_concepts", _failing_print_concepts)
        assert main(argv) == 2  # an OSError: one line, no traceback
    err = capsys.readouterr().err
    checkpoint = checkpoint_path(out)
    command = shlex.join(["spcopyro", *argv, "--resume", str(checkpoint)])
    assert (
        f"note: nothing written to {out}; the finished fit is saved in {checkpoint} -- once "
        f"fixed, write its outputs (without fitting again) with: {command}"
    ) in err.splitlines(), err
    assert checkpoint.is_file() and not out.exists()

    def no_fit(*args, **kwargs):
        raise AssertionError("the finished fit was run again")

    with monkeypatch.context() as patch:
        patch.setattr(spcopyro.fit.house, "fit_house_chains", no_fit)
        assert main(shlex.split(command)[1:]) == 0
    assert (out / "result.npz").is_file() and not checkpoint.exists()


@pytest.mark.parametrize(
    ("method", "extra"),
    [("lbp", ["--chains", "2"]), ("vi-gibbs", ["--chains", "2"]), ("gibbs", ["--update", "u"])],
)  # fmt: skip
def test_several_fits_or_an_update_not_saved_say_their_file_could_not_be(method, extra, tmp_path):
    """Ctrl-C while the outputs of two finished fits, or of an update, are written, where their
    file could not be written (a full disk): the line names the file. It blamed the method
    (vi-gibbs: "the 'vi-gibbs' method"), a checkpoint of iterations ("an lbp checkpoint holds
    one fit"), the file ("a finished fit's file holds one fit": since, it holds every fit) or
    ``--update``, which keep the finished fit now (test_fit_finished_several)."""
    from spcopyro.cli.fit_resume import interrupted_message
    from spcopyro.cli.main import build_parser

    out = tmp_path / "o"
    args = build_parser().parse_args(["fit", "--out", str(out), "--method", method, *extra,
                                      "--sweeps", "12"])  # fmt: skip
    line = interrupted_message(args, " while writing the outputs", None, out, finished=True)
    why = (f"no checkpoint kept (its iterations had all run; the finished fit could not be saved "
           f"in {checkpoint_path(out)}): the finished fit is lost")  # fmt: skip
    assert why in line, line
