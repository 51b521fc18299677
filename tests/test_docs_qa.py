"""What a QA pass over the documentation (README, docs/commands.md, robot.md, defaults.md) found
the code doing differently from what the pages say."""

from __future__ import annotations

import pytest

from spcopyro.cli.main import main


@pytest.mark.parametrize("init", ["random", "rooms"])
def test_update_refuses_any_init(tmp_path, capsys, init):
    """docs/robot.md: "`--update` cannot be combined with ... `--init`". An explicit
    ``--init random`` was accepted and ignored (the check compared with the value the preset
    fills in, random for an update); now every ``--init`` is refused, before any data is read."""
    out = tmp_path / "out"
    assert main(["fit", "--out", str(out), "--update", str(tmp_path), "--init", init]) == 2
    assert "--update starts from the saved fit; --init chooses another start" in (
        capsys.readouterr().err
    )
    assert not out.exists()


def test_fit_refusal_says_overwrite_keeps_other_files(tmp_path, capsys):
    """docs/commands.md: ``--overwrite`` replaces the files the old fit wrote and keeps anything
    else (notes, ``where`` figures); the refusal without it said "(its files are then deleted)"."""
    out = tmp_path / "fit"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    assert main(["fit", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "its files are then deleted" not in err
    assert "the files the earlier fit wrote are then deleted, others kept" in err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def test_robot_page_names_the_p_navigate_prints_on_room1dk5():
    """docs/robot.md's room1dk5 walk quoted navigate's two stop lines as 'p = 0.58 and 0.78 of
    the word's concept'; the stop line prints the goal cell's p(cell in the word's place)
    ('goal cell: p(cell is the place) = ...', spcopyro/cli/navigate.py), not where's p(C | word).
    Re-run (fit --sweeps 2000, navigate --start=-4.7,-1.3): 0.575 and 0.777, equal there to
    where's p(C | word) for living and kitchen, since the goal cells lie inside their regions."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    source = (root / "spcopyro" / "cli" / "navigate.py").read_text(encoding="utf-8")
    assert "(goal cell: p(cell is the place) = {choice.candidate.probability:.3f}; " in source
    page = re.sub(r"\s+", " ", (root / "docs" / "robot.md").read_text(encoding="utf-8"))
    start = page.index("prints `route: entrance -> living -> kitchen`")
    paragraph = page[start : page.index("![navigate on room1dk5", start)]
    assert "of the word's concept" not in paragraph, paragraph
    assert "`goal cell: p(cell is the place) = 0.575` and `0.777`" in paragraph, paragraph
    assert "p(cell in the word's place) at each goal cell" in paragraph, paragraph


def test_robot_page_walks_run_features_as_written():
    """docs/robot.md's walkthrough ran `spcopyro features data/house --out data/house/Ft.csv`
    with `--weights random` only in a comment: `features` defaults to the ImageNet weights and
    stops where torchvision has none cached, and the walk's numbers (180 images, ARI 0.66) are
    of random weights. Every `spcopyro features` line of the page's bash blocks names them."""
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "robot.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```bash\n(.*?)```", page, flags=re.DOTALL)
    lines = [
        line.split("#", 1)[0]
        for block in blocks
        for line in block.splitlines()
        if line.startswith("spcopyro features ")
    ]
    assert len(lines) >= 2, lines  # the short walk and the walkthrough
    for line in lines:
        assert "--weights random" in line, line
