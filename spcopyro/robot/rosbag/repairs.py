"""What to do with a bag that does not open, or whose messages do not read: the usual repair,
named in the error (:mod:`spcopyro.robot.rosbag.bag` raises it).

* a ROS 1 ``.bag`` that did not end cleanly: ``rosbag reindex``; an unfinished recording
  (``.bag.active``, ``rosbag record`` killed): ``rosbag reindex`` it, then give the ``.bag``;
* an ``.mcap`` cut short: ``mcap recover``; a ``.db3`` damaged or cut short: a fresh copy;
* a ROS 2 bag folder whose metadata.yaml fails (a newer version than rosbags reads, broken
  YAML, a storage file renamed): its storage file given itself, or ``ros2 bag reindex``;
* a storage file compressed whole (``.db3.zstd``, ``--compression-mode file``) or one whose
  messages are compressed (``--compression-mode message``) given without its folder: the folder;
* one storage file of a ROS 2 bag split into several (``--max-bag-size``,
  ``--max-bag-duration``) given alone: only its part of the recording is read, and the import
  says so (:func:`other_pieces`);
* a ROS 1 bag of a format before 2.0 (``#ROSRECORD V1.2``, recorded before ROS C Turtle, 2010),
  which rosbags does not read: ROS 1's ``rosbag filter`` writes it anew in format 2.0.
"""

from __future__ import annotations

import glob
import os
import re
from collections.abc import Sequence
from pathlib import Path

__all__ = [
    "REPAIR",
    "compressed_messages",
    "none_read_fix",
    "other_pieces",
    "old_ros1_format",
    "packed_file",
    "repair",
]

REPAIR = {
    ".bag": "; if its recording did not end cleanly, `rosbag reindex` repairs its index",
    ".mcap": "; if it was cut short, `mcap recover` rewrites what it holds",
    ".db3": "; its sqlite3 file is damaged or cut short (an interrupted copy or recording?): "
    "copy it again from the robot",
}
"""The usual repair of a bag file that does not open (a recorder killed before it closed it)."""


def packed_file(path: Path) -> str | None:
    """Why the file ``path`` is no bag to read as it is, and what to give instead (None: try
    it): a storage file compressed whole, a ROS 1 recording never closed, or a ROS 1 bag of a
    format older than 2.0 (:func:`old_ros1_format`)."""
    if path.suffix == ".bag" and (old := old_ros1_format(path)):
        return old
    inner = Path(path.stem).suffix
    if path.suffix == ".zstd" and inner in (".db3", ".mcap"):
        return (
            "a storage file compressed whole (rosbag2's --compression-mode file): give the bag "
            "folder it was recorded in (with its metadata.yaml), or decompress it with "
            f"`zstd -d` and give the {inner} file"
        )
    if path.suffix == ".active" and inner == ".bag":
        return (
            "an unfinished ROS 1 recording (rosbag record stopped before it closed the bag): "
            f"`rosbag reindex {path.name}` repairs it; then give it as {path.stem}"
        )
    return None


_ROS1_MAGIC = re.compile(rb"#(ROSBAG|ROSRECORD|ROSLOG) V(\d+)\.(\d+)\n")
"""A ROS 1 bag's first line: ``#ROSBAG V2.0`` since C Turtle (2010); ``#ROSRECORD V1.2``,
``#ROSRECORD V1.1`` or ``#ROSLOG V1.x`` before (ros_comm's tools/rosbag/FORMATS)."""


def old_ros1_format(path: Path) -> str | None:
    """What to do with a ROS 1 bag file of a format older than 2.0, the only one rosbags reads
    (rosbags said 'File magic is invalid.' of a ``#ROSRECORD V1.2`` bag, and the import
    suggested ``rosbag reindex``, which keeps its format); None for any other file."""
    try:
        with path.open("rb") as file:
            first = file.readline(64)
    except OSError:
        return None
    match = _ROS1_MAGIC.fullmatch(first)
    if match is None:
        return None
    version = (int(match.group(2)), int(match.group(3)))
    if version >= (2, 0):  # 2.0 reads; a later one is rosbags' own 'not supported'
        return None
    what = (
        f"a ROS 1 bag of format {version[0]}.{version[1]} ({first.decode().strip()}; recorded "
        "before ROS C Turtle, 2010), which rosbags does not read (it reads format 2.0 only)"
    )
    if version == (1, 2):  # ROS 1's rosbag (to Noetic) reads 1.2 and writes 2.0
        return (
            f"{what}: ROS 1's rosbag writes it anew in format 2.0: `rosbag filter {path.name} "
            f'{path.stem}_v2.bag "True"`, then give {path.stem}_v2.bag'
        )
    return (
        f"{what}: rewrite it in format 2.0 with the rosbag tools of a ROS 1 release that reads it"
    )


def compressed_messages(metadata: Path) -> bool:
    """Whether a ROS 2 bag's metadata.yaml says its messages are compressed one by one."""
    try:
        text = metadata.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return False
    return re.search(r"compression_mode:\s*['\"]?message", text, re.IGNORECASE) is not None


def none_read_fix(path: Path) -> str:
    """What to do about a topic the bag's index counts messages of, none of which read:
    rosbags reads a ROS 2 bag folder's messages only of the topics whose type and offered QoS
    in its metadata.yaml match the storage file's, and skips the rest without a word."""
    if (path / "metadata.yaml").is_file():
        return (
            "its metadata.yaml and its storage file disagree about the topic (its type or offered "
            "QoS profiles): give the .db3 / .mcap file itself as BAG, or rewrite metadata.yaml "
            "with `ros2 bag reindex`"
        )
    return "the bag's index and its messages disagree"


def repair(path: Path, why: str) -> str:
    """The usual repair of a bag ``path`` that does not open with the error ``why``: a bag
    folder whose metadata.yaml fails is read from its storage file; a ROS 1, mcap or sqlite3 file
    cut short has its remedy (:data:`REPAIR`)."""
    found = list(path.glob("*"))  # nothing for a file
    storage = sorted(p.name for p in found if p.suffix in (".db3", ".mcap"))
    if (
        path.is_dir()
        and storage
        and any(w in why for w in ("metadata", "version", "YAML", "files are missing"))
    ):
        given = (  # a split recording's files would be one trial each
            f"give its storage file ({path / storage[0]}) as BAG, or " if len(storage) == 1 else ""
        )
        return f"; it is its metadata.yaml that fails: {given}rewrite it with `ros2 bag reindex`"
    inside = {p.suffix for p in found}
    suffix = path.suffix or next((s for s in (".mcap", ".db3") if s in inside), "")
    return REPAIR.get(suffix, "")


_PIECE = re.compile(r"(.+)_(\d+)")
"""The stem of a piece of a split ROS 2 recording: rosbag2 names its storage files ``NAME_0``,
``NAME_1``, ... (``NAME`` the bag folder's name) in the one folder of the recording."""


def other_pieces(path: Path, given: Sequence[str | os.PathLike[str]] = ()) -> list[str]:
    """The other storage files of the split ROS 2 recording the storage file ``path``
    (``.db3`` / ``.mcap``) is a piece of: those beside it named as its stem with another
    number (``rec_1.db3`` beside ``rec_0.db3``: :data:`_PIECE`), in the order of their number,
    less those ``given`` (read as bags of their own). Empty for a bag folder, a ROS 1 bag, a
    storage file not named as a piece or alone in its folder: other storage files beside it
    (unrelated recordings copied together) are no part of it."""
    piece = _PIECE.fullmatch(path.stem)
    if not path.is_file() or path.suffix not in (".db3", ".mcap") or piece is None:
        return []
    read = {os.path.realpath(p) for p in given}
    others = []
    for other in path.parent.glob(f"{glob.escape(piece.group(1))}_*{path.suffix}"):
        match = _PIECE.fullmatch(other.stem)
        if (
            match is not None
            and match.group(1) == piece.group(1)
            and other.name != path.name
            and other.is_file()
            and os.path.realpath(other) not in read
        ):
            others.append((int(match.group(2)), other.name))
    return [name for _, name in sorted(others)]
