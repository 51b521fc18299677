"""The one wrap of rosbags' internals (spcopyro.robot.rosbag.mcap_schemas) fails loudly, naming
the installed rosbags version, when a rosbags release no longer has the function it wraps;
before, opening a bag then went on unwrapped and mcap bags whose schemas hold no definition
failed again with rosbags' bare ``KeyError: 'unknown'``."""

from __future__ import annotations

from importlib.metadata import version

import pytest

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.robot.rosbag.bag import open_bag  # noqa: E402
from spcopyro.robot.rosbag.mcap_schemas import (  # noqa: E402
    RosbagsInternalsError,
    schemas_without_data_as_none,
)
from spcopyro.robot.rosbag.synthetic import BagWriter  # noqa: E402


def _bag(path, ros: int):
    with BagWriter(path, ros=ros, storage="mcap") as w:
        w.pose("/amcl_pose", 1.0, 0.0, 0.0, 0.0)
        w.text("/speech", 1.5, "kitchen")
    return path


def test_the_wrap_is_undone_after_the_block():
    from rosbags.rosbag2 import storage_mcap

    original = storage_mcap.get_msgdef
    with schemas_without_data_as_none():
        assert storage_mcap.get_msgdef is not original
    assert storage_mcap.get_msgdef is original


def test_a_rosbags_without_the_wrapped_function_is_a_clear_error(tmp_path, monkeypatch):
    from rosbags.rosbag2 import storage_mcap

    ros2 = _bag(tmp_path / "ros2", 2)
    ros1 = _bag(tmp_path / "ros1.bag", 1)
    monkeypatch.delattr(storage_mcap, "get_msgdef")
    with pytest.raises(RosbagsInternalsError, match="get_msgdef") as error:
        with open_bag(ros2):
            pass
    assert f"rosbags {version('rosbags')} " in str(error.value)
    with open_bag(ros1) as reader:  # a ROS 1 bag has no mcap schemas: nothing to wrap
        assert "/speech" in reader.topics
