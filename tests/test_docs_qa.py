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
