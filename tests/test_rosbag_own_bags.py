"""``spcopyro import-bag`` on bags as a robot records them, not as simulate-bag writes them: tf
samples arriving late, header stamps on another clock than the bag's record times (a simulator),
a ROS 2 bag whose metadata.yaml and storage file disagree. Small bags written with
:class:`spcopyro.robot.rosbag.BagWriter`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.maps.grid import FREE, OccupancyGrid  # noqa: E402
from spcopyro.maps.map_server import save_map  # noqa: E402
from spcopyro.robot.rosbag import (  # noqa: E402
    BagContentError,
    BagWriter,
    ImportOptions,
    import_bags,
)

T0 = 1_600_000_000.0


@pytest.fixture
def map_yaml(tmp_path: Path) -> Path:
    """A 60 x 60 free map at 0.1 m, origin (-3, -3): x, y in [-3, 3) m."""
    grid = OccupancyGrid(np.full((60, 60), FREE, dtype=np.int8), 0.1, (-3.0, -3.0, 0.0))
    return save_map(grid, tmp_path / "maps" / "floor.yaml")


def _image() -> np.ndarray:
    return np.zeros((4, 4, 3), dtype=np.uint8)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_tf_edge_going_backwards_names_its_messages_on_tf(tmp_path, map_yaml, ros):
    """The error named the edge's n-th sample ('message 7') as if it were the n-th message of
    /tf; /tf interleaves every edge (here map -> odom and odom -> base_link), so the late
    sample is /tf's 13th message, after its 12th."""
    bag = tmp_path / ("rec.bag" if ros == 1 else "rec")
    with BagWriter(bag, ros=ros) as w:
        for i, t in enumerate((T0 + np.arange(6.0)).tolist()):
            w.tf(t, [("map", "odom", 0.0, 0.0, 0.0)])
            w.tf(t, [("odom", "base_link", 0.1 * i, 0.0, 0.0)], log_time=t + 0.01)
        w.tf(T0 + 2.5, [("odom", "base_link", 0.0, 0.0, 0.0)], log_time=T0 + 5.5)  # late
        w.image("/camera/image", T0 + 1.0, _image())
        w.text("/speech", T0 + 1.0, "hall")
    options = ImportOptions(pose_tf=("map", "base_link"))
    with pytest.raises(BagContentError) as error:
        import_bags([bag], map_yaml, tmp_path / "d" / "h", options, progress=False)
    assert (
        "topic /tf (edge odom -> base_link): timestamps go backwards: message 13 is stamped "
        "1600000002.500000000 s after message 12 at 1600000005.000000000 s" in str(error.value)
    )
