"""``spcopyro import-bag`` on bags as a robot records them, not as simulate-bag writes them: tf
samples arriving late, header stamps on another clock than the bag's record times (a simulator),
a ROS 2 bag whose metadata.yaml and storage file disagree. Small bags written with
:class:`spcopyro.robot.rosbag.BagWriter`."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.robot.rosbag import (  # noqa: E402
    BagContentError,
    BagFormatError,
    BagWriter,
    ImportOptions,
    import_bags,
)

T0 = 1_600_000_000.0


def _image() -> np.ndarray:
    return np.zeros((4, 4, 3), dtype=np.uint8)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_tf_sample_arriving_late_is_sorted_in(tmp_path, map_yaml, ros):
    """A tf sample recorded after later-stamped ones (it arrived late) stopped the import
    ('timestamps go backwards'); tf2 sorts it into its buffer, and so does the import now,
    counting it."""
    bag = tmp_path / ("rec.bag" if ros == 1 else "rec")
    with BagWriter(bag, ros=ros) as w:
        for i, t in enumerate((T0 + np.arange(6.0)).tolist()):
            w.tf(t, [("map", "odom", 0.0, 0.0, 0.0)])
            w.tf(t, [("odom", "base_link", 0.1 * i, 0.0, 0.0)], log_time=t + 0.01)
        w.tf(T0 + 2.5, [("odom", "base_link", 0.0, 0.0, 0.0)], log_time=T0 + 5.5)  # late
        w.image("/camera/image", T0 + 1.0, _image())
        w.image("/camera/image", T0 + 2.5, _image())
        w.text("/speech", T0 + 1.0, "hall")
    out = tmp_path / "d" / "h"
    options = ImportOptions(pose_tf=("map", "base_link"))
    report = import_bags([bag], map_yaml, out, options, progress=False)
    assert np.allclose(np.loadtxt(out / "Xtx.csv"), [0.1, 0.0])  # 2.5 s: the late sample's
    assert report.trials[0]["poses_out_of_order"] == 1
    assert "1 pose sample(s) came after one stamped later" in report.text()


@pytest.mark.parametrize("ros", [1, 2])
def test_a_tf_edge_going_backwards_names_its_messages_on_tf(tmp_path, map_yaml, ros):
    """The error named the edge's n-th sample ('message 7') as if it were the n-th message of
    /tf; /tf interleaves every edge (here map -> odom and odom -> base_link), so the first
    sample going back is /tf's 13th message, after its 12th. (A clock that went back: three
    of the edge's nine samples go back, more than a few arriving late.)"""
    bag = tmp_path / ("rec.bag" if ros == 1 else "rec")
    with BagWriter(bag, ros=ros) as w:
        for i, t in enumerate((T0 + np.arange(6.0)).tolist()):
            w.tf(t, [("map", "odom", 0.0, 0.0, 0.0)])
            w.tf(t, [("odom", "base_link", 0.1 * i, 0.0, 0.0)], log_time=t + 0.01)
        for k, t in enumerate([0.5, 1.5, 2.5]):  # the edge's clock went back
            w.tf(T0 + t, [("odom", "base_link", 0.0, 0.0, 0.0)], log_time=T0 + 5.5 + 0.1 * k)
        w.image("/camera/image", T0 + 1.0, _image())
        w.text("/speech", T0 + 1.0, "hall")
    options = ImportOptions(pose_tf=("map", "base_link"))
    with pytest.raises(BagContentError) as error:
        import_bags([bag], map_yaml, tmp_path / "d" / "h", options, progress=False)
    assert (
        "topic /tf (edge odom -> base_link): timestamps go backwards: message 13 is stamped "
        "1600000000.500000000 s after message 12 at 1600000005.000000000 s; 3 of 9 messages"
        in str(error.value)
    )


@pytest.mark.parametrize("pose_tf", [False, True], ids=["amcl_pose", "pose-tf"])
def test_utterances_of_a_simulator_recording_are_placed_on_its_clock(
    tmp_path, map_yaml, capsys, pose_tf
):
    """A simulator's recording (use_sim_time; the bag recorder on the wall clock): the poses and
    images are stamped from 10 s, at half real time, while an utterance (std_msgs/String, no
    header) has only its record time, 1.6e9 s later. It was skipped ('nearest 1599999997 s
    away') and the import stopped with no utterance left. Its record time is now mapped onto
    the stamps' clock through the pose messages' record times (following the drift), and the
    mapping is printed and recorded."""
    from spcopyro.cli.main import main

    bag = tmp_path / "sim"
    with BagWriter(bag, ros=2) as w:
        for k in range(21):  # stamp 10 + 0.5 k, recorded at T0 + k: half real time
            stamp, record = 10.0 + 0.5 * k, T0 + k
            if pose_tf:
                w.tf(stamp, [("map", "odom", 0.0, 0.0, 0.0)], log_time=record)
                w.tf(stamp, [("odom", "base_link", 0.2 * (stamp - 10.0), 0.0, 0.0)],
                     log_time=record)  # fmt: skip
            else:
                w.pose("/amcl_pose", stamp, 0.2 * (stamp - 10.0), 0.0, 0.0, log_time=record)
        w.image("/camera/image", 12.0, _image(), log_time=T0 + 4.0)  # x 0.4
        w.text("/speech", T0 + 7.0, "kitchen")  # stamp clock 13.5: x 0.7
    out = tmp_path / "d" / "h"
    argv = ["import-bag", str(bag), "--map", str(map_yaml), "--out", str(out)]
    if pose_tf:
        argv += ["--pose-tf", "map", "base_link"]
    assert main(argv) == 0
    assert np.loadtxt(out / "Xtx.csv") == pytest.approx(0.4)
    assert np.loadtxt(out / "StXtx.csv") == pytest.approx(0.7)
    printed = capsys.readouterr().out
    assert "the pose stamps are 1599999995.000 s behind the bag's record times" in printed
    assert "utterances and images without a stamp (1) were placed on the stamps' clock" in printed
    (trial,) = json.loads((out / "bag_import.json").read_text())["trials"]
    assert trial["record_clock_offset"] == pytest.approx(T0 - 5.0)  # the median k = 10


def test_a_recording_on_one_clock_keeps_the_record_times(tmp_path, map_yaml):
    """Poses stamped 0.3 s before they were recorded (a slow localiser): the clocks agree, so an
    utterance stays at its record time and nothing is said about clocks."""
    bag = tmp_path / "rec"
    with BagWriter(bag, ros=2) as w:
        for k in range(6):
            w.pose("/amcl_pose", T0 + k, 0.5 * k, 0.0, 0.0, log_time=T0 + k + 0.3)
        w.image("/camera/image", T0 + 1.0, _image())
        w.text("/speech", T0 + 2.5, "hall")
    report = import_bags([bag], map_yaml, tmp_path / "d" / "h", progress=False)
    assert np.loadtxt(report.out / "StXtx.csv") == pytest.approx(1.25)
    assert report.trials[0]["record_clock_offset"] is None
    assert "record times" not in report.text()


def test_samples_merged_on_a_tf_edge_walked_backwards_are_counted(tmp_path, map_yaml):
    """tf holds base_link -> odom (the chain map -> base_link walks it backwards, inverted);
    two of its samples share a stamp. The inverted track lost the merged count: the summary said
    nothing was merged."""
    bag = tmp_path / "rec"
    with BagWriter(bag, ros=2) as w:
        for k in range(5):
            t = T0 + k
            w.tf(t, [("map", "odom", 0.0, 0.0, 0.0), ("base_link", "odom", -0.5 * k, 0.0, 0.0)])
        w.tf(T0 + 2.0, [("base_link", "odom", -1.0, 0.0, 0.0)], log_time=T0 + 2.01)  # again
        w.image("/camera/image", T0 + 1.0, _image())
        w.text("/speech", T0 + 3.0, "hall")
    options = ImportOptions(pose_tf=("map", "base_link"))
    report = import_bags([bag], map_yaml, tmp_path / "d" / "h", options, progress=False)
    assert report.trials[0]["poses_merged"] == 1
    assert "1 pose sample(s) repeated the previous one's stamp" in report.text()
    assert np.loadtxt(report.out / "StXtx.csv") == pytest.approx(1.5)


def test_pose_stamps_ahead_of_the_record_times_are_said_to_be_ahead(tmp_path, map_yaml):
    """A robot whose clock is 30 s ahead of the recording laptop's."""
    bag = tmp_path / "rec"
    with BagWriter(bag, ros=2) as w:
        for k in range(6):
            w.pose("/amcl_pose", T0 + 30.0 + k, 0.5 * k, 0.0, 0.0, log_time=T0 + k)
        w.image("/camera/image", T0 + 31.0, _image(), log_time=T0 + 1.0)
        w.text("/speech", T0 + 2.5, "hall")
    report = import_bags([bag], map_yaml, tmp_path / "d" / "h", progress=False)
    assert np.loadtxt(report.out / "StXtx.csv") == pytest.approx(1.25)
    assert "the pose stamps are 30.000 s ahead of the bag's record times" in report.text()


QOS = (  # one offered QoS profile as rosbag2 (Foxy .. Humble) writes it: a YAML string
    "- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: 0\n"
    "    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n  liveliness: 1\n"
    "  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n"
    "  avoid_ros_namespace_conventions: false"
)


def _edit_metadata(bag: Path, topic: str, **changes: object) -> None:
    """Change ``topic``'s entry of a ROS 2 bag's metadata.yaml (``message_count``, or a
    ``topic_metadata`` key such as ``offered_qos_profiles``)."""
    import yaml

    path = bag / "metadata.yaml"
    metadata = yaml.safe_load(path.read_text())
    for entry in metadata["rosbag2_bagfile_information"]["topics_with_message_count"]:
        if entry["topic_metadata"]["name"] == topic:
            for key, value in changes.items():
                (entry if key == "message_count" else entry["topic_metadata"])[key] = value
    path.write_text(yaml.safe_dump(metadata))


def _write_plain(bag: Path, storage: str = "sqlite3") -> None:
    with BagWriter(bag, ros=2, storage=storage) as w:
        for k in range(5):
            w.pose("/amcl_pose", T0 + k, 0.5 * k, 0.0, 0.0)
        for t in (0.5, 1.5, 2.5):
            w.image("/camera/image", T0 + t, _image())
        w.text("/speech", T0 + 1.0, "kitchen")


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_topic_metadata_yaml_and_storage_disagree_on_is_an_error(tmp_path, map_yaml, storage):
    """rosbags reads a bag folder's messages only of the topics whose offered QoS (and type) in
    metadata.yaml match the storage file's, and returned none of the others: the image topic
    read as empty, 'images 0 kept of 0', and the import went on (or stopped at 'the bags hold
    none'). The storage file given itself reads them all."""
    bag = tmp_path / "rec"
    _write_plain(bag, storage)
    _edit_metadata(bag, "/camera/image", offered_qos_profiles=QOS)
    with pytest.raises(BagContentError) as error:
        import_bags([bag], map_yaml, tmp_path / "d" / "h", progress=False)
    message = str(error.value)
    assert f"{bag}: topic /camera/image: the bag's index counts 3 message(s), but none" in message
    assert "metadata.yaml and its storage file disagree" in message
    assert "`ros2 bag reindex`" in message
    (storage_file,) = bag.glob("*.db3" if storage == "sqlite3" else "*.mcap")
    report = import_bags([storage_file], map_yaml, tmp_path / "e" / "h", progress=False)
    assert report.trials[0]["images_kept"] == 3


def test_messages_metadata_yaml_counts_but_the_storage_lacks_are_reported(tmp_path, map_yaml):
    bag = tmp_path / "rec"
    _write_plain(bag)
    _edit_metadata(bag, "/camera/image", message_count=5)
    _edit_metadata(bag, "/speech", message_count=2)
    report = import_bags([bag], map_yaml, tmp_path / "d" / "h", progress=False)
    trial = report.trials[0]
    assert (trial["images_unread"], trial["utterances_unread"]) == (2, 1)
    assert "the bag's index counts 5 image message(s), 3 could be read: 2 are" in report.text()
    assert "counts 2 utterance message(s), 1 could be read" in report.text()


@pytest.mark.parametrize(
    ("case", "reason"),
    [
        ("newer", r"Rosbag2 version 10 not supported"),
        ("bad yaml", r"Could not load YAML from .*metadata\.yaml: while parsing"),
        ("renamed", r"Some database files are missing"),
    ],
)
def test_a_bag_folder_whose_metadata_fails_points_to_its_storage_file(
    tmp_path, map_yaml, case, reason
):
    """A bag folder whose metadata.yaml rosbags cannot read -- a newer rosbag2's version, a
    broken YAML, a storage file renamed -- said 'not a readable bag (...)' and, for an mcap
    bag, suggested `mcap recover`, which does not apply; a YAML error spanned several lines.
    The storage file itself reads."""
    bag = tmp_path / "rec"
    _write_plain(bag, "mcap")
    metadata = bag / "metadata.yaml"
    (storage,) = bag.glob("*.mcap")
    if case == "newer":
        metadata.write_text(metadata.read_text().replace("  version: 9", "  version: 10"))
    elif case == "bad yaml":
        metadata.write_text(metadata.read_text() + "  : [\n")
    else:
        storage = storage.rename(bag / "renamed.mcap")
    with pytest.raises(BagFormatError) as error:
        import_bags([bag], map_yaml, tmp_path / "d" / "h", progress=False)
    message = str(error.value)
    assert "\n" not in message
    assert re.search(rf"{re.escape(str(bag))}: not a readable bag \({reason}", message)
    assert message.endswith(
        f"; it is its metadata.yaml that fails: give its storage file ({storage}) as BAG, or "
        "rewrite it with `ros2 bag reindex`"
    )
    assert "mcap recover" not in message
    report = import_bags([storage], map_yaml, tmp_path / "e" / "h", progress=False)
    assert report.trials[0]["images_kept"] == 3


def test_a_cut_short_mcap_in_its_folder_still_names_mcap_recover(tmp_path, map_yaml):
    bag = tmp_path / "rec"
    _write_plain(bag, "mcap")
    (storage,) = bag.glob("*.mcap")
    storage.write_bytes(storage.read_bytes()[:200])
    with pytest.raises(BagFormatError, match="`mcap recover` rewrites what it holds"):
        import_bags([bag], map_yaml, tmp_path / "d" / "h", progress=False)


def _write_compressed(bag: Path, mode: str, monkeypatch) -> None:
    """A bag written as ``ros2 bag record --compression-mode MODE --compression-format zstd``
    would (rosbags' writer with compression set before it opens)."""
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

    original = Writer.open

    def open_compressed(self):
        self.set_compression(CompressionMode[mode.upper()], CompressionFormat.ZSTD)
        return original(self)

    with monkeypatch.context() as patch:
        patch.setattr(Writer, "open", open_compressed)
        _write_plain(bag)


def test_compressed_bags_read_from_their_folder_and_their_files_say_how(
    tmp_path, map_yaml, monkeypatch
):
    """Both rosbag2 compression modes read from the bag folder. Given itself, a .db3 whose
    messages are compressed one by one failed as 'the bag is damaged or cut short', and a
    .db3.zstd was 'not a bag (... got suffix '.zstd')'; each now says what it is and what to
    give instead."""
    for mode in ("file", "message"):
        bag = tmp_path / mode
        _write_compressed(bag, mode, monkeypatch)
        report = import_bags([bag], map_yaml, tmp_path / f"{mode}_house", progress=False)
        assert report.trials[0]["images_kept"] == 3
    (db3,) = (tmp_path / "message").glob("*.db3")
    with pytest.raises(BagFormatError) as error:
        import_bags([db3], map_yaml, tmp_path / "d" / "h", progress=False)
    assert str(error.value).startswith(f"{db3}: message 1 on /amcl_pose cannot be read (")
    assert str(error.value).endswith(
        "its messages are compressed (compression_mode: message in the metadata.yaml beside it): "
        f"give the bag folder {tmp_path / 'message'}"
    )
    (whole,) = (tmp_path / "file").glob("*.zstd")
    with pytest.raises(BagFormatError) as error:
        import_bags([whole], map_yaml, tmp_path / "d" / "h", progress=False)
    assert str(error.value) == (
        f"{whole}: a storage file compressed whole (rosbag2's --compression-mode file): give the "
        "bag folder it was recorded in (with its metadata.yaml), or decompress it with `zstd -d` "
        "and give the .db3 file"
    )


def test_a_future_dated_map_to_odom_is_not_taken_for_another_clock(tmp_path, map_yaml):
    """Nav2's amcl stamps map -> odom transform_tolerance ahead of the scan (here 1.5 s, at
    20 Hz) while odometry's odom -> base_link (5 Hz) is on time: the clocks agree, so the
    utterance stays at its record time. Pooled over the chain, the median offset (-1.5 s, the
    future-dated edge outnumbering) moved the utterance 1.5 s along the path."""
    bag = tmp_path / "rec"
    with BagWriter(bag, ros=2) as w:
        for t in (T0 + np.arange(0.0, 8.0, 0.05)).tolist():
            w.tf(t + 1.5, [("map", "odom", 0.0, 0.0, 0.0)], log_time=t)
        for t in (T0 + np.arange(0.0, 8.0, 0.2)).tolist():
            w.tf(t, [("odom", "base_link", 0.25 * (t - T0), 0.0, 0.0)])
        w.image("/camera/image", T0 + 4.0, _image())
        w.text("/speech", T0 + 5.1, "hall")
    options = ImportOptions(pose_tf=("map", "base_link"))
    report = import_bags([bag], map_yaml, tmp_path / "d" / "h", options, progress=False)
    assert report.trials[0]["record_clock_offset"] is None
    assert np.loadtxt(report.out / "StXtx.csv") == pytest.approx(1.275)


def test_a_missing_topic_names_the_one_topic_of_its_type(tmp_path, map_yaml):
    """A camera publishing only /camera/color/image_raw/compressed: the default /camera/image is
    missing, and the one image topic there is named with its option (with two, none is)."""
    bag = tmp_path / "rec"
    with BagWriter(bag, ros=2) as w:
        w.pose("/amcl_pose", T0, 0.0, 0.0, 0.0)
        w.image("/camera/color/image_raw/compressed", T0, _image(), "jpeg")
        w.text("/speech", T0, "hall")
    with pytest.raises(BagContentError) as error:
        import_bags([bag], map_yaml, tmp_path / "d" / "h", progress=False)
    assert (
        f"{bag}: no image topic '/camera/image' (pass --image-topic "
        "/camera/color/image_raw/compressed?); the bag has: /amcl_pose" in str(error.value)
    )
    second = tmp_path / "two"
    with BagWriter(second, ros=2) as w:
        w.pose("/amcl_pose", T0, 0.0, 0.0, 0.0)
        w.image("/left/image", T0, _image())
        w.image("/right/image", T0, _image())
        w.text("/speech", T0, "hall")
    with pytest.raises(BagContentError, match=r"no image topic '/camera/image'; the bag has"):
        import_bags([second], map_yaml, tmp_path / "d" / "h", progress=False)


def test_an_unfinished_ros1_recording_names_rosbag_reindex(tmp_path, map_yaml):
    """rosbag record killed leaves NAME.bag.active: it was 'not a bag (... got suffix
    '.active')'."""
    active = tmp_path / "rec.bag.active"
    active.write_bytes(b"#ROSBAG V2.0\n" + bytes(100))
    with pytest.raises(BagFormatError) as error:
        import_bags([active], map_yaml, tmp_path / "d" / "h", progress=False)
    assert str(error.value) == (
        f"{active}: an unfinished ROS 1 recording (rosbag record stopped before it closed the "
        "bag): `rosbag reindex rec.bag.active` repairs it; then give it as rec.bag"
    )
