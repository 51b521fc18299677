"""Reading a recording with ``rosbags``: topics, poses, image stamps and utterances (the tf tree
is read on these: :mod:`~spcopyro.robot.rosbag.tf_chain`).

``rosbags`` (pure Python; ROS 1 ``.bag`` files and ROS 2 bags in sqlite3 or mcap storage, read
alike through :class:`rosbags.highlevel.AnyReader`) is an optional dependency: it is imported
only here, when a bag is opened, and a clear :class:`RosbagsMissingError` names
``pip install "spcopyro[ros]"`` when it is absent. rosbags gives message types in ROS 2 spelling
(``geometry_msgs/msg/PoseWithCovarianceStamped``) for both ROS versions.

Timestamps: a message with a ``header`` is placed at its header stamp (when the sensor saw it);
one without (``std_msgs/String``) or with a zero stamp at the time the bag recorded it, mapped
on the stamps' clock when the pose messages' stamps are on another (a simulator's:
:func:`~spcopyro.robot.rosbag.poses.header_clock`; a pose or tf sample's through its own track's
stamped samples: :func:`~spcopyro.robot.rosbag.poses.on_stamp_clock`). Images may come in any
order of their stamps. The samples of a pose topic or tf edge are sorted by stamp: a few
arriving late are counted (the import reports them), more than a tenth (a clock that went back)
are a :class:`BagContentError` naming the topic, the two messages and their stamps. Equal pose
stamps keep the first pose.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from spcopyro._util.messages import listed as listed_names
from spcopyro.robot.rosbag.mcap_schemas import schemas_without_data_as_none
from spcopyro.robot.rosbag.poses import (
    PoseTrack,
    frame_name,
    late_count,
    on_stamp_clock,
    quaternion_yaw,
)
from spcopyro.robot.rosbag.repairs import compressed_messages, none_read_fix, packed_file, repair

__all__ = [
    "DEFAULT_ROS_DISTRO",
    "ROS_DISTROS",
    "typestore",
    "IMAGE_TYPES",
    "POSE_TYPES",
    "TEXT_TYPES",
    "TF_TYPES",
    "BagContentError",
    "BagFormatError",
    "RosbagsMissingError",
    "TopicData",
    "check_not_empty",
    "check_order",
    "iter_images",
    "message_time",
    "open_bag",
    "pose_track",
    "read_pose_topic",
    "read_stamps",
    "read_texts",
    "reading_errors",
    "stamp_seconds",
    "topic_connections",
    "topic_listing",
    "topic_messages",
]

INSTALL_HINT = 'pip install "spcopyro[ros]"'

POSE_TYPES = (
    "geometry_msgs/msg/PoseWithCovarianceStamped",  # amcl's /amcl_pose
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/PoseStamped",
)
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
TEXT_TYPES = ("std_msgs/msg/String",)
TF_TYPES = ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage")


class RosbagsMissingError(ImportError):
    """The optional ``rosbags`` (or ``rosbags-image``) package is not installed."""


class BagFormatError(ValueError):
    """A path that is not a readable ROS 1 or ROS 2 bag (the message names it and why)."""


class BagContentError(ValueError):
    """A bag that lacks what the import needs, or holds it malformed (topic, type, stamps)."""


def _rosbags() -> Any:
    try:
        from rosbags import highlevel
    except ImportError as error:
        raise RosbagsMissingError(
            f"reading rosbags needs the optional package 'rosbags' ({error}); install it with: "
            f"{INSTALL_HINT}"
        ) from None
    return highlevel


def stamp_seconds(stamp: Any) -> float:
    """A ROS time (``sec``, ``nanosec``) in float64 seconds."""
    return float(stamp.sec) + float(stamp.nanosec) * 1e-9


ROS_DISTROS = ("foxy", "galactic", "humble", "iron", "jazzy", "kilted")
"""ROS 2 distributions whose message definitions a bag without its own can be read with."""
DEFAULT_ROS_DISTRO = "humble"
"""The message definitions a ROS 2 bag that stores none is read with (``--ros-distro``): Foxy,
Galactic and Humble record no definitions in their sqlite3 bags. The messages spcopyro reads
(poses, tf, images, strings) are the same in every distribution since Foxy."""


def typestore(distro: str) -> Any:
    """rosbags' typestore of a ROS 2 distribution of :data:`ROS_DISTROS`."""
    from rosbags.typesys import Stores, get_typestore

    if distro not in ROS_DISTROS:
        raise ValueError(f"unknown ROS 2 distribution {distro!r}; choose one of {ROS_DISTROS}")
    return get_typestore(Stores[f"ROS2_{distro.upper()}"])


@contextmanager
def open_bag(path: str | os.PathLike[str], ros_distro: str = DEFAULT_ROS_DISTRO) -> Iterator[Any]:
    """An open :class:`rosbags.highlevel.AnyReader` of one bag: a ROS 1 ``.bag`` file, a ROS 2
    bag folder (with ``metadata.yaml``), or a ROS 2 ``.db3`` / ``.mcap`` file. A ROS 2 bag that
    stores no message definitions (Foxy, Galactic, Humble) is read with those of ``ros_distro``
    (:data:`ROS_DISTROS`); one that stores its own is read with its own, and the types it stores
    none for (an mcap schema with empty data, as rosbag2 writes when it cannot find a
    definition: :func:`~spcopyro.robot.rosbag.mcap_schemas.schemas_without_data_as_none`) with
    those of ``ros_distro``.

    Raises:
        FileNotFoundError: no such file or folder.
        BagFormatError: anything else that is not a readable bag (the message names the path).
        RosbagsMissingError: rosbags is not installed.
        RosbagsInternalsError: a ROS 2 bag, and a rosbags release without the internal
            function :mod:`~spcopyro.robot.rosbag.mcap_schemas` wraps.
    """
    highlevel = _rosbags()
    store = typestore(ros_distro)
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: bag not found")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        inside = sorted(
            p.name + ("/" if p.is_dir() else "")
            for p in path.iterdir()
            if (p.is_file() and p.suffix in (".bag", ".db3", ".mcap"))
            or (p / "metadata.yaml").is_file()
        )
        listed = f"; it holds {listed_names(inside, 5)}"
        pieces = [n for n in inside if n.endswith((".db3", ".mcap"))]
        if len(pieces) > 1:  # a split recording stopped before rosbag2 wrote metadata.yaml
            hint = (
                f"{listed}: likely one recording that rosbag2 split into {len(pieces)} files: "
                f"`ros2 bag reindex {path}` writes its metadata.yaml, and the folder is read as "
                "one trial (given as BAG arguments, each file would be a trial)"
            )
        else:  # a recording stopped before rosbag2 wrote metadata.yaml; a folder of bags
            hint = f"{listed}: give the bags as BAG arguments" if inside else ""
        raise BagFormatError(
            f"{path}: not a bag (a ROS 2 bag is a folder with metadata.yaml; a ROS 1 bag a .bag "
            f"file){hint}"
        )
    if path.is_file() and (packed := packed_file(path)):
        raise BagFormatError(f"{path}: {packed}")
    if path.is_file() and path.suffix not in (".bag", ".db3", ".mcap"):
        raise BagFormatError(
            f"{path}: not a bag (expected a ROS 1 .bag file, or a ROS 2 bag folder, .db3 or "
            f".mcap file; got suffix {path.suffix!r})"
        )
    reader = highlevel.AnyReader([path], default_typestore=store)
    try:
        with schemas_without_data_as_none(ros2=reader.is2):
            reader.open()
    except (highlevel.AnyReaderError, OSError, KeyError, ValueError, AssertionError) as error:
        why = " ".join(str(error).split()) or type(error).__name__  # one line (yaml's span lines)
        raise BagFormatError(f"{path}: not a readable bag ({why}){repair(path, why)}") from None
    if reader.is2:  # types it stores no definition for (empty mcap schemas): ros_distro's
        known = reader.typestore.fielddefs
        reader.typestore.register({k: v for k, v in store.fielddefs.items() if k not in known})
    try:
        with reading_errors(path):
            yield reader
    finally:
        reader.close()


@contextmanager
def reading_errors(path: str | os.PathLike[str]) -> Iterator[None]:
    """rosbags' error for a message that does not deserialise as a :class:`BagFormatError`
    naming the bag ``path`` (:func:`open_bag` reads its bag in one; a reader of several bags
    open at once reads each in its own, so that none is named for another's message)."""
    try:
        yield
    except _rosbags().AnyReaderError as error:
        raise BagFormatError(f"{path}: unreadable message ({error})") from None


def topic_messages(
    reader: Any, connections: list[Any], topic: str, wanted: set[int] | None = None
) -> Iterator[tuple[int, Any, int, Any]]:
    """``(index, connection, log time ns, message)`` of the connections' messages in bag order,
    each deserialised (only those whose index is in ``wanted`` when given; the others' message
    is None). A message that cannot be read or deserialised -- a damaged or cut-short bag -- is a
    :class:`BagFormatError` naming the bag, the topic and the message, not a traceback of
    rosbags, apsw or zstd (only their calls are in the ``try``: an error of the caller's, which
    runs outside this generator, is not caught here). A topic the bag's index counts messages
    of but of which none can be read is a :class:`BagContentError` (:func:`_none_read`)."""
    messages = reader.messages(connections=connections)
    index = 0
    while True:
        try:
            connection, log_ns, raw = next(messages)
            wanted_here = wanted is None or index in wanted
            msg = reader.deserialize(raw, connection.msgtype) if wanted_here else None
        except StopIteration:
            if not index and (indexed := _indexed(connections)):
                raise _none_read(reader, topic, indexed) from None
            return
        except Exception as error:  # noqa: BLE001 - whatever the readers raise on bad bytes
            path = Path(reader.paths[0])
            why = (  # its messages compressed one by one: rosbags reads them from the folder
                "its messages are compressed (compression_mode: message in the metadata.yaml "
                f"beside it): give the bag folder {path.parent}"
                if path.is_file() and compressed_messages(path.parent / "metadata.yaml")
                else "the bag is damaged or cut short"
            )
            raise BagFormatError(
                f"{path}: message {index + 1} on {topic} cannot be read "
                f"({type(error).__name__}: {error}); {why}"
            ) from None
        yield index, connection, log_ns, msg
        index += 1


def _indexed(connections: list[Any]) -> int:
    """How many messages the bag's index (a ROS 2 bag's metadata.yaml, a ROS 1 bag's or an
    mcap file's index) counts on ``connections``."""
    return int(sum(int(getattr(c, "msgcount", 0) or 0) for c in connections))


def _none_read(reader: Any, topic: str, indexed: int) -> BagContentError:
    """The error for a topic of ``indexed`` messages none of which could be read: rosbags reads
    a ROS 2 bag folder's messages only of the topics whose type and offered QoS in its
    metadata.yaml match the storage file's, and skipped the rest without a word."""
    path = Path(reader.paths[0])
    return BagContentError(
        f"{path}: topic {topic}: the bag's index counts {indexed} message(s), but none could "
        f"be read; {none_read_fix(path)}"
    )


def topic_listing(reader: Any) -> str:
    return ", ".join(f"{name} ({info.msgtype})" for name, info in sorted(reader.topics.items()))


def check_not_empty(reader: Any) -> None:
    """BagContentError for a bag that holds no message (a recording stopped before anything
    arrived: "no pose topic ... the bag has: no topics" said nothing of that), naming the bag
    and the topics it declares. The index's counts are checked by reading: a message there
    is a message, whatever a metadata.yaml counts."""
    if _indexed(reader.connections) or next(iter(reader.messages()), None) is not None:
        return
    topics = topic_listing(reader)
    raise BagContentError(
        f"{reader.paths[0]}: the bag holds no messages ("
        + (f"its topics, each empty: {topics}" if topics else "and no topics")
        + "): a recording stopped before anything arrived? Leave it out, or give the bag "
        "that holds the recording"
    )


def topic_connections(reader: Any, topic: str, allowed: tuple[str, ...], role: str) -> list[Any]:
    """The connections of ``topic`` (with or without its leading ``/``: a name without one is
    resolved in the root namespace, as a ROS node there would); BagContentError if it is absent
    (listing the bag's topics and types, and asking for the bag's one topic of an ``allowed``
    type, or of several the one whose name is close to ``topic``: a typo) or of a type not in
    ``allowed``."""
    found = [c for c in reader.connections if c.topic.lstrip("/") == topic.lstrip("/")]
    if not found:
        fits = sorted({c.topic for c in reader.connections if c.msgtype in allowed})
        option = {"pose": "--pose-topic", "image": "--image-topic", "utterance": "--words-topic"}
        # the one topic of its type, else the one a mistyped name is closest to (of its type)
        near = fits if len(fits) == 1 else difflib.get_close_matches(topic, fits, 1, 0.8)
        hint = f" (pass {option[role]} {near[0]}?)" if near and role in option else ""
        raise BagContentError(
            f"{reader.paths[0]}: no {role} topic {topic!r}{hint}; the bag has: "
            f"{topic_listing(reader) or 'no topics'}"
        )
    for connection in found:
        if connection.msgtype not in allowed:
            raise BagContentError(
                f"{reader.paths[0]}: {role} topic {topic} has message type "
                f"{connection.msgtype}, which the import does not read (expected one of: "
                f"{', '.join(allowed)})"
            )
    return found


def message_time(msg: Any, log_ns: int) -> tuple[float, bool]:
    """The message's time (its header stamp, else the bag's record time) and whether it is
    the header stamp."""
    header = getattr(msg, "header", None)
    if header is not None:
        t = stamp_seconds(header.stamp)
        if t > 0:
            return t, True
    return log_ns * 1e-9, False


def check_order(
    reader: Any, topic: str, times: list[float], what: str = "", numbers: list[int] | None = None
) -> None:
    """BagContentError when more than a few of ``times`` go back (more than one, and more than
    a tenth: a clock that went back, not samples arriving late, which :func:`pose_track` sorts in),
    naming the bag, the topic, the first two stamps that go back and the messages' numbers on
    the topic (1-based, bag order: ``numbers`` when ``times`` are a subset of the topic's
    messages, as a tf edge's are)."""
    late = late_count(times)
    if late > max(1, len(times) // 10):
        k = int(np.flatnonzero(np.diff(np.asarray(times, dtype=np.float64)) < 0)[0])
        first, second = (k + 1, k + 2) if numbers is None else (numbers[k], numbers[k + 1])
        raise BagContentError(
            f"{reader.paths[0]}: topic {topic}{what}: timestamps go backwards: message "
            f"{second} is stamped {times[k + 1]:.9f} s after message {first} at {times[k]:.9f} "
            f"s; {late} of {len(times)} messages are stamped before an earlier one, more than a "
            "few late ones (which are sorted in): a clock that went back (a simulator reset?)"
        )


def pose_track(
    name: str,
    times: list[float],
    poses: list[tuple[float, float, float]],
    frame: str | None = None,
    clock: list[tuple[float, float]] | None = None,
) -> PoseTrack:
    """A pose track from samples in bag order, sorted by stamp (how many arrived late is the
    track's ``late``); a repeated stamp keeps the first sample (how many were dropped is the
    track's ``merged``); both are reported by the import. ``clock``: (record time, header
    stamp) of the samples that have a stamp (:func:`~spcopyro.robot.rosbag.poses.header_clock`)."""
    order = np.argsort(np.asarray(times, dtype=np.float64), kind="stable")  # [P]
    t = np.asarray(times, dtype=np.float64)[order]  # [P]
    keep = np.ones(t.size, dtype=bool)
    keep[1:] = np.diff(t) > 0
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)[order][keep]  # [P', 3]
    merged, late = int((~keep).sum()), late_count(times)
    pairs = np.asarray(clock or [], dtype=np.float64).reshape(-1, 2)  # [K, 2]
    return PoseTrack(
        name, t[keep], p[:, :2], p[:, 2], merged=merged, frame=frame, clock=pairs, late=late
    )


def _planar(pose: Any) -> tuple[float, float, float]:
    q = pose.orientation
    return float(pose.position.x), float(pose.position.y), quaternion_yaw(q.x, q.y, q.z, q.w)


def read_pose_topic(reader: Any, topic: str) -> PoseTrack:
    """The poses of a PoseWithCovarianceStamped, Odometry or PoseStamped topic as a track, in
    the frame its headers name (the track's ``frame``; None when every frame_id is empty; an
    empty frame_id among named ones, as some drivers leave the first, is taken to be theirs).

    A topic whose messages name two different frames is a :class:`BagContentError`: its
    samples could not be interpolated into one another."""
    connections = topic_connections(reader, topic, POSE_TYPES, "pose")
    times: list[float] = []
    poses: list[tuple[float, float, float]] = []
    clock: list[tuple[float, float]] = []
    unstamped: list[int] = []  # the samples of zero stamp, at their record time
    frames: set[str] = set()
    for _, connection, log_ns, msg in topic_messages(reader, connections, topic):
        pose = msg.pose if connection.msgtype.endswith("PoseStamped") else msg.pose.pose
        t, stamped = message_time(msg, log_ns)
        times.append(t)
        if stamped:
            clock.append((log_ns * 1e-9, t))
        else:
            unstamped.append(len(times) - 1)
        poses.append(_planar(pose))
        frames.add(frame_name(msg.header.frame_id))
    if not times:
        raise BagContentError(f"{reader.paths[0]}: pose topic {topic} holds no messages")
    times = on_stamp_clock(times, unstamped, clock)
    check_order(reader, topic, times)
    named = sorted(f for f in frames if f)
    if len(named) > 1:
        raise BagContentError(
            f"{reader.paths[0]}: pose topic {topic} gives poses in several frames "
            f"({', '.join(repr(f) for f in named)}); the import reads one frame per topic"
        )
    return pose_track(topic, times, poses, frame=named[0] if named else None, clock=clock)


@dataclass
class TopicData:
    """What the first pass keeps of an image or text topic: per message (in bag order) its
    stamp ``times`` [M] seconds, whether it is the header's (``stamped`` [M]; else the record
    time), for text the strings, and how many messages the bag's index counts (``indexed``;
    more than M where a ROS 2 bag's metadata.yaml counts messages its storage does not hold)."""

    topic: str
    msgtype: str
    times: np.ndarray  # [M] float64 s
    stamped: np.ndarray  # [M] bool
    texts: list[str] = field(default_factory=list)
    indexed: int = 0
    record: np.ndarray | None = None  # [M] float64 s: when the bag recorded each (images)


def read_stamps(reader: Any, topic: str) -> TopicData:
    """The stamps of an image topic's messages, in bag order, which need not be the stamps'
    (the images are decoded later, only those kept)."""
    connections = topic_connections(reader, topic, IMAGE_TYPES, "image")
    times, stamped, record = [], [], []
    for _, _connection, log_ns, msg in topic_messages(reader, connections, topic):
        t, has_stamp = message_time(msg, log_ns)
        times.append(t)
        stamped.append(has_stamp)
        record.append(log_ns * 1e-9)
    times_s = np.asarray(times, dtype=np.float64)
    return TopicData(
        topic,
        connections[0].msgtype,
        times_s,
        np.asarray(stamped, bool),
        indexed=_indexed(connections),
        record=np.asarray(record, dtype=np.float64),
    )


def read_texts(reader: Any, topic: str) -> TopicData:
    """The strings of a std_msgs/String topic, at the times the bag recorded them."""
    connections = topic_connections(reader, topic, TEXT_TYPES, "utterance")
    times, texts = [], []
    for _, _connection, log_ns, msg in topic_messages(reader, connections, topic):
        times.append(message_time(msg, log_ns)[0])
        texts.append(str(msg.data))
    check_order(reader, topic, times)
    stamped = np.zeros(len(times), dtype=bool)  # std_msgs/String has no header
    times_s = np.asarray(times, dtype=np.float64)
    return TopicData(topic, connections[0].msgtype, times_s, stamped, texts, _indexed(connections))


def iter_images(reader: Any, topic: str, keep: set[int]) -> Iterator[tuple[int, Any]]:
    """``(index, message)`` of the image messages whose index (bag order) is in ``keep``."""
    connections = topic_connections(reader, topic, IMAGE_TYPES, "image")
    for index, _connection, _log_ns, msg in topic_messages(reader, connections, topic, keep):
        if index in keep:
            yield index, msg
