"""``spcopyro import-bag --overwrite`` (spcopyro/robot/rosbag/house_folder.py): what it may
replace is decided by the earlier import's record (bag_import.json: the trials it wrote), not by
names alone, and the map beside OUT is replaced only when it is an earlier import's."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
from bag_maps import four_pose_bag, free_grid

from spcopyro._util.outputs import OutputError

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.cli.main import main  # noqa: E402
from spcopyro.maps.map_server import load_map, save_map  # noqa: E402
from spcopyro.robot.rosbag import import_bags  # noqa: E402


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    return four_pose_bag(tmp_path / "rec")


@pytest.fixture
def bag_copy(tmp_path: Path, bag: Path) -> Path:
    """A copy of ``bag``: a second trial (the same bag twice is refused)."""
    return Path(shutil.copytree(bag, tmp_path / "rec_copy"))


def test_a_different_map_beside_no_import_is_not_replaced(tmp_path, bag, map_yaml, capsys):
    """QA: with --overwrite, a different map at OUT/../map/NAME.yaml was replaced whenever OUT
    was missing or empty, though no import had written it (another tool's map, a house folder
    removed by hand): only the house folder's name tied it to the import."""
    other = save_map(free_grid(wall=True), tmp_path / "data" / "map" / "house.yaml")
    before = other.read_bytes(), other.with_suffix(".pgm").read_bytes()
    out = tmp_path / "data" / "house"
    argv = ["import-bag", str(bag), "--map", str(map_yaml), "--out", str(out), "--overwrite"]
    assert main(argv) == 2
    assert "holds no earlier import (no bag_import.json) whose map it would be" in (
        capsys.readouterr().err
    )
    assert (other.read_bytes(), other.with_suffix(".pgm").read_bytes()) == before
    assert not out.exists()
    out.mkdir()  # an empty folder is no earlier import either
    with pytest.raises(FileExistsError, match="not replacing it, even with --overwrite"):
        import_bags([bag], map_yaml, out, overwrite=True)
    assert load_map(other) == free_grid(wall=True)


def test_the_earlier_imports_map_is_replaced_and_said(tmp_path, bag, map_yaml, capsys):
    out = tmp_path / "data" / "house"
    walled = save_map(free_grid(wall=True), tmp_path / "maps" / "walled.yaml")
    assert not import_bags([bag], walled, out).map_replaced
    argv = ["import-bag", str(bag), "--map", str(map_yaml), "--out", str(out), "--overwrite"]
    assert main(argv) == 0
    target = tmp_path / "data" / "map" / "house.yaml"
    assert f"warning: --overwrite replaced the map {target} of the earlier import" in (
        capsys.readouterr().err
    )
    assert load_map(target) == free_grid()
    assert not import_bags([bag], map_yaml, out, overwrite=True).map_replaced  # the same map


def test_overwrite_keeps_the_trials_the_earlier_import_did_not_write(
    tmp_path, bag, bag_copy, map_yaml
):
    """QA: --overwrite replaced every img_K/pose_K.csv/word_K.csv by name, so a trial added by
    hand beside an import (img_5, pose_5.csv, word_5.csv) was deleted without a word; now what
    the earlier import wrote is read from its bag_import.json, and the rest kept and named."""
    out = tmp_path / "data" / "house"
    import_bags([bag, bag_copy], map_yaml, out)  # trials 0 and 1
    (out / "img_5").mkdir()
    (out / "img_5" / "00000.png").write_bytes(b"mine")
    (out / "pose_5.csv").write_text("0,0,0,1\n")
    report = import_bags([bag], map_yaml, out, overwrite=True)  # trial 0 only
    assert report.kept == ("img_5", "pose_5.csv")
    assert (out / "img_5" / "00000.png").read_bytes() == b"mine"
    assert not (out / "img_1").exists() and not (out / "pose_1.csv").exists()  # the import's


def test_overwrite_refuses_an_entry_it_would_write_that_the_import_did_not(
    tmp_path, bag, bag_copy, map_yaml
):
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out)  # trial 0
    (out / "pose_1.csv").write_text("mine\n")
    with pytest.raises(FileExistsError, match=r"holds pose_1\.csv, which the import there did"):
        import_bags([bag, bag_copy], map_yaml, out, overwrite=True)  # would write trials 0 and 1
    assert (out / "pose_1.csv").read_text() == "mine\n"
    import_bags([bag], map_yaml, out, overwrite=True, first_trial=0)  # trial 0 only: fine
    assert (out / "pose_1.csv").read_text() == "mine\n"


def test_overwrite_needs_an_import_record_and_a_real_folder(tmp_path, bag, map_yaml):
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out)
    marker = out / "bag_import.json"
    for text in ("{not json", json.dumps({"bags": []}), json.dumps({"trials": [{"trial": -1}]})):
        marker.write_text(text)
        with pytest.raises(FileExistsError, match=r"bag_import\.json is not a record import-bag"):
            import_bags([bag], map_yaml, out, overwrite=True)
        assert (out / "pose_0.csv").is_file()
    link = tmp_path / "data" / "link"
    os.symlink(out, link)
    with pytest.raises(FileExistsError, match="is a symbolic link"):
        import_bags([bag], map_yaml, link, overwrite=True)
    assert (out / "pose_0.csv").is_file() and link.is_symlink()


def test_an_out_under_a_file_says_so(tmp_path, bag, map_yaml):
    """QA: import-bag --out FILE/house said "[Errno 17] File exists: 'FILE'"."""
    taken = tmp_path / "notes.txt"
    taken.write_text("mine")
    for out in (taken, taken / "house"):
        with pytest.raises(NotADirectoryError, match=rf"^--out {out}: {taken} is a file, not a "):
            import_bags([bag], map_yaml, out)  # the one message (_util.outputs.check_folder_path)
    assert taken.read_text() == "mine"


def test_a_kept_ft_csv_is_called_stale_only_when_the_images_changed(
    tmp_path, bag, bag_copy, map_yaml, capsys
):
    """QA: re-importing the very same bags (say, to fix the map) warned that the kept Ft.csv
    "does not describe these [images]: write it again", though they were the same bytes."""
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out)
    (out / "Ft.csv").write_text("0.5,0.5\n")
    argv = ["import-bag", str(bag), "--map", str(map_yaml), "--out", str(out), "--overwrite"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err
    assert "the images are the replaced import's, byte for byte" in captured.out
    report = import_bags([bag, bag_copy], map_yaml, out, overwrite=True)  # a second trial's images
    assert report.kept == ("Ft.csv",) and not report.images_unchanged
    assert main([*argv, "--min-distance", "1"]) == 0  # fewer images of trial 0
    assert "the images differ from the replaced import's" in capsys.readouterr().err


def test_overwrite_refuses_the_folder_it_is_run_in(tmp_path, bag, map_yaml, monkeypatch):
    """QA: import-bag --overwrite run inside OUT (or a folder of it) replaced OUT and deleted the
    shell's current directory under it; fit --overwrite and export refuse that."""
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out)
    for here in (out, out / "img_0"):
        monkeypatch.chdir(here)
        with pytest.raises(OutputError, match="holds the current directory"):
            import_bags([bag], map_yaml, out, overwrite=True)
    assert (out / "img_0").is_dir() and (out / "pose_0.csv").is_file()
    empty = tmp_path / "empty"  # an empty OUT run in was replaced too: the shell's folder gone
    empty.mkdir()
    monkeypatch.chdir(empty)
    with pytest.raises(OutputError, match=r"holds the current directory.*--out empty\)"):
        import_bags([bag], map_yaml, empty)
    assert not any(empty.iterdir())


def test_an_unreadable_map_of_an_earlier_import_is_replaced_with_overwrite(tmp_path, bag, map_yaml):
    """QA: a broken map at map/NAME.yaml (invalid yaml, a missing key) stopped every later
    import, --overwrite or not, with the map loader's error, as if --map were broken."""
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out)
    target = tmp_path / "data" / "map" / "house.yaml"
    target.write_text("garbage: [\n")
    assert import_bags([bag], map_yaml, out, overwrite=True).map_replaced
    assert load_map(target) == free_grid()
    other = tmp_path / "data" / "other"  # beside no import: refused even with --overwrite
    (tmp_path / "data" / "map" / "other.yaml").write_text("garbage: [\n")
    with pytest.raises(FileExistsError, match=r"cannot be read as a map .*pass --overwrite"):
        import_bags([bag], map_yaml, other)
    with pytest.raises(FileExistsError, match="cannot be read as a map .* holds no earlier"):
        import_bags([bag], map_yaml, other, overwrite=True)
    assert not other.exists()
