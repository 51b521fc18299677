"""``import-bag --overwrite`` and ``simulate`` write a house folder and its map
(``../map/NAME.yaml`` and ``.pgm``) whole, together, or not at all
(:func:`spcopyro._util.outputs.commit_folder`): import-bag wrote the map in place before it moved
the folder in, so a failed or stopped import left a new map beside the old house; simulate wrote
every file in place, so one stopped halfway left half of a new house over the old one."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import numpy as np
import pytest

from spcopyro._util import outputs
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
    """No folder set aside by :func:`spcopyro._util.outputs.swapped_in` recorded by another
    test, and none of this one's left for the next."""
    monkeypatch.setattr(outputs, "_SET_ASIDE", [])


def _sigint_at_the_maps_move(monkeypatch, map_folder: Path) -> None:
    """A Ctrl-C (a real SIGINT) the moment the new map's first file is moved over the old."""
    replace = os.replace

    def replace_and_stop(source, target):
        if Path(target).parent == map_folder:
            monkeypatch.setattr(os, "replace", replace)
            os.kill(os.getpid(), signal.SIGINT)
        return replace(source, target)

    monkeypatch.setattr(os, "replace", replace_and_stop)


# --- import-bag ---------------------------------------------------------------------------


@pytest.fixture
def imported(tmp_path):
    """(argv of an --overwrite import with another map, the house folder): an earlier import
    into ``data/house`` is there, with its map."""
    pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")
    from spcopyro.maps.grid import FREE, OCCUPIED, OccupancyGrid
    from spcopyro.maps.map_server import save_map
    from spcopyro.robot.rosbag import BagWriter, import_bags

    bag, t0 = tmp_path / "rec", 1_600_000_000.0
    with BagWriter(bag, ros=2) as w:
        for t in t0 + np.arange(4.0):
            w.pose("/amcl_pose", t, 0.5 * (t - t0), 0.0, 0.0)
        for k, t in enumerate(t0 + np.array([0.5, 1.5, 2.5])):
            w.image("/camera/image", t, np.full((6, 8, 3), 40 * k, dtype=np.uint8))
        w.text("/speech", t0 + 1.0, "kitchen")
    cells = np.full((60, 60), FREE, dtype=np.int8)
    plain = save_map(OccupancyGrid(cells.copy(), 0.1, (-3.0, -3.0, 0.0)), tmp_path / "m" / "a.yaml")
    cells[0, :] = OCCUPIED
    walled = save_map(OccupancyGrid(cells, 0.1, (-3.0, -3.0, 0.0)), tmp_path / "m" / "b.yaml")
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

    monkeypatch.setattr(importer, "replace_out", fail)
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
    ones; the old folder, not yet removed, is named by the Ctrl-C line."""
    from spcopyro.maps.map_server import load_map
    from spcopyro.robot.rosbag import import_bags

    argv, out = imported
    _sigint_at_the_maps_move(monkeypatch, out.parent / "map")
    with pytest.raises(KeyboardInterrupt):
        import_bags([argv[1]], argv[3], out, overwrite=True)
    assert load_map(out.parent / "map" / "house.yaml") == load_map(argv[3])
    (aside,) = [p.name for p in out.parent.iterdir() if p.name.startswith(".house.replaced-")]
    assert sorted(p.name for p in out.parent.iterdir()) == sorted(["house", "map", aside])
    assert sorted(p.name for p in (out.parent / "map").iterdir()) == ["house.pgm", "house.yaml"]
    assert interrupted_line(build_parser().parse_args(argv)).endswith(
        f"is in {out.parent / aside}; {out.parent / 'map' / 'house'}.yaml and .pgm are the new "
        "map's (moved in with OUT)"
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


def test_a_ctrl_c_during_the_simulate_commit_names_the_old_house(tmp_path, monkeypatch, no_swaps):
    """A Ctrl-C as the map is moved in is held until the house and map are both new; the line
    names the old house's folder, set aside and not yet removed."""
    root = tmp_path / "r"
    assert main(["simulate", "--out", str(root), "--name", "h"]) == 0
    argv = ["simulate", "--out", str(root), "--name", "h", "--seed", "1", "--overwrite"]
    _sigint_at_the_maps_move(monkeypatch, root / "map")
    assert main(argv) == 130
    (aside,) = [p.name for p in root.iterdir() if p.name.startswith("h.replaced-")]
    assert sorted(p.name for p in root.iterdir()) == sorted(["h", "map", aside])
    assert sorted(p.name for p in (root / "map").iterdir()) == ["h.pgm", "h.yaml"]
    assert interrupted_line(build_parser().parse_args(argv)) == (
        f"interrupted spcopyro simulate: {root / 'h'} and its map {root / 'map' / 'h'}.yaml are "
        f"the new ones, written whole; what of the old {root / 'h'} was not yet carried into it "
        f"is in {root / aside}"
    )
