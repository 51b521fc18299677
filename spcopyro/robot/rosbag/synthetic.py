"""Synthetic bags: a small bag writer, and the synthetic house's tour recorded as bags.

:class:`BagWriter` writes ROS 1 (``.bag``) or ROS 2 (sqlite3 or mcap) bags with ``rosbags``'
writers from plain values (poses, tf transforms, images, strings); the tests use it to build the
bags they import. :func:`write_synthetic_bags` records the synthetic house
(:func:`spcopyro.synthetic.make_house`) as one bag per trial, for the README's walkthrough and the
tests (``spcopyro simulate-bag``):

* the robot drives in straight lines from one image position of the trial to the next at
  ``speed`` m/s (through walls: the map is not consulted), stops ``dwell`` seconds at each,
  facing the house's image yaw, takes the image halfway through the stop and speaks the house's
  utterances there (0.1 s apart);
* ``/amcl_pose`` (PoseWithCovarianceStamped, frame ``map``) at ``rate`` Hz; ``/tf`` with
  ``map -> odom`` (a fixed offset, as amcl publishes it) and ``odom -> base_link`` at the same
  stamps; ``/tf_static`` ``base_link -> camera_link``; ``/odom`` (Odometry, frame ``odom``);
* ``/camera/image`` (``sensor_msgs/Image`` rgb8 for ``image_format="raw"``) or
  ``/camera/image/compressed`` (``CompressedImage``, JPEG or PNG): an image whose colour and
  stripes depend on the ground-truth category of the cell it was taken in
  (:func:`render_category_image`), so image features differ between rooms even with a
  random-weight CNN;
* ``/speech`` (std_msgs/String): the utterances, words or sentences as the house has them.

Poses at the image and utterance stamps are constant (the robot stands still), so an import
interpolates them back exactly to the house's positions.
"""

from __future__ import annotations

import contextlib
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from spcopyro._util.interrupts import remove_tree
from spcopyro._util.number_checks import is_integer
from spcopyro._util.outputs import check_folder_path
from spcopyro.data.dataset import House
from spcopyro.maps.map_server import save_map
from spcopyro.robot.rosbag.bag import INSTALL_HINT, RosbagsMissingError, _rosbags
from spcopyro.robot.rosbag.poses import PoseTrack, compose, yaw_quaternion

__all__ = [
    "MAP_TO_ODOM",
    "BagWriter",
    "SyntheticBags",
    "render_category_image",
    "write_synthetic_bags",
]

T0 = 1_700_000_000.0  # seconds: the first trial's start (a plausible ROS time)
MAP_TO_ODOM = (0.3, -0.2, 0.1)  # x, y (m), yaw (rad) of frame odom in frame map
BASE_TO_CAMERA = (0.1, 0.0, 0.0)
POSE_TYPE = {
    "amcl": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "odom": "nav_msgs/msg/Odometry",
    "pose": "geometry_msgs/msg/PoseStamped",
}


def _ns(t: float) -> int:
    """Nanoseconds of ``t`` seconds (whole seconds apart: ``t * 1e9`` would round to 256 ns)."""
    sec = math.floor(t)
    return int(sec) * 10**9 + int(round((t - sec) * 1e9))


MAX_IMAGE_SIDE = 8192
"""Pixels: the largest image height or width simulate-bag renders (an 8K camera's frame is
7680 x 4320; a mistyped --image-size 480000 640 ran out of memory with a numpy traceback)."""


class BagWriter:
    """Write a small bag: ``ros=1`` (a ``.bag`` file) or ``ros=2`` (a folder; ``storage``
    ``"sqlite3"`` or ``"mcap"``; ``version`` the metadata.yaml version, 9 (Jazzy) or 8 (Iron),
    those rosbags writes). Messages are buffered and written sorted by their log time
    (``log_time``, default the stamp) when the writer closes (``with BagWriter(...) as w:``)."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        ros: int = 2,
        storage: str = "sqlite3",
        version: int = 9,
    ):
        try:
            from rosbags.typesys import Stores, get_typestore
        except ImportError as error:
            raise RosbagsMissingError(
                f"writing bags needs 'rosbags' ({error}); install it with: {INSTALL_HINT}"
            ) from None
        if ros not in (1, 2):
            raise ValueError(f"ros must be 1 or 2, got {ros!r}")
        if storage not in ("sqlite3", "mcap"):
            raise ValueError(f"storage must be 'sqlite3' or 'mcap', got {storage!r}")
        if version not in (8, 9):  # rosbags' writer: said here, not when the bag closes
            raise ValueError(f"version must be 8 or 9 (rosbag2 metadata), got {version!r}")
        self.path = Path(path)
        self.version = version
        self.ros = ros
        self.storage = storage
        self.store = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
        if "tf2_msgs/msg/TFMessage" not in self.store.types:  # not in rosbags' noetic store
            from rosbags.typesys import get_types_from_msg

            self.store.register(
                get_types_from_msg(
                    "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
                )
            )
        self.types = self.store.types
        self._records: list[tuple[int, int, str, str, Any]] = []  # log ns, order, topic, type, msg

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        if exc[0] is None:
            self.close()

    # ------------------------------------------------------------------ message builders
    def _time(self, t: float) -> Any:
        ns = _ns(t)
        return self.types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)

    def header(self, t: float, frame: str) -> Any:
        header = self.types["std_msgs/msg/Header"]
        if "seq" in header.__dataclass_fields__:  # ROS 1
            return header(seq=0, stamp=self._time(t), frame_id=frame)
        return header(stamp=self._time(t), frame_id=frame)

    def _pose(self, x: float, y: float, yaw: float) -> Any:
        T = self.types
        qx, qy, qz, qw = yaw_quaternion(yaw)
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
        )

    def write(self, topic: str, msgtype: str, msg: Any, log_time: float) -> None:
        """Buffer any message (``msg`` built from ``self.types``) at ``log_time`` seconds."""
        self._records.append((_ns(log_time), len(self._records), topic, msgtype, msg))

    def pose(
        self,
        topic: str,
        t: float,
        x: float,
        y: float,
        yaw: float,
        kind: str = "amcl",
        frame: str = "map",
        log_time: float | None = None,
    ) -> None:
        """A pose message: ``kind`` amcl (PoseWithCovarianceStamped), odom (Odometry) or pose
        (PoseStamped)."""
        T = self.types
        pose = self._pose(x, y, yaw)
        header = self.header(t, frame)
        if kind == "pose":
            msg = T[POSE_TYPE[kind]](header=header, pose=pose)
        else:
            with_cov = T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36))
            if kind == "amcl":
                msg = T[POSE_TYPE[kind]](header=header, pose=with_cov)
            else:
                zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
                twist = T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                    covariance=np.zeros(36),
                )
                msg = T[POSE_TYPE[kind]](
                    header=header, child_frame_id="base_link", pose=with_cov, twist=twist
                )
        self.write(topic, POSE_TYPE[kind], msg, t if log_time is None else log_time)

    def tf(
        self,
        t: float,
        transforms: list[tuple[str, str, float, float, float]],
        static: bool = False,
        log_time: float | None = None,
    ) -> None:
        """One TFMessage on /tf (or /tf_static) of ``(parent, child, x, y, yaw)`` transforms."""
        T = self.types
        stamped = []
        for parent, child, x, y, yaw in transforms:
            qx, qy, qz, qw = yaw_quaternion(yaw)
            stamped.append(
                T["geometry_msgs/msg/TransformStamped"](
                    header=self.header(t, parent),
                    child_frame_id=child,
                    transform=T["geometry_msgs/msg/Transform"](
                        translation=T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=0.0),
                        rotation=T["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
                    ),
                )
            )
        msg = T["tf2_msgs/msg/TFMessage"](transforms=stamped)
        topic = "/tf_static" if static else "/tf"
        self.write(topic, "tf2_msgs/msg/TFMessage", msg, t if log_time is None else log_time)

    def image(
        self,
        topic: str,
        t: float,
        rgb: np.ndarray,
        image_format: str = "raw",
        log_time: float | None = None,
    ) -> None:
        """An ``[H, W, 3]`` uint8 RGB image: ``raw`` (Image, rgb8) or ``jpeg`` / ``png``
        (CompressedImage)."""
        T = self.types
        rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
        header = self.header(t, "camera_link")
        if image_format == "raw":
            height, width = rgb.shape[:2]
            msg = T["sensor_msgs/msg/Image"](
                header=header, height=height, width=width, encoding="rgb8", is_bigendian=0,
                step=3 * width, data=rgb.reshape(-1),
            )  # fmt: skip
            msgtype = "sensor_msgs/msg/Image"
        elif image_format in ("jpeg", "png"):
            ok, data = cv2.imencode(f".{image_format}", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
            assert ok
            msg = T["sensor_msgs/msg/CompressedImage"](
                header=header, format=image_format, data=data.reshape(-1)
            )
            msgtype = "sensor_msgs/msg/CompressedImage"
        else:
            raise ValueError(f"image_format must be raw, jpeg or png, got {image_format!r}")
        self.write(topic, msgtype, msg, t if log_time is None else log_time)

    def text(self, topic: str, t: float, text: str) -> None:
        """A std_msgs/String (no header: its time is the log time ``t``)."""
        self.write(topic, "std_msgs/msg/String", self.types["std_msgs/msg/String"](data=text), t)

    # ------------------------------------------------------------------ writing
    def close(self) -> Path:
        """Write the buffered messages; returns the bag's path."""
        if self.ros == 1:
            from rosbags.rosbag1 import Writer

            writer = Writer(self.path)
            serialize = self.store.serialize_ros1
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3
            writer = Writer(self.path, version=self.version, storage_plugin=plugin)
            serialize = self.store.serialize_cdr
        writer.open()
        connections: dict[str, Any] = {}
        try:
            for log_ns, _, topic, msgtype, msg in sorted(self._records, key=lambda r: r[:2]):
                if topic not in connections:
                    connections[topic] = writer.add_connection(topic, msgtype, typestore=self.store)
                writer.write(connections[topic], log_ns, serialize(msg, msgtype))
        finally:
            writer.close()
        return self.path


_CATEGORY_HUES = (0, 30, 60, 90, 120, 150, 105, 15, 45, 75, 135, 165)  # OpenCV hue (0..179)


def render_category_image(
    category: int, rng: np.random.Generator, size: tuple[int, int] = (48, 64)
) -> np.ndarray:
    """``[H, W, 3]`` uint8 RGB: a category's colour (hue) with stripes whose angle and period
    depend on the category, plus noise (category -1, unlabelled: grey)."""
    height, width = size
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)  # [H, W] each
    c = max(int(category), 0)
    angle = np.pi * (c % 6) / 6
    period = 6 + 3 * (c % 4)
    stripes = 0.5 + 0.5 * np.sin(2 * np.pi * (cols * np.cos(angle) + rows * np.sin(angle)) / period)
    hsv = np.empty((height, width, 3), dtype=np.uint8)  # [H, W, 3]
    hsv[..., 0] = _CATEGORY_HUES[c % len(_CATEGORY_HUES)]
    hsv[..., 1] = 0 if category < 0 else 200
    value = 90 + 130 * stripes + rng.normal(0.0, 12.0, size=(height, width))
    hsv[..., 2] = np.clip(value, 0, 255).astype(np.uint8)
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)


@dataclass(frozen=True)
class SyntheticBags:
    """What :func:`write_synthetic_bags` wrote: the bags (one per trial), the map yaml, and the
    image / utterance topics to import them with."""

    bags: tuple[Path, ...]
    map_yaml: Path
    image_topic: str
    words_topic: str
    house: House


def _trial_track(
    xy: np.ndarray, yaw: np.ndarray, t_start: float, speed: float, dwell: float
) -> tuple[PoseTrack, np.ndarray]:
    """Key poses of a stop-and-go drive through ``xy`` [n, 2]: the track and the arrival times
    [n] at each stop."""
    distance = np.r_[0.0, np.hypot(*np.diff(xy, axis=0).T)]  # [n] from the previous stop
    travel = np.maximum(distance / speed, 0.05)  # [n] s (a minimum step between stops)
    arrive = t_start + np.cumsum(travel + np.r_[0.0, np.full(len(xy) - 1, dwell)])  # [n]
    times = np.stack([arrive, arrive + dwell], axis=1).reshape(-1)  # [2n]
    return (
        PoseTrack("synthetic tour", times, np.repeat(xy, 2, axis=0), np.repeat(yaw, 2)),
        arrive,
    )


def write_synthetic_bags(
    out: str | os.PathLike[str],
    *,
    seed: int = 0,
    house: House | None = None,
    ros: int = 2,
    storage: str = "sqlite3",
    image_format: str = "jpeg",
    image_size: tuple[int, int] = (48, 64),
    trials: list[int] | None = None,
    speed: float = 0.5,
    dwell: float = 1.0,
    rate: float = 10.0,
) -> SyntheticBags:
    """Record the synthetic house of ``seed`` (or ``house``) as bags under ``out``: the map as
    ``out/map.yaml`` + ``.pgm`` and one bag per trial, ``out/trial_K.bag`` (ROS 1) or the folder
    ``out/trial_K`` (ROS 2). See the module docstring for the topics.

    Nothing is written before the arguments are checked, the map is written last, and a run
    that fails removes what it wrote (so a retry finds no bag or map of it in the way).

    Raises FileExistsError when a bag or the map already exists, or ``out`` (or a parent) is a
    file; ValueError for a bad ``ros``, ``storage``, ``image_format`` or ``image_size``.
    """
    if ros not in (1, 2):
        raise ValueError(f"ros must be 1 or 2, got {ros!r}")
    if storage not in ("sqlite3", "mcap"):
        raise ValueError(f"storage must be 'sqlite3' or 'mcap', got {storage!r}")
    if image_format not in ("raw", "jpeg", "png"):
        raise ValueError(f"image_format must be raw, jpeg or png, got {image_format!r}")
    size = tuple(image_size)
    if len(size) != 2 or not all(is_integer(v) and 1 <= v <= MAX_IMAGE_SIDE for v in size):
        raise ValueError(
            f"image_size must be two integers in 1..{MAX_IMAGE_SIDE} (H, W), got {image_size!r}"
        )
    _rosbags()  # a missing rosbags is said before anything is written
    if house is None:
        from spcopyro.synthetic import HouseSpec, make_house

        house = make_house(seed=seed, spec=HouseSpec.embedded())
    out = Path(out)
    check_folder_path(out, f"--out {out}")
    obs = house.observations
    chosen = sorted(set(obs.trials if trials is None else trials))
    unknown = sorted(set(chosen) - set(np.asarray(obs.trials).tolist()))
    if unknown:
        raise ValueError(f"the house has no trial {unknown[0]} (its trials: {list(obs.trials)})")
    names = [out / (f"trial_{k}.bag" if ros == 1 else f"trial_{k}") for k in chosen]
    map_yaml = out / "map.yaml"
    for path in (*names, map_yaml):
        if path.exists():
            raise FileExistsError(
                f"{path} already exists: write the bags into another --out folder, or remove "
                "the earlier ones (simulate-bag never overwrites a recording)"
            )
    # What a failed run removes again: the bags, the map and the folders it created.
    written = [*names, map_yaml, *[p for p in [map_yaml.with_suffix(".pgm")] if not p.exists()]]
    created = [p for p in (out, *out.parents) if not p.exists()]  # deepest first
    out.mkdir(parents=True, exist_ok=True)
    try:
        image_topic = _record(house, names, chosen, seed, ros, storage, image_format, size,
                              speed, dwell, rate)  # fmt: skip
        save_map(house.grid, map_yaml)  # last: a failed run leaves no map in a retry's way
    except BaseException:
        for path in written:
            if path.is_dir():
                remove_tree(path)  # a Ctrl-C meanwhile: that KeyboardInterrupt
            elif path.exists():
                path.unlink()
        for folder in created:  # only if nothing else was put there meanwhile
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    return SyntheticBags(tuple(names), map_yaml, image_topic, "/speech", house)


def _record(
    house: House,
    names: list[Path],
    chosen: list[int],
    seed: int,
    ros: int,
    storage: str,
    image_format: str,
    image_size: tuple[int, int],
    speed: float,
    dwell: float,
    rate: float,
) -> str:
    """Write one bag per trial of ``chosen`` to ``names``; returns the image topic."""
    obs = house.observations
    rng = np.random.default_rng(seed)
    yaw_all = obs.image_yaw if obs.image_yaw is not None else np.zeros(obs.num_images)
    cells = house.grid.world_to_cell(obs.image_xy)  # [T, 2] (row, col)
    if house.truth is not None:
        category = house.truth[cells[:, 0], cells[:, 1]]  # [T]
    else:
        category = np.zeros(obs.num_images, dtype=np.int64)
    image_topic = "/camera/image" if image_format == "raw" else "/camera/image/compressed"
    for n, (k, path) in enumerate(zip(chosen, names, strict=True)):
        images = np.flatnonzero(obs.image_trial == k)  # [n_k]
        track, arrive = _trial_track(
            obs.image_xy[images], yaw_all[images], T0 + 10_000.0 * n, speed, dwell
        )
        with BagWriter(path, ros=ros, storage=storage) as writer:
            stamps = np.arange(track.times[0] - 1.0, track.times[-1] + 1.0, 1.0 / rate)  # [P]
            xy, yaw = track.at(stamps)  # [P, 2], [P]
            odom = PoseTrack("odom", [0.0], [MAP_TO_ODOM[:2]], [MAP_TO_ODOM[2]]).inverse()
            base = PoseTrack("base", stamps, xy, yaw)
            odom_xy, odom_yaw, _, _ = compose([odom, base], stamps, np.inf)  # [P, 2], [P]
            for p, t in enumerate(stamps.tolist()):
                writer.pose("/amcl_pose", t, xy[p, 0], xy[p, 1], yaw[p])
                writer.pose("/odom", t, odom_xy[p, 0], odom_xy[p, 1], odom_yaw[p], kind="odom",
                            frame="odom")  # fmt: skip
                odom_base = ("odom", "base_link", odom_xy[p, 0], odom_xy[p, 1], odom_yaw[p])
                writer.tf(t, [("map", "odom", *MAP_TO_ODOM), odom_base])
            writer.tf(stamps[0], [("base_link", "camera_link", *BASE_TO_CAMERA)], static=True)
            shot = arrive + dwell / 2  # [n_k] image stamps
            for j, i in enumerate(images.tolist()):
                rgb = render_category_image(int(category[i]), rng, image_size)
                writer.image(image_topic, float(shot[j]), rgb, image_format)
            spoken = np.flatnonzero(obs.word_trial == k)  # [u_k]
            said_at: dict[int, int] = {}  # utterances so far at each stop
            for u in spoken.tolist():  # at the stop where it was said (the house's image xy)
                j = int(np.argmin(np.hypot(*(obs.image_xy[images] - obs.word_xy[u]).T)))
                said_at[j] = said_at.get(j, 0) + 1
                writer.text("/speech", float(shot[j]) + 0.1 * said_at[j],
                            " ".join(obs.utterances[u]))  # fmt: skip
    return image_topic
