"""The line ``spcopyro`` prints when Ctrl-C stops a command other than ``fit``: it said a bare
"interrupted", naming neither the command nor what became of its output."""

from __future__ import annotations

import pytest

from spcopyro.cli import main as main_module
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
        (["where", "R", "kitchen", "--out", "w.png"], "interrupted spcopyro where: w.png may "
         "hold half-written files; run the same command again to write them whole"),
        (["show", "--out", "s.png"], "interrupted spcopyro show: s.png may hold half-written "
         "files; run the same command again to write them whole"),
        (["study", "S", "--out", "O"], "interrupted spcopyro study: O keeps the cells finished "
         "so far; run the same command again to continue"),
        (["compare-inference", "--out", "C"], "interrupted spcopyro compare-inference: C keeps "
         "the cells finished so far; run the same command again to continue"),
    ],
)  # fmt: skip
def test_the_line_names_the_command_and_what_became_of_its_output(argv, said):
    assert interrupted_line(build_parser().parse_args(argv)) == said


def test_ctrl_c_in_simulate_names_it_and_its_folder(tmp_path, monkeypatch, capsys):
    """simulate writes its house in place: the line says which folder may be half-written."""

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(main_module, "_simulate", interrupted)
    assert main(["simulate", "--out", str(tmp_path / "h")]) == 130
    assert capsys.readouterr().err == (
        f"interrupted spcopyro simulate: {tmp_path / 'h'} may hold half-written files; run the "
        "same command again (with --overwrite) to write them whole\n"
    )
