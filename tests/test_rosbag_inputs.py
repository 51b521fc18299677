"""``spcopyro import-bag`` on awkward inputs: mistyped paths and topics (found before OUT is
looked at or any bag is read), 16-bit camera images, stamps out of order, a simulator's
recording with some images unstamped. Small bags written with
:class:`spcopyro.robot.rosbag.BagWriter`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.cli.main import main  # noqa: E402
from spcopyro.maps.grid import FREE, OccupancyGrid  # noqa: E402
from spcopyro.maps.map_server import save_map  # noqa: E402
from spcopyro.robot.rosbag import BagWriter  # noqa: E402

T0 = 1_600_000_000.0


@pytest.fixture
def map_yaml(tmp_path: Path) -> Path:
    """A 60 x 60 free map at 0.1 m, origin (-3, -3): x, y in [-3, 3) m."""
    grid = OccupancyGrid(np.full((60, 60), FREE, dtype=np.int8), 0.1, (-3.0, -3.0, 0.0))
    return save_map(grid, tmp_path / "maps" / "floor.yaml")


def _basic_bag(path: Path) -> Path:
    with BagWriter(path, ros=2) as w:
        for t in T0 + np.arange(4.0):
            w.pose("/amcl_pose", t, 0.1 * (t - T0), 0.0, 0.0)
        w.image("/camera/image", T0 + 1.0, np.zeros((4, 4, 3), np.uint8))
        w.text("/speech", T0 + 1.0, "hall")
    return path


@pytest.mark.parametrize(
    ("bag", "map_name", "extra", "expected"),
    [
        ("nope", "floor.yaml", [], "nope: bag not found"),
        ("maps", "floor.yaml", [], "maps: not a bag"),
        ("rec", "nomap.yaml", [], "nomap.yaml: map yaml not found"),
        ("rec", "floor.yaml", ["--image-topic", "/cam"], "no image topic '/cam'"),
        ("rec", "floor.yaml", ["--words-topic", "/words"], "no utterance topic '/words'"),
    ],
    ids=["missing-bag", "not-a-bag", "missing-map", "image-topic", "words-topic"],
)
def test_bad_inputs_are_named_before_out(
    tmp_path, map_yaml, capsys, monkeypatch, bag, map_name, extra, expected
):
    """A mistyped map, a path that is not a bag, or a topic that is not in a bag was reported
    as 'OUT already exists and is not empty' when OUT held an earlier run's folder, and with
    --overwrite a topic missing from the last bag was found only after the others were read."""
    monkeypatch.chdir(tmp_path)
    _basic_bag(tmp_path / "rec")
    (tmp_path / "data" / "house").mkdir(parents=True)
    (tmp_path / "data" / "house" / "notes.txt").write_text("mine\n")
    args = ["import-bag", bag, "--map", f"maps/{map_name}", "--out", "data/house", *extra]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert expected in err, err
    assert "already exists" not in err, err
    assert (tmp_path / "data" / "house" / "notes.txt").read_text() == "mine\n"
