"""``spcopyro import-bag``: a robot's recordings -> a house folder in the dataset layout.

Each bag is one trial K (``first_trial``, ``first_trial + 1``, ... in the order given). From a
bag the import reads:

* the robot's pose: a pose topic (``geometry_msgs/PoseWithCovarianceStamped`` from amcl,
  ``nav_msgs/Odometry`` or ``geometry_msgs/PoseStamped``) or a tf frame pair (the chain of
  ``/tf`` and ``/tf_static`` transforms from the map frame to the robot's frame, composed in
  SE(2): :mod:`spcopyro.robot.rosbag.poses`). A pose topic in another frame than the map's
  (``odom``) is placed on the map through the bag's tf chain ``map -> ... -> odom``, and is an
  error without one; the report and ``bag_import.json`` name the frame (``pose_frame``) and
  the chain (``pose_frame_via_tf``). Pose stamps on another clock than the bag's record times (a
  simulator's, ``use_sim_time``) put the messages without a stamp (utterances) on theirs
  (:func:`~spcopyro.robot.rosbag.poses.header_clock`; the report's ``record_clock_offset``);
* camera images (``sensor_msgs/Image`` or ``CompressedImage``) and utterances
  (``std_msgs/String``: a word or a whole sentence).

Every image and utterance gets the pose interpolated at its timestamp (linear in x, y; yaw by the
shortest angle). One with no pose sample within ``pose_tolerance`` seconds is *skipped and
reported*: printed with its timestamp and listed in ``skipped.csv`` (``trial,bag,topic,kind,
stamp,reason``), as is an image that does not decode or an utterance without a word. Of the
images with a pose, an image is kept when at least ``min_interval`` seconds have passed and the
robot is at least ``min_distance`` metres (straight line) from where the last kept image was
taken (both 0 by default: every image is kept); the others are counted, not listed.

Output ``OUT`` (a house folder named NAME = OUT's folder name), read by
:func:`spcopyro.data.load_house` once ``spcopyro features OUT --out OUT/Ft.csv`` has written the
image features:

* ``img_K/NNNNN.jpg|png`` (a JPEG or 8-bit PNG CompressedImage stored as recorded, anything
  else as a lossless 8-bit PNG: :mod:`spcopyro.robot.rosbag.images`), ``pose_K.csv``
  (``x, y, qz, qw`` per image), ``word_K.csv`` (one utterance a line: its tokens joined by
  spaces), ``Xtx.csv``, ``Xty.csv``, ``St.csv``, ``StXtx.csv``,
  ``StXty.csv`` (all trials concatenated), ``skipped.csv`` and ``bag_import.json`` (the bags,
  topics, options and counts);
* the map, re-saved as map_server yaml + pgm at ``OUT/../map/NAME.yaml`` where the loaders look
  for it (an existing different map there is refused unless ``overwrite``).

The folder is written in a staging folder beside OUT, the map's files beside theirs, and they
are moved into place together when whole (a Ctrl-C finds both old or both new); an
existing non-empty OUT is refused unless ``overwrite``, which replaces only a folder an earlier
import wrote, and of it only what that import wrote (its ``bag_import.json`` names its trials:
:mod:`spcopyro.robot.rosbag.house_folder`): the rest (``Ft.csv`` of ``spcopyro features``, a
user's notes) is kept in the new OUT and named in the report's ``kept``, as ``fit --overwrite``
keeps what a fit did not write; a different map is replaced only beside an earlier import
(the report's ``map_replaced``). A failed import leaves no OUT,
no staging folder, and none of the folders it created for them. A pose of a kept observation
outside the map's bounds stops the import (:class:`PoseOutsideMapError`: a wrong map, or a pose
in another frame), as does no image or no utterance left (:class:`NothingLeftError`, which holds
the skipped observations). Errors about a bag's content name the bag.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from spcopyro._util.folder_commit import absolute_path, commit_folder
from spcopyro._util.interrupts import remove_tree
from spcopyro._util.number_checks import is_finite_number
from spcopyro._util.outputs import staging_folder
from spcopyro._util.progress import clears_when_done, progress_enabled
from spcopyro.data.text import tokenize
from spcopyro.maps.grid import OccupancyGrid
from spcopyro.maps.map_server import load_map, stage_map
from spcopyro.robot.rosbag.bag import (
    DEFAULT_ROS_DISTRO,
    IMAGE_TYPES,
    POSE_TYPES,
    ROS_DISTROS,
    TEXT_TYPES,
    BagContentError,
    _rosbags,
    check_not_empty,
    iter_images,
    open_bag,
    read_stamps,
    read_texts,
    reading_errors,
    topic_connections,
)
from spcopyro.robot.rosbag.house_folder import (
    MARKER,
    check_map,
    check_out,
    same_images,
)
from spcopyro.robot.rosbag.images import SENSOR_BITS, ImageDecodeError, encoded_image
from spcopyro.robot.rosbag.poses import (
    PoseTrack,
    compose,
    frame_name,
    header_clock,
    image_clock,
    late_count,
)
from spcopyro.robot.rosbag.repairs import other_pieces
from spcopyro.robot.rosbag.report import (
    BagImportReport,
    SkippedObservation,
    image_clock_note,
    write_skipped,
)
from spcopyro.robot.rosbag.tf_chain import check_tf_topics, read_pose_in_map, read_tf_chain

__all__ = [
    "MARKER",
    "BagImportReport",
    "ImportOptions",
    "NothingLeftError",
    "PoseOutsideMapError",
    "SkippedObservation",
    "import_bags",
]


class PoseOutsideMapError(BagContentError):
    """An observation's pose lies outside the map (a wrong map, or poses in another frame)."""


class NothingLeftError(BagContentError):
    """No image or no utterance is left to write; ``skipped`` lists every observation skipped
    (the command prints them before the error: they are never dropped silently)."""

    def __init__(self, message: str, skipped: Sequence[SkippedObservation]) -> None:
        super().__init__(message)
        self.skipped = tuple(skipped)


IMAGE_TIMES = ("header", "record")
"""An image's time (``ImportOptions.image_time``): its header stamp (a zero one: the bag's record
time), or the time the bag recorded it (mapped onto the poses' clock where those are on
another: a camera whose stamps are on another clock than the poses')."""


@dataclass(frozen=True)
class ImportOptions:
    """Which topics to read and which observations to keep (see the module docstring).

    ``pose_tf`` (parent frame, child frame), when given, replaces ``pose_topic``.
    """

    pose_topic: str = "/amcl_pose"
    pose_tf: tuple[str, str] | None = None
    image_topic: str = "/camera/image"
    words_topic: str = "/speech"
    min_distance: float = 0.0  # metres between kept images
    min_interval: float = 0.0  # seconds between kept images
    pose_tolerance: float = 0.5  # seconds to the nearest pose sample
    ros_distro: str = DEFAULT_ROS_DISTRO  # definitions for ROS 2 bags that store none
    map_frame: str = "map"  # the map's frame: a pose topic's poses are in it or linked by tf
    image_bits: int | None = None  # a 16-bit camera's bit depth (None: from each image)
    image_time: str = "header"  # an image's time: its header stamp, or "record": the bag's

    def __post_init__(self) -> None:
        for name in ("min_distance", "min_interval", "pose_tolerance"):
            value = getattr(self, name)
            if not (is_finite_number(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        for name in ("pose_topic", "image_topic", "words_topic", "map_frame"):
            if not str(getattr(self, name)).strip("/ "):  # "" gave "no pose topic ''" or a
                # pose frame check that suggested "--pose-tf  BASE_FRAME"
                raise ValueError(f"{name} must name a topic or frame, got {getattr(self, name)!r}")
        if self.image_bits is not None and self.image_bits not in SENSOR_BITS:
            raise ValueError(f"image_bits must be one of {SENSOR_BITS}, got {self.image_bits!r}")
        if self.image_time not in IMAGE_TIMES:
            raise ValueError(f"image_time must be one of {IMAGE_TIMES}, got {self.image_time!r}")
        if self.ros_distro not in ROS_DISTROS:
            raise ValueError(f"ros_distro must be one of {ROS_DISTROS}, got {self.ros_distro!r}")
        if self.pose_tf is not None and (
            len(self.pose_tf) != 2 or not all(str(f).strip("/ ") for f in self.pose_tf)
        ):
            raise ValueError(f"pose_tf must be (parent frame, child frame), got {self.pose_tf!r}")
        if self.pose_tf is not None and frame_name(self.pose_tf[0]) != frame_name(self.map_frame):
            parent, child = frame_name(self.pose_tf[0]), frame_name(self.pose_tf[1])
            map_frame = frame_name(self.map_frame)
            raise ValueError(
                f"--pose-tf {parent} {child} gives poses in frame {parent!r}, not the map's "
                f"frame {map_frame!r}: pass --pose-tf {map_frame} "
                f"{child} (the tf chain is followed through {parent}), or --map-frame {parent} "
                "if the map is in that frame"
            )

    @property
    def pose_source(self) -> str:
        return f"tf {self.pose_tf[0]} -> {self.pose_tf[1]}" if self.pose_tf else self.pose_topic


@dataclass
class _Trial:
    trial: int
    bag: str
    image_xy: np.ndarray  # [n, 2]
    image_yaw: np.ndarray  # [n]
    image_files: list[str]  # relative to OUT
    utterances: list[str]  # tokens joined by spaces
    word_xy: np.ndarray  # [u, 2]
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def summary(self) -> dict[str, object]:
        """The trial as bag_import.json and :class:`BagImportReport` list it: its number, its
        bag and its counts."""
        return {"trial": self.trial, "bag": self.bag, **self.counts}


def _pose_at(
    chain: list[PoseTrack], times: np.ndarray, tolerance: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str | None]]:
    return compose(chain, times, tolerance)


def _thin(
    times: np.ndarray, xy: np.ndarray, candidates: np.ndarray, min_interval: float, min_dist: float
) -> np.ndarray:
    """Indices of ``candidates`` (in stamp order) kept: each at least ``min_interval`` s and
    ``min_dist`` m after / from the last kept one (the first candidate is kept)."""
    if min_interval <= 0 and min_dist <= 0:
        return candidates
    kept: list[int] = []
    for i in candidates.tolist():  # one step per image, not per cell
        if kept:
            j = kept[-1]
            if times[i] - times[j] < min_interval:
                continue
            if math.hypot(*(xy[i] - xy[j])) < min_dist:
                continue
        kept.append(i)
    return np.asarray(kept, dtype=np.int64)


def _check_inside(grid: OccupancyGrid, xy: np.ndarray, times: np.ndarray, what: str) -> None:
    if not xy.size:
        return
    inside = grid.in_bounds(grid.world_to_cell(xy))  # [n] bool
    if not inside.all():
        i = int(np.flatnonzero(~inside)[0])
        (x0, y0), (x1, y1) = _extent(grid)
        raise PoseOutsideMapError(
            f"{what} at {times[i]:.6f} s has pose x={xy[i, 0]:.3f}, y={xy[i, 1]:.3f} m, outside "
            f"the map {grid.source or ''} (x {x0:.2f}..{x1:.2f}, y {y0:.2f}..{y1:.2f} m); "
            f"{int((~inside).sum())} of {len(inside)} such are outside. Is it the map "
            "the robot localised in, and the pose in its frame?"
        )


def _extent(grid: OccupancyGrid) -> tuple[tuple[float, float], tuple[float, float]]:
    ox, oy = grid.origin[0], grid.origin[1]
    return (ox, oy), (ox + grid.width * grid.resolution, oy + grid.height * grid.resolution)


def _check_distinct(bags: Sequence[str | os.PathLike[str]]) -> None:
    """ValueError for a bag given twice (the same path, or a ROS 2 bag folder and a storage file
    in it): it was imported as two trials, every observation counted twice."""
    paths = [Path(os.path.realpath(bag)) for bag in bags]
    for k, path in enumerate(paths):
        for j, other in enumerate(paths[:k]):
            if other in (path, path.parent) or path == other.parent:
                raise ValueError(
                    f"{bags[k]}: the recording of {bags[j]} (BAG {j + 1} and {k + 1}); each "
                    "BAG is one trial: give each recording once"
                )


def _check_bag(reader: Any, options: ImportOptions) -> Any:
    """``reader`` (an open bag) once its topics are found, reading no message; BagContentError
    (as :func:`_import_one` would raise it, later) otherwise."""
    check_not_empty(reader)
    if options.pose_tf:
        check_tf_topics(reader, *options.pose_tf)
    else:
        topic_connections(reader, options.pose_topic, POSE_TYPES, "pose")
    topic_connections(reader, options.image_topic, IMAGE_TYPES, "image")
    topic_connections(reader, options.words_topic, TEXT_TYPES, "utterance")
    return reader


def _import_one(
    reader: Any,
    bag: Path,
    trial: int,
    options: ImportOptions,
    grid: OccupancyGrid,
    staging: Path,
    skipped: list[SkippedObservation],
    progress: bool | None = None,
    given: Sequence[str | os.PathLike[str]] = (),
) -> _Trial:
    """The trial of ``bag``; ``given``: every bag of the import (a piece of a split recording
    given among them is read as a trial of its own, not one this bag leaves unread)."""
    tol = options.pose_tolerance
    with reading_errors(bag):  # the bag stays open: import_bags closes it
        if options.pose_tf:
            chain = read_tf_chain(reader, *options.pose_tf)
            pose_frame, via_tf = frame_name(options.pose_tf[0]), None  # the chain is the pose
        else:
            chain, via_tf = read_pose_in_map(reader, options.pose_topic, options.map_frame)
            pose_frame = chain[-1].frame
        images = read_stamps(reader, options.image_topic)
        if options.image_time == "record":  # each image at its record time, not its stamp
            images.times, images.stamped = images.record.copy(), np.zeros_like(images.stamped)
        words = read_texts(reader, options.words_topic)
        # Poses stamped on another clock than the recorder's (use_sim_time): the record times
        # of the messages without a stamp (utterances) are mapped onto the stamps' clock.
        clock_offset, to_stamp = header_clock(chain)
        if to_stamp is not None:
            for data in (images, words):
                data.times[~data.stamped] = to_stamp(data.times[~data.stamped])

        def skip(topic: str, kind: str, stamp: float, reason: str) -> None:
            skipped.append(SkippedObservation(trial, str(bag), topic, kind, float(stamp), reason))

        # Images: pose, then thinning, then decoding (only the kept ones are decoded).
        image_xy, image_yaw, ok, reasons = _pose_at(chain, images.times, tol)
        stamped = images.stamped  # [M] the images at their header stamps: on another clock?
        camera = image_clock(
            chain, images.times[stamped], images.record[stamped], clock_offset, bool(ok.any())
        )
        for i in np.flatnonzero(~ok).tolist():
            skip(images.topic, "image", images.times[i], reasons[i] or "no pose")
        candidates = np.flatnonzero(ok)  # thinned in stamp order, which need not be the bag's
        candidates = candidates[np.argsort(images.times[candidates], kind="stable")]
        kept = _thin(images.times, image_xy, candidates, options.min_interval, options.min_distance)
        _check_inside(grid, image_xy[kept], images.times[kept], f"{bag}: image on {images.topic}")
        folder = staging / f"img_{trial}"
        folder.mkdir()
        written: dict[int, str] = {}
        undecodable = 0
        bits_seen: set[int] = set()  # the bit depths 16-bit images were scaled from
        from tqdm.auto import tqdm  # here: `spcopyro --help` imports this module, not tqdm

        bar = tqdm(total=kept.size, desc=f"images of trial {trial}", unit="img",
                   disable=not progress_enabled(progress),
                   leave=not clears_when_done())  # a log file: no line of spaces  # fmt: skip
        for index, msg in iter_images(reader, images.topic, set(kept.tolist())):
            bar.update(1)
            try:
                data, suffix = encoded_image(msg, options.image_bits, bits_seen)
            except ImageDecodeError as error:
                skip(images.topic, "image", images.times[index], f"not decodable: {error}")
                undecodable += 1
                continue
            name = f"img_{trial}/{len(written) + 1:05d}{suffix}"
            (staging / name).write_bytes(data)
            written[index] = name
        bar.close()
        stored = np.asarray(sorted(written), dtype=np.int64)  # [n]

        # Utterances: pose and words.
        word_xy, _, word_ok, word_reasons = _pose_at(chain, words.times, tol)
        sentences: list[str] = []
        word_rows: list[int] = []
        empty = 0
        for u, text in enumerate(words.texts):
            if not word_ok[u]:
                skip(words.topic, "utterance", words.times[u], f"{word_reasons[u]}: {text!r}")
                continue
            tokens = tokenize(text.replace(",", " "))  # a comma would split St.csv's entry
            if not tokens:
                skip(words.topic, "utterance", words.times[u], f"no words in {text!r}")
                empty += 1
                continue
            sentences.append(" ".join(tokens))
            word_rows.append(u)
        rows = np.asarray(word_rows, dtype=np.int64)
        _check_inside(grid, word_xy[rows], words.times[rows], f"{bag}: utterance on {words.topic}")
    counts = {
        # a storage file given alone: the other files of its split recording, not read
        "storage_files_not_read": other_pieces(bag, given),
        "pose_frame": pose_frame,  # the frame the poses came in (None: no frame_id)
        "pose_frame_via_tf": via_tf,  # "map -> odom": the tf chain that placed them on the map
        "ros_version": 2 if reader.is2 else 1,  # ROS 1 bags hold their message definitions
        # the images' stamps on another clock than the poses' (image_clock), else None
        "image_clock": camera,
        "poses_merged": int(sum(track.merged for track in chain)),
        # pose / tf samples and images stamped before an earlier one (sorted into place)
        "poses_out_of_order": int(sum(track.late for track in chain)),
        "images_out_of_order": late_count(images.times),
        "image_bits": sorted(bits_seen),  # 16-bit images: the depths scaled from (8-bit: [])
        # record time - pose stamp (median, s) where the stamps are on another clock and the
        # observations without a stamp were placed on it; None where the clocks agree
        "record_clock_offset": clock_offset if to_stamp is not None else None,
        "unstamped_moved_to_stamp_clock": int((~images.stamped).sum() + (~words.stamped).sum())
        if to_stamp is not None
        else 0,
        "images_in_bag": int(images.times.size),
        # the bag's index (a ROS 2 bag's metadata.yaml) counts more than could be read
        "images_unread": max(images.indexed - int(images.times.size), 0),
        "utterances_unread": max(words.indexed - len(words.texts), 0),
        "images_no_pose": int((~ok).sum()),
        "images_thinned": int(candidates.size - kept.size),
        "images_undecodable": undecodable,
        "images_kept": int(stored.size),
        "utterances_in_bag": len(words.texts),
        "utterances_no_pose": int((~word_ok).sum()),
        "utterances_empty": empty,
        "utterances_kept": len(sentences),
    }
    return _Trial(
        trial=trial,
        bag=str(bag),
        image_xy=image_xy[stored],
        image_yaw=image_yaw[stored],
        image_files=[written[i] for i in stored.tolist()],
        utterances=sentences,
        word_xy=word_xy[rows],
        counts=counts,
    )


def _lines(path: Path, lines: Sequence[str], trailing_newline: bool = True) -> None:
    text = "\n".join(lines)
    path.write_text(text + ("\n" if trailing_newline and text else ""), encoding="utf-8")


def _write_house(staging: Path, trials: list[_Trial]) -> None:
    fmt = lambda v: repr(float(v))  # noqa: E731 - shortest string that reads back exactly
    image_xy = np.concatenate([t.image_xy for t in trials])  # [T, 2]
    word_xy = np.concatenate([t.word_xy for t in trials])  # [U, 2]
    _lines(staging / "Xtx.csv", [fmt(v) for v in image_xy[:, 0]])
    _lines(staging / "Xty.csv", [fmt(v) for v in image_xy[:, 1]])
    _lines(staging / "St.csv", [",".join(s for t in trials for s in t.utterances)], False)
    _lines(staging / "StXtx.csv", [fmt(v) for v in word_xy[:, 0]])
    _lines(staging / "StXty.csv", [fmt(v) for v in word_xy[:, 1]])
    for t in trials:
        pose = np.column_stack(
            [t.image_xy, np.sin(t.image_yaw / 2), np.cos(t.image_yaw / 2)]
        )  # [n, 4] x, y, qz, qw
        _lines(staging / f"pose_{t.trial}.csv", [",".join(map(fmt, row)) for row in pose])
        _lines(staging / f"word_{t.trial}.csv", t.utterances)


def import_bags(
    bags: Sequence[str | os.PathLike[str]],
    map_yaml: str | os.PathLike[str],
    out: str | os.PathLike[str],
    options: ImportOptions = ImportOptions(),
    *,
    first_trial: int = 0,
    overwrite: bool = False,
    progress: bool | None = None,
) -> BagImportReport:
    """Import ``bags`` (one trial each) recorded in the map ``map_yaml`` into the house folder
    ``out`` (see the module docstring for what is read, kept and written). ``progress``: a
    progress bar over each bag's images (default: on unless ``$CI`` is set).

    Raises:
        ValueError: no bag, a ``first_trial`` below 0, or one recording given twice (the same
            path, or a ROS 2 bag folder and its storage file).
        FileNotFoundError: a bag or the map is missing.
        FileExistsError: ``out`` (or a different map at ``out/../map/NAME.yaml``) exists and
            ``overwrite`` is not given; with it, ``out`` is not an earlier import's (nor the map
            beside one), or holds an entry that import did not write and this one would
            (:func:`~spcopyro.robot.rosbag.house_folder.check_out`). With ``overwrite``, the
            entries of ``out`` its import did not write are kept (the report's ``kept``).
        BagFormatError: a path that is not a bag.
        BagContentError: a missing topic (the message lists the bag's topics and types), a
            topic of a type the import does not read, pose or tf stamps that go backwards
            more than a few times (the bag, topic and the two stamps);
            :class:`NothingLeftError`: no image or no utterance left to write (its ``skipped``
            lists the skipped observations).
        PoseOutsideMapError: a kept observation's pose outside the map.
        RosbagsMissingError: rosbags is not installed.
    """
    _rosbags()  # a missing rosbags is said before anything else
    if not bags:
        raise ValueError("import_bags: no bag given")
    flag = isinstance(first_trial, bool | np.bool_)  # True == int(True): taken as trial 1
    if flag or int(first_trial) != first_trial or first_trial < 0:
        raise ValueError(f"first_trial must be an integer >= 0, got {first_trial!r}")
    # The inputs before OUT: a mistyped bag, map or topic was reported as "OUT already exists",
    # and a topic missing from the last bag was found after the others had been read.
    _check_distinct(bags)
    with contextlib.ExitStack() as open_bags:  # each bag opened once: checked, then imported
        readers = [
            _check_bag(open_bags.enter_context(open_bag(bag, options.ros_distro)), options)
            for bag in bags
        ]
        grid = load_map(map_yaml)
        out = absolute_path(out)
        earlier = check_out(out, overwrite, range(first_trial, first_trial + len(bags)))
        map_target = out.parent / "map" / f"{out.name}.yaml"
        map_replaced = check_map(map_target, grid, map_yaml, overwrite, out, earlier)
        # What a failed import removes again: the folders it created (the map's files and the
        # folder are written beside their places and moved in together at the end).
        created = [
            p for p in (map_target.parent, out.parent, *out.parent.parents) if not p.exists()
        ]
        staging = staging_folder(out, hidden=True)  # .OUT.partial-PID-*: a killed import's swept
        skipped: list[SkippedObservation] = []
        done = False
        try:
            trials = [
                _import_one(
                    reader,
                    Path(bag),
                    first_trial + k,
                    options,
                    grid,
                    staging,
                    skipped,
                    progress,
                    given=bags,
                )
                for k, (reader, bag) in enumerate(zip(readers, bags, strict=True))
            ]
            for what, key in (("image", "images_kept"), ("utterance", "utterances_kept")):
                if not sum(t.counts[key] for t in trials):
                    topic = options.image_topic if what == "image" else options.words_topic
                    why = (
                        f"{len(skipped)} observation(s) skipped, the first: {skipped[0].line()}"
                        if skipped
                        else "the bags hold none"
                    )
                    notes = [image_clock_note(t.summary) for t in trials if what == "image"]
                    raise NothingLeftError(
                        f"no {what} left to write from {topic} ({why}); a house needs at least one "
                        "image and one utterance" + "".join(f". {note}" for note in notes if note),
                        skipped,
                    )
            _write_house(staging, trials)
            write_skipped(staging / "skipped.csv", skipped)
            record = {
                "bags": [str(Path(b).resolve()) for b in bags],
                "map": str(Path(map_yaml).resolve()),
                "options": asdict(options),
                "first_trial": first_trial,
                "trials": [t.summary for t in trials],
                "skipped": len(skipped),
            }
            (staging / MARKER).write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
            with stage_map(grid, map_target) as map_files:  # written beside map_target
                images_unchanged = earlier is not None and same_images(out, staging)
                # OUT and the map both old or both new after a Ctrl-C; an earlier import set
                # aside, what it did not write (Ft.csv, notes) carried in, as fit --overwrite
                written = earlier or frozenset()  # None: OUT is empty or absent
                kept = commit_folder(staging, out, written, map_files, hidden=True)
            done = True
        finally:
            # this import's files only (none after the commit); what a failed removal leaves,
            # the next import into OUT sweeps (staging_folder); a Ctrl-C meanwhile is one
            remove_tree(staging)
            if not done:
                for folder in created:  # deepest first; only if nothing else was put there
                    with contextlib.suppress(OSError):
                        folder.rmdir()
    return BagImportReport(
        out=out,
        map_yaml=map_target,
        trials=tuple(t.summary for t in trials),
        skipped=tuple(skipped),
        kept=kept,
        map_replaced=map_replaced,
        images_unchanged=images_unchanged,
    )
