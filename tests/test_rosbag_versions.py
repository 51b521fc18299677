"""``spcopyro import-bag`` on bags of older formats gives what it gives of a current one: the same
images, poses and utterances (the house folder's files byte for byte) from one recording
written as ROS 2 bags of every metadata.yaml version 1..9 (sqlite3, and mcap from version 5, when
rosbag2 gained it), each sqlite3 storage schema (no ``schema`` table and no QoS column, Dashing
and Eloquent; a QoS column, Foxy; ``schema`` version 3, Humble; 4, with message definitions,
Iron on), a .db3 given without its folder, both rosbag2 compression modes, and ROS 1 bags
(uncompressed, bz2, lz4 chunks; tf on the old ``tf/tfMessage``).

rosbags writes ROS 2 metadata versions 8 and 9 only; the older ones are written as those ROS
releases did, from a version-8 bag: the keys each later version added are removed from its
metadata.yaml (``files`` 5, ``custom_data`` 6, ``type_description_hash`` 7, ``ros_distro`` 8;
QoS profiles 4, compression 3) and its .db3 is rebuilt with that release's tables. None of the
message types the import reads changed between ROS 2 distributions (rosbags' typestores, Dashing
to Lyrical), so there is no older message definition of them to read.

A ROS 1 bag of a format before 2.0 (rosbags reads 2.0 only) says what it is and how to convert
it; it said 'File magic is invalid' and suggested ``rosbag reindex``, which keeps its format.
"""

from __future__ import annotations

import hashlib
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest
import yaml
from bag_maps import save_free_map

pytest.importorskip("rosbags", reason="the rosbag import needs rosbags (pip install .[ros])")

from spcopyro.robot.rosbag import BagFormatError, BagWriter, ImportOptions, import_bags  # noqa: E402

T0 = 1_600_000_000.0
OPTIONS = ImportOptions(pose_tolerance=0.6)
TF_OPTIONS = ImportOptions(pose_tolerance=0.6, pose_tf=("map", "base_link"))
FOXY_QOS = (  # a publisher's offered QoS as Foxy to Iron wrote it: a YAML string
    "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: "
    "2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  avoid_ros_namespace_conventions: false"
)
ADDED_IN = {"compression_format": 3, "compression_mode": 3, "files": 5, "custom_data": 6,
            "ros_distro": 8}  # fmt: skip


@pytest.fixture(scope="module")
def map_yaml(tmp_path_factory) -> Path:
    """The rosbag tests' map (tests/bag_maps.py), once per module: origin (-3, -3)."""
    return save_free_map(tmp_path_factory.mktemp("maps"))


def _record(writer: BagWriter) -> None:
    """Poses on /amcl_pose and tf at 1 Hz over 0..4 s, three raw images, two utterances."""
    for i, t in enumerate((T0 + np.arange(5.0)).tolist()):
        writer.pose("/amcl_pose", t, 0.5 * i, 0.25 * i, 0.3 * i)
        odom_base = ("odom", "base_link", 0.5 * i, 0.2 * i, 0.1 * i)
        writer.tf(t, [("map", "odom", 0.1, 0.0, 0.0), odom_base])
    for k, t in enumerate([0.5, 1.25, 2.75]):
        rgb = np.random.default_rng(k).integers(0, 256, size=(6, 8, 3), dtype=np.uint8)
        writer.image("/camera/image", T0 + t, rgb)
    writer.text("/speech", T0 + 1.5, "kitchen sink")
    writer.text("/speech", T0 + 3.0, "bedroom")


def _write(path: Path, ros=2, storage="sqlite3", version=9, compression=None) -> Path:
    """The recording as a bag; ``compression`` a rosbag2 mode (FILE, MESSAGE; zstd) or a ROS 1
    chunk format (BZ2, LZ4), set as ``ros2 bag record`` / ``rosbag record`` would."""
    with pytest.MonkeyPatch.context() as patch:
        if compression is not None:
            if ros == 1:
                from rosbags.rosbag1 import Writer

                def compress(writer):
                    writer.set_compression(Writer.CompressionFormat[compression])
            else:
                from rosbags.rosbag2 import Writer
                from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

                def compress(writer):
                    writer.set_compression(CompressionMode[compression], CompressionFormat.ZSTD)

            original = Writer.open
            patch.setattr(Writer, "open", lambda self: (compress(self), original(self))[1])
        with BagWriter(path, ros=ros, storage=storage, version=version) as writer:
            _record(writer)
    return path


def _old_tf(path: Path) -> Path:
    """A ROS 1 bag whose tf is on the pre-tf2 type ``tf/tfMessage``."""
    from rosbags.typesys import get_types_from_msg

    writer = BagWriter(path, ros=1)
    writer.store.register(
        get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf/msg/tfMessage")
    )
    _record(writer)
    old = writer.types["tf/msg/tfMessage"]
    writer._records = [
        (ns, n, topic, "tf/msg/tfMessage", old(transforms=msg.transforms))
        if msgtype == "tf2_msgs/msg/TFMessage"
        else (ns, n, topic, msgtype, msg)
        for ns, n, topic, msgtype, msg in writer._records
    ]
    return writer.close()


def _downgrade(bag: Path, out: Path, version: int, schema: int | None) -> Path:
    """A copy of the version-8 ``bag`` as a rosbag2 of metadata ``version`` wrote it, its .db3
    with the storage ``schema`` of that release (None: keep the storage file, an mcap)."""
    shutil.copytree(bag, out)
    meta = yaml.safe_load((out / "metadata.yaml").read_text())
    info = meta["rosbag2_bagfile_information"]
    info["version"] = version
    for key, added in ADDED_IN.items():
        if version < added:
            del info[key]
    qos = version >= 4 and schema is not None  # an mcap channel's QoS stays the writer's ''
    for topic in info["topics_with_message_count"]:
        metadata = topic["topic_metadata"]
        if version < 7:
            del metadata["type_description_hash"]
        if version < 4:
            del metadata["offered_qos_profiles"]
        elif qos:
            metadata["offered_qos_profiles"] = FOXY_QOS
    if version < 2:  # Dashing named the storage files with the bag's folder
        info["relative_file_paths"] = [f"{out.name}/{p}" for p in info["relative_file_paths"]]
    (out / "metadata.yaml").write_text(yaml.safe_dump(meta))
    if schema is not None:
        _rebuild_db3(next(out.glob("*.db3")), schema, meta, qos)
    return out


def _rebuild_db3(db3: Path, schema: int, meta: dict, qos: bool) -> None:
    """The .db3 with the tables of a storage ``schema``: 1 (Dashing, Eloquent: no QoS
    column, no ``schema`` table), 2 (Foxy: a QoS column), 3 (Humble: ``schema`` and
    ``metadata`` tables); its topics and messages as they were."""
    with sqlite3.connect(db3) as old:
        topics = old.execute("SELECT id, name, type, serialization_format FROM topics").fetchall()
        messages = old.execute("SELECT id, topic_id, timestamp, data FROM messages").fetchall()
    old.close()
    db3.unlink()
    qos_column = ", offered_qos_profiles TEXT NOT NULL" if schema >= 2 else ""
    with sqlite3.connect(db3) as con:
        con.execute(
            "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT "
            f"NULL, serialization_format TEXT NOT NULL{qos_column})"
        )
        con.execute(
            "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, "
            "timestamp INTEGER NOT NULL, data BLOB NOT NULL)"
        )
        con.execute("CREATE INDEX timestamp_idx ON messages (timestamp ASC)")
        if schema >= 3:
            con.execute("CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT)")
            con.execute("INSERT INTO schema VALUES (3, 'humble')")
            con.execute(
                "CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT "
                "NULL, metadata TEXT NOT NULL)"
            )
            version = meta["rosbag2_bagfile_information"]["version"]
            con.execute(
                "INSERT INTO metadata(metadata_version, metadata) VALUES (?, ?)",
                (version, yaml.safe_dump(meta)),
            )
        rows = [(*t, FOXY_QOS if qos else "") for t in topics] if schema >= 2 else topics
        con.executemany(f"INSERT INTO topics VALUES ({', '.join('?' * len(rows[0]))})", rows)
        con.executemany("INSERT INTO messages VALUES (?, ?, ?, ?)", messages)
    con.close()


def _house(bag: Path, map_yaml: Path, out: Path, options: ImportOptions) -> dict[str, str]:
    """The imported house folder's files (images, poses, utterances): name -> md5."""
    import_bags([bag], map_yaml, out, options, progress=False)
    files = sorted(f for f in out.rglob("*") if f.is_file() and f.suffix in (".csv", ".png"))
    assert any(f.suffix == ".png" for f in files) and (out / "word_0.csv").is_file()
    return {str(f.relative_to(out)): hashlib.md5(f.read_bytes()).hexdigest() for f in files}


@pytest.fixture(scope="module")
def reference(tmp_path_factory, map_yaml) -> dict[str, dict[str, str]]:
    """The house folder of the recording as a version-9 sqlite3 bag, with poses from
    /amcl_pose and from tf."""
    root = tmp_path_factory.mktemp("reference")
    bag = _write(root / "bag")
    return {
        "amcl": _house(bag, map_yaml, root / "amcl" / "house", OPTIONS),
        "tf": _house(bag, map_yaml, root / "tf" / "house", TF_OPTIONS),
    }


ROS2_WRITTEN = {  # id: storage, version, compression
    "v9-sqlite3": ("sqlite3", 9, None),
    "v9-mcap": ("mcap", 9, None),
    "v8-sqlite3": ("sqlite3", 8, None),
    "v8-mcap": ("mcap", 8, None),
    "v9-sqlite3-zstd-file": ("sqlite3", 9, "FILE"),
    "v9-sqlite3-zstd-message": ("sqlite3", 9, "MESSAGE"),
    "v8-mcap-zstd-file": ("mcap", 8, "FILE"),
    "v8-mcap-zstd-message": ("mcap", 8, "MESSAGE"),
}


@pytest.mark.parametrize("case", list(ROS2_WRITTEN))
def test_ros2_bags_rosbags_writes_import_the_same(tmp_path, map_yaml, reference, case):
    storage, version, compression = ROS2_WRITTEN[case]
    bag = _write(tmp_path / "bag", 2, storage, version, compression)
    assert yaml.safe_load((bag / "metadata.yaml").read_text())[
        "rosbag2_bagfile_information"
    ]["version"] == version  # fmt: skip
    assert _house(bag, map_yaml, tmp_path / "a" / "house", OPTIONS) == reference["amcl"]
    assert _house(bag, map_yaml, tmp_path / "t" / "house", TF_OPTIONS) == reference["tf"]


OLDER_ROS2 = {  # id: metadata version, sqlite3 schema (None: mcap)
    "v1-dashing": (1, 1),
    "v2": (2, 1),
    "v3-eloquent": (3, 1),
    "v4-foxy": (4, 2),
    "v5-galactic": (5, 2),
    "v5-humble": (5, 3),
    "v6": (6, 3),
    "v7": (7, 3),
    "v5-humble-mcap": (5, None),
    "v6-mcap": (6, None),
    "v7-mcap": (7, None),
}


@pytest.mark.parametrize("case", list(OLDER_ROS2))
def test_older_ros2_bags_import_the_same(tmp_path, map_yaml, reference, case):
    version, schema = OLDER_ROS2[case]
    storage = "mcap" if schema is None else "sqlite3"
    bag = _write(tmp_path / "v8", 2, storage, 8)
    old = _downgrade(bag, tmp_path / "old", version, schema)
    assert _house(old, map_yaml, tmp_path / "a" / "house", OPTIONS) == reference["amcl"]
    assert _house(old, map_yaml, tmp_path / "t" / "house", TF_OPTIONS) == reference["tf"]
    if schema is not None:  # the storage file given without its folder
        db3 = next(old.glob("*.db3"))
        assert _house(db3, map_yaml, tmp_path / "f" / "house", OPTIONS) == reference["amcl"]


@pytest.mark.parametrize("compression", [None, "BZ2", "LZ4", "old-tf"])
def test_ros1_bags_import_the_same(tmp_path, map_yaml, reference, compression):
    bag = tmp_path / "rec.bag"
    if compression == "old-tf":
        _old_tf(bag)
    else:
        _write(bag, 1, compression=compression)
    assert _house(bag, map_yaml, tmp_path / "a" / "house", OPTIONS) == reference["amcl"]
    assert _house(bag, map_yaml, tmp_path / "t" / "house", TF_OPTIONS) == reference["tf"]


def test_the_writer_says_which_ros2_versions_it_writes(tmp_path):
    with pytest.raises(ValueError, match=r"version must be 8 or 9 \(rosbag2 metadata\), got 5"):
        BagWriter(tmp_path / "bag", version=5)


@pytest.mark.parametrize(
    ("magic", "says"),
    [
        (b"#ROSRECORD V1.2\n", "format 1.2 (#ROSRECORD V1.2; recorded before ROS C Turtle, 2010)"),
        (b"#ROSLOG V1.1\n", "format 1.1 (#ROSLOG V1.1; recorded before ROS C Turtle, 2010)"),
    ],
)
def test_a_ros1_bag_of_an_old_format_says_how_to_convert_it(tmp_path, map_yaml, magic, says):
    """rosbags reads ROS 1 bag format 2.0 only. A bag of format 1.2 said 'not a readable bag
    (File magic is invalid.); if its recording did not end cleanly, `rosbag reindex` repairs
    its index', which keeps the format."""
    bag = tmp_path / "old.bag"
    bag.write_bytes(magic + b"op=\x02".ljust(4096, b" "))
    with pytest.raises(BagFormatError) as error:
        import_bags([bag], map_yaml, tmp_path / "d" / "h", progress=False)
    message = str(error.value)
    assert message.startswith(f"{bag}: a ROS 1 bag of {says}, which rosbags does not read")
    assert "reindex" not in message
    if magic.startswith(b"#ROSRECORD V1.2"):
        assert message.endswith('`rosbag filter old.bag old_v2.bag "True"`, then give old_v2.bag')
    else:
        assert message.endswith("with the rosbag tools of a ROS 1 release that reads it")
