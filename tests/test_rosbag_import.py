"""``spcopyro import-bag`` (spcopyro/robot/rosbag/): small bags of ROS 1 and ROS 2 (sqlite3, mcap)
written with rosbags' writers, imported and read back with the real loaders.

Checks: poses interpolated at known stamps (linear x, y; yaw the short way round 180 deg), tf
chains composed (dynamic, static, inverted edges), a pose topic in another frame placed on the
map through tf, bags without message definitions (sqlite3 and mcap), images decoded equal,
words kept (sentences tokenised), thinning by distance and time, skipped observations reported
(skipped.csv, never dropped silently), every error case (missing topic, unknown type, stamps
going backwards, pose outside the map, not a bag, no tf chain, existing output), the synthetic
bags of the synthetic house, and import -> features -> load_house -> fit.
"""

from __future__ import annotations

import csv
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.cli.main import main  # noqa: E402
from spcopyro.data import load_house  # noqa: E402
from spcopyro.robot.rosbag import (  # noqa: E402
    BagContentError,
    BagFormatError,
    BagWriter,
    ImportOptions,
    NothingLeftError,
    PoseOutsideMapError,
    RosbagsMissingError,
    import_bags,
    write_synthetic_bags,
)
from spcopyro.robot.rosbag.poses import PoseTrack, compose, wrap_angle  # noqa: E402

T0 = 1_600_000_000.0
FORMATS = [(1, "sqlite3"), (2, "sqlite3"), (2, "mcap")]
FORMAT_IDS = ["ros1", "ros2-sqlite3", "ros2-mcap"]


def _bag_path(tmp_path: Path, ros: int, name: str = "rec") -> Path:
    return tmp_path / (f"{name}.bag" if ros == 1 else name)


def _image(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, size=(6, 8, 3), dtype=np.uint8)


def _trajectory(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pose samples: x = 0.5 s, y = 0.25 s (s = t - T0), yaw 170 deg then -170 deg, ..."""
    s = t - T0
    yaw = np.deg2rad(np.where(np.arange(t.size) % 2 == 0, 170.0, -170.0))
    return 0.5 * s, 0.25 * s, yaw


def _write_basic(path: Path, ros: int, storage: str, image_format: str = "raw") -> dict:
    """Poses at 1 Hz over 0..4 s; images at 0.5, 1.25, 2.75 and 9 s (no pose: skipped);
    utterances at 1.5 s (a sentence), 3 s ('') and 20 s (no pose)."""
    pose_t = T0 + np.arange(5.0)  # [5]
    x, y, yaw = _trajectory(pose_t)
    image_t = T0 + np.array([0.5, 1.25, 2.75, 9.0])
    images = [_image(i) for i in range(image_t.size)]
    with BagWriter(path, ros=ros, storage=storage) as w:
        for i, t in enumerate(pose_t.tolist()):
            w.pose("/amcl_pose", t, x[i], y[i], yaw[i])
        for t, rgb in zip(image_t.tolist(), images, strict=True):
            w.image("/camera/image", t, rgb, image_format)
        w.text("/speech", T0 + 1.5, "Here is the Kitchen, near the sink!")
        w.text("/speech", T0 + 3.0, "  ...  ")
        w.text("/speech", T0 + 20.0, "bedroom")
    return {"pose_t": pose_t, "image_t": image_t, "images": images}


def test_pose_track_interpolation_and_composition():
    track = PoseTrack("p", [0.0, 1.0, 3.0], [[0, 0], [1, 2], [3, 2]], np.deg2rad([170, -170, 0]))
    xy, yaw = track.at(np.array([0.5, 2.0, -1.0, 5.0]))
    assert np.allclose(xy, [[0.5, 1.0], [2.0, 2.0], [0, 0], [3, 2]])
    # 170 deg -> -170 deg turns 20 deg through 180, not 340 deg through 0.
    assert np.isclose(abs(np.rad2deg(yaw[0])), 180.0)
    assert np.isclose(np.rad2deg(yaw[1]), -85.0)
    assert np.allclose(track.gap(np.array([0.4, 2.2, 4.5])), [0.4, 0.8, 1.5])
    # A track composed with its inverse is the identity; the tolerance names the track.
    xy, yaw, ok, reasons = compose([track, track.inverse()], np.array([0.25, 2.5, 10.0]), 1.0)
    assert np.allclose(xy, 0.0, atol=1e-12) and np.allclose(wrap_angle(yaw), 0.0, atol=1e-12)
    assert ok.tolist() == [True, True, False] and "no pose of p within 1 s" in reasons[2]
    assert "(nearest 7.000 s away)" in reasons[2]
    # with a tolerance of 0, a gap below a millisecond is shown (it read "0.000 s away")
    _, _, ok, reasons = compose([track], np.array([1.0002, 3.0]), 0.0)
    assert ok.tolist() == [False, True] and "within 0 s (nearest 0.0002 s away)" in reasons[0]
    with pytest.raises(ValueError, match="not strictly increasing"):
        PoseTrack("q", [0.0, 0.0], [[0, 0], [1, 1]], [0, 0])


@pytest.mark.parametrize(("ros", "storage"), FORMATS, ids=FORMAT_IDS)
def test_round_trip(tmp_path, map_yaml, ros, storage):
    bag = _bag_path(tmp_path, ros)
    written = _write_basic(bag, ros, storage)
    out = tmp_path / "data" / "house"
    report = import_bags([bag], map_yaml, out, ImportOptions(pose_tolerance=0.6))
    # Poses: linear in x, y between the samples at 0, 1, 2, 3 s.
    x = np.loadtxt(out / "Xtx.csv", ndmin=1)
    y = np.loadtxt(out / "Xty.csv", ndmin=1)
    s = written["image_t"][:3] - T0
    assert np.allclose(x, 0.5 * s, atol=1e-9) and np.allclose(y, 0.25 * s, atol=1e-9)
    pose = np.loadtxt(out / "pose_0.csv", delimiter=",", ndmin=2)  # x, y, qz, qw
    yaw = np.rad2deg(2 * np.arctan2(pose[:, 2], pose[:, 3]))
    # Yaw the short way round: 170 -> -170 deg halfway is 180 deg; -170 -> 170 deg a quarter
    # of the way (1.25 s) is -175 deg, 170 -> -170 deg three quarters (2.75 s) is -175 deg.
    assert np.allclose(np.abs(yaw[0]), 180.0) and np.allclose(yaw[1:], [-175.0, -175.0])
    # Images decoded equal (raw -> lossless PNG); the one without a pose is not written.
    files = sorted((out / "img_0").iterdir())
    assert [f.name for f in files] == ["00001.png", "00002.png", "00003.png"]
    for f, rgb in zip(files, written["images"][:3], strict=True):
        assert np.array_equal(cv2.cvtColor(cv2.imread(str(f)), cv2.COLOR_BGR2RGB), rgb)
    # Words: the sentence tokenised (comma and punctuation gone), the empty one reported.
    assert (out / "word_0.csv").read_text().splitlines() == ["here is the kitchen near the sink"]
    assert np.loadtxt(out / "StXtx.csv", ndmin=1) == pytest.approx([0.75])
    # Skipped: the image at 9 s, the empty utterance, the utterance at 20 s.
    with (out / "skipped.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [r["kind"] for r in rows] == ["image", "utterance", "utterance"]
    assert [float(r["stamp"]) - T0 for r in rows] == pytest.approx([9.0, 3.0, 20.0])
    assert "no words" in rows[1]["reason"] and "'bedroom'" in rows[2]["reason"]
    assert "no pose of /amcl_pose within 0.6 s (nearest 5.000 s away)" in rows[0]["reason"]
    assert len(report.skipped) == 3 and report.trials[0]["images_kept"] == 3
    # The real loader reads it once Ft.csv exists (the map beside it as the loaders expect).
    assert (tmp_path / "data" / "map" / "house.yaml").is_file()
    (out / "Ft.csv").write_text("0.5,0.5\n" * 3)
    house = load_house(out)
    assert house.observations.num_images == 3
    assert house.observations.utterances == (
        ("here", "is", "the", "kitchen", "near", "the", "sink"),
    )
    assert [p.name for p in house.observations.image_paths] == [f.name for f in files]
    assert np.allclose(wrap_angle(house.observations.image_yaw - np.deg2rad(yaw)), 0.0)


@pytest.mark.parametrize("image_format", ["jpeg", "png"])
def test_compressed_images_stored_as_recorded(tmp_path, map_yaml, image_format):
    bag = _bag_path(tmp_path, 2)
    written = _write_basic(bag, 2, "mcap", image_format)
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out, ImportOptions(image_topic="/camera/image"))
    suffix = ".jpg" if image_format == "jpeg" else ".png"
    files = sorted((out / "img_0").iterdir())
    assert [f.suffix for f in files] == [suffix] * 3
    for f, rgb in zip(files, written["images"][:3], strict=True):
        ok, data = cv2.imencode(f".{image_format}", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        assert f.read_bytes() == data.tobytes()  # the recorded bytes, not re-encoded


@pytest.mark.parametrize(("ros", "storage"), FORMATS[:2], ids=FORMAT_IDS[:2])
def test_tf_chain(tmp_path, map_yaml, ros, storage):
    """map -> odom (1 Hz, x 1 m, yaw 90 deg), odom -> base_link (10 Hz, x = s), static
    base_link -> camera_link (x 0.1): camera_link in map is (1, s + 0.1) facing 90 deg."""
    bag = _bag_path(tmp_path, ros)
    with BagWriter(bag, ros=ros, storage=storage) as w:
        for t in T0 + np.arange(0.0, 4.01, 1.0):
            w.tf(t, [("map", "odom", 1.0, 0.0, np.pi / 2)])
        for t in T0 + np.arange(0.0, 4.01, 0.1):
            w.tf(t, [("odom", "base_link", t - T0, 0.0, 0.0)])
        w.tf(T0, [("base_link", "camera_link", 0.1, 0.0, 0.0)], static=True)
        w.image("/camera/image", T0 + 1.55, _image(0))
        w.image("/camera/image", T0 + 2.0, _image(1))
        w.text("/speech", T0 + 1.0, "kitchen")
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out, ImportOptions(pose_tf=("map", "camera_link")))
    pose = np.loadtxt(out / "pose_0.csv", delimiter=",", ndmin=2)
    assert np.allclose(pose[:, :2], [[1.0, 1.65], [1.0, 2.1]], atol=1e-9)
    assert np.allclose(2 * np.arctan2(pose[:, 2], pose[:, 3]), np.pi / 2)
    # The inverse direction: odom in base_link frame walks the edges backwards.
    out2 = tmp_path / "data" / "inverse"
    inverse = ImportOptions(pose_tf=("base_link", "odom"), map_frame="base_link")
    import_bags([bag], map_yaml, out2, inverse)
    assert np.allclose(np.loadtxt(out2 / "Xtx.csv"), [-1.55, -2.0], atol=1e-9)
    with pytest.raises(BagContentError, match="no chain of tf transforms from frame 'map' to "
                       "'laser'.*odom -> base_link"):  # fmt: skip
        import_bags([bag], map_yaml, tmp_path / "x" / "h", ImportOptions(pose_tf=("map", "laser")))


def test_a_pose_tf_whose_parent_is_not_the_maps_frame_is_refused():
    """--pose-tf odom base_link put odom-frame poses on a map-frame map without a word."""
    with pytest.raises(ValueError, match=r"--pose-tf odom base_link gives poses in frame 'odom', "
                       r"not the map's frame 'map': pass --pose-tf map base_link"):  # fmt: skip
        ImportOptions(pose_tf=("odom", "base_link"))
    assert ImportOptions(pose_tf=("/odom", "base_link"), map_frame="odom").pose_tf[0] == "/odom"


@pytest.mark.parametrize("kind", ["odom", "pose"])
def test_odometry_and_pose_stamped(tmp_path, map_yaml, kind):
    bag = _bag_path(tmp_path, 1)
    with BagWriter(bag, ros=1) as w:
        for t in T0 + np.arange(3.0):
            w.pose("/odom", t, t - T0, 0.0, 0.0, kind=kind, frame="odom")
        w.image("/camera/image", T0 + 0.5, _image(0))
        w.text("/speech", T0 + 1.5, "sofa")
    out = tmp_path / "data" / "house"
    # The poses are in frame odom: placed on the map only when the map is in that frame.
    with pytest.raises(BagContentError, match="frame 'odom', not the map's frame 'map'"):
        import_bags([bag], map_yaml, out, ImportOptions(pose_topic="/odom"))
    import_bags([bag], map_yaml, out, ImportOptions(pose_topic="/odom", map_frame="odom"))
    assert np.loadtxt(out / "Xtx.csv", ndmin=1) == pytest.approx([0.5])
    assert np.loadtxt(out / "StXtx.csv", ndmin=1) == pytest.approx([1.5])


def test_min_distance_and_interval(tmp_path, map_yaml):
    """Poses x = 0.2 s; images every 0.5 s over 0..5 s, at x = 0, 0.1, ..., 1.0 m."""
    bag = _bag_path(tmp_path, 2)
    with BagWriter(bag, ros=2) as w:
        for t in T0 + np.arange(6.0):
            w.pose("/amcl_pose", t, 0.2 * (t - T0), 0.0, 0.0)
        for t in T0 + np.arange(0.0, 5.01, 0.5):
            w.image("/camera/image", t, _image(0))
        w.text("/speech", T0, "hall")
    runs = iter(range(10))

    def kept(**options):
        out = tmp_path / "data" / f"h{next(runs)}"
        report = import_bags([bag], map_yaml, out, ImportOptions(**options))
        return np.loadtxt(out / "Xtx.csv", ndmin=1), report.trials[0]

    x, trial = kept()
    assert x.size == 11 and trial["images_thinned"] == 0
    x, trial = kept(min_distance=0.25)
    assert np.allclose(x, [0.0, 0.3, 0.6, 0.9]) and trial["images_thinned"] == 7
    # No silent loss: every image is kept, thinned or skipped.
    assert trial["images_kept"] + trial["images_thinned"] + trial["images_no_pose"] == 11
    x, _ = kept(min_interval=2.0)
    assert np.allclose(x, [0.0, 0.4, 0.8])
    x, _ = kept(min_interval=1.0, min_distance=0.35)  # both must hold
    assert np.allclose(x, [0.0, 0.4, 0.8])
    x, _ = kept(min_interval=1.0, min_distance=0.15)
    assert np.allclose(x, [0.0, 0.2, 0.4, 0.6, 0.8, 1.0])


def test_padded_mono_and_unstamped_images(tmp_path, map_yaml):
    """Rows padded to ``step`` bytes, a mono8 image, a zero header stamp (-> the log time), and
    an undecodable image (reported, not written)."""
    bag = _bag_path(tmp_path, 2)
    rgb = _image(3)  # [6, 8, 3]
    grey = rgb[..., 0].copy()  # [6, 8]
    with BagWriter(bag, ros=2) as w:
        for t in T0 + np.arange(4.0):
            w.pose("/amcl_pose", t, 0.5 * (t - T0), 0.0, 0.0)
        image = w.types["sensor_msgs/msg/Image"]
        padded = np.concatenate([rgb.reshape(6, 24), np.full((6, 4), 7, np.uint8)], axis=1)
        w.write("/camera/image", "sensor_msgs/msg/Image", image(
            header=w.header(T0 + 1.0, "cam"), height=6, width=8, encoding="rgb8",
            is_bigendian=0, step=28, data=padded.reshape(-1)), log_time=T0 + 1.0)  # fmt: skip
        w.write("/camera/image", "sensor_msgs/msg/Image", image(
            header=w.header(0.0, "cam"), height=6, width=8, encoding="mono8",
            is_bigendian=0, step=8, data=grey.reshape(-1)), log_time=T0 + 2.0)  # fmt: skip
        w.write("/camera/image", "sensor_msgs/msg/Image", image(
            header=w.header(T0 + 2.5, "cam"), height=6, width=8, encoding="rgb8",
            is_bigendian=0, step=24, data=np.zeros(10, np.uint8)), log_time=T0 + 2.5)  # fmt: skip
        w.text("/speech", T0 + 1.0, "hall")
    out = tmp_path / "data" / "house"
    report = import_bags([bag], map_yaml, out)
    files = sorted((out / "img_0").iterdir())
    assert len(files) == 2
    assert np.array_equal(cv2.cvtColor(cv2.imread(str(files[0])), cv2.COLOR_BGR2RGB), rgb)
    assert np.array_equal(cv2.imread(str(files[1]))[..., 0], grey)
    assert np.allclose(np.loadtxt(out / "Xtx.csv"), [0.5, 1.0])  # the mono image at log 2 s
    (skip,) = report.skipped
    assert skip.kind == "image" and skip.stamp == pytest.approx(T0 + 2.5)
    assert "not decodable" in skip.reason and "holds 10 bytes, expected 144" in skip.reason


def test_missing_topic_lists_the_bags_topics(tmp_path, map_yaml):
    bag = _bag_path(tmp_path, 2)
    _write_basic(bag, 2, "sqlite3")
    with pytest.raises(BagContentError) as error:
        import_bags([bag], map_yaml, tmp_path / "d" / "h", ImportOptions(words_topic="/words"))
    message = str(error.value)
    assert "no utterance topic '/words'" in message
    assert "/speech (std_msgs/msg/String)" in message
    assert "/amcl_pose (geometry_msgs/msg/PoseWithCovarianceStamped)" in message
    assert not (tmp_path / "d" / "h").exists() and not list((tmp_path / "d").glob(".h.partial*"))


def test_unknown_message_type(tmp_path, map_yaml):
    bag = _bag_path(tmp_path, 1)
    with BagWriter(bag, ros=1) as w:
        w.text("/amcl_pose", T0, "not a pose")
    with pytest.raises(BagContentError, match="pose topic /amcl_pose has message type "
                       "std_msgs/msg/String, which the import does not read"):  # fmt: skip
        import_bags([bag], map_yaml, tmp_path / "d" / "h")


@pytest.mark.parametrize(("ros", "storage"), FORMATS, ids=FORMAT_IDS)
def test_timestamps_going_backwards(tmp_path, map_yaml, ros, storage):
    """An image or pose sample stamped before the one recorded ahead of it stopped the whole
    import ('timestamps go backwards'). A few late ones are now taken in stamp order and
    counted; a clock that went back (more than a tenth late) is still an error."""
    bag = _bag_path(tmp_path, ros)
    with BagWriter(bag, ros=ros, storage=storage) as w:
        for t in T0 + np.arange(4.0):
            w.pose("/amcl_pose", t, 0.5 * (t - T0), 0.0, 0.0)
        w.pose("/amcl_pose", T0 + 2.5, 2.0, 0.0, 0.0, log_time=T0 + 3.5)  # late pose sample
        w.image("/camera/image", T0 + 1.5, _image(0), log_time=T0 + 1.0)
        w.image("/camera/image", T0 + 1.25, _image(1), log_time=T0 + 2.0)  # stamp goes back
        w.image("/camera/image", T0 + 2.5, _image(2), log_time=T0 + 3.0)
        w.text("/speech", T0, "hall")
    out = tmp_path / "d" / "h"
    report = import_bags([bag], map_yaml, out, ImportOptions(min_interval=0.3), progress=False)
    # stamp order 1.25, 1.5, 2.5: 1.5 is thinned (0.25 s after 1.25), not 1.25 (before 1.5)
    assert np.allclose(np.loadtxt(out / "Xtx.csv"), [0.625, 2.0])  # 2.5 s: the late sample
    (counts,) = report.trials
    assert counts["images_out_of_order"] == 1 and counts["poses_out_of_order"] == 1
    assert counts["images_thinned"] == 1
    assert "1 image(s) came after one stamped later (arrived late)" in report.text()
    assert "1 pose sample(s) came after one stamped later" in report.text()

    reset = _bag_path(tmp_path, ros, "reset")
    with BagWriter(reset, ros=ros, storage=storage) as w:
        for k, t in enumerate([*range(6), 0.5, 1.5, 2.5, 3.5]):  # the clock went back to 0.5
            w.pose("/amcl_pose", T0 + t, 0.0, 0.0, 0.0, log_time=T0 + k)
        w.image("/camera/image", T0 + 1.0, _image(0))
        w.text("/speech", T0, "hall")
    with pytest.raises(BagContentError, match=r"topic /amcl_pose: timestamps go backwards: "
                       r"message 7 is stamped 1600000000\.500000000 s after message 6 at "
                       r"1600000005\.000000000 s; 4 of 10 messages are stamped before an "
                       r"earlier one"):  # fmt: skip
        import_bags([reset], map_yaml, tmp_path / "d" / "r", progress=False)


def test_pose_outside_the_map(tmp_path, map_yaml):
    bag = _bag_path(tmp_path, 2)
    with BagWriter(bag, ros=2) as w:
        for t in T0 + np.arange(3.0):
            w.pose("/amcl_pose", t, 5.0 * (t - T0), 0.0, 0.0)  # x 0, 5, 10: the map ends at 3
        w.image("/camera/image", T0 + 0.1, _image(0))
        w.image("/camera/image", T0 + 1.0, _image(1))
        w.text("/speech", T0, "hall")
    with pytest.raises(PoseOutsideMapError, match=r"image on /camera/image at 1600000001\.0+ s "
                       r"has pose x=5\.000, y=0\.000 m, outside the map .*floor\.yaml "
                       r"\(x -3\.00\.\.3\.00, y -3\.00\.\.3\.00 m\)"):  # fmt: skip
        import_bags([bag], map_yaml, tmp_path / "d" / "h")


def test_not_a_bag(tmp_path, map_yaml):
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"this is not a bag" * 10)
    with pytest.raises(BagFormatError, match=r"junk\.bag: not a readable bag"):
        import_bags([junk], map_yaml, tmp_path / "d" / "h")
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    with pytest.raises(BagFormatError, match=r"notes\.txt: not a bag"):
        import_bags([text], map_yaml, tmp_path / "d" / "h")
    with pytest.raises(BagFormatError, match="folder with metadata.yaml"):
        import_bags([tmp_path / "maps"], map_yaml, tmp_path / "d" / "h")
    with pytest.raises(FileNotFoundError, match="bag not found"):
        import_bags([tmp_path / "nothing.bag"], map_yaml, tmp_path / "d" / "h")
    taken = tmp_path / "taken"  # an OUT in use: the missing bag is still what is said
    (taken / "h").mkdir(parents=True)
    (taken / "h" / "x.csv").write_text("1\n")
    with pytest.raises(FileNotFoundError, match=r"nothing\.bag: bag not found"):
        import_bags([tmp_path / "nothing.bag"], map_yaml, taken / "h")


def test_existing_output_and_overwrite(tmp_path, map_yaml):
    bag = _bag_path(tmp_path, 2)
    _write_basic(bag, 2, "sqlite3")
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out)
    with pytest.raises(FileExistsError, match="pass --overwrite"):
        import_bags([bag], map_yaml, out)
    copy = shutil.copytree(bag, tmp_path / "rec_copy")  # the same bag twice is refused
    import_bags([bag, copy], map_yaml, out, overwrite=True, first_trial=1)  # two trials
    assert sorted(p.name for p in out.glob("pose_*.csv")) == ["pose_1.csv", "pose_2.csv"]
    assert json.loads((out / "bag_import.json").read_text())["first_trial"] == 1
    other = tmp_path / "data" / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    with pytest.raises(FileExistsError, match="not written by import-bag"):
        import_bags([bag], map_yaml, other, overwrite=True)
    assert (other / "notes.txt").read_text() == "keep me"


def test_rosbags_missing_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rosbags", None)
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)
    with pytest.raises(RosbagsMissingError, match=r'pip install "spcopyro\[ros\]"'):
        import_bags([tmp_path / "x.bag"], tmp_path / "m.yaml", tmp_path / "d" / "h")
    # and importing spcopyro and its rosbag commands works without rosbags (blocked here)
    code = "import sys; sys.modules['rosbags'] = None; import spcopyro, spcopyro.robot.rosbag.cli"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


@pytest.mark.parametrize(("ros", "storage"), FORMATS, ids=FORMAT_IDS)
def test_synthetic_bags_round_trip(tmp_path, ros, storage):
    """The synthetic house recorded and imported: positions, yaws and words come back."""
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house
    from spcopyro.synthetic import HouseSpec, make_house

    spec = HouseSpec.scaled(30, 40, images_per_room_per_trial=3, utterances_per_room_per_trial=2,
                            num_trials=2, sentence_fraction=0.5)  # fmt: skip
    house = make_house(seed=1, spec=spec)
    bags = write_synthetic_bags(tmp_path / "bags", house=house, ros=ros, storage=storage,
                                image_format="png", image_size=(12, 16))  # fmt: skip
    out = tmp_path / "data" / "house"
    import_bags(bags.bags, bags.map_yaml, out, ImportOptions(image_topic=bags.image_topic))
    obs = house.observations
    assert np.allclose(np.loadtxt(out / "Xtx.csv"), obs.image_xy[:, 0], atol=1e-9)
    assert np.allclose(np.loadtxt(out / "StXty.csv"), obs.word_xy[:, 1], atol=1e-9)
    # With the house's own features, the imported house is the house: the same fit, bit for bit.
    rows = (",".join(repr(float(v)) for v in row) for row in obs.image_features)
    (out / "Ft.csv").write_text("\n".join(rows) + "\n")
    imported = load_house(out)
    loaded = imported.observations
    assert loaded.utterances == obs.utterances
    assert np.array_equal(loaded.word_trial, obs.word_trial)
    assert np.array_equal(loaded.image_trial, obs.image_trial)
    assert np.allclose(wrap_angle(loaded.image_yaw - obs.image_yaw), 0.0, atol=1e-9)
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    fits = [fit_house(h, settings, sweeps=3, seed=2, progress=False) for h in (house, imported)]
    assert np.array_equal(fits[0].label_image(), fits[1].label_image())
    # tf (map -> odom -> base_link) gives the same poses as /amcl_pose.
    via_tf = tmp_path / "data" / "tf"
    options = ImportOptions(image_topic=bags.image_topic, pose_tf=("map", "base_link"))
    import_bags(bags.bags, bags.map_yaml, via_tf, options)
    assert np.allclose(np.loadtxt(via_tf / "Xty.csv"), obs.image_xy[:, 1], atol=1e-9)
    # Images of rooms of different categories differ in colour.
    cells = house.grid.world_to_cell(obs.image_xy)
    category = house.truth[cells[:, 0], cells[:, 1]]
    hue = [cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2HSV)[..., 0].mean()
           for p in loaded.image_paths]  # fmt: skip
    for c in np.unique(category):
        assert np.ptp(np.asarray(hue)[category == c]) < 3
    assert len({round(h) for h in hue}) >= min(3, len(np.unique(category)))


def test_cli_simulate_import_features_fit(tmp_path, capsys):
    """The README walkthrough, small: simulate-bag -> import-bag -> features -> load -> fit."""
    from spcopyro.config import preset
    from spcopyro.features.extract import extract_to_csv
    from spcopyro.fit.house import fit_house

    simulate = ["simulate-bag", "--out", str(tmp_path / "bags"), "--ros", "1",
                "--image-size", "16", "20", "--trials", "0"]  # fmt: skip
    assert main(simulate) == 0
    assert main(simulate) == 2  # never over a recording, and says what to do
    assert "write the bags into another --out folder" in capsys.readouterr().err
    bags = sorted(str(p) for p in (tmp_path / "bags").glob("trial_*.bag"))
    assert len(bags) == 1
    out = tmp_path / "data" / "house"
    code = main(["import-bag", *bags[:1], "--map", str(tmp_path / "bags" / "map.yaml"),
                 "--image-topic", "/camera/image/compressed", "--min-distance", "1.0",
                 "--out", str(out)])  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    assert "thinned by --min-distance" in printed and f"spcopyro features {out}" in printed
    extract_to_csv(out, out / "Ft.csv", weights="random", progress=False, batch_size=8)
    house = load_house(out)
    assert house.observations.num_images == len(list((out / "img_0").iterdir())) > 3
    result = fit_house(house, preset("original-code", gamma=3.0, num_concepts=6), sweeps=3,
                       progress=False)  # fmt: skip
    assert result.label_image().shape == house.grid.shape
    # A CLI error is one line and exit code 2.
    code = main(["import-bag", *bags[:1], "--map", str(tmp_path / "bags" / "map.yaml"),
                 "--image-topic", "/camera/image/compressed", "--out", str(out)])  # fmt: skip
    assert code == 2
    assert "already exists" in capsys.readouterr().err


def _strip_definitions(bag: Path) -> None:
    """Make a ROS 2 sqlite3 bag look like Foxy's, Galactic's or Humble's: no message
    definitions stored (an older database schema without the message_definitions table)."""
    import sqlite3

    (db,) = bag.glob("*.db3")
    with sqlite3.connect(db) as con:
        con.execute("DROP TABLE message_definitions")
        con.execute("UPDATE schema SET schema_version = 3")
    meta = bag / "metadata.yaml"
    meta.write_text(meta.read_text().replace("  version: 9", "  version: 5"))


def _blank_mcap_schemas(monkeypatch, encoding: str, types: set[str] | None = None) -> None:
    """Make the mcap bags written next store no definitions: each schema (of ``types``, or all)
    is written with empty data and ``encoding``, as rosbag2 does for a type whose definition it
    cannot find (``unknown``; rosbag2_cpp's LocalMessageDefinitionSource) or as the MCAP
    specification allows (``""``). The schema's name still names the type, as it must: an
    mcap channel has no other place for it. Done in rosbags' own mcap writer, whose
    ``add_msgtype`` writes the schema record (in the chunk, and from ``schemas`` in the
    summary)."""
    from rosbags.rosbag2.storage_mcap import McapWriter, Schema, write_schema

    original = McapWriter.add_msgtype

    def add_msgtype(self, connection):
        if types is not None and connection.msgtype not in types:
            return original(self, connection)
        self.schemas.append(Schema(len(self.schemas) + 1, connection.msgtype, encoding, ""))
        write_schema(self.chunk.bio, self.schemas[-1])

    monkeypatch.setattr(McapWriter, "add_msgtype", add_msgtype)


BARE_BAGS = {  # id: (storage, distro, mcap schema encoding, types without definitions)
    "foxy": ("sqlite3", "foxy", None, None),
    "humble": ("sqlite3", "humble", None, None),
    "jazzy": ("sqlite3", "jazzy", None, None),
    "mcap-unknown": ("mcap", "jazzy", "unknown", None),
    "mcap-empty-encoding": ("mcap", "humble", "", None),
    "mcap-one-topic-unknown": ("mcap", "jazzy", "unknown", {"std_msgs/msg/String"}),
}


@pytest.mark.parametrize("case", list(BARE_BAGS))
def test_a_bag_without_message_definitions_imports_like_its_twin(
    tmp_path, map_yaml, monkeypatch, case
):
    """Issue 24 item 1: real Foxy / Galactic / Humble bags store no message definitions and
    ended with "Bag contains no type definitions". They are read with the --ros-distro
    typestore and give the same observations as the same bag with definitions. So are mcap
    bags whose schemas hold no definition (empty data): with an empty encoding rosbags needs
    the typestore as for sqlite3; with rosbag2's ``unknown`` rosbags 0.11 fails with
    ``KeyError: 'unknown'`` even when given one, and even when only one topic's definition is
    missing (open_bag reads such schemas as "no definition")."""
    from rosbags.highlevel import AnyReader

    from spcopyro.robot.rosbag.bag import open_bag, typestore

    storage, distro, encoding, types = BARE_BAGS[case]
    twin, bare = tmp_path / "twin", tmp_path / "bare"
    _write_basic(twin, 2, storage)
    if storage == "sqlite3":
        _write_basic(bare, 2, storage)
        _strip_definitions(bare)
    else:
        with monkeypatch.context() as patch:
            _blank_mcap_schemas(patch, encoding, types)
            _write_basic(bare, 2, storage)
    # rosbags alone cannot: without a typestore, and with one for rosbag2's 'unknown'.
    if encoding == "unknown":
        with pytest.raises(KeyError, match="'unknown'"):
            AnyReader([bare], default_typestore=typestore(distro)).open()
    else:
        with pytest.raises(Exception, match="no type definitions"):
            AnyReader([bare]).open()
    options = ImportOptions(pose_tolerance=0.6, ros_distro=distro)
    import_bags([twin], map_yaml, tmp_path / "a" / "house", options)
    report = import_bags([bare], map_yaml, tmp_path / "b" / "house", options)
    for name in ("Xtx.csv", "Xty.csv", "StXtx.csv", "StXty.csv", "word_0.csv", "pose_0.csv"):
        a = (tmp_path / "a" / "house" / name).read_text()
        assert (tmp_path / "b" / "house" / name).read_text() == a, name
    record = json.loads((report.out / "bag_import.json").read_text())
    assert record["options"]["ros_distro"] == distro
    with open_bag(bare, distro) as reader:
        assert {c.msgtype for c in reader.connections} >= {"std_msgs/msg/String"}


def test_the_cli_names_the_ros_distro_it_read_with(tmp_path, map_yaml, capsys):
    bare = tmp_path / "bare"
    _write_basic(bare, 2, "sqlite3")
    _strip_definitions(bare)
    argv = ["import-bag", str(bare), "--map", str(map_yaml), "--out", str(tmp_path / "h"),
            "--pose-tolerance", "0.6", "--ros-distro", "foxy"]  # fmt: skip
    assert main(argv) == 0
    assert "ROS 2 types      foxy" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main([*argv[:-1], "rolling"])


def test_poses_merged_by_coarse_stamps_are_counted(tmp_path, map_yaml):
    """Issue 24 item 3: a bag whose header stamps have 1 s resolution kept the first pose of
    each stamp without a count or a warning."""
    bag = tmp_path / "coarse"
    with BagWriter(bag, ros=2) as w:
        for k in range(40):  # 10 Hz poses, stamps floored to whole seconds
            t = T0 + np.floor(k / 10.0)
            w.pose("/amcl_pose", t, 0.01 * k, 0.0, 0.0, log_time=T0 + k / 10.0)
        w.image("/camera/image", T0 + 1.0, _image(0))
        w.text("/speech", T0 + 1.0, "kitchen")
    report = import_bags([bag], map_yaml, tmp_path / "h", ImportOptions())
    assert report.trials[0]["poses_merged"] == 36  # 40 samples, 4 distinct stamps
    assert "36 pose sample(s) repeated the previous one's stamp" in report.text()
    assert report.trials[0]["pose_frame"] == "map"


def test_poses_in_another_frame_are_an_error(tmp_path, map_yaml):
    """Issue 24 item 3: header.frame_id was never checked against the map's frame."""
    bag = tmp_path / "odom"
    with BagWriter(bag, ros=2) as w:
        for k in range(5):
            w.pose("/amcl_pose", T0 + k, 0.1 * k, 0.0, 0.0, frame="odom")
        w.image("/camera/image", T0 + 1.0, _image(0))
        w.text("/speech", T0 + 1.0, "kitchen")
    with pytest.raises(BagContentError, match=r"frame 'odom', not the map's frame 'map', and no "
                       r"tf chain links them \(the bag has no /tf"):  # fmt: skip
        import_bags([bag], map_yaml, tmp_path / "h", ImportOptions())
    report = import_bags([bag], map_yaml, tmp_path / "h2", ImportOptions(map_frame="odom"))
    assert report.trials[0]["pose_frame"] == "odom"
    assert report.trials[0]["pose_frame_via_tf"] is None


@pytest.mark.parametrize(("ros", "storage"), FORMATS, ids=FORMAT_IDS)
def test_poses_in_another_frame_are_placed_on_the_map_through_tf(
    tmp_path, map_yaml, ros, storage, capsys
):
    """Issue 24 item 1: a pose topic in frame odom, with tf map -> odom in the bag, is placed
    on the map through that transform, and the import says so.

    Odometry in odom: x = 0.5 s, y = 0.2, yaw 0.3 (s = t - T0). tf map -> odom at 1 Hz:
    x = 1 + 0.1 s, y 0, yaw 90 deg, so R(90 deg) (x, y) = (-y, x) and the pose on the map is
    (1 + 0.1 s - 0.2, 0.5 s), yaw 90 deg + 0.3 rad. At the image (s = 1.5): (0.95, 0.75); at
    the utterance (s = 2.25): (1.025, 1.125)."""
    bag = _bag_path(tmp_path, ros)
    with BagWriter(bag, ros=ros, storage=storage) as w:
        for t in T0 + np.arange(0.0, 4.01, 0.5):
            w.pose("/amcl_pose", t, 0.5 * (t - T0), 0.2, 0.3, frame="odom")
        for t in T0 + np.arange(0.0, 4.01, 1.0):
            w.tf(t, [("map", "odom", 1.0 + 0.1 * (t - T0), 0.0, np.pi / 2)])
        w.image("/camera/image", T0 + 1.5, _image(0))
        w.text("/speech", T0 + 2.25, "kitchen")
    out = tmp_path / "data" / "house"
    argv = ["import-bag", str(bag), "--map", str(map_yaml), "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "pose frame       odom (the map's: map)" in printed
    assert "pose frame -> map through tf map -> odom" in printed
    assert "poses in frame odom placed on the map through tf map -> odom" in printed
    pose = np.loadtxt(out / "pose_0.csv", delimiter=",", ndmin=2)  # x, y, qz, qw
    assert np.allclose(pose[:, :2], [[0.95, 0.75]], atol=1e-9)
    assert np.allclose(2 * np.arctan2(pose[:, 2], pose[:, 3]), np.pi / 2 + 0.3)
    assert np.allclose(np.loadtxt(out / "StXtx.csv", ndmin=1), [1.025], atol=1e-9)
    assert np.allclose(np.loadtxt(out / "StXty.csv", ndmin=1), [1.125], atol=1e-9)
    record = json.loads((out / "bag_import.json").read_text())["trials"][0]
    assert (record["pose_frame"], record["pose_frame_via_tf"]) == ("odom", "map -> odom")


def test_poses_in_a_frame_tf_does_not_reach_are_an_error(tmp_path, map_yaml):
    """A bag with tf, but none of it linking the map to the poses' frame."""
    bag = tmp_path / "odom"
    with BagWriter(bag, ros=2) as w:
        for k in range(5):
            w.pose("/amcl_pose", T0 + k, 0.1 * k, 0.0, 0.0, frame="odom")
            w.tf(T0 + k, [("base_link", "laser", 0.1, 0.0, 0.0)])
        w.image("/camera/image", T0 + 1.0, _image(0))
        w.text("/speech", T0 + 1.0, "kitchen")
    expected = (
        r"frame 'odom', not the map's frame 'map', and no tf chain links them "
        r"\(the bag's tf edges: base_link -> laser\)"
    )
    with pytest.raises(BagContentError, match=expected):
        import_bags([bag], map_yaml, tmp_path / "h", ImportOptions())


def test_simulate_bag_checks_its_options_before_writing(tmp_path, capsys):
    """QA: --image-size 0 0 gave a cv2 traceback and -4 10 "negative dimensions are not
    allowed"; --ros 1 --storage mcap ignored --storage."""
    out = tmp_path / "sb"
    for size in (["0", "0"], ["-4", "10"]):
        with pytest.raises(SystemExit):
            main(["simulate-bag", "--out", str(out), "--image-size", *size])
        assert f"argument --image-size: must be an integer >= 1, got '{size[0]}'" in (
            capsys.readouterr().err
        )
    assert main(["simulate-bag", "--out", str(out), "--ros", "1", "--storage", "mcap"]) == 2
    assert "--storage mcap applies to ROS 2 bags only" in capsys.readouterr().err
    with pytest.raises(ValueError, match=r"image_size must be two integers in 1\.\.8192"):
        write_synthetic_bags(out, image_size=(0, 64))
    assert not out.exists()


@pytest.mark.parametrize(
    ("call", "message"),
    [
        ("min_distance", "min_distance must be a finite number >= 0, got True"),
        ("min_interval", "min_interval must be a finite number >= 0, got False"),
        ("pose_tolerance", "pose_tolerance must be a finite number >= 0, got True"),
        ("first_trial", "first_trial must be an integer >= 0, got True"),
        ("image_size", r"image_size must be two integers in 1\.\.8192 \(H, W\), got \(True, 64\)"),
    ],
)
def test_a_bool_is_no_distance_interval_trial_or_image_side(tmp_path, map_yaml, call, message):
    """True is an int: ImportOptions took ``min_distance=True`` as 1 m, import_bags'
    ``first_trial=True`` as trial 1, write_synthetic_bags' ``image_size=(True, 64)`` as 1 row (a
    library caller's; the commands parse numbers). Refused with a bad value's message, before
    any bag is read or written."""
    with pytest.raises(ValueError, match=message):
        if call == "first_trial":
            import_bags([tmp_path / "b.bag"], map_yaml, tmp_path / "h", first_trial=True)
        elif call == "image_size":
            write_synthetic_bags(tmp_path / "sb", image_size=(True, 64))
        else:
            ImportOptions(**{call: call != "min_interval"})
    assert not (tmp_path / "h").exists() and not (tmp_path / "sb").exists()


def test_a_failed_simulate_bag_leaves_nothing_in_a_retrys_way(tmp_path, monkeypatch):
    """QA: a failed simulate-bag left map.yaml behind, so a retry said "map.yaml already
    exists ... never overwrites a recording". The map is written last, and a failure removes
    the bags, the map and the folders the run made."""
    import spcopyro.robot.rosbag.synthetic as synthetic

    calls = []
    render = synthetic.render_category_image

    def failing(*args, **kwargs):  # fails in the second trial's bag
        calls.append(1)
        if len(calls) > 70:  # trial 0 has 60 images
            raise RuntimeError("camera unplugged")
        return render(*args, **kwargs)

    monkeypatch.setattr(synthetic, "render_category_image", failing)
    out = tmp_path / "new" / "bags"
    with pytest.raises(RuntimeError, match="camera unplugged"):
        write_synthetic_bags(out, image_size=(8, 8), trials=[0, 1])
    assert not (tmp_path / "new").exists()
    (tmp_path / "kept").mkdir()
    (tmp_path / "kept" / "notes.txt").write_text("mine")
    calls.clear()
    with pytest.raises(RuntimeError):
        write_synthetic_bags(tmp_path / "kept", image_size=(8, 8), trials=[0, 1])
    assert [p.name for p in (tmp_path / "kept").iterdir()] == ["notes.txt"]
    monkeypatch.setattr(synthetic, "render_category_image", render)
    bags = write_synthetic_bags(out, image_size=(8, 8), trials=[0, 1])
    assert bags.map_yaml.is_file() and all(p.exists() for p in bags.bags)


def test_nothing_left_prints_the_skipped_observations_and_leaves_no_folder(
    tmp_path, map_yaml, capsys
):
    """QA: the error said "see the 78 skipped observations above" but none were printed (the
    import raised before the command printed them) and no skipped.csv remained; and the parent
    folders of OUT, created before the import could fail, were left empty."""
    bag = _bag_path(tmp_path, 2)
    _write_basic(bag, 2, "sqlite3")
    out = tmp_path / "new" / "deeper" / "house"
    code = main(["import-bag", str(bag), "--map", str(map_yaml), "--pose-tolerance", "0.1",
                 "--out", str(out)])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    listing, error = err.split("error: ")
    assert "skipped 7 observation(s) (nothing was written: the import failed):" in listing
    assert "trial 0 image at 1600000009.000000 s on /camera/image: no pose of /amcl_pose " in (
        listing
    )
    assert "no image left to write from /camera/image (7 observation(s) skipped, the first: " in (
        error
    )
    assert not (tmp_path / "new").exists()  # nor deeper/, map/ or a staging folder
    with pytest.raises(NothingLeftError, match="no image left") as caught:  # a BagContentError
        import_bags([bag], map_yaml, out, ImportOptions(pose_tolerance=0.1))
    assert isinstance(caught.value, BagContentError) and len(caught.value.skipped) == 7
    assert not (tmp_path / "new").exists()


def test_content_errors_name_the_bag_of_several(tmp_path, map_yaml):
    """QA: with several bags, the off-map pose and the stamps-going-back errors did not say
    which bag (the missing-topic errors did)."""
    good = _bag_path(tmp_path, 2, "good")
    _write_basic(good, 2, "sqlite3")
    off = _bag_path(tmp_path, 2, "off")
    with BagWriter(off, ros=2) as w:
        for t in T0 + np.arange(3.0):
            w.pose("/amcl_pose", t, 5.0 * (t - T0), 0.0, 0.0)  # x 0, 5, 10: the map ends at 3
        w.image("/camera/image", T0 + 1.0, _image(1))
        w.text("/speech", T0, "hall")
    with pytest.raises(PoseOutsideMapError, match=rf"^{off}: image on /camera/image at "):
        import_bags([good, off], map_yaml, tmp_path / "d" / "h")
    back = _bag_path(tmp_path, 2, "back")
    with BagWriter(back, ros=2) as w:
        for k, t in enumerate([0.0, 1.0, 2.0, 0.5, 1.5]):  # the clock went back
            w.pose("/amcl_pose", T0 + t, 0.0, 0.0, 0.0, log_time=T0 + k)
        w.image("/camera/image", T0 + 1.5, _image(0))
        w.text("/speech", T0, "hall")
    with pytest.raises(BagContentError, match=rf"^{back}: topic /amcl_pose: timestamps go"):
        import_bags([good, back], map_yaml, tmp_path / "d" / "h")


def test_overwrite_keeps_what_the_import_did_not_write(tmp_path, map_yaml, capsys):
    """QA: import-bag --overwrite deleted files added since (Ft.csv of spcopyro features)
    without a word; as fit --overwrite, it replaces what an import writes, keeps the rest and
    says so."""
    bag = _bag_path(tmp_path, 2)
    _write_basic(bag, 2, "sqlite3")
    out = tmp_path / "data" / "house"
    import_bags([bag, shutil.copytree(bag, tmp_path / "copy")], map_yaml, out)  # trials 0, 1
    (out / "Ft.csv").write_text("0.5,0.5\n")
    (out / "notes").mkdir()
    argv = ["import-bag", str(bag), "--map", str(map_yaml), "--out", str(out), "--overwrite"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert f"warning: --overwrite kept Ft.csv, notes in {out}, which import-bag did not write" in (
        err
    )
    assert (out / "Ft.csv").read_text() == "0.5,0.5\n" and (out / "notes").is_dir()
    assert not (out / "pose_1.csv").exists() and not (out / "img_1").exists()  # the old import's
    assert (out / "pose_0.csv").is_file() and not list(out.parent.glob(".house.*"))


def test_bag_commands_share_the_argument_types(tmp_path, capsys):
    """QA: import-bag's --min-distance/--min-interval/--pose-tolerance had their own type, whose
    message differed from every other command's ("must be a finite number >= 0"); simulate-bag's
    --seed was a plain int (a seed above 2**63 - 1 was taken, -1 failed after parsing) and
    import-bag's --first-trial -1 failed after parsing, not as a usage error."""
    cases = [
        (["import-bag", "b", "--map", "m", "--out", "o", "--min-distance", "-1"],
         "argument --min-distance: '-1': the distance is metres >= 0"),
        (["import-bag", "b", "--map", "m", "--out", "o", "--min-interval", "nan"],
         "argument --min-interval: 'nan': the interval is seconds >= 0"),
        (["import-bag", "b", "--map", "m", "--out", "o", "--pose-tolerance", "inf"],
         "argument --pose-tolerance: 'inf': the tolerance is seconds >= 0"),
        (["import-bag", "b", "--map", "m", "--out", "o", "--first-trial", "-1"],
         "argument --first-trial: must be an integer >= 0, got '-1'"),
        (["simulate-bag", "--out", str(tmp_path / "s"), "--seed", "-1"],
         "argument --seed: must be an integer >= 0, got '-1'"),
        (["simulate-bag", "--out", str(tmp_path / "s"), "--seed", str(2**63)],
         f"argument --seed: must be at most 2**63 - 1 = {2**63 - 1}, got '{2**63}'"),
    ]  # fmt: skip
    for argv, message in cases:
        with pytest.raises(SystemExit) as exited:
            main(argv)
        assert exited.value.code == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_a_folder_of_bags_names_what_it_holds(tmp_path, map_yaml):
    """QA: a ROS 2 recording stopped before rosbag2 wrote metadata.yaml, a folder of ROS 1 .bag
    files and simulate-bag's --out folder were each "not a bag" with no word of the bags inside
    (the .db3 / .bag / bag folders import when given themselves)."""
    bag = _bag_path(tmp_path / "rec", 2)
    _write_basic(bag, 2, "sqlite3")
    (bag / "metadata.yaml").unlink()
    with pytest.raises(BagFormatError, match=r"it holds rec\.db3: give the bags as BAG"):
        import_bags([bag], map_yaml, tmp_path / "d" / "h")
    import_bags([bag / "rec.db3"], map_yaml, tmp_path / "d" / "h")
    ros1 = _bag_path(tmp_path / "ros1", 1)
    ros1.parent.mkdir()
    _write_basic(ros1, 1, "sqlite3")
    with pytest.raises(BagFormatError, match=r"it holds rec\.bag: give"):
        import_bags([ros1.parent], map_yaml, tmp_path / "d" / "h2")
    folder = _bag_path(tmp_path / "many", 2, "trial_0")
    _write_basic(folder, 2, "sqlite3")
    with pytest.raises(BagFormatError, match=r"it holds trial_0/: give"):
        import_bags([folder.parent], map_yaml, tmp_path / "d" / "h2")
    with pytest.raises(BagFormatError, match=r"metadata\.yaml; a ROS 1 bag a \.bag file\)$"):
        import_bags([tmp_path / "maps"], map_yaml, tmp_path / "d" / "h2")  # no bag inside


def test_a_folder_of_six_bags_names_them_all(tmp_path, map_yaml):
    """The folder's list showed 5 names and " ...": a sixth piece was hidden behind as much text
    as its name, and more than six were not counted (messages.listed: all six named, seven as
    five and "(2 more)")."""
    folder = tmp_path / "bags"
    folder.mkdir()
    for i in range(6):
        (folder / f"t{i}.bag").write_bytes(b"")
    with pytest.raises(BagFormatError, match=r"it holds t0\.bag, .*, t5\.bag: give the bags"):
        import_bags([folder], map_yaml, tmp_path / "d" / "h")
    (folder / "t6.bag").write_bytes(b"")
    with pytest.raises(BagFormatError, match=r"t4\.bag, \.\.\. \(2 more\): give the bags"):
        import_bags([folder], map_yaml, tmp_path / "d" / "h")


def test_simulate_bag_into_a_file_says_so(tmp_path, capsys):
    """QA: simulate-bag --out FILE said "[Errno 17] File exists: 'FILE'", and --out FILE/x
    "[Errno 20] Not a directory"."""
    taken = tmp_path / "notes.txt"
    taken.write_text("mine")
    for out in (taken, taken / "bags"):
        assert main(["simulate-bag", "--out", str(out), "--trials", "0"]) == 2
        assert f"error: --out {out}: {taken} is a file, not a folder" in capsys.readouterr().err
    assert taken.read_text() == "mine"


def test_a_message_that_cannot_be_read_is_an_error_not_a_traceback(tmp_path, map_yaml):
    """QA: a bag damaged past its header (sqlite 'database disk image is malformed' on a later
    page, an mcap record cut short, bytes that do not decompress) stopped the import with a
    traceback of apsw / rosbags / zstd; now one line names the bag, the topic and the message.
    Here: a bag whose metadata.yaml says its messages are zstd-compressed, which they are not."""
    bag = _bag_path(tmp_path, 2)
    _write_basic(bag, 2, "sqlite3")
    metadata = bag / "metadata.yaml"
    text = metadata.read_text()
    text = text.replace("compression_format: ''", "compression_format: zstd")
    metadata.write_text(text.replace("compression_mode: ''", "compression_mode: MESSAGE"))
    with pytest.raises(BagFormatError, match=rf"^{bag}: message 1 on /amcl_pose cannot be read "
                       r"\(.+\); the bag is damaged or cut short$"):  # fmt: skip
        import_bags([bag], map_yaml, tmp_path / "d" / "h")
    assert not (tmp_path / "d").exists()


def test_simulate_bag_refuses_an_image_size_no_camera_has(tmp_path, capsys):
    """QA: --image-size 1000000 1000000 (a typo's extra zeros) stopped with a numpy traceback,
    'Unable to allocate 14.6 TiB'; sizes are checked, up to 8192 pixels a side."""
    out = tmp_path / "sb"
    with pytest.raises(SystemExit):
        main(["simulate-bag", "--out", str(out), "--image-size", "480000", "640"])
    assert "argument --image-size: must be at most 8192 pixels, got '480000'" in (
        capsys.readouterr().err
    )
    with pytest.raises(ValueError, match="two integers in 1..8192"):
        write_synthetic_bags(out, image_size=(48, 10**6))
    assert not out.exists()


def test_the_printed_next_commands_can_be_pasted_with_spaces_in_paths(tmp_path, capsys):
    """QA: with a space in a path (`--out "my bags"`), the printed 'import with:', 'next:' and
    'then:' commands split it into two arguments when pasted."""
    import shlex

    out = tmp_path / "my home" / "my bags"
    assert main(["simulate-bag", "--out", str(out), "--trials", "0", "--image-size", "8", "8"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "import with:" in x)
    argv = shlex.split(line.split("import with: spcopyro ", 1)[1])
    house = tmp_path / "my home" / "data" / "house"  # beside the bags folder
    assert argv[1] == str(out / "trial_0") and argv[argv.index("--out") + 1] == str(house)
    assert main(argv) == 0
    printed = capsys.readouterr().out.splitlines()
    for prefix in ("  next: spcopyro ", "  then: spcopyro "):
        command = shlex.split(next(x for x in printed if x.startswith(prefix))[len(prefix) :])
        assert command[1] == str(house)


def test_topics_without_their_leading_slash_are_found(tmp_path, map_yaml):
    """QA: --image-topic camera/image (as a ROS node in the root namespace resolves it to
    /camera/image) was 'no image topic' though the bag's listing, in the same message, had it."""
    bag = _bag_path(tmp_path, 2)
    _write_basic(bag, 2, "sqlite3")
    options = ImportOptions(pose_topic="amcl_pose", image_topic="camera/image",
                            words_topic="speech")  # fmt: skip
    report = import_bags([bag], map_yaml, tmp_path / "d" / "h", options)
    twin = import_bags([bag], map_yaml, tmp_path / "d" / "h2")
    assert report.trials[0]["images_kept"] == twin.trials[0]["images_kept"] == 3
    assert (tmp_path / "d" / "h" / "pose_0.csv").read_text() == (
        tmp_path / "d" / "h2" / "pose_0.csv"
    ).read_text()


def test_an_empty_topic_or_frame_is_refused(tmp_path, capsys):
    """QA: --map-frame '' ran the import to an error that suggested '--pose-tf  BASE_FRAME'
    (an empty frame), --pose-topic '' to "no pose topic ''"."""
    for option in ("--pose-topic", "--image-topic", "--words-topic", "--map-frame"):
        with pytest.raises(SystemExit):
            main(["import-bag", "b", "--map", "m", "--out", str(tmp_path / "h"), option, "/"])
        assert f"argument {option}: must name a topic or frame, got '/'" in (
            capsys.readouterr().err
        )
    for options in ({"map_frame": ""}, {"pose_topic": " "}, {"pose_tf": ("map", "")}):
        with pytest.raises(ValueError, match="must"):
            ImportOptions(**options)


@pytest.mark.parametrize(("ros", "storage", "hint"), [
    (1, "sqlite3", "`rosbag reindex` repairs its index"),
    (2, "mcap", "`mcap recover` rewrites what it holds"),
])  # fmt: skip
def test_a_bag_cut_short_names_its_usual_repair(tmp_path, map_yaml, ros, storage, hint):
    """QA: a recording killed before its recorder closed it (a .bag without its index, an .mcap
    without its footer) said only 'not a readable bag (Bag index looks damaged ...)'."""
    bag = _bag_path(tmp_path, ros)
    _write_basic(bag, ros, storage)
    data = bag if ros == 1 else next(bag.glob("*.mcap"))
    data.write_bytes(data.read_bytes()[: data.stat().st_size * 2 // 3])
    with pytest.raises(BagFormatError, match=rf"not a readable bag .*; if .*{re.escape(hint)}$"):
        import_bags([bag], map_yaml, tmp_path / "d" / "h")


def test_simulate_bag_prints_an_import_that_keeps_the_trials_numbers(tmp_path, capsys):
    """`simulate-bag --trials 1 2` printed an import that brought them in as trials 0 and 1."""
    import shlex

    out = tmp_path / "bags"
    argv = ["simulate-bag", "--out", str(out), "--image-size", "8", "8", "--trials", "2", "1"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    command = printed.split("import with: ")[1].splitlines()[0]
    assert "--first-trial 1" in command and "come in as" not in printed
    assert main(shlex.split(command)[1:]) == 0
    house = tmp_path / "data" / "house"  # beside the bags folder (the README's walk)
    assert sorted(p.name for p in house.glob("img_*")) == ["img_1", "img_2"]
    assert main(["simulate-bag", "--out", str(tmp_path / "gap"), "--image-size", "8", "8",
                 "--trials", "0", "2"]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    command = printed.split("import with: ")[1].splitlines()[0]
    assert "--first-trial" not in command and "trials 0, 2 come in as 0, 1" in printed
