"""Planar pose tracks from a recording: interpolation at a timestamp, and composition.

A :class:`PoseTrack` is a time series of planar poses (x, y, yaw) of one frame in another, e.g.
``base_link`` in ``map`` from amcl, or one edge ``odom -> base_link`` of the tf tree. At a
timestamp t between two samples (t0, p0) and (t1, p1) the pose is interpolated linearly,

    x(t) = x0 + s (x1 - x0),  y(t) likewise,  yaw(t) = yaw0 + s wrap(yaw1 - yaw0),
    s = (t - t0) / (t1 - t0),

with ``wrap`` the shortest signed angle in (-pi, pi] (so 179 deg -> -179 deg turns 2 deg, not
358). A timestamp before the first or after the last sample takes that sample's pose. A pose
*exists* at t only if the nearest sample is within ``tolerance`` seconds of t; otherwise the
observation at t has no pose and is reported (never dropped silently; see
:mod:`spcopyro.robot.rosbag.importer`). A *static* track (from ``/tf_static``) holds one pose valid
at every time.

Composition (a chain of tf edges, :func:`compose`) is in SE(2): a pose (x, y, yaw) of frame B in
frame A is the transform ``T_AB``; ``T_AC = T_AB T_BC`` and the inverse of (x, y, yaw) is
``(-R(-yaw) (x, y), -yaw)``. Transforms with roll or pitch are projected onto the plane (their
yaw about z is kept), which is exact for a robot base moving on a floor.

Times are float64 seconds (ROS stamps: ``sec + nanosec * 1e-9``).

A track also keeps its messages' (record time, header stamp) pairs (``clock``): where every track
of a chain stamps on another clock than the bag's record times (a simulator's),
:func:`header_clock` maps the record times of messages without a stamp onto it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = [
    "CLOCKS_APART",
    "CLOCKS_DIFFER",
    "PLAUSIBLE_DELAY",
    "PoseTrack",
    "compose",
    "frame_name",
    "header_clock",
    "image_clock",
    "late_count",
    "on_stamp_clock",
    "quaternion_yaw",
    "wrap_angle",
    "yaw_quaternion",
]


def frame_name(name: str) -> str:
    """A frame id as the import compares them: blanks around it and a leading ``/`` (ROS 1's
    global prefix: ``/odom`` is ``odom``) dropped."""
    return name.strip().lstrip("/")


def wrap_angle(angle: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to (-pi, pi] (the shortest signed rotation)."""
    wrapped = np.mod(np.asarray(angle, dtype=np.float64) + np.pi, 2 * np.pi) - np.pi
    return np.where(wrapped == -np.pi, np.pi, wrapped)


def quaternion_yaw(x: float, y: float, z: float, w: float) -> float:
    """The rotation about z (yaw, radians) of a unit quaternion (x, y, z, w); roll and pitch
    are dropped (ZYX Euler angles)."""
    return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """The unit quaternion (x, y, z, w) of a rotation by ``yaw`` about z."""
    return 0.0, 0.0, float(np.sin(yaw / 2)), float(np.cos(yaw / 2))


@dataclass(frozen=True)
class PoseTrack:
    """Poses of one frame in another over time (or one static pose).

    ``times`` [P] float64 seconds, strictly increasing; ``xy`` [P, 2]; ``yaw`` [P] radians.
    ``static``: one pose (P = 1) valid at every time. ``inverted``: :meth:`at` gives the inverse
    of the interpolated pose (as tf2 does for an edge walked backwards; interpolating inverted
    samples would differ between samples). ``name`` says where it came from (a topic, or a tf
    edge ``parent -> child``), for messages.
    """

    name: str
    times: np.ndarray  # [P] float64 s, strictly increasing
    xy: np.ndarray  # [P, 2] float64 m
    yaw: np.ndarray  # [P] float64 rad
    static: bool = False
    inverted: bool = False  # the parent in the child frame: interpolated, then inverted
    merged: int = 0  # samples dropped because they repeated the previous sample's stamp
    frame: str | None = None  # the frame the poses are given in (a pose topic's header)
    clock: np.ndarray | None = None  # [K, 2] (record time, header stamp) of its messages, s
    late: int = 0  # samples that came after one stamped later (sorted into place)

    def __post_init__(self) -> None:
        times = np.asarray(self.times, dtype=np.float64).reshape(-1)  # [P]
        xy = np.asarray(self.xy, dtype=np.float64).reshape(-1, 2)  # [P, 2]
        yaw = np.asarray(self.yaw, dtype=np.float64).reshape(-1)  # [P]
        if not times.size or xy.shape[0] != times.size or yaw.size != times.size:
            raise ValueError(
                f"pose track {self.name}: {times.size} times, {xy.shape[0]} positions and "
                f"{yaw.size} yaws (need the same number, at least one)"
            )
        if (np.diff(times) <= 0).any():
            k = int(np.flatnonzero(np.diff(times) <= 0)[0])
            raise ValueError(
                f"pose track {self.name}: times not strictly increasing "
                f"({times[k]:.9f} s, then {times[k + 1]:.9f} s)"
            )
        if self.static and times.size != 1:
            raise ValueError(f"pose track {self.name}: a static track holds one pose")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "xy", xy)
        object.__setattr__(self, "yaw", yaw)

    def gap(self, t: np.ndarray) -> np.ndarray:
        """Seconds from each of ``t`` [M] to the nearest sample ([M]; 0 for a static track)."""
        t = np.asarray(t, dtype=np.float64)  # [M]
        if self.static:
            return np.zeros_like(t)
        after = np.searchsorted(self.times, t)  # [M] first sample >= t
        later = self.times[np.minimum(after, self.times.size - 1)]  # [M]
        earlier = self.times[np.maximum(after - 1, 0)]  # [M]
        return np.minimum(np.abs(later - t), np.abs(t - earlier))

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pose at each of ``t`` [M]: ``xy`` [M, 2] and ``yaw`` [M], interpolated (linear in
        x, y; yaw by the shortest angle); clamped to the first / last sample outside them."""
        t = np.asarray(t, dtype=np.float64)  # [M]
        if self.static or self.times.size == 1:
            xy, yaw = np.repeat(self.xy, t.size, axis=0), np.repeat(self.yaw, t.size)
        else:
            right = np.clip(np.searchsorted(self.times, t, side="right"), 1, self.times.size - 1)
            left = right - 1  # [M] segments [left, right]
            t0, t1 = self.times[left], self.times[right]  # [M]
            s = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)[:, None]  # [M, 1]
            xy = self.xy[left] + s * (self.xy[right] - self.xy[left])  # [M, 2]
            turn = wrap_angle(self.yaw[right] - self.yaw[left])  # [M]
            yaw = wrap_angle(self.yaw[left] + s[:, 0] * turn)  # [M]
        if self.inverted:
            return _invert(xy, yaw)
        return xy, yaw

    def inverse(self) -> PoseTrack:
        """The track of the parent frame in the child frame (each interpolated pose inverted)."""
        name = self.name[len("inverse of ") :] if self.inverted else f"inverse of {self.name}"
        return PoseTrack(
            name, self.times, self.xy, self.yaw, self.static, not self.inverted, self.merged,
            clock=self.clock, late=self.late,
        )  # fmt: skip


def _invert(xy: np.ndarray, yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """SE(2) inverses of poses ``xy`` [M, 2], ``yaw`` [M]: ``(-R(-yaw) (x, y), -yaw)``."""
    c, s = np.cos(yaw), np.sin(yaw)  # [M]
    x, y = xy[:, 0], xy[:, 1]
    return np.stack([-(c * x + s * y), s * x - c * y], axis=1), wrap_angle(-yaw)


def _seconds(gap: float) -> str:
    """A pose gap for a message: milliseconds' precision, or two significant digits below a
    millisecond (with a tolerance of 0, '0.000 s away' hid the gap that was too long)."""
    return f"{gap:.3f}" if gap >= 1e-3 else f"{gap:.2g}"


def compose(
    chain: list[PoseTrack], t: np.ndarray, tolerance: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str | None]]:
    """The chain's product ``T_0 T_1 … T_n`` at each of ``t`` [M].

    Returns ``xy`` [M, 2], ``yaw`` [M], ``ok`` [M] bool (every track of the chain has a sample
    within ``tolerance`` seconds) and, per timestamp, None or the reason it has no pose (the
    first track that misses, and by how much).
    """
    t = np.asarray(t, dtype=np.float64)  # [M]
    xy = np.zeros((t.size, 2))  # [M, 2]
    yaw = np.zeros(t.size)  # [M]
    ok = np.ones(t.size, dtype=bool)  # [M]
    reasons: list[str | None] = [None] * t.size
    for track in chain:
        gap = track.gap(t)  # [M]
        missing = ok & (gap > tolerance)  # [M]
        for m in np.flatnonzero(missing).tolist():
            reasons[m] = (
                f"no pose of {track.name} within {tolerance:g} s (nearest "
                f"{_seconds(float(gap[m]))} s away)"
            )
        ok &= ~missing
        step_xy, step_yaw = track.at(t)  # [M, 2], [M]
        c, s = np.cos(yaw), np.sin(yaw)  # [M]
        xy = xy + np.stack([c * step_xy[:, 0] - s * step_xy[:, 1],
                            s * step_xy[:, 0] + c * step_xy[:, 1]], axis=1)  # fmt: skip
        yaw = wrap_angle(yaw + step_yaw)
    return xy, yaw, ok, reasons


CLOCKS_DIFFER = 1.0
"""Seconds: a pose source whose header stamps lie further than this (median) from the bag's
record times stamps on another clock than the recorder's -- a simulator's (``use_sim_time``:
stamps from 0 s) or another machine's -- and messages without a stamp (std_msgs/String) are
placed on the stamps' clock (:func:`header_clock`). No transport delay of a pose is that long."""


CLOCKS_APART = 86_400.0
"""Seconds: ranges of stamps further apart than this (a day) are on two clocks (a simulator's
from 0 s beside the wall clock's, ~1.7e9 s). Nearer, they are one clock's: amcl publishes only
after the robot moved, so a camera's first images can come well before the first pose."""


PLAUSIBLE_DELAY = 60.0
"""Seconds: an image clock's offset (:func:`image_clock`) under this, where some image got a
pose, may be a difference in transport delay to the recorder (the images' or the poses') or a
skew between two machines' clocks, with each image rightly at its header stamp for the first
(kind ``"delay"``); beyond it, or with no image posed, only two clocks (``"clocks"``)."""


def header_clock(
    chain: list[PoseTrack],
) -> tuple[float | None, Callable[[np.ndarray], np.ndarray] | None]:
    """The median of record time minus header stamp over the messages of the robot's own pose
    track (the chain's last with stamped messages: the pose topic, or the tf edge to the
    robot's frame), and, when every track of the chain is off by more than
    :data:`CLOCKS_DIFFER` (median), the map from record times to the stamps' clock through that
    track (its offset interpolated in record time, so a clock that drifts -- a simulator not at
    real time -- is followed); (median, None) when the clocks agree, (None, None) without
    stamped samples. One edge alone off (Nav2's amcl stamps ``map -> odom``
    ``transform_tolerance`` ahead) is no other clock."""
    clocks = [track.clock for track in chain if track.clock is not None and len(track.clock)]
    if not clocks:
        return None, None
    medians = [float(np.median(c[:, 0] - c[:, 1])) for c in clocks]
    clock = clocks[-1][np.argsort(clocks[-1][:, 0], kind="stable")]  # [K, 2]
    record, offset = clock[:, 0], clock[:, 0] - clock[:, 1]  # [K] each
    if min(abs(m) for m in medians) <= CLOCKS_DIFFER:
        return medians[-1], None
    return medians[-1], lambda times: times - np.interp(times, record, offset)


def image_clock(
    chain: list[PoseTrack],
    stamps: np.ndarray,
    record: np.ndarray,
    pose_offset: float | None,
    posed: bool,
) -> dict[str, object] | None:
    """Whether a topic's header ``stamps`` [M] (its stamped messages, recorded at ``record``
    [M] s) are on another clock than the poses': None when they agree; else what to report
    (``offset``: how many seconds the stamps are ahead of the poses' at the same record time,
    None where the record times do not tell; the stamps' range ``stamps`` and the robot's own
    pose track's, ``poses`` of ``pose_source``; ``kind``: ``"delay"`` for an offset under
    :data:`PLAUSIBLE_DELAY` where some message got a pose, a difference in transport delay or a
    skew between machines, else ``"clocks"``, two clocks). They differ when the median of record
    time minus stamp is more than :data:`CLOCKS_DIFFER` from the poses' (``pose_offset``, of
    :func:`header_clock`; 0 where the poses carry no stamp), or when no message got a pose
    (``posed`` False) and the two ranges are more than :data:`CLOCKS_APART` apart (a bag whose
    record times are its stamps tells nothing by its offsets; images all before the first pose,
    nearer, are on the poses' clock). A chain of static transforms only has no clock."""
    moving = [track for track in chain if not track.static]
    if not stamps.size or not moving:
        return None
    track = moving[-1]  # the robot's own: the pose topic, or the tf edge to its frame
    offset = (pose_offset or 0.0) - float(np.median(record - stamps))
    apart = (stamps.max() < track.times[0] - CLOCKS_APART
             or stamps.min() > track.times[-1] + CLOCKS_APART)  # fmt: skip
    if abs(offset) <= CLOCKS_DIFFER and (posed or not apart):
        return None
    told = abs(offset) > CLOCKS_DIFFER  # else the ranges apart say it, not the offset
    return {
        "kind": "delay" if told and abs(offset) < PLAUSIBLE_DELAY and posed else "clocks",
        "offset": offset if told else None,
        "stamps": [float(stamps.min()), float(stamps.max())],
        "poses": [float(track.times[0]), float(track.times[-1])],
        "pose_source": track.name,
    }


def late_count(times: np.ndarray | list[float]) -> int:
    """How many of ``times`` (bag order) are before an earlier one: messages that arrived late."""
    t = np.asarray(times, dtype=np.float64)  # [M]
    return int((t[1:] < np.maximum.accumulate(t)[:-1]).sum()) if t.size else 0


def on_stamp_clock(
    times: list[float], unstamped: list[int], clock: list[tuple[float, float]]
) -> list[float]:
    """``times`` of a pose track with those of its samples ``unstamped`` (a zero stamp: their
    record time) moved onto the stamps' clock through the track's ``clock`` (record time,
    stamp) pairs, when the stamps are more than :data:`CLOCKS_DIFFER` s from their record times
    (median: a simulator's clock). One such sample, 1.6e9 s past the simulated times, was read
    as a clock that went back."""
    pairs = np.asarray(clock, dtype=np.float64).reshape(-1, 2)  # [K, 2]
    if not unstamped or not pairs.size:
        return times
    offset = pairs[:, 0] - pairs[:, 1]  # [K]
    if abs(float(np.median(offset))) <= CLOCKS_DIFFER:
        return times
    order = np.argsort(pairs[:, 0], kind="stable")
    moved = np.asarray(times, dtype=np.float64)  # [P]
    moved[unstamped] -= np.interp(moved[unstamped], pairs[order, 0], offset[order])
    return moved.tolist()
