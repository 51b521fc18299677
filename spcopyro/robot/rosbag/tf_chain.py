"""The bag's tf tree: its edges as pose tracks, the chain between two frames, and a pose topic
placed on the map through it.

Every edge ``(parent, child)`` of ``/tf`` and ``/tf_static`` is a
:class:`~spcopyro.robot.rosbag.poses.PoseTrack` of the child in the parent (:func:`tf_tracks`;
``/tf`` samples sorted by stamp as :mod:`~spcopyro.robot.rosbag.bag` sorts a pose topic's,
``/tf_static`` ones valid at every time). The chain between two frames is found breadth-first
over the tree, edges usable both ways (walked against their direction they are inverted:
:func:`tf_path`). ``--pose-tf PARENT CHILD`` reads the pose from such a chain
(:func:`read_tf_chain`); a pose topic in another frame than the map's is placed on the map
through one (:func:`read_pose_in_map`). Frame names are compared as
:func:`~spcopyro.robot.rosbag.poses.frame_name` gives them (no leading ``/``).
"""

from __future__ import annotations

from collections import deque
from typing import Any

from spcopyro.robot.rosbag.bag import (
    TF_TYPES,
    BagContentError,
    check_order,
    message_time,
    pose_track,
    read_pose_topic,
    topic_connections,
    topic_listing,
    topic_messages,
)
from spcopyro.robot.rosbag.poses import PoseTrack, frame_name, on_stamp_clock, quaternion_yaw

__all__ = [
    "check_tf_topics",
    "edge_listing",
    "read_pose_in_map",
    "read_tf_chain",
    "tf_path",
    "tf_tracks",
]


def read_pose_in_map(reader: Any, topic: str, map_frame: str) -> tuple[list[PoseTrack], str | None]:
    """The pose topic's poses placed on the map of frame ``map_frame``: the chain to
    :func:`~spcopyro.robot.rosbag.poses.compose` at each observation's stamp, and the tf path used
    (``"map -> odom"``; None when the poses are in the map's frame already).

    A pose topic whose ``header.frame_id`` names another frame (``odom``) is placed on the map
    through the bag's tf: the chain is the tf edges from ``map_frame`` to that frame
    (:func:`read_tf_chain`, each edge interpolated at the observation's stamp, as tf2's
    ``lookupTransform`` would) followed by the pose topic's own track, so every observation
    needs a sample of every edge within the pose tolerance (else it is skipped and reported,
    naming the edge). Without such a chain the poses would be wrong on the map by the transform
    between the frames: :class:`BagContentError`, saying so. An empty frame_id is taken to be
    the map's."""
    track = read_pose_topic(reader, topic)
    frame, map_frame = track.frame, frame_name(map_frame)
    if frame is None or frame == map_frame:
        return [track], None
    tracks = tf_tracks(reader)
    found = None if tracks is None else tf_path(tracks, map_frame, frame)
    if found is None:
        why = "the bag has no /tf or /tf_static topic" if tracks is None else edge_listing(tracks)
        raise BagContentError(
            f"{reader.paths[0]}: pose topic {topic} gives poses in frame {frame!r}, not the "
            f"map's frame {map_frame!r}, and no tf chain links them ({why}): pass "
            f"--map-frame {frame} if the map is in that frame, or read the pose from tf with "
            f"--pose-tf {map_frame} BASE_FRAME"
        )
    chain, path = found
    return [*chain, track], " -> ".join(path)


def tf_tracks(reader: Any) -> dict[tuple[str, str], PoseTrack] | None:
    """Every tf edge ``(parent, child)`` of ``/tf`` and ``/tf_static`` as a pose track of the
    child in the parent; None when the bag has neither topic."""
    topics = [t for t in ("/tf", "/tf_static", "tf", "tf_static") if t in reader.topics]
    if not topics:
        return None
    connections = [c for t in topics for c in topic_connections(reader, t, TF_TYPES, "tf")]
    samples: dict[tuple[str, str], tuple[list[float], list[tuple[float, float, float]]]] = {}
    numbers: dict[tuple[str, str], list[int]] = {}  # each sample's message number on /tf
    clocks: dict[tuple[str, str], list[tuple[float, float]]] = {}
    unstamped: dict[tuple[str, str], list[int]] = {}
    static: dict[tuple[str, str], tuple[float, float, float]] = {}
    counted = {"tf": 0, "tf_static": 0}
    for _, connection, log_ns, msg in topic_messages(reader, connections, " and ".join(topics)):
        is_static = connection.topic.lstrip("/") == "tf_static"
        counted[connection.topic.lstrip("/")] += 1
        for transform in msg.transforms:
            edge = (frame_name(transform.header.frame_id), frame_name(transform.child_frame_id))
            tr, q = transform.transform.translation, transform.transform.rotation
            pose = (float(tr.x), float(tr.y), quaternion_yaw(q.x, q.y, q.z, q.w))
            if is_static:
                static[edge] = pose
                continue
            times, poses = samples.setdefault(edge, ([], []))
            t, stamped = message_time(transform, log_ns)
            times.append(t)
            poses.append(pose)
            if stamped:
                clocks.setdefault(edge, []).append((log_ns * 1e-9, t))
            else:
                unstamped.setdefault(edge, []).append(len(times) - 1)
            numbers.setdefault(edge, []).append(counted["tf"])
    tracks: dict[tuple[str, str], PoseTrack] = {}
    for edge, (times, poses) in samples.items():
        times = on_stamp_clock(times, unstamped.get(edge, []), clocks.get(edge, []))
        check_order(reader, "/tf", times, f" (edge {edge[0]} -> {edge[1]})", numbers[edge])
        name = f"tf {edge[0]} -> {edge[1]}"
        tracks[edge] = pose_track(name, times, poses, None, clocks.get(edge))
    for edge, pose in static.items():
        tracks[edge] = PoseTrack(
            f"tf_static {edge[0]} -> {edge[1]}", [0.0], [pose[:2]], [pose[2]], static=True
        )
    return tracks


def edge_listing(tracks: dict[tuple[str, str], PoseTrack]) -> str:
    return "the bag's tf edges: " + (", ".join(f"{a} -> {b}" for a, b in sorted(tracks)) or "none")


def tf_path(
    tracks: dict[tuple[str, str], PoseTrack], parent: str, child: str
) -> tuple[list[PoseTrack], list[str]] | None:
    """The chain of ``tracks`` (:func:`tf_tracks`) from frame ``parent`` to frame ``child``
    and the frames it walks (``[parent, ..., child]``); None when no chain links them."""
    # Breadth-first search over the tree, edges usable both ways.
    neighbours: dict[str, list[tuple[str, tuple[str, str], bool]]] = {}
    for a, b in tracks:
        neighbours.setdefault(a, []).append((b, (a, b), False))
        neighbours.setdefault(b, []).append((a, (a, b), True))
    previous: dict[str, tuple[str, tuple[str, str], bool] | None] = {parent: None}
    queue = deque([parent])
    while queue:
        frame = queue.popleft()
        for other, edge, inverted in neighbours.get(frame, []):
            if other not in previous:
                previous[other] = (frame, edge, inverted)
                queue.append(other)
    if child not in previous or parent not in neighbours:
        return None
    chain: list[PoseTrack] = []
    path = [child]
    frame = child
    while (step := previous[frame]) is not None:
        before, edge, inverted = step
        chain.append(tracks[edge].inverse() if inverted else tracks[edge])
        path.append(before)
        frame = before
    return chain[::-1], path[::-1]


def check_tf_topics(reader: Any, parent: str, child: str) -> None:
    """BagContentError when the bag has no ``/tf`` or ``/tf_static`` topic for the tf pose."""
    if not any(t in reader.topics for t in ("/tf", "/tf_static", "tf", "tf_static")):
        raise BagContentError(
            f"{reader.paths[0]}: no /tf or /tf_static topic for the tf pose "
            f"{frame_name(parent)} -> {frame_name(child)}; the bag has: "
            f"{topic_listing(reader) or 'no topics'}"
        )


def read_tf_chain(reader: Any, parent: str, child: str) -> list[PoseTrack]:
    """The tf edges from frame ``parent`` to frame ``child`` (``/tf`` and ``/tf_static``) as
    pose tracks whose product (:func:`spcopyro.robot.rosbag.poses.compose`) is the pose of ``child``
    in ``parent``; edges walked against their direction are inverted."""
    parent, child = frame_name(parent), frame_name(child)
    check_tf_topics(reader, parent, child)
    tracks = tf_tracks(reader) or {}
    found = tf_path(tracks, parent, child)
    if found is None:
        raise BagContentError(
            f"{reader.paths[0]}: no chain of tf transforms from frame {parent!r} to {child!r}; "
            f"{edge_listing(tracks)}"
        )
    return found[0]
