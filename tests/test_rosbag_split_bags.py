"""``spcopyro import-bag`` on a ROS 2 recording split into several storage files (rosbag2's
``--max-bag-size`` / ``--max-bag-duration``), a damaged ``.db3`` and a mistyped topic among
several of its type. One file of a split bag given alone was read without a word about the rest
(a third of the recording, silently); a folder of split files without metadata.yaml was to be
given 'as BAG arguments', one trial per file. Bags written with
:class:`spcopyro.robot.rosbag.BagWriter`, the split one joined as rosbag2 writes it."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from bag_maps import save_free_map

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.robot.rosbag import (  # noqa: E402
    BagContentError,
    BagFormatError,
    BagWriter,
    ImportOptions,
    import_bags,
)

T0 = 1_600_000_000.0
WORDS = ("kitchen", "bedroom", "toilet")


@pytest.fixture
def map_yaml(tmp_path: Path) -> Path:
    """The rosbag tests' map (tests/bag_maps.py) at origin (-1, -1): x, y in [-1, 5) m."""
    return save_free_map(tmp_path / "maps", origin=-1.0)


def _split_bag(tmp_path: Path, storage: str = "sqlite3") -> Path:
    """One recording of 30 s split into three storage files of 10 s each (3 images and one
    utterance each), in one folder with the metadata.yaml rosbag2 writes for it."""
    suffix = ".db3" if storage == "sqlite3" else ".mcap"
    bag = tmp_path / "rec"
    bag.mkdir()
    infos, names = [], []
    for part in range(3):
        piece = tmp_path / f"piece_{part}"
        with BagWriter(piece, storage=storage) as w:
            for i in range(10):
                t = T0 + 10 * part + i
                w.pose("/amcl_pose", t, 0.1 * (10 * part + i), 0.0, 0.0)
                if i % 3 == 1:
                    w.image("/camera/image", t, np.full((4, 4, 3), part, np.uint8))
            w.text("/speech", T0 + 10 * part + 3, WORDS[part])
        meta = yaml.safe_load((piece / "metadata.yaml").read_text())
        infos.append(meta["rosbag2_bagfile_information"])
        names.append(f"rec_{part}{suffix}")
        shutil.move(piece / f"piece_{part}{suffix}", bag / names[-1])
        shutil.rmtree(piece)
    info = infos[0]
    info["relative_file_paths"] = names
    info["files"] = [dict(i["files"][0], path=n) for i, n in zip(infos, names, strict=True)]
    info["message_count"] = sum(i["message_count"] for i in infos)
    for topic in info["topics_with_message_count"]:
        topic["message_count"] *= 3  # every piece holds the same topics, as many messages
    info["duration"]["nanoseconds"] = 30 * 10**9
    (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}))
    return bag


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_split_bag_reads_whole_from_its_folder_and_one_file_says_what_it_leaves(
    tmp_path, map_yaml, storage
):
    bag = _split_bag(tmp_path, storage)
    report = import_bags([bag], map_yaml, tmp_path / "d" / "whole", progress=False)
    assert report.trials[0]["images_kept"] == 9
    assert (report.out / "St.csv").read_text() == ",".join(WORDS)
    assert report.trials[0]["storage_files_not_read"] == []
    assert "warning" not in report.text()

    suffix = ".db3" if storage == "sqlite3" else ".mcap"
    piece = bag / f"rec_1{suffix}"
    report = import_bags([piece], map_yaml, tmp_path / "d" / "piece", progress=False)
    assert report.trials[0]["images_kept"] == 3  # its own third, as asked
    others = [f"rec_0{suffix}", f"rec_2{suffix}"]
    assert report.trials[0]["storage_files_not_read"] == others
    assert (
        f"warning: trial 0 ({piece}): {bag} holds 2 more storage file(s) of its recording "
        f"({', '.join(others)}; rosbag2 split it), not read: give the folder to read the whole "
        "recording as one trial" in report.text()
    )


def test_a_split_recording_without_metadata_says_ros2_bag_reindex(tmp_path, map_yaml):
    """rosbag2 killed before it wrote metadata.yaml: the folder holds the pieces alone. Given as
    BAG arguments (as the error said) they were three trials of one recording."""
    bag = _split_bag(tmp_path)
    (bag / "metadata.yaml").unlink()
    with pytest.raises(BagFormatError) as error:
        import_bags([bag], map_yaml, tmp_path / "d" / "h", progress=False)
    assert (
        f"it holds rec_0.db3, rec_1.db3, rec_2.db3: likely one recording that rosbag2 split into "
        f"3 files: `ros2 bag reindex {bag}` writes its metadata.yaml" in str(error.value)
    )
    assert "give the bags as BAG arguments" not in str(error.value)


@pytest.mark.parametrize("given", ["folder", "file"])
def test_a_damaged_db3_says_what_to_do(tmp_path, map_yaml, given):
    """A .db3 cut short (an interrupted copy): sqlite's 'database disk image is malformed' alone,
    with no word of what to do (an .mcap or .bag named its repair tool)."""
    bag = tmp_path / "rec"
    with BagWriter(bag) as w:
        for i in range(20):
            w.pose("/amcl_pose", T0 + i, 0.0, 0.0, 0.0)
            w.image("/camera/image", T0 + i, np.zeros((8, 8, 3), np.uint8))
        w.text("/speech", T0, "hall")
    db3 = bag / "rec.db3"
    db3.write_bytes(db3.read_bytes()[: db3.stat().st_size // 2])
    path = bag if given == "folder" else db3
    with pytest.raises(BagFormatError) as error:
        import_bags([path], map_yaml, tmp_path / "d" / "h", progress=False)
    assert str(error.value).startswith(f"{path}: not a readable bag (")
    assert str(error.value).endswith(
        "; its sqlite3 file is damaged or cut short (an interrupted copy or recording?): copy "
        "it again from the robot"
    )


def test_a_mistyped_topic_among_several_of_its_type_is_asked_for(tmp_path, map_yaml):
    """A camera publishing raw and compressed: '/camera/imag' (a typo) named no topic to try
    (only a bag's single topic of the type was); the close one is asked for now, and a name
    close to none still asks for none."""
    bag = tmp_path / "rec"
    with BagWriter(bag) as w:
        w.pose("/amcl_pose", T0, 0.0, 0.0, 0.0)
        w.image("/camera/image", T0, np.zeros((4, 4, 3), np.uint8))
        w.image("/camera/image/compressed", T0, np.zeros((4, 4, 3), np.uint8), "jpeg")
        w.text("/speech", T0, "hall")
    for typed, asked in (
        ("/camera/imag", "/camera/image"),
        ("/camera/image/compresed", "/camera/image/compressed"),
    ):
        options = ImportOptions(image_topic=typed)
        with pytest.raises(BagContentError) as error:
            import_bags([bag], map_yaml, tmp_path / "d" / "h", options, progress=False)
        hint = f" (pass --image-topic {asked}?)" if asked else ""
        assert f"{bag}: no image topic {typed!r}{hint}; the bag has: /amcl_pose" in str(error.value)
    options = ImportOptions(image_topic="/front/rgb")
    with pytest.raises(BagContentError, match=r"no image topic '/front/rgb'; the bag has"):
        import_bags([bag], map_yaml, tmp_path / "d" / "h", options, progress=False)


def test_pieces_given_as_bags_of_their_own_are_not_said_to_be_unread(tmp_path, map_yaml):
    """``rec_0.db3 rec_1.db3 rec_2.db3`` given as three BAGs: each trial warned that the other
    two were 'not read', though each was read, as a trial of its own. Given two of the three,
    the third is the one left unread."""
    bag = _split_bag(tmp_path)
    pieces = [bag / f"rec_{part}.db3" for part in range(3)]
    report = import_bags(pieces, map_yaml, tmp_path / "d" / "all", progress=False)
    assert [t["images_kept"] for t in report.trials] == [3, 3, 3]
    assert [t["storage_files_not_read"] for t in report.trials] == [[], [], []]
    assert "warning" not in report.text()
    report = import_bags(pieces[:2], map_yaml, tmp_path / "d" / "two", progress=False)
    assert [t["storage_files_not_read"] for t in report.trials] == [["rec_2.db3"]] * 2


def test_two_pieces_given_warn_once_naming_the_pieces_given_and_the_one_not(tmp_path, map_yaml):
    """Two of three pieces given as BAGs: both trials printed the same 'holds 1 more storage
    file(s)' warning (read as two files missed) and advised the folder as one trial, against
    the choice of reading each piece as a trial. Now one warning per import, naming both."""
    bag = _split_bag(tmp_path)
    pieces = [bag / f"rec_{part}.db3" for part in (0, 2)]
    report = import_bags(pieces, map_yaml, tmp_path / "d" / "two", progress=False)
    warnings = [line for line in report.text().splitlines() if line.startswith("warning")]
    assert warnings == [
        "warning: trials 0, 1 (rec_0.db3, rec_2.db3) are pieces of one recording (rosbag2 split "
        f"it), each read as a trial of its own; {bag} holds 1 more piece of it, not given, not "
        "read: rec_1.db3 (give it too to read the rest of the recording)"
    ]
    alone = import_bags(pieces[:1], map_yaml, tmp_path / "d" / "one", progress=False).text()
    assert f"{bag} holds 2 more storage file(s) of its recording (rec_1.db3, rec_2.db3;" in alone
    assert "give the folder to read the whole recording as one trial" in alone


def test_storage_files_not_named_as_pieces_are_no_part_of_a_recording(tmp_path, map_yaml):
    """A folder of unrelated .db3 files (recordings copied together) got 'rosbag2 split it' for
    each file given; only files named as the given one's pieces (NAME_N, the same NAME) are."""
    bag = _split_bag(tmp_path)
    (bag / "metadata.yaml").unlink()
    for name in ("kitchen", "hall_0", "rec_x", "rec_1_2"):
        shutil.copy(bag / "rec_0.db3", bag / f"{name}.db3")
    shutil.copy(bag / "rec_0.db3", bag / "rec_10.db3")
    report = import_bags([bag / "rec_1.db3"], map_yaml, tmp_path / "d" / "p", progress=False)
    assert report.trials[0]["storage_files_not_read"] == ["rec_0.db3", "rec_2.db3", "rec_10.db3"]
    alone = bag / "kitchen.db3"
    report = import_bags([alone], map_yaml, tmp_path / "d" / "k", progress=False)
    assert report.trials[0]["storage_files_not_read"] == []
    assert "rosbag2 split it" not in report.text()
