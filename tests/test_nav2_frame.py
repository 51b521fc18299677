"""`spcopyro export --frame`: the tf frame of the Nav2 masks (the fit of tests/test_nav2.py)."""

from __future__ import annotations

import json

import pytest
import yaml
from test_nav2 import top_and_bottom

from spcopyro.cli.main import main


@pytest.fixture
def fit(tmp_path):
    return top_and_bottom().save(tmp_path / "fit")


def _mask_frame(out, name):
    params = yaml.safe_load((out / f"{name}_params.yaml").read_text())
    return params[f"{name}_mask_server"]["ros__parameters"]["frame_id"]


@pytest.mark.parametrize(("mode", "argv", "frame"), [
    ("keepout", [], "map"),
    ("keepout", ["--frame", "robot1/map"], "robot1/map"),
    ("speed", ["--frame", "world"], "world"),
])  # fmt: skip
def test_the_masks_are_in_the_frame_given(fit, tmp_path, mode, argv, frame):
    """QA: the mask servers' frame_id was always "map": a robot whose global frame is another
    ("robot1/map" in a fleet) got masks its costmap filters could not transform (no "map" in
    its tf tree), so the filters had no mask; --frame names it, the default stays "map"."""
    out = tmp_path / "nav2"
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen", "--mode", mode,
                 *argv]) == 0  # fmt: skip
    assert _mask_frame(out, f"{mode}_kitchen") == frame
    assert json.loads((out / "nav2_export.json").read_text())["frame"] == frame


@pytest.mark.parametrize("frame", ["/map", "my map", ""])
def test_a_frame_tf2_refuses_is_refused_before_anything_is_written(fit, tmp_path, capsys, frame):
    out = tmp_path / "nav2"
    assert main(["export", str(fit), "--nav2", str(out), "--word", "kitchen",
                 f"--frame={frame}"]) == 2  # fmt: skip
    assert f"frame {frame!r}" in capsys.readouterr().err
    assert not out.exists()
