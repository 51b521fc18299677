"""``import-bag --overwrite`` and ``simulate`` write a house folder and its map
(``../map/NAME.yaml`` and ``.pgm``) whole, together, or not at all
(:func:`spcopyro._util.folder_commit.commit_folder`): import-bag wrote the map in place before it
moved the folder in, so a failed or stopped import left a new map beside the old house; simulate
wrote every file in place, so one stopped halfway left half of a new house over the old one."""

from __future__ import annotations

import linecache
import os
import shutil
import signal
import sys
from pathlib import Path

import pytest
from bag_maps import four_pose_bag, free_grid

from spcopyro._util import folder_commit, outputs
from spcopyro.cli.interrupted import interrupted_line
from spcopyro.cli.main import build_parser, main


def _tree(root: Path) -> dict[str, bytes | None]:
    """Every entry under ``root`` by its path: a file's bytes, None for a folder."""
    return {
        str(path.relative_to(root)): None if path.is_dir() else path.read_bytes()
        for path in sorted(root.rglob("*"))
    }


@pytest.fixture
def no_swaps(monkeypatch):
    """No folder set aside by :func:`spcopyro._util.folder_commit.swapped_in`, nor OUT
    committed, recorded by another test, and none of this one's left for the next."""
    monkeypatch.setattr(folder_commit, "_SET_ASIDE", [])
    monkeypatch.setattr(folder_commit, "_COMPLETED", set())


def _sigint_at_the_maps_move(monkeypatch, map_folder: Path, signum: int = signal.SIGINT) -> None:
    """A Ctrl-C (a real SIGINT; or ``signum``) the moment the new map's first file is moved in."""
    replace = os.replace

    def replace_and_stop(source, target):
        if Path(target).parent == map_folder:
            monkeypatch.setattr(os, "replace", replace)
            os.kill(os.getpid(), signum)
        return replace(source, target)

    monkeypatch.setattr(os, "replace", replace_and_stop)


# --- import-bag ---------------------------------------------------------------------------


def _recording(tmp_path: Path) -> tuple[Path, Path, Path]:
    """(a bag of four poses, three images and a word, a map, another map with a wall)."""
    pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")
    from spcopyro.maps.map_server import save_map

    bag = four_pose_bag(tmp_path / "rec")
    plain = save_map(free_grid(), tmp_path / "m" / "a.yaml")  # tests/bag_maps.py
    walled = save_map(free_grid(wall=True), tmp_path / "m" / "b.yaml")
    return bag, plain, walled


@pytest.fixture
def imported(tmp_path):
    """(argv of an --overwrite import with another map, the house folder): an earlier import
    into ``data/house`` is there, with its map."""
    from spcopyro.robot.rosbag import import_bags

    bag, plain, walled = _recording(tmp_path)
    out = tmp_path / "data" / "house"
    import_bags([bag], walled, out)
    (out / "notes.txt").write_text("mine")
    return ["import-bag", str(bag), "--map", str(plain), "--out", str(out), "--overwrite"], out


@pytest.mark.parametrize("stop", [KeyboardInterrupt, OSError])
def test_a_failed_or_stopped_import_leaves_the_old_house_and_map(imported, monkeypatch, stop):
    """A Ctrl-C or an error as the import moves its house in: the old house and the old map,
    byte for byte, and nothing beside them (the new map was already written over the old)."""
    from spcopyro.robot.rosbag import importer

    argv, out = imported
    before = _tree(out.parent)

    def fail(*args, **kwargs):
        raise stop("stopped")

    monkeypatch.setattr(importer, "commit_folder", fail)
    with pytest.raises(stop):
        importer.import_bags([argv[1]], argv[3], out, overwrite=True)
    assert _tree(out.parent) == before
    assert interrupted_line(build_parser().parse_args(argv)).endswith(
        "map/house.yaml and .pgm are still the old map's (moved in with OUT)"
    )


def test_a_failed_map_write_leaves_the_old_house_and_map(imported, monkeypatch):
    """Writing the map stopped halfway (a full disk): the old map was left half-written."""
    from spcopyro.maps import map_server

    argv, out = imported
    before = _tree(out.parent)
    write_image = map_server._write_image

    def half_then_full(path, pixels):
        write_image(path, pixels)
        Path(path).write_bytes(Path(path).read_bytes()[:20])
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(map_server, "_write_image", half_then_full)
    assert main(argv) != 0  # the error said
    assert _tree(out.parent) == before


def test_a_ctrl_c_during_the_import_commit_waits_until_house_and_map_are_new(
    imported, monkeypatch, no_swaps
):
    """A Ctrl-C as the map is moved in is held until the folder and the map are both the new
    ones and the user's files are carried into the new folder: it was raised before, leaving
    them in .house.replaced-* and the new house without them."""
    from spcopyro.maps.map_server import load_map
    from spcopyro.robot.rosbag import import_bags

    argv, out = imported
    _sigint_at_the_maps_move(monkeypatch, out.parent / "map")
    with pytest.raises(KeyboardInterrupt):
        import_bags([argv[1]], argv[3], out, overwrite=True)
    assert load_map(out.parent / "map" / "house.yaml") == load_map(argv[3])
    assert sorted(p.name for p in out.parent.iterdir()) == ["house", "map"]  # nothing aside
    assert (out / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in (out.parent / "map").iterdir()) == ["house.pgm", "house.yaml"]
    assert interrupted_line(build_parser().parse_args(argv)).endswith(
        f"{out} was written whole; {out.parent / 'map' / 'house'}.yaml and .pgm are the new "
        "map's (moved in with OUT)"
    )


def test_a_ctrl_c_during_a_first_import_commit_says_it_was_written(tmp_path, monkeypatch, no_swaps):
    """A first import (no OUT before, nothing set aside), a Ctrl-C held as its map is moved in:
    the line said "nothing written to OUT" while OUT and its map were the new, complete ones."""
    bag, plain, _ = _recording(tmp_path)
    out = tmp_path / "data" / "house"
    argv = ["import-bag", str(bag), "--map", str(plain), "--out", str(out)]
    _sigint_at_the_maps_move(monkeypatch, out.parent / "map")
    assert main(argv) == 130
    assert sorted(p.name for p in out.parent.iterdir()) == ["house", "map"]
    assert sorted(p.name for p in (out.parent / "map").iterdir()) == ["house.pgm", "house.yaml"]
    assert interrupted_line(build_parser().parse_args(argv)) == (
        f"interrupted spcopyro import-bag: {out} was written whole"
    )


# --- simulate -----------------------------------------------------------------------------


def test_a_stopped_simulate_leaves_the_old_house_and_map(tmp_path, monkeypatch, capsys):
    """simulate --overwrite stopped while writing the new house: the old house and map, byte for
    byte, nothing beside them; then a whole run replaces them and keeps the user's notes."""
    from spcopyro.data import dataset

    root = tmp_path / "r"
    assert main(["simulate", "--out", str(root)]) == 0
    (root / "synthetic" / "notes.txt").write_text("mine")
    before = _tree(root)
    write_lines = dataset._write_lines

    def stopped_at_st_xty(path, lines, **kwargs):
        write_lines(path, list(lines)[:3], **kwargs)  # half of it
        if Path(path).name == "StXty.csv":
            raise KeyboardInterrupt

    monkeypatch.setattr(dataset, "_write_lines", stopped_at_st_xty)
    argv = ["simulate", "--out", str(root), "--seed", "1", "--overwrite"]
    capsys.readouterr()
    assert main(argv) == 130
    assert _tree(root) == before
    assert capsys.readouterr().err == (
        f"interrupted spcopyro simulate: nothing written to {root / 'synthetic'} and its map "
        f"{root / 'map' / 'synthetic'}.yaml (they are written whole at the end, or not at all)\n"
    )
    monkeypatch.setattr(dataset, "_write_lines", write_lines)
    assert main(argv) == 0
    after = _tree(root)
    assert sorted(after) == sorted(before)  # the same files, nothing beside them
    assert after["synthetic/notes.txt"] == b"mine"
    assert after["synthetic/Xtx.csv"] != before["synthetic/Xtx.csv"]
    assert after["map/synthetic.pgm"] != before["map/synthetic.pgm"]


def test_a_ctrl_c_during_the_simulate_commit_carries_the_users_files(
    tmp_path, monkeypatch, no_swaps
):
    """A Ctrl-C as the map is moved in is held until the house and map are both new and the
    user's files are carried into the new house: it was raised before that, leaving them in
    h.replaced-* and the new house without them."""
    root = tmp_path / "r"
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 0
    (root / "h" / "notes.txt").write_text("mine")
    argv = ["simulate", "--out", str(root), "--name", "h", "--seed", "1", "--overwrite"]
    _sigint_at_the_maps_move(monkeypatch, root / "map")
    assert main(argv) == 130
    assert sorted(p.name for p in root.iterdir()) == ["h", "map"]  # nothing set aside
    assert (root / "h" / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in (root / "map").iterdir()) == ["h.pgm", "h.yaml"]
    assert interrupted_line(build_parser().parse_args(argv)) == (
        f"interrupted spcopyro simulate: {root / 'h'} and its map {root / 'map' / 'h'}.yaml were "
        "written whole"
    )


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_during_a_first_simulate_commit_says_it_was_written(
    tmp_path, monkeypatch, capsys, no_swaps, signum
):
    """A first simulate (no house before: nothing set aside), stopped as its map is moved in:
    the line said "nothing written" while the house and map were the new, complete ones. SIGTERM
    (``timeout``) is held as Ctrl-C is: simulate had no handler for it, so it killed the process
    halfway through the renames."""
    root = tmp_path / "r"
    terminate = signal.getsignal(signal.SIGTERM)
    replace = os.replace

    def stopped(source, target):  # the default SIGTERM would end pytest: checked, not sent
        if Path(target).parent == root / "map":
            monkeypatch.setattr(os, "replace", replace)
            if signum == signal.SIGINT or signal.getsignal(signal.SIGTERM) is not terminate:
                os.kill(os.getpid(), signum)  # SIGTERM only to a handler: it is held
        return replace(source, target)

    monkeypatch.setattr(os, "replace", stopped)
    capsys.readouterr()
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 130
    assert sorted(p.name for p in root.iterdir()) == ["h", "map"]
    assert sorted(p.name for p in (root / "map").iterdir()) == ["h.pgm", "h.yaml"]
    assert capsys.readouterr().err == (
        f"interrupted spcopyro simulate: {root / 'h'} and its map {root / 'map' / 'h'}.yaml were "
        "written whole\n"
    )


def test_simulate_sweeps_the_staging_folders_a_killed_one_left(tmp_path):
    """``kill -9`` of a simulate leaves ``NAME.partial-PID-*`` beside the house and
    ``NAME.yaml.partial-PID-*`` beside its map: the next simulate removed neither (staging_folder
    skipped :func:`~spcopyro._util.outputs.remove_stale_stagings`)."""
    import subprocess
    import sys

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # a PID no process has now
    root = tmp_path / "r"
    stale = [root / f"h.partial-{dead.pid}-0a1b2c3d", root / "map" / f"h.yaml.partial-{dead.pid}-x"]
    for folder in stale:
        folder.mkdir(parents=True)
        (folder / "half.csv").write_text("1,")
    live = root / f"h.partial-{os.getpid()}-0a1b2c3d"  # this process's: not a dead one's
    live.mkdir()
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 0
    assert sorted(p.name for p in root.iterdir()) == sorted(["h", "map", live.name])
    assert sorted(p.name for p in (root / "map").iterdir()) == ["h.pgm", "h.yaml"]


def test_a_dead_ones_staged_map_holding_a_kept_old_file_is_not_swept(tmp_path, capsys):
    """A refused commit whose old map file could not be put back keeps it in the staged map
    folder as ``NAME.pgm.old`` and names it; once that process is gone, the next simulate into
    the same map swept the folder as stale and deleted the user's only copy."""
    import subprocess
    import sys

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # a PID no process has now
    root = tmp_path / "r"
    kept = root / "map" / f"h.yaml.partial-{dead.pid}-x"
    kept.mkdir(parents=True)
    (kept / "h.pgm.old").write_bytes(b"P5 old map")
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 0
    assert (kept / "h.pgm.old").read_bytes() == b"P5 old map"
    # and said again: the next run of the same command skipped the folder without a word
    assert capsys.readouterr().err == (
        f"warning: {kept / 'h.pgm.old'} is a file an earlier run replaced and could not put back "
        f"(its error said where): move it back, then remove {kept}\n"
    )


def test_deferred_signals_get_every_handler_back_when_putting_one_back_raises(monkeypatch):
    """A Ctrl-C pending as signals_deferred puts SIGINT's handler back raises there: SIGTERM's
    was left the deferring one (a SIGTERM after it then went to a dead list, ignored)."""
    from spcopyro._util import interrupts

    def term(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, term)
    try:
        put_back = signal.signal
        calls = []

        def raising_once(number, handler):
            calls.append(number)
            put_back(number, handler)
            if len(calls) == 3:  # the first put back (after the two deferring ones)
                raise KeyboardInterrupt("pending")

        monkeypatch.setattr(interrupts.signal, "signal", raising_once)
        with pytest.raises(KeyboardInterrupt, match="pending"):
            with interrupts.signals_deferred(lambda signum, frame: None):
                pass
        monkeypatch.setattr(interrupts.signal, "signal", put_back)
        assert calls == [signal.SIGINT, signal.SIGTERM, signal.SIGINT, signal.SIGTERM]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        assert signal.getsignal(signal.SIGTERM) is term
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_a_map_file_that_cannot_be_replaced_leaves_house_and_map_as_they_were(
    tmp_path, capsys, no_swaps
):
    """simulate --overwrite where a folder stands at map/h.yaml: the new map's .pgm and the
    house folder were moved in, the old house set aside in h.replaced-*, the staged yaml
    deleted, and the error was a bare ``[Errno 21] Is a directory``. Now nothing changes and
    the error says so; without the folder, the next run writes all."""
    root = tmp_path / "r"
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 0
    (root / "map" / "h.yaml").unlink()
    (root / "map" / "h.yaml").mkdir()
    before = _tree(root)
    argv = ["simulate", "--out", str(root), "--name", "h", "--seed", "1", "--overwrite"]
    capsys.readouterr()
    assert main(argv) == 2
    assert _tree(root) == before  # house, .pgm, nothing set aside or staged beside them
    assert capsys.readouterr().err == (
        f"error: cannot put {root / 'map' / 'h.yaml'} in place (Is a directory); {root / 'h'}, "
        f"{root / 'map' / 'h.pgm'}, {root / 'map' / 'h.yaml'} left as they were\n"
    )
    assert folder_commit.set_aside(root / "h") == [] and not folder_commit.completed(root / "h")
    fresh = tmp_path / "fresh"  # a first write: no house before, nor a .pgm
    (fresh / "map" / "h.yaml").mkdir(parents=True)
    assert main(["simulate", "--out", str(fresh), "--name", "h"]) == 2
    assert sorted(_tree(fresh)) == ["map", "map/h.yaml"]
    (root / "map" / "h.yaml").rmdir()
    assert main(argv) == 0
    assert sorted(p.name for p in (root / "map").iterdir()) == ["h.pgm", "h.yaml"]


def test_an_overwritten_house_and_map_keep_their_modes(tmp_path):
    """simulate --overwrite of a house folder made 0o750 and a map made 0o640: the new ones
    had the umask's modes (0o755, 0o644), opening them to every user."""
    root = tmp_path / "r"
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 0
    (root / "h").chmod(0o750)
    for name in ("h.pgm", "h.yaml"):
        (root / "map" / name).chmod(0o640)
    assert main(["simulate", "--out", str(root), "--name", "h", "--seed", "1", "--overwrite"]) == 0
    assert (root / "h").stat().st_mode & 0o7777 == 0o750
    for name in ("h.pgm", "h.yaml"):
        assert (root / "map" / name).stat().st_mode & 0o7777 == 0o640


def test_an_old_map_file_that_cannot_be_put_back_is_kept_and_named(tmp_path, capsys, no_swaps):
    """simulate --overwrite on a file system without hard links (the old h.pgm set aside, renamed
    into the staged map folder) where h.yaml cannot be moved in and the old h.pgm not put back:
    the put-back stopped there, the error was that of the put-back, and the staged map folder,
    the old h.pgm in it, was removed. Now the old h.pgm is kept where the message says, which
    says what to do (it named the file only)."""
    root = tmp_path / "r"
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 0
    old_pgm = (root / "map" / "h.pgm").read_bytes()
    (root / "map" / "h.yaml").unlink()
    (root / "map" / "h.yaml").mkdir()
    replace = os.replace

    def no_links(*args, **kwargs):
        raise OSError(1, "Operation not permitted")

    def no_putting_back(source, target):
        if str(source).endswith(".old"):
            raise PermissionError(13, "Permission denied")
        return replace(source, target)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(os, "link", no_links)
        patch.setattr(os, "replace", no_putting_back)
        argv = ["simulate", "--out", str(root), "--name", "h", "--seed", "1", "--overwrite"]
        assert main(argv) == 2
    err = capsys.readouterr().err
    kept = [path for path in root.rglob("*") if path.is_file() and path.read_bytes() == old_pgm]
    assert len(kept) == 1, kept  # and what to do with it: put it back, remove its folder
    assert err.endswith(
        f"it is kept as {kept[0]} (move it back to {root / 'map' / 'h.pgm'}, then remove "
        f"{kept[0].parent})\n"
    ), err
    assert err.startswith(
        f"error: cannot put {root / 'map' / 'h.yaml'} in place (Is a directory); {root / 'h'}, "
        f"{root / 'map' / 'h.yaml'} left as they were; the old {root / 'map' / 'h.pgm'} could "
        "not be put back (Permission denied)"
    )


def test_an_empty_house_folder_put_back_keeps_its_mode(tmp_path, capsys, no_swaps):
    """simulate into an empty house folder made 0o775 where map/h.yaml cannot be replaced: the
    empty folder made again had the umask's mode (0o755)."""
    root = tmp_path / "r"
    (root / "map" / "h.yaml").mkdir(parents=True)
    (root / "h").mkdir()
    (root / "h").chmod(0o775)
    umask = os.umask(0o022)
    try:
        assert main(["simulate", "--out", str(root), "--name", "h", "--overwrite"]) == 2
    finally:
        os.umask(umask)
    assert "cannot put" in capsys.readouterr().err
    assert sorted(_tree(root)) == ["h", "map", "map/h.yaml"]
    assert (root / "h").stat().st_mode & 0o7777 == 0o775


def test_a_ctrl_c_held_through_a_refused_commit_is_said_with_the_error(
    tmp_path, monkeypatch, capsys, no_swaps
):
    """simulate --overwrite where map/h.yaml cannot be replaced (a folder there), a Ctrl-C held
    as the new map is moved in: the error was said and the Ctrl-C dropped (exit status 2, as if
    it had not come). Now the error naming the path, then the Ctrl-C's line, and status 130;
    house and map as they were."""
    root = tmp_path / "r"
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 0
    (root / "map" / "h.yaml").unlink()
    (root / "map" / "h.yaml").mkdir()
    before = _tree(root)
    capsys.readouterr()
    _sigint_at_the_maps_move(monkeypatch, root / "map")
    assert (
        main(["simulate", "--out", str(root), "--name", "h", "--seed", "1", "--overwrite"]) == 130
    )
    assert _tree(root) == before
    assert capsys.readouterr().err == (
        f"error: cannot put {root / 'map' / 'h.yaml'} in place (Is a directory); {root / 'h'}, "
        f"{root / 'map' / 'h.pgm'}, {root / 'map' / 'h.yaml'} left as they were\n"
        f"interrupted spcopyro simulate: nothing written to {root / 'h'} and its map "
        f"{root / 'map' / 'h'}.yaml (they are written whole at the end, or not at all)\n"
    )


def test_an_import_whose_old_map_file_cannot_be_put_back_keeps_it_and_names_it(
    imported, capsys, no_swaps
):
    """import-bag --overwrite's side of the stranded case (simulate's is above; it had no test):
    on a file system without hard links, where map/house.yaml cannot be replaced and the old
    house.pgm not put back, the old house.pgm is kept in the staged map folder, which the error
    names with what to do, and the house folder is the old one."""
    argv, out = imported
    maps = out.parent / "map"
    old_pgm = (maps / "house.pgm").read_bytes()
    (maps / "house.yaml").unlink()
    (maps / "house.yaml").mkdir()
    replace = os.replace

    def no_links(*args, **kwargs):
        raise OSError(1, "Operation not permitted")

    def no_putting_back(source, target):
        if str(source).endswith(".old"):
            raise PermissionError(13, "Permission denied")
        return replace(source, target)

    capsys.readouterr()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(os, "link", no_links)
        patch.setattr(os, "replace", no_putting_back)
        assert main(argv) == 2
    err = capsys.readouterr().err
    kept = [path for path in out.parent.rglob("*.old") if path.read_bytes() == old_pgm]
    assert len(kept) == 1, (err, kept)
    line = err.splitlines()[-1]  # after the import's progress bar
    assert line.startswith(f"error: cannot put {maps / 'house.yaml'} in place (Is a directory)")
    assert err.endswith(
        f"it is kept as {kept[0]} (move it back to {maps / 'house.pgm'}, then remove "
        f"{kept[0].parent})\n"
    ), err
    assert (out / "notes.txt").read_text() == "mine"  # the old house, not the new one


# --- a second Ctrl-C as the replaced folder is removed ------------------------------------


def _ctrl_c_in_rmtree(monkeypatch, marker: str, at: int | None = None) -> list[int]:
    """A KeyboardInterrupt, as Python raises a Ctrl-C's at its next check, in shutil.rmtree
    removing a path with ``marker`` in it: at its ``at``-th line (counted over rmtree's frames
    for that path), or where None, at the line after its first ``os.close(...)`` (then its
    ``finally`` closes that descriptor again: Python 3.11). Returns the lines it was raised at
    (empty where the removal had fewer lines)."""
    raised: list[int] = []
    count = 0
    rmtree = shutil.rmtree

    def tracer(frame, event, arg):
        if event != "call" or frame.f_code.co_filename != shutil.__file__:
            return None
        if marker not in str(frame.f_locals.get("path", "")):
            return None
        closed = False

        def lines(frame, event, arg):
            nonlocal closed, count
            if event != "line" or raised:
                return lines
            count += 1
            if closed if at is None else count == at:
                raised.append(frame.f_lineno)
                raise KeyboardInterrupt
            closed = "os.close(" in linecache.getline(frame.f_code.co_filename, frame.f_lineno)
            return lines

        return lines

    def traced(path, *args, **kwargs):
        previous = sys.gettrace()
        sys.settrace(tracer)
        try:
            return rmtree(path, *args, **kwargs)
        finally:
            sys.settrace(previous)

    monkeypatch.setattr(shutil, "rmtree", traced)
    return raised


def test_a_second_ctrl_c_as_the_old_house_is_removed_is_said_as_one(
    tmp_path, monkeypatch, capsys, no_swaps
):
    """simulate --overwrite, a Ctrl-C held as the map is moved in, a second one just after
    rmtree closed the old house folder's descriptor as it removed it: rmtree closed it again in
    its ``finally`` and the EBADF stood for the Ctrl-C ("error: [Errno 9] Bad file descriptor",
    the new house already in place). Now the Ctrl-C's line, naming the old house's folder (what
    is left of it), and 130."""
    root = tmp_path / "r"
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 0
    (root / "h" / "notes.txt").write_text("mine")
    capsys.readouterr()
    _sigint_at_the_maps_move(monkeypatch, root / "map")
    raised = _ctrl_c_in_rmtree(monkeypatch, ".replaced-")
    argv = ["simulate", "--out", str(root), "--name", "h", "--seed", "1", "--overwrite"]
    assert main(argv) == 130
    assert raised  # it landed
    (aside,) = [p for p in root.iterdir() if p.name.startswith("h.replaced-")]
    assert capsys.readouterr().err == (
        f"interrupted spcopyro simulate: {root / 'h'} and its map {root / 'map' / 'h'}.yaml were "
        f"written whole; the old one, not yet removed, is in {aside}\n"
    )
    assert (root / "h" / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in (root / "map").iterdir()) == ["h.pgm", "h.yaml"]


def test_a_ctrl_c_anywhere_in_the_old_folders_removal_is_a_ctrl_c(tmp_path, monkeypatch, no_swaps):
    """A Ctrl-C at each line of rmtree removing the set-aside OUT (a file and a folder of files
    in it) ends commit_folder with a KeyboardInterrupt, OUT the new one: at the line after a
    descriptor's close it was rmtree's OSError (EBADF)."""
    count = 0
    while True:
        count += 1
        case = tmp_path / str(count)
        (case / "N" / "sub").mkdir(parents=True)
        for path in (case / "N" / "a", case / "N" / "sub" / "b", case / "N" / "sub" / "c"):
            path.write_text("old")
        (case / "S").mkdir()
        (case / "S" / "new").write_text("new")
        with monkeypatch.context() as patch:
            raised = _ctrl_c_in_rmtree(patch, ".replaced-", at=count)
            try:
                folder_commit.commit_folder(case / "S", case / "N", {"a", "sub"})
            except KeyboardInterrupt:
                assert raised, count
            else:
                assert not raised, count
                break
        assert sorted(p.name for p in (case / "N").iterdir()) == ["new"], count
    assert count > 20  # every line of the removal tried


# --- a Ctrl-C as a writer's own leftovers are removed (remove_tree) -----------------------


def test_a_ctrl_c_as_a_stopped_simulates_staging_is_removed_is_one(tmp_path, monkeypatch, capsys):
    """simulate stopped while writing its house (a Ctrl-C), a second Ctrl-C just after rmtree
    closed the staging folder's descriptor as save_house removed it: the EBADF rmtree's
    ``finally`` raised stood for it ("error: [Errno 9] Bad file descriptor", status 2). Now the
    Ctrl-C's line and 130."""
    from spcopyro.data import dataset

    def stopped(house, room):
        raise KeyboardInterrupt

    monkeypatch.setattr(dataset, "_write_room", stopped)  # the staging folder left empty
    raised = _ctrl_c_in_rmtree(monkeypatch, f"{os.sep}h.partial-")
    root = tmp_path / "r"
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 130
    assert raised  # it landed
    assert capsys.readouterr().err.startswith("interrupted spcopyro simulate: nothing written")


def test_a_ctrl_c_as_the_staged_maps_folder_is_removed_is_one(tmp_path, monkeypatch):
    """stage_map removing its folder on leaving, a Ctrl-C just after rmtree closed the folder's
    descriptor: a KeyboardInterrupt, where it was rmtree's OSError (EBADF)."""
    from spcopyro.maps.map_server import stage_map

    raised = _ctrl_c_in_rmtree(monkeypatch, ".yaml.partial-")
    with pytest.raises(KeyboardInterrupt), stage_map(free_grid(), tmp_path / "m" / "a.yaml"):
        pass
    assert raised


def test_a_ctrl_c_as_a_stopped_simulate_bag_removes_its_bag_is_one(tmp_path, monkeypatch):
    """simulate-bag stopped (a Ctrl-C) before its map, a second Ctrl-C just after rmtree closed
    the ROS 2 bag folder's descriptor as the run removed what it wrote: a KeyboardInterrupt,
    where it was rmtree's OSError (EBADF)."""
    pytest.importorskip("rosbags", reason="simulate-bag needs rosbags (pip install .[ros])")
    from spcopyro.robot.rosbag import synthetic

    def stopped(grid, path):
        raise KeyboardInterrupt

    monkeypatch.setattr(synthetic, "save_map", stopped)  # the bags written, then stopped
    raised = _ctrl_c_in_rmtree(monkeypatch, f"{os.sep}trial_0")
    with pytest.raises(KeyboardInterrupt):
        synthetic.write_synthetic_bags(tmp_path / "bags", image_size=(8, 8), trials=[0])
    assert raised


def _import_stopped(monkeypatch, stop: type[BaseException]) -> None:
    """import_bags stopped by ``stop`` as it reads its first bag (its staging folder empty)."""
    from spcopyro.robot.rosbag import importer

    def stopped(*args, **kwargs):
        raise stop("stopped")

    monkeypatch.setattr(importer, "_import_one", stopped)


def test_a_ctrl_c_as_a_stopped_imports_staging_is_removed_is_one(tmp_path, monkeypatch):
    """import-bag stopped (a Ctrl-C), a second Ctrl-C just after rmtree closed the staging
    folder's descriptor as the import removed it: a KeyboardInterrupt, where it was rmtree's
    OSError (EBADF)."""
    from spcopyro.robot.rosbag import import_bags

    bag, plain, _ = _recording(tmp_path)
    _import_stopped(monkeypatch, KeyboardInterrupt)
    raised = _ctrl_c_in_rmtree(monkeypatch, ".house.partial-")
    with pytest.raises(KeyboardInterrupt):
        import_bags([bag], plain, tmp_path / "data" / "house")
    assert raised


def test_a_failed_import_whose_staging_cannot_be_removed_says_its_own_error(tmp_path, monkeypatch):
    """A failed import whose staging folder cannot be removed raises its own error, not the
    removal's (PermissionError, which stood for it); the folder left is this import's files
    only, and the next import into OUT sweeps it once this process is gone."""
    from spcopyro.robot.rosbag import import_bags

    bag, plain, _ = _recording(tmp_path)
    out = tmp_path / "data" / "house"
    _import_stopped(monkeypatch, ValueError)
    rmdir = os.rmdir

    def refused(path, *args, **kwargs):
        if ".house.partial-" in str(path):
            raise PermissionError(13, "Permission denied", str(path))
        return rmdir(path, *args, **kwargs)

    monkeypatch.setattr(os, "rmdir", refused)
    with pytest.raises(ValueError, match="stopped"):
        import_bags([bag], plain, out)
    monkeypatch.setattr(os, "rmdir", rmdir)
    (left,) = out.parent.glob(".house.partial-*")
    monkeypatch.setattr(outputs, "_alive", lambda pid: False)  # as the next process sees it
    assert outputs.remove_stale_stagings(out, hidden=True) == [left]
