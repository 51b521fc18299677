"""``spcopyro import-bag`` on a camera stamping on another clock than the poses, an empty bag, and
what the command prints for a ROS 1 bag (helper 233's leftovers of the import-bag testing).

A camera on simulated time beside poses on the wall clock (or the other way round) had every
image skipped ("nearest 1699999900 s away") and the import end with "no image left" and nothing
about clocks; an empty bag said "no pose topic '/amcl_pose'; the bag has: no topics"; a ROS 1
bag's import printed "ROS 2 types humble". Bags written with
:class:`spcopyro.robot.rosbag.BagWriter` in tmp_path."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from bag_maps import save_free_map

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.cli.main import main  # noqa: E402
from spcopyro.robot.rosbag import (  # noqa: E402
    BagContentError,
    BagWriter,
    ImportOptions,
    NothingLeftError,
    import_bags,
)

T0 = 1_700_000_000.0  # the wall clock
SIM = 100.0  # a simulator's clock (use_sim_time): stamps from about 0 s
ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def map_yaml(tmp_path: Path) -> Path:
    """The rosbag tests' map (tests/bag_maps.py) at origin (-1, -1): x, y in [-1, 5) m."""
    return save_free_map(tmp_path / "maps", origin=-1.0)


def _two_clocks(path: Path, pose_clock: float, image_clock: float, ros: int = 2) -> Path:
    """Ten seconds recorded on the wall clock (record times T0 + i): poses stamped on
    ``pose_clock`` + i, images on ``image_clock`` + i + 0.25, one utterance (no stamp)."""
    with BagWriter(path, ros=ros) as w:
        for i in range(10):
            w.pose("/amcl_pose", pose_clock + i, 0.1 * i, 0.0, 0.0, log_time=T0 + i)
            w.image("/camera/image", image_clock + i + 0.25, np.full((4, 4, 3), i, np.uint8),
                    log_time=T0 + i + 0.25)  # fmt: skip
        w.text("/speech", T0 + 3.0, "kitchen")
    return path


@pytest.mark.parametrize(
    ("pose_clock", "image_clock", "behind"),
    [(T0, SIM, True), (SIM, T0, False)],
    ids=["camera-on-sim-time", "poses-on-sim-time"],
)
def test_a_camera_on_another_clock_says_so_and_record_time_imports_it(
    tmp_path, map_yaml, pose_clock, image_clock, behind
):
    bag = _two_clocks(tmp_path / "rec", pose_clock, image_clock)
    with pytest.raises(NothingLeftError, match="no image left") as caught:
        import_bags([bag], map_yaml, tmp_path / "a" / "house", progress=False)
    message = str(caught.value)
    assert len(caught.value.skipped) == 10
    # both ranges, the offset, what it likely is and what to do
    first, last = image_clock + 0.25, image_clock + 9.25
    assert f"the image stamps ({first:.3f}..{last:.3f} s) are " in message
    assert f"(/amcl_pose: {pose_clock:.3f}..{pose_clock + 9:.3f} s)" in message
    side = "behind" if behind else "ahead of"
    assert f"{abs(image_clock - pose_clock):.3f} s {side} the poses' at the same record" in message
    assert "different clocks" in message and "use_sim_time" in message
    assert "places an image at its header stamp; --image-time record" in message
    # and the option it names places each image at its record time, on the poses' clock
    report = import_bags([bag], map_yaml, tmp_path / "b" / "house",
                         ImportOptions(image_time="record"), progress=False)  # fmt: skip
    assert report.trials[0]["images_kept"] == 10
    assert report.trials[0]["image_clock"] is None  # the images are at their record times
    xs = [float(v) for v in (report.out / "Xtx.csv").read_text().split()]
    # interpolated at i + 0.25 s on the poses' clock; the last one at the last pose's
    assert np.allclose(xs, np.minimum(0.1 * (np.arange(10) + 0.25), 0.9))


def test_stamps_apart_with_record_times_equal_to_them_are_named_too(tmp_path, map_yaml):
    """A bag whose record times are its stamps (written by a converter) tells nothing by its
    offsets: the two ranges, apart, are what says it."""
    with BagWriter(tmp_path / "rec") as w:
        for i in range(10):
            w.pose("/amcl_pose", T0 + i, 0.1 * i, 0.0, 0.0)
            w.image("/camera/image", SIM + i, np.zeros((4, 4, 3), np.uint8))
        w.text("/speech", T0 + 3.0, "kitchen")
    with pytest.raises(NothingLeftError) as caught:
        import_bags([tmp_path / "rec"], map_yaml, tmp_path / "house", progress=False)
    assert (
        f"the image stamps ({SIM:.3f}..{SIM + 9:.3f} s) are apart from the poses' (/amcl_pose: "
        f"{T0:.3f}..{T0 + 9:.3f} s)" in str(caught.value)
    )


def test_a_camera_some_seconds_off_is_warned_of_and_agreeing_clocks_are_not(tmp_path, map_yaml):
    """A camera 3 s ahead of the poses: its images got poses 3 s off (the last ones the last
    pose's, within the raised tolerance), and the report says why."""
    bag = _two_clocks(tmp_path / "rec", T0, T0 + 3.0)
    report = import_bags([bag], map_yaml, tmp_path / "a" / "house",
                         ImportOptions(pose_tolerance=3.5), progress=False)  # fmt: skip
    assert report.trials[0]["image_clock"]["offset"] == pytest.approx(3.0)
    assert re.search(
        r"warning: trial 0 \(.*rec\): the image stamps \(1700000003.250\.\.1700000012.250 s\) "
        r"are 3.000 s ahead of the poses'",
        report.text(),
    )
    same = _two_clocks(tmp_path / "same", T0, T0)
    report = import_bags([same], map_yaml, tmp_path / "b" / "house", progress=False)
    assert report.trials[0]["image_clock"] is None and "clocks" not in report.text()


def test_images_with_more_transport_delay_than_the_poses_are_not_called_another_clock(
    tmp_path, map_yaml
):
    """Images that reach the recorder 1.5 s after they were taken, poses at once: offset -1.5.
    The warning blamed use_sim_time and recommended --image-time record, which would place every
    image 1.5 s late; at their header stamps they are right."""
    bag = _two_clocks(tmp_path / "rec", T0, T0 - 1.5)  # stamps 1.5 s before their record times
    report = import_bags([bag], map_yaml, tmp_path / "house", progress=False)
    assert report.trials[0]["image_clock"]["offset"] == pytest.approx(-1.5)
    assert report.trials[0]["images_kept"] > 0
    # poses.image_clock decides it, the note reads it, and bag_import.json records it
    assert report.trials[0]["image_clock"]["kind"] == "delay"
    recorded = json.loads((report.out / "bag_import.json").read_text())
    assert recorded["trials"][0]["image_clock"]["kind"] == "delay"
    text = " ".join(report.text().split())
    assert "are 1.500 s behind the poses' at the same record time" in text
    assert "transport delay" in text and "clock skew between machines" in text
    assert "use_sim_time" not in text and "different clocks" not in text
    assert "--image-time record places it" not in text  # not recommended
    assert "--image-time record would move each image later by its own delay" in text


@pytest.mark.parametrize(
    ("offset", "posed", "kind"),
    [(-1.5, True, "delay"), (59.0, True, "delay"), (-120.0, True, "clocks"),
     (-1.5, False, "clocks")],
    ids=["delay", "under-a-minute", "two-minutes", "no-image-posed"],
)  # fmt: skip
def test_a_large_offset_or_no_posed_image_still_recommends_record_time(offset, posed, kind):
    """Beyond any plausible delay (two minutes), or with no image posed, the clocks differ: the
    kind is poses.image_clock's (beside CLOCKS_DIFFER and CLOCKS_APART), the note only words it
    (it recomputed "some image got a pose" from the counts, with PLAUSIBLE_DELAY of its own)."""
    from spcopyro.robot.rosbag.poses import PLAUSIBLE_DELAY, PoseTrack, image_clock
    from spcopyro.robot.rosbag.report import image_clock_note

    assert PLAUSIBLE_DELAY == 60.0
    track = PoseTrack("/amcl_pose", np.arange(10.0) + T0, np.zeros((10, 2)), np.zeros(10))
    record = np.arange(10.0) + T0 + 0.25  # [10]
    clock = image_clock([track], record + offset, record, 0.0, posed)
    assert clock is not None and clock["kind"] == kind
    assert clock["offset"] == pytest.approx(offset)
    note = image_clock_note({"trial": 0, "bag": "b", "image_clock": clock})
    delay = kind == "delay"
    assert ("transport delay" in note) == delay, note
    assert ("different clocks" in note and "--image-time record places it" in note) != delay


def test_images_before_the_first_pose_on_its_clock_are_not_apart_from_it(tmp_path, map_yaml):
    """amcl publishes only after the robot moves: a camera's images, all 20 s before the first
    pose on the same clock, got no pose, and the error said their stamps were "apart from the
    poses'" (two clocks) where they are one clock's; two clocks are more than a day apart."""
    with BagWriter(tmp_path / "rec") as w:
        for i in range(10):
            w.image("/camera/image", T0 + i, np.zeros((4, 4, 3), np.uint8), log_time=T0 + i)
            w.pose("/amcl_pose", T0 + 20 + i, 0.1 * i, 0.0, 0.0, log_time=T0 + 20 + i)
        w.text("/speech", T0 + 23.0, "kitchen")
    with pytest.raises(NothingLeftError, match="no image left") as caught:
        import_bags([tmp_path / "rec"], map_yaml, tmp_path / "house", progress=False)
    assert "apart from the poses'" not in str(caught.value)
    assert "clock" not in str(caught.value)


@pytest.mark.parametrize(("ros", "storage"), [(1, "sqlite3"), (2, "sqlite3"), (2, "mcap")],
                         ids=["ros1", "ros2-sqlite3", "ros2-mcap"])  # fmt: skip
def test_an_empty_bag_says_it_holds_no_messages(tmp_path, map_yaml, ros, storage):
    bag = tmp_path / ("empty.bag" if ros == 1 else "empty")
    with BagWriter(bag, ros=ros, storage=storage):
        pass
    with pytest.raises(BagContentError) as caught:
        import_bags([bag], map_yaml, tmp_path / "house", progress=False)
    assert str(caught.value).startswith(f"{bag}: the bag holds no messages (and no topics)")
    assert not (tmp_path / "house").exists()


def test_a_bag_of_topics_without_messages_says_it_holds_no_messages(tmp_path, map_yaml):
    """rosbag2 declares the topics it subscribed to before any message arrives."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    bag = tmp_path / "declared"
    writer = Writer(bag, version=9)
    writer.open()
    store = get_typestore(Stores.ROS2_HUMBLE)
    writer.add_connection("/amcl_pose", "geometry_msgs/msg/PoseWithCovarianceStamped",
                          typestore=store)  # fmt: skip
    writer.close()
    with pytest.raises(BagContentError) as caught:
        import_bags([bag], map_yaml, tmp_path / "house", progress=False)
    assert str(caught.value).startswith(
        f"{bag}: the bag holds no messages (its topics, each empty: /amcl_pose "
        "(geometry_msgs/msg/PoseWithCovarianceStamped))"
    )


@pytest.mark.parametrize("ros", [1, 2])
def test_the_cli_names_ros_2_types_only_for_a_ros_2_bag(tmp_path, map_yaml, capsys, ros):
    bag = _two_clocks(tmp_path / ("rec.bag" if ros == 1 else "rec"), T0, T0, ros=ros)
    assert main(["import-bag", str(bag), "--map", str(map_yaml), "--out",
                 str(tmp_path / "house")]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert ("ROS 2 types      humble" in out) == (ros == 2)
    assert ("ROS 1 types      each bag's own" in out) == (ros == 1)


def test_the_docs_limitations_say_a_pose_topic_in_another_frame_goes_through_tf():
    """docs/robot.md's limitations said the pose topic must be in the map's frame, which the
    import has not needed since a pose topic in another frame is placed through tf."""
    text = " ".join((ROOT / "docs" / "robot.md").read_text(encoding="utf-8").split())
    limits = text[text.index("**Limitations.** Poses are planar") :][:1200]
    assert "must be in the map's frame" not in limits
    assert "placed on the map through the bag's tf" in limits


def test_the_docs_say_record_time_moves_rightly_stamped_images_by_their_delay():
    """docs/robot.md recommended --image-time record for a camera on another clock without
    saying that it also places every rightly stamped image later by its transport delay."""
    text = " ".join((ROOT / "docs" / "robot.md").read_text(encoding="utf-8").split())
    assert "`record` also moves every correctly stamped image later by its transport delay" in text
    assert "the two ranges of stamps more than a day apart" in text
