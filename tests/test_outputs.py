"""Output folders that are never lost or mixed (:mod:`spcopyro._util.outputs`, ``fit --out``,
``--overwrite``) and the record ``config.json`` keeps of a run."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import torch

import spcopyro
from spcopyro._util.outputs import (
    OutputError,
    StagedOutput,
    check_output,
    checkpoint_path,
    replace_file,
    replace_text,
    stage_marked_folder,
    stage_output,
)
from spcopyro.cli.main import main
from spcopyro.results.result import SpCoResult
from spcopyro.synthetic import HouseSpec, write_synthetic

FIT = ["--sweeps", "6", "--preset", "original-code", "--gamma", "3", "--concepts", "8"]


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    root = tmp_path_factory.mktemp("data")
    return write_synthetic(root, seed=1, spec=HouseSpec(height=36, width=44, num_rooms=3))


@pytest.fixture(autouse=True)
def _no_progress_bars(monkeypatch):
    monkeypatch.setenv("CI", "1")  # stderr holds only what the command says


def _fit(room, out, *extra: str) -> int:
    return main(["fit", str(room), "--out", str(out), *FIT, *extra])


def _entries(folder) -> set[str]:
    return {path.name for path in folder.iterdir()}


def _fit_folder(folder, files=("result.npz", "config.json")):
    """A folder that looks like a fit's output."""
    folder.mkdir(parents=True)
    for name in files:
        (folder / name).write_text("old run\n")
    return folder


# -- refusing and replacing --------------------------------------------------------------------


def test_a_non_empty_out_is_refused_before_anything_is_read_or_sampled(
    room, tmp_path, capsys, monkeypatch
):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    import spcopyro.fit.house

    def no_sampling(*args, **kwargs):
        raise AssertionError("the fit went on to prepare its data")

    monkeypatch.setattr(spcopyro.fit.house, "prepare_model_data", no_sampling)
    before = _entries(tmp_path)
    assert _fit(room, out) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: --out {out}: {out} exists and is not empty; pass --overwrite")
    assert err.count("\n") == 1
    assert _entries(tmp_path) == before and _entries(out) == {"notes.txt"}
    # --overwrite replaces only a fit's folder: notes.txt is no fit's output
    assert _fit(room, out, "--overwrite") == 2
    assert "no result.npz or config.json" in capsys.readouterr().err
    assert _entries(tmp_path) == before and _entries(out) == {"notes.txt"}


def test_an_empty_or_missing_out_is_fine_and_a_file_is_not(tmp_path):
    (tmp_path / "empty").mkdir()
    assert check_output(tmp_path / "empty") == tmp_path / "empty"
    assert check_output(tmp_path / "a" / "b") == tmp_path / "a" / "b"
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_output(tmp_path / "file")


def test_overwrite_replaces_the_fits_files_and_keeps_the_rest(room, tmp_path, capsys):
    """No file the old run wrote survives (chains.json of a two-chain fit); what it did not
    write (a user's notes) is kept: its manifest says which are its own (issue 22 item 3)."""
    out = tmp_path / "out"
    assert _fit(room, out, "--chains", "2") == 0
    assert "chains.json" in _entries(out)
    manifest = json.loads((out / "outputs.json").read_text())["files"]
    assert set(manifest) == _entries(out)
    (out / "stray.txt").write_text("old\n")
    capsys.readouterr()
    assert _fit(room, out) == 2  # without --overwrite: refused, untouched
    assert "stray.txt" in _entries(out)
    assert _fit(room, out, "--overwrite") == 0
    assert "chains.json" not in _entries(out)
    assert (out / "stray.txt").read_text() == "old\n"
    assert "stray.txt" not in json.loads((out / "outputs.json").read_text())["files"]
    assert {"result.npz", "config.json", "labels.npy", "semantic_map.png"} <= _entries(out)
    assert json.loads((out / "config.json").read_text())["inference"]["seed"] == 0
    assert not [p for p in tmp_path.iterdir() if ".partial-" in p.name or ".replaced-" in p.name]


def test_an_unwritable_place_is_reported_before_sampling(room, tmp_path, capsys, monkeypatch):
    import spcopyro.fit.house

    def no_sampling(*args, **kwargs):
        raise AssertionError("the fit went on to prepare its data")

    monkeypatch.setattr(spcopyro.fit.house, "prepare_model_data", no_sampling)
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    assert _fit(room, blocker / "out") == 2  # its parent is a file
    err = capsys.readouterr().err
    assert err.startswith("error: --out ") and f"{blocker} is a file, not a folder" in err
    import spcopyro._util.outputs

    def refused(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    with monkeypatch.context() as patch:  # what a read-only parent does (also when run as root)
        patch.setattr(spcopyro._util.outputs, "_new_folder", refused)
        assert _fit(room, tmp_path / "out") == 2
    err = capsys.readouterr().err
    assert f"cannot write in {tmp_path} (Permission denied)" in err
    assert _entries(tmp_path) == {"a_file"}
    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders: the real permission case is not checked")
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        assert _fit(room, locked / "out") == 2
        assert "cannot write in" in capsys.readouterr().err
        assert _entries(locked) == set()
    finally:
        locked.chmod(0o700)


def test_a_failed_fit_leaves_no_output_and_keeps_its_chains(room, tmp_path, capsys, monkeypatch):
    """An error while writing: no OUT, no staging folder; the finished chains stay in the
    checkpoint, and resuming from it writes what an unbroken fit writes."""
    import spcopyro.figures.plotting

    out = tmp_path / "out"
    plot_trace = spcopyro.figures.plotting.plot_trace

    def broken(*args, **kwargs):
        raise ValueError("the figure could not be drawn")

    monkeypatch.setattr(spcopyro.figures.plotting, "plot_trace", broken)
    assert _fit(room, out) == 2
    err = capsys.readouterr().err
    assert "could not be drawn" in err and "continue with: spcopyro fit" in err
    assert _entries(tmp_path) == {checkpoint_path(out).name}
    monkeypatch.setattr(spcopyro.figures.plotting, "plot_trace", plot_trace)
    assert _fit(room, out, "--resume", str(checkpoint_path(out))) == 0
    assert _fit(room, tmp_path / "unbroken") == 0
    unbroken = tmp_path / "unbroken" / "result.npz"
    with np.load(out / "result.npz") as mine, np.load(unbroken) as theirs:
        for name in ("labels", "pi", "objective", "labels_final"):  # closed: no ResourceWarning
            np.testing.assert_array_equal(mine[name], theirs[name])
    assert _entries(tmp_path) == {"out", "unbroken"}


def test_the_staging_folder_sits_beside_out_and_goes_when_discarded(tmp_path):
    with pytest.raises(RuntimeError), stage_output(tmp_path / "out") as staged:
        assert staged.path.parent == tmp_path and staged.path.name.startswith("out.partial-")
        (staged.path / "half.txt").write_text("x")
        raise RuntimeError("crash")
    assert _entries(tmp_path) == set()


def test_a_ctrl_c_between_the_overwrite_renames_waits_for_the_whole_new_out(tmp_path, monkeypatch):
    """fit/export/navigate --overwrite (StagedOutput.commit) had its own swap, unguarded: a Ctrl-C
    just after the old OUT was set aside left no OUT (the old one in OUT.replaced-*); now the
    commit is :func:`~spcopyro._util.folder_commit.commit_folder`'s, the Ctrl-C held until OUT is
    the new one with the user's files carried over, then raised (the commit marked done)."""
    import signal

    from spcopyro._util import folder_commit

    monkeypatch.setattr(folder_commit, "_SET_ASIDE", [])
    monkeypatch.setattr(folder_commit, "_COMPLETED", set())
    out = _fit_folder(tmp_path / "out")
    (out / "notes.txt").write_text("mine")
    staged = stage_output(out, overwrite=True)
    (staged.path / "result.npz").write_text("new run\n")
    rename = os.rename

    def set_aside_then_stop(source, target):
        rename(source, target)
        if ".replaced-" in str(target):  # the old OUT set aside, the new one not yet in
            monkeypatch.setattr(os, "rename", rename)
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(os, "rename", set_aside_then_stop)
    with pytest.raises(KeyboardInterrupt):
        staged.commit()
    assert staged.committed
    assert _entries(tmp_path) == {"out"}  # nothing set aside, no staging folder left
    assert _entries(out) == {"result.npz", "notes.txt", "outputs.json"}
    assert (out / "result.npz").read_text() == "new run\n"


def test_a_ctrl_c_held_through_a_refused_commit_is_on_its_output_error(tmp_path, monkeypatch):
    """An empty OUT written into after staging: the rename is refused and StagedOutput.commit
    says so in an OutputError, which carries commit_folder's ``signalled`` (the Ctrl-C held
    meanwhile) for cli.main to say it (status 130); it was on the OSError, its __context__."""
    import signal

    out = tmp_path / "out"
    out.mkdir()
    staged = stage_output(out)
    (staged.path / "result.npz").write_text("new run\n")
    (out / "other.txt").write_text("another run's")  # OUT not empty any more, the same folder
    rename = os.rename

    def stopped_then_refused(source, target):
        os.kill(os.getpid(), signal.SIGINT)  # held by commit_folder until the renames end
        rename(source, target)

    monkeypatch.setattr(os, "rename", stopped_then_refused)
    with pytest.raises(OutputError, match="could not be written") as error:
        staged.commit()
    assert error.value.signalled == [signal.SIGINT]
    assert staged.kept and (staged.path / "result.npz").is_file()


# -- two fits into one folder --------------------------------------------------------------------


@pytest.mark.parametrize("overwrite", [False, True])
def test_two_stagings_race_and_one_wins_whole(tmp_path, overwrite):
    out = tmp_path / "out"
    if overwrite:
        _fit_folder(out, ("result.npz", "config.json", "old.txt"))
    first = stage_output(out, overwrite=overwrite)
    second = stage_output(out, overwrite=overwrite)
    for staged, name in ((first, "first.txt"), (second, "second.txt")):
        (staged.path / "result.npz").write_text(name)
        (staged.path / name).write_text(name)
    assert first.commit() == out
    with pytest.raises(OutputError, match="written by another process") as error:
        second.commit()
    assert str(second.path) in str(error.value)
    second.discard()  # kept: its files are named in the message
    assert (second.path / "second.txt").is_file()
    kept = {"old.txt"} if overwrite else set()  # not the old fit's: carried over
    assert _entries(out) == {"result.npz", "first.txt", "outputs.json"} | kept
    assert (out / "result.npz").read_text() == "first.txt"


def test_two_processes_commit_at_once_and_one_wins_whole(tmp_path):
    """Two processes stage OUT (an earlier fit's folder) with --overwrite, wait for each other,
    then commit at once: one replaces OUT whole, the other fails and keeps its files."""
    out = _fit_folder(tmp_path / "out", ("result.npz", "config.json", "old.txt"))
    script = textwrap.dedent(
        """
        import sys, time
        from pathlib import Path
        from spcopyro._util.outputs import OutputError, stage_output
        me, out = sys.argv[1], Path(sys.argv[2])
        staged = stage_output(out, overwrite=True)
        for name in ("result.npz", "config.json", me):
            (staged.path / name).write_text(me)
        (out.parent / f"ready-{me}").touch()
        while len(list(out.parent.glob("ready-*"))) < 2:
            time.sleep(0.01)
        try:
            staged.commit()
        except OutputError as error:
            print(error)
            sys.exit(3)
        """
    )
    env = {**os.environ, "PYTHONPATH": str(Path(spcopyro.__file__).parents[1])}
    runs = [
        subprocess.Popen(
            [sys.executable, "-c", script, name, str(out)],
            env=env,
            stdout=subprocess.PIPE,
            text=True,
        )  # fmt: skip
        for name in ("one", "two")
    ]
    messages = [run.communicate(timeout=120)[0] for run in runs]
    codes = [run.returncode for run in runs]
    assert sorted(codes) == [0, 3], messages
    winner = ("one", "two")[codes.index(0)]
    assert _entries(out) == {"result.npz", "config.json", winner, "outputs.json", "old.txt"}
    written = _entries(out) - {"outputs.json", "old.txt"}  # old.txt: the user's, carried over
    assert all((out / name).read_text() == winner for name in written)
    assert "written by another process" in messages[codes.index(3)]


def test_a_commit_holds_a_lock_on_the_parent_folder(tmp_path, monkeypatch):
    """While a commit looks at OUT and renames, no other commit can take the parent's lock."""
    fcntl = pytest.importorskip("fcntl")
    import spcopyro._util.outputs

    rename = os.rename
    tried: list[bool] = []

    def rename_and_try_the_lock(source, target):
        descriptor = os.open(tmp_path, os.O_RDONLY)
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
            tried.append(True)  # the lock was free: another commit could interleave
        except BlockingIOError:
            tried.append(False)
        finally:
            os.close(descriptor)
        rename(source, target)

    staged = stage_output(tmp_path / "out")
    monkeypatch.setattr(spcopyro._util.outputs.os, "rename", rename_and_try_the_lock)
    staged.commit()
    assert tried == [False]


def test_a_second_cli_fit_that_finishes_first_wins_and_the_first_fails(
    room, tmp_path, capsys, monkeypatch
):
    out = tmp_path / "out"
    commit = StagedOutput.commit
    raced: list[int] = []

    def racing_commit(self):
        if not raced:  # the first fit, about to commit: another one runs to its end first
            raced.append(-1)
            raced[0] = _fit(room, out, "--seed", "1")
        return commit(self)

    monkeypatch.setattr(StagedOutput, "commit", racing_commit)
    assert _fit(room, out, "--seed", "0") == 2
    assert raced == [0]
    err = capsys.readouterr().err
    assert "was written by another process while this fit ran" in err
    assert json.loads((out / "config.json").read_text())["inference"]["seed"] == 1
    kept = [p for p in tmp_path.iterdir() if p.name.startswith("out.partial-")]
    assert len(kept) == 1 and str(kept[0]) in err
    assert json.loads((kept[0] / "config.json").read_text())["inference"]["seed"] == 0
    assert not checkpoint_path(out).exists()


def test_replace_file_leaves_the_old_file_when_writing_fails(tmp_path):
    path = tmp_path / "f.bin"
    replace_file(path, lambda f: f.write(b"old"))

    def half(file):
        file.write(b"ne")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        replace_file(path, half)
    assert path.read_bytes() == b"old" and _entries(tmp_path) == {"f.bin"}


@pytest.mark.parametrize("umask", [0o022, 0o077])
def test_outputs_get_the_permissions_of_the_users_umask(tmp_path, umask):
    """A committed output folder (a fit's, a Nav2 export's) and a replaced file have the mode a
    plain mkdir / open gives under the umask: 0755 / 0644 under 022 (tempfile's 0700 / 0600 kept
    a map server running as another user from reading an export)."""
    previous = os.umask(umask)
    try:
        with stage_output(tmp_path / "fit") as staged:
            (staged.path / "labels.npy").write_bytes(b"x")
            out = staged.commit()
        export = stage_marked_folder(tmp_path / "nav2", False, option="--nav2",
                                     marker="nav2.json", writer="export")  # fmt: skip
        exported = export.commit()
        file = replace_file(tmp_path / "checkpoint.npz", lambda f: f.write(b"x"))
    finally:
        os.umask(previous)
    assert (out.stat().st_mode & 0o777) == 0o777 & ~umask
    assert (exported.stat().st_mode & 0o777) == 0o777 & ~umask
    assert (file.stat().st_mode & 0o777) == 0o666 & ~umask


def test_a_replaced_file_keeps_its_mode(tmp_path):
    """A report or checkpoint made 0o640 and replaced (replace_file) came back 0o644, the
    umask's, opening it to every user, where a map replaced with a house keeps its mode
    (file_moves.move_files_in) and a file rewritten by ``open`` keeps its own."""
    path = tmp_path / "report.md"
    path.write_text("old")
    path.chmod(0o640)
    previous = os.umask(0o022)
    try:
        replace_text(path, "new")
    finally:
        os.umask(previous)
    assert path.read_text() == "new" and path.stat().st_mode & 0o7777 == 0o640


# -- the record of a run -----------------------------------------------------------------------


def test_config_json_records_source_versions_backend_and_command(room, tmp_path, capsys):
    import pyro

    out = tmp_path / "out"
    assert _fit(room, out, "--backend", "torch") == 0
    printed = capsys.readouterr().out
    assert "backend used     torch" in printed
    settings = json.loads((out / "config.json").read_text())
    assert settings["source"]["data"] == str(room.resolve())
    assert settings["source"]["house"] == room.name and len(settings["source"]["data_sha256"]) == 64
    software = settings["software"]
    assert software["torch"] == torch.__version__ and software["pyro"] == pyro.__version__
    assert software["numpy"] == np.__version__ and software["spcopyro"]
    assert "numba" in software and software["python"]
    inference = settings["inference"]
    assert inference["backend"] == "torch" and inference["backend_used"] == "torch"
    assert inference["seed"] == 0 and inference["sweeps"] == 6 and inference["init"] == "random"
    assert "different random streams" in settings["reproducibility"]
    assert (
        settings["command"].startswith("spcopyro fit ") and "--backend torch" in settings["command"]
    )
    loaded = SpCoResult.load(out)
    assert loaded.provenance["source"] == settings["source"]
    assert loaded.settings_json() == settings


def test_auto_backend_is_resolved_and_the_embedded_house_named(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fit", "--out", str(out), *FIT]) == 0
    settings = json.loads((out / "config.json").read_text())
    from spcopyro.gibbs.backends import get_backend

    used = get_backend("auto").name
    assert settings["inference"]["backend"] == "auto"
    assert settings["inference"]["backend_used"] == used
    assert f"backend used     {used}" in capsys.readouterr().out
    assert settings["source"]["data"] == "embedded synthetic house, seed 0"


def test_a_refined_fit_of_the_embedded_house_still_names_it(tmp_path):
    """The refinement's refit recorded "in-memory house 'synthetic' (not read from a folder)"
    as config.json's source for ``spcopyro fit`` with no DATA (the default preset refines)."""
    out = tmp_path / "out"
    assert main(["fit", "--out", str(out), "--sweeps", "2", "--refine", "always",
                 "--no-figures"]) == 0  # fmt: skip
    settings = json.loads((out / "config.json").read_text())
    assert settings["inference"]["refine"]["refine"] is True
    assert settings["source"]["data"] == "embedded synthetic house, seed 0"


def test_sweeps_auto_records_the_backend_used(room, tmp_path):
    out = tmp_path / "out"
    argv = ["fit", str(room), "--out", str(out), "--sweeps", "auto", "--chains", "2",
            "--max-sweeps", "16", "--concepts", "4", "--backend", "torch"]  # fmt: skip
    assert main(argv) == 0
    settings = json.loads((out / "config.json").read_text())
    assert settings["inference"]["backend_used"] == "torch"
    assert settings["source"]["data"] == str(room.resolve())
    assert {"convergence.json", "result.npz"} <= _entries(out)


def test_overwrite_refuses_an_out_that_holds_the_input_data(tmp_path, capsys):
    """Issue 22 item 3: ``fit proj/synthetic --out proj --overwrite``, where ``proj`` is an
    earlier fit's folder that also holds the data, used to delete ``proj/synthetic`` and
    ``proj/map``. Now refused, naming the input, and nothing is deleted."""
    proj = _fit_folder(tmp_path / "proj")  # an earlier fit's folder ...
    data = write_synthetic(proj, seed=1, spec=HouseSpec(height=36, width=44, num_rooms=3))
    before = sorted(p.relative_to(proj) for p in proj.rglob("*"))
    capsys.readouterr()
    assert _fit(data, proj, "--overwrite") == 2
    err = capsys.readouterr().err
    assert f"holds the input {data}" in err and "choose an --out outside the data" in err
    assert sorted(p.relative_to(proj) for p in proj.rglob("*")) == before
    # The library check names the input too, with or without --overwrite.
    with pytest.raises(OutputError, match="holds the input"):
        check_output(proj, overwrite=False, inputs=(data / "Ft.csv",))
    assert check_output(tmp_path / "elsewhere", inputs=(data,)) == tmp_path / "elsewhere"


def test_check_folder_path_is_the_one_file_in_the_way_error(tmp_path):
    """Seven commands checked for a file in the way of their output folder, each in its own
    words and exception; one function now (an OutputError and a NotADirectoryError)."""
    from spcopyro._util.outputs import NotAFolderError, check_folder_path

    taken = tmp_path / "notes.txt"
    taken.write_text("mine")
    assert check_folder_path(tmp_path / "a" / "b", "--out X") == tmp_path
    for path in (taken, taken / "a" / "b"):
        with pytest.raises(NotAFolderError, match=rf"^--out X: {taken} is a file, not a folder$"):
            check_folder_path(path, "--out X")
    assert issubclass(NotAFolderError, OutputError) and issubclass(NotAFolderError, OSError)


def test_an_empty_out_the_shell_stands_in_is_refused(tmp_path, monkeypatch):
    """fit --out . (and export --nav2 ., navigate --out .) in an empty folder moved the finished
    folder onto it: the shell was left in a deleted folder that listed nothing."""
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    with pytest.raises(OutputError, match=rf"--out \.: {here} holds the current directory"):
        check_output(".")
    with pytest.raises(OutputError, match=r"--nav2 \.: .* holds the current directory"):
        stage_marked_folder(".", False, option="--nav2", marker="m", writer="export")
    monkeypatch.chdir(tmp_path)
    assert check_output(here) == here  # from outside it: written as before


def test_a_killed_exports_staging_folder_is_swept_by_the_next_export(tmp_path):
    """``kill -9`` of ``export --nav2 DIR`` (or ``navigate --out DIR``) leaves its staging
    folder beside DIR; stage_marked_folder named it ``DIR.partial-XXXX``, without the PID that
    remove_stale_stagings reads, so no later export removed it. Now it is
    ``DIR.partial-PID-XXXX`` and the next export into DIR sweeps a dead process's (a live one's,
    and one with no PID, are left)."""
    from tests.test_nav2 import top_and_bottom

    fit = top_and_bottom().save(tmp_path / "fit")
    out = tmp_path / "nav2"
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # a PID no process has now
    stale = tmp_path / f"nav2.partial-{dead.pid}-0a1b2c3d"
    stale.mkdir()
    (stale / "map.pgm").write_bytes(b"P5 half written")
    live = tmp_path / f"nav2.partial-{os.getpid()}-0a1b2c3d"  # this process's: alive
    live.mkdir()
    other = tmp_path / "nav2.partial-0a1b2c3d"  # no PID: not ours to judge
    other.mkdir()

    staged = stage_marked_folder(out, False, option="--nav2", marker="nav2_export.json",
                                 writer="export")  # fmt: skip
    assert staged.path.name.startswith(f"nav2.partial-{os.getpid()}-")  # a kill leaves a PID
    staged.discard()
    assert not stale.exists() and live.exists() and other.exists()

    stale.mkdir()  # the command line's export sweeps it too
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen"]) == 0
    assert not stale.exists() and (out / "nav2_export.json").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["fit", "nav2", live.name, other.name]
    )
