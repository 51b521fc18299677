"""The line ``spcopyro`` prints when Ctrl-C stops a command other than ``fit``: it said a bare
"interrupted", naming neither the command nor what became of its output."""

from __future__ import annotations

import pytest

from spcopyro.cli import main as main_module
from spcopyro.cli import simulate as simulate_module
from spcopyro.cli.interrupted import interrupted_line
from spcopyro.cli.main import build_parser, main


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["export", "R", "--nav2", "N"], "interrupted spcopyro export: nothing written to N (it "
         "is written whole at the end, or not at all)"),
        (["navigate", "R", "go to the kitchen", "--start", "0,0"],
         "interrupted spcopyro navigate: nothing written"),
        (["navigate", "R", "kitchen", "--start", "0,0", "--out", "P"],
         "interrupted spcopyro navigate: nothing written to P (it is written whole at the end, "
         "or not at all)"),
        (["features", "I", "--out", "F.csv"], "interrupted spcopyro features: nothing written to "
         "F.csv (it is written whole at the end, or not at all)"),
        (["import-bag", "B", "--map", "M", "--out", "H"], "interrupted spcopyro import-bag: "
         "nothing written to H (it is written whole at the end, or not at all)"),
        (["simulate-bag", "--out", "B"],
         "interrupted spcopyro simulate-bag: what it had written to B is removed"),
        (["where", "R", "kitchen"], "interrupted spcopyro where: nothing written"),
        (["where", "R", "kitchen", "--out", "w.png"], "interrupted spcopyro where: w.png and "
         "w_probability.png are each written whole or not at all (a file there before stays "
         "until it is replaced)"),
        (["where", "R", "kitchen", "--out", "d/w"], "interrupted spcopyro where: d/w.png and "
         "d/w_probability.png are each written whole or not at all (a file there before stays "
         "until it is replaced)"),
        (["show", "--out", "s.png"], "interrupted spcopyro show: s.png is written whole or not "
         "at all (a file there before stays until it is replaced)"),
        (["show", "R", "--graph", "--out", "g.png"], "interrupted spcopyro show: g.png and "
         "g.json are each written whole or not at all (a file there before stays until it is "
         "replaced)"),
        (["import-bag", "B", "--map", "M", "--out", "d/H", "--overwrite"], "interrupted "
         "spcopyro import-bag: nothing written to d/H (it is written whole at the end, or not "
         "at all); d/map/H.yaml and .pgm are still the old map's (moved in with OUT)"),
        (["fit", "D", "--out", "O"], "interrupted spcopyro fit: nothing written to O (it is "
         "written whole at the end, or not at all)"),
        (["study", "S", "--out", "O"], "interrupted spcopyro study: O keeps the cells finished "
         "so far; run the same command again to continue"),
        (["compare-inference", "--out", "C"], "interrupted spcopyro compare-inference: C keeps "
         "the cells finished so far; run the same command again to continue"),
    ],
)  # fmt: skip
def test_the_line_names_the_command_and_what_became_of_its_output(argv, said):
    assert interrupted_line(build_parser().parse_args(argv)) == said


def test_ctrl_c_in_simulate_names_it_and_its_folder(tmp_path, monkeypatch, capsys):
    """simulate writes its house whole, with its map: the line names both (it said the folder
    "may hold half-written files" while simulate wrote in place)."""

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(simulate_module, "_simulate", interrupted)
    assert main(["simulate", "--out", str(tmp_path / "h")]) == 130
    house = tmp_path / "h" / "synthetic"
    assert capsys.readouterr().err == (
        f"interrupted spcopyro simulate: nothing written to {house} and its map "
        f"{tmp_path / 'h' / 'map' / 'synthetic'}.yaml (they are written whole at the end, or not "
        "at all)\n"
    )


@pytest.mark.parametrize(
    ("options", "name"),
    [([], "synthetic"), (["--name", "h"], "h"), (["--map", "m/lab.yaml"], "lab"),
     (["--map", "m/lab.yaml", "--name", "h"], "h")],
)  # fmt: skip
def test_the_simulate_line_names_the_house_as_simulate_names_it(options, name):
    args = build_parser().parse_args(["simulate", "--out", "r", *options])
    assert interrupted_line(args) == (
        f"interrupted spcopyro simulate: nothing written to r/{name} and its map r/map/{name}.yaml "
        "(they are written whole at the end, or not at all)"
    )


def test_where_and_show_name_the_files_they_write():
    """The line's files are those ``where`` and ``show --graph`` write (the probability figure,
    the JSON beside the graph), named by the one definition the commands use
    (:mod:`spcopyro.cli.out_names`), not a copy of it in interrupted.py."""
    from pathlib import Path

    from spcopyro.cli import interrupted, main, navigate, simulate
    from spcopyro.cli.interrupted import _figures
    from spcopyro.cli.out_names import graph_json, probability_figure

    assert interrupted.probability_figure is main.probability_figure is probability_figure
    assert interrupted.house_name is simulate.house_name  # simulate's OUT/NAME, defined once
    assert interrupted.graph_json is navigate.graph_json is graph_json
    for out in ("w.png", "d/w", "w.jpg"):
        args = build_parser().parse_args(["where", "R", "kitchen", "--out", out])
        figure = Path(out if Path(out).suffix else f"{out}.png")
        assert _figures(args, out) == [str(figure), str(probability_figure(Path(out)))]
        assert str(probability_figure(figure)).endswith(f"_probability{figure.suffix}")
        args = build_parser().parse_args(["show", "R", "--graph", "--out", out])
        assert _figures(args, out) == [str(figure), str(figure.with_suffix(".json"))]


def _overwrite_args(command: str):
    argv = (["export", "R", "--nav2", "N", "--overwrite"] if command == "export"
            else ["import-bag", "B", "--map", "M", "--out", "N", "--overwrite"])  # fmt: skip
    return build_parser().parse_args(argv)


def _map_note(command: str, new: bool = False) -> str:
    return (f"; map/N.yaml and .pgm are {'the new' if new else 'still the old'} map's (moved in "
            "with OUT)") if command == "import-bag" else ""  # fmt: skip


@pytest.fixture
def no_swaps(monkeypatch):
    """No folder set aside by :func:`spcopyro._util.folder_commit.swapped_in`, nor OUT committed,
    in this process, and none this test sets aside or commits left recorded for the next."""
    from spcopyro._util import folder_commit

    monkeypatch.setattr(folder_commit, "_SET_ASIDE", [])
    monkeypatch.setattr(folder_commit, "_COMPLETED", set())


@pytest.mark.parametrize(("command", "hidden"), [("export", ""), ("import-bag", ".")])
def test_a_ctrl_c_as_the_replaced_folder_is_removed_names_it(
    tmp_path, monkeypatch, no_swaps, command, hidden
):
    """--overwrite sets the old OUT aside (OUT.replaced-XXXXXXXX, hidden for import-bag), puts
    the new one in its place and carries the user's files over, a Ctrl-C held meanwhile; one
    that comes as the old folder is then removed (the handlers back) leaves OUT new and whole
    and the earlier run's own files in the set-aside folder, which the line names."""
    import os
    import shutil
    import signal

    from spcopyro._util.folder_commit import commit_folder

    monkeypatch.chdir(tmp_path)
    (tmp_path / "N").mkdir()
    (tmp_path / "N" / "old.txt").write_text("the earlier run's")
    (tmp_path / "N" / "notes.txt").write_text("mine")
    (tmp_path / "S").mkdir()  # the new OUT, staged
    rmtree = shutil.rmtree

    def stopped(path, *args, **kwargs):
        if ".replaced-" in str(path):
            os.kill(os.getpid(), signal.SIGINT)
        return rmtree(path, *args, **kwargs)

    monkeypatch.setattr(shutil, "rmtree", stopped)
    with pytest.raises(KeyboardInterrupt):
        commit_folder(tmp_path / "S", tmp_path / "N", {"old.txt"}, hidden=bool(hidden))
    monkeypatch.setattr(shutil, "rmtree", rmtree)
    assert sorted(p.name for p in (tmp_path / "N").iterdir()) == ["notes.txt"]
    (aside,) = [p.name for p in tmp_path.iterdir() if p.name.startswith(f"{hidden}N.replaced-")]
    assert interrupted_line(_overwrite_args(command)) == (
        f"interrupted spcopyro {command}: N was written whole; the old one, not yet removed, is "
        f"in {aside}{_map_note(command, new=True)}"
    )


@pytest.mark.parametrize(("command", "hidden"), [("export", ""), ("import-bag", ".")])
def test_a_set_aside_folder_an_earlier_run_left_does_not_make_out_the_new_one(
    tmp_path, monkeypatch, no_swaps, command, hidden
):
    """swapped_in keeps the set-aside folder after a stopped run, and nothing removes it: a later
    --overwrite stopped before its own swap said "N is the new one, written whole" from that
    leftover while N was still the old one."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "N").mkdir()  # the old OUT, not replaced by this run
    (tmp_path / f"{hidden}N.replaced-0a1b2c3d").mkdir()  # an earlier run's leftover
    assert interrupted_line(_overwrite_args(command)) == (
        f"interrupted spcopyro {command}: nothing written to N (it is written whole at the end, "
        f"or not at all){_map_note(command)}"
    )
    (tmp_path / "N").rmdir()  # nor, with no N, that this run set the old one aside
    assert "replaced-" not in interrupted_line(_overwrite_args(command))


def test_a_second_ctrl_c_as_the_line_is_said_ends_as_cleanly(tmp_path, monkeypatch, capsys):
    """The first Ctrl-C held through a commit and raised once the renames are done; a second one
    as the command's line was being said ended main with a KeyboardInterrupt (a traceback, not
    the line and status 130)."""
    import os
    import signal

    def interrupted(args):
        raise KeyboardInterrupt

    said = main_module.interrupted_line

    def second_ctrl_c(args):
        os.kill(os.getpid(), signal.SIGINT)
        return said(args)

    monkeypatch.setattr(simulate_module, "_simulate", interrupted)
    monkeypatch.setattr(main_module, "interrupted_line", second_ctrl_c)
    try:
        code = main(["simulate", "--out", str(tmp_path / "h")])
    except KeyboardInterrupt:
        pytest.fail("the second Ctrl-C escaped main: a traceback")
    assert code == 130
    assert capsys.readouterr().err.startswith("interrupted spcopyro simulate: nothing written")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.parametrize(
    ("stop", "at", "said"),
    [(KeyboardInterrupt, "_say_interrupted", ""),
     (OSError, "_say_interrupted", "error: a commit failed, a Ctrl-C held\n"),
     (OSError, "_error_line", "")],
)  # fmt: skip
def test_a_second_ctrl_c_before_the_line_is_guarded_ends_as_cleanly(
    tmp_path, monkeypatch, capsys, stop, at, said
):
    """A second Ctrl-C between main's ``except`` and :func:`_say_interrupted`'s guard (as Python
    raises one at its next check: at the call of ``_say_interrupted``, or of ``_error_line`` as
    the error of a commit with a Ctrl-C held is said) escaped main: a traceback, not the line
    and 130. A tracer raises it on entering that function."""
    import sys

    def stopped(args):
        if stop is KeyboardInterrupt:
            raise KeyboardInterrupt
        error = OSError("a commit failed, a Ctrl-C held")
        error.signalled = [2]
        raise error

    target = getattr(main_module, at).__code__
    raised = []

    def tracer(frame, event, arg):
        if event == "call" and frame.f_code is target and not raised:
            raised.append(at)
            raise KeyboardInterrupt
        return None

    monkeypatch.setattr(simulate_module, "_simulate", stopped)
    previous = sys.gettrace()
    sys.settrace(tracer)
    try:
        code = main(["simulate", "--out", str(tmp_path / "h")])
    except KeyboardInterrupt:
        pytest.fail("the second Ctrl-C escaped main: a traceback")
    finally:
        sys.settrace(previous)
    assert raised
    assert code == 130
    assert capsys.readouterr().err == (
        f"{said}interrupted spcopyro simulate: nothing written to {tmp_path / 'h' / 'synthetic'} "
        f"and its map {tmp_path / 'h' / 'map' / 'synthetic'}.yaml (they are written whole at the "
        "end, or not at all)\n"
    )


def test_a_ctrl_c_held_through_a_failed_commit_of_simulate_is_said_after_its_error(
    tmp_path, monkeypatch, capsys
):
    """simulate names its flag in a FileExistsError it raises again ``from None``: the new error
    has no ``signalled``, but the commit's error it replaces (its ``__context__``, kept under
    ``__suppress_context__``) does, so main still says the Ctrl-C held through the commit after
    the error: its line and 130, not 2."""
    import errno
    import os
    import signal

    import spcopyro._util.folder_commit as folder_commit

    def refused(files, folder):  # a Ctrl-C as the commit moves the map, then EEXIST (a fake:
        # the real move_files_in raises FilesNotMoved, an OSError, with the folder put back)
        os.kill(os.getpid(), signal.SIGINT)  # held by commit_folder
        raise FileExistsError(errno.EEXIST, "File exists", str(folder))

    monkeypatch.setattr(folder_commit, "move_files_in", refused)
    out = tmp_path / "h"
    assert main(["simulate", "--out", str(out)]) == 130
    error = capsys.readouterr().err
    assert error.startswith(f"error: [Errno 17] File exists: '{out / 'synthetic'}'\n")
    assert "\ninterrupted spcopyro simulate: " in error
