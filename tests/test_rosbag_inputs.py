"""``spcopyro import-bag`` on awkward inputs: mistyped paths and topics (found before OUT is
looked at or any bag is read), 16-bit camera images, stamps out of order, a simulator's
recording with some images unstamped. Small bags written with
:class:`spcopyro.robot.rosbag.BagWriter`."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.cli.main import main  # noqa: E402
from spcopyro.robot.rosbag import BagFormatError, BagWriter, ImportOptions, import_bags  # noqa: E402
from spcopyro.robot.rosbag.images import to_8_bits  # noqa: E402

T0 = 1_600_000_000.0


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
        ("rec", "floor.yaml", ["--pose-tf", "map", "base_link"], "no /tf or /tf_static topic"),
    ],
    ids=["missing-bag", "not-a-bag", "missing-map", "image-topic", "words-topic", "tf"],
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


@pytest.mark.parametrize(
    "second", ["rec", "rec/", "./rec", "rec/rec.db3"], ids=["same", "slash", "dot", "db3"]
)
def test_a_bag_given_twice_is_refused(tmp_path, map_yaml, capsys, monkeypatch, second):
    """`import-bag rec rec/` (or a bag folder and its .db3) imported one recording as two
    trials, every image and utterance counted twice, without a word."""
    monkeypatch.chdir(tmp_path)
    _basic_bag(tmp_path / "rec")
    assert (tmp_path / second).exists()
    assert main(["import-bag", "rec", second, "--map", "maps/floor.yaml", "--out", "h"]) == 2
    err = capsys.readouterr().err
    assert f"{second}: the recording of rec (BAG 1 and 2)" in err, err
    assert not (tmp_path / "h").exists()


def _raw_image(
    w: BagWriter, t: float, pixels: np.ndarray, encoding: str, log_time: float | None = None
) -> None:
    """A sensor_msgs/Image of ``pixels`` [H, W(, C)] as they are (little-endian), stamped ``t``
    and recorded at ``log_time`` (default ``t``)."""
    h, width = pixels.shape[:2]
    data = np.ascontiguousarray(pixels).view(np.uint8).reshape(-1)
    msg = w.types["sensor_msgs/msg/Image"](
        header=w.header(t, "cam"), height=h, width=width, encoding=encoding, is_bigendian=0,
        step=data.size // h, data=data)  # fmt: skip
    w.write(
        "/camera/image", "sensor_msgs/msg/Image", msg, log_time=t if log_time is None else log_time
    )


def _bag_of_two_16_bit_images(bag: Path, *images: tuple[np.ndarray, str]) -> Path:
    """A ROS 2 bag standing at the origin: raw images (pixels, encoding) at 1 s and 2 s."""
    with BagWriter(bag, ros=2) as w:
        for t in T0 + np.arange(4.0):
            w.pose("/amcl_pose", t, 0.0, 0.0, 0.0)
        for k, (pixels, encoding) in enumerate(images):
            _raw_image(w, T0 + 1.0 + k, pixels, encoding)
        w.text("/speech", T0 + 1.0, "hall")
    return bag


def test_16_bit_images_use_the_range_their_values_span(tmp_path, map_yaml):
    """A 12-bit camera's mono16 (0..4095) came out 0..15, nearly black: rosbags-image's bgr8
    keeps the high byte, and the rescale after it never ran. A 16-bit image is now scaled from
    the smallest of 8, 10, 12, 14, 16 bits that holds its values."""
    grey12 = np.linspace(0, 4095, 48).round().astype(np.uint16).reshape(6, 8)  # [6, 8]
    rgb16 = np.random.default_rng(0).integers(0, 65536, (6, 8, 3)).astype(np.uint16)
    rgb16[0, 0] = 65535
    bag = _bag_of_two_16_bit_images(tmp_path / "rec", (grey12, "mono16"), (rgb16, "rgb16"))
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out, progress=False)
    first, second = (cv2.imread(str(p)) for p in sorted((out / "img_0").iterdir()))
    expected = np.rint(grey12 * (255 / 4095)).astype(np.uint8)
    assert np.array_equal(first, np.repeat(expected[..., None], 3, axis=2))
    assert first.max() == 255
    expected = np.rint(rgb16[..., ::-1] * (255 / 65535)).astype(np.uint8)
    assert np.array_equal(second, expected)


def test_a_16_bit_png_compressed_image_is_stored_scaled(tmp_path, map_yaml):
    """image_transport's png of a mono16 camera (a 16-bit PNG CompressedImage) was stored as
    recorded, and read as its high byte (0..15 of a 12-bit camera) by `features`; it is now
    stored as an 8-bit PNG scaled as a raw mono16 image is."""
    grey12 = np.linspace(0, 4095, 48).round().astype(np.uint16).reshape(6, 8)  # [6, 8]
    ok, png = cv2.imencode(".png", grey12)
    assert ok and png.tobytes()[24] == 16  # a 16-bit PNG
    bag = tmp_path / "rec"
    with BagWriter(bag, ros=2) as w:
        for t in T0 + np.arange(4.0):
            w.pose("/amcl_pose", t, 0.0, 0.0, 0.0)
        msg = w.types["sensor_msgs/msg/CompressedImage"](
            header=w.header(T0 + 1.0, "cam"), format="mono16; png compressed",
            data=png.reshape(-1))  # fmt: skip
        w.write("/camera/image", "sensor_msgs/msg/CompressedImage", msg, log_time=T0 + 1.0)
        w.text("/speech", T0 + 1.0, "hall")
    out = tmp_path / "data" / "house"
    import_bags([bag], map_yaml, out, progress=False)
    (stored,) = (out / "img_0").iterdir()
    assert stored.read_bytes()[24] == 8  # an 8-bit PNG
    expected = np.rint(grey12 * (255 / 4095)).astype(np.uint8)
    assert np.array_equal(cv2.imread(str(stored)), np.repeat(expected[..., None], 3, axis=2))


def test_a_dark_frame_of_a_16_bit_camera_is_said_and_image_bits_scales_alike(
    tmp_path, map_yaml, capsys
):
    """Each 16-bit image is scaled from the depth its own largest value needs: a dark frame of
    a 12-bit camera (max 900, read as 10 bits) came out 4x brighter than the others, without
    a word. The import now says so, and --image-bits 12 scales every frame from 12 bits."""
    bright = np.linspace(0, 4095, 48).round().astype(np.uint16).reshape(6, 8)  # [6, 8]
    dark = np.linspace(0, 900, 48).round().astype(np.uint16).reshape(6, 8)
    bag = _bag_of_two_16_bit_images(tmp_path / "rec", (bright, "mono16"), (dark, "mono16"))
    argv = ["import-bag", str(bag), "--map", str(map_yaml), "--out"]
    assert main([*argv, str(tmp_path / "auto")]) == 0
    said = capsys.readouterr().out
    assert "its 16-bit images were scaled from 10 to 12 bits" in said
    assert "--image-bits 12 scales them all alike" in said
    assert main([*argv, str(tmp_path / "twelve"), "--image-bits", "12"]) == 0
    assert "16-bit images were scaled" not in capsys.readouterr().out
    _, stored = sorted((tmp_path / "twelve" / "img_0").iterdir())
    expected = np.rint(dark * (255 / 4095)).astype(np.uint8)
    assert np.array_equal(cv2.imread(str(stored)), np.repeat(expected[..., None], 3, axis=2))
    with pytest.raises(ValueError, match="image_bits must be one of"):
        ImportOptions(image_bits=11)


def test_to_8_bits_picks_the_smallest_sensor_depth():
    assert to_8_bits(np.array([[0, 200, 255]], np.uint16)).tolist() == [[0, 200, 255]]
    assert to_8_bits(np.array([[0, 256, 1023]], np.uint16)).tolist() == [[0, 64, 255]]
    assert to_8_bits(np.array([[4096, 16383]], np.uint16)).tolist() == [[64, 255]]
    assert to_8_bits(np.zeros((2, 2), np.uint16)).tolist() == [[0, 0], [0, 0]]
    seen: set[int] = set()
    assert to_8_bits(np.array([[0, 1023, 4095]], np.uint16), 10, seen).tolist() == [[0, 255, 255]]
    assert seen == {10}  # values above the depth given are clipped


@pytest.mark.parametrize("pose_tf", [False, True], ids=["amcl_pose", "pose-tf"])
def test_a_simulator_recording_with_unstamped_images_and_poses(tmp_path, map_yaml, pose_tf):
    """A simulator's recording (poses and images stamped from 10 s, recorded from T0) with an
    image and a pose sample of zero stamp: their record times, 1.6e9 s, were checked for order
    among the stamps before the clock fix mapped them onto their clock, and the import stopped
    ('timestamps go backwards'). Both are now placed on the stamps' clock: the image's pose is
    the one at its record time, and the pose sample (x = 2 m) is where it was recorded."""
    bag = tmp_path / "sim"
    with BagWriter(bag, ros=2) as w:
        for k in range(21):  # stamp 10 + 0.5 k, recorded at T0 + k: half real time
            stamp, record = 10.0 + 0.5 * k, T0 + k
            x, pose_stamp = (2.0, 0.0) if k == 9 else (0.1 * k, stamp)
            if pose_tf:
                w.tf(pose_stamp, [("map", "base_link", x, 0.0, 0.0)], log_time=record)
            else:
                w.pose("/amcl_pose", pose_stamp, x, 0.0, 0.0, log_time=record)
            if k in (2, 7, 9, 12):
                pixels = np.zeros((4, 4, 3), np.uint8)
                _raw_image(w, 0.0 if k == 7 else stamp, pixels, "rgb8", log_time=record)
        w.text("/speech", T0 + 3.0, "hall")
    out = tmp_path / "data" / "house"
    options = ImportOptions(pose_tf=("map", "base_link") if pose_tf else None)
    report = import_bags([bag], map_yaml, out, options, progress=False)
    assert np.allclose(np.loadtxt(out / "Xtx.csv"), [0.2, 0.7, 2.0, 1.2])
    (counts,) = report.trials
    assert counts["images_kept"] == 4 and counts["unstamped_moved_to_stamp_clock"] == 2
    assert counts["images_out_of_order"] == 0 and counts["poses_out_of_order"] == 0


def test_each_bag_is_opened_once_and_an_unreadable_message_names_its_own_bag(
    tmp_path, map_yaml, monkeypatch
):
    """The import opened every bag twice, once to find its topics and again to read them; now
    the reader that was checked is the one read. With several bags open at once, rosbags'
    error for a message of the first bag is still said for the first bag, not the last."""
    from rosbags.highlevel import AnyReaderError

    from spcopyro.robot.rosbag import importer

    bags = [_basic_bag(tmp_path / "one"), _basic_bag(tmp_path / "two")]
    opened: list[str] = []
    open_bag = importer.open_bag

    def counting(path, *args):
        opened.append(Path(path).name)
        return open_bag(path, *args)

    monkeypatch.setattr(importer, "open_bag", counting)
    report = import_bags(bags, map_yaml, tmp_path / "d" / "h", progress=False)
    assert [t["images_kept"] for t in report.trials] == [1, 1]
    assert opened == ["one", "two"]
    read_stamps = importer.read_stamps

    def unreadable(reader, topic):
        if Path(reader.paths[0]).name == "one":
            raise AnyReaderError("a message of one")
        return read_stamps(reader, topic)

    monkeypatch.setattr(importer, "read_stamps", unreadable)
    with pytest.raises(BagFormatError, match=r"one: unreadable message \(a message of one\)$"):
        import_bags(bags, map_yaml, tmp_path / "d" / "h2", progress=False)
    assert not (tmp_path / "d" / "h2").exists()
