r"""A navigation plan as the files a ROS 2 / Nav2 robot reads.

In ``--out DIR`` (written whole or not at all: a staging folder beside DIR, renamed when done;
a non-empty DIR needs ``overwrite`` and must hold an earlier plan, :data:`PLAN_MARKER`):

* ``goal.yaml``: the goal as the fields of ``geometry_msgs/PoseStamped`` --
  ``header: {stamp: {sec, nanosec}, frame_id}``, ``pose: {position: {x, y, z}, orientation:
  {x, y, z, w}}``, the quaternion a rotation about z by the yaw facing along the path's end
  (``ros2 topic pub /goal_pose geometry_msgs/msg/PoseStamped "$(cat goal.yaml)"`` sends it).
* ``path.yaml``: ``nav_msgs/Path`` -- ``header`` and ``poses``, a PoseStamped per cell of the
  path, each facing the next.
* ``path.csv``: ``index,x,y,yaw,distance_m`` (metres and radians in the map frame; distance
  along the path).
* ``waypoints.yaml``: the goal of Nav2's ``nav2_msgs/action/FollowWaypoints`` -- ``poses``, a
  list of PoseStamped: each stop of the instruction in order ("via" places, then the
  destination), facing along the path where it reaches them.
* ``navigate.png``: the map, the destination word's probability map, the path, start, stops.
* ``navigate.json``: the instruction, its places (each as the instruction spells it and as
  the vocabulary's word it was read as, with the reason when that is another word:
  ``word_note``; a fit saved by an older spcopyro's words read as the tokenizer reads them
  now: ``saved_words_read_as``), every candidate region, the lengths and settings, the route
  over the place graph and the graph itself (:mod:`~spcopyro.robot.navigation.places`), how
  each leg was planned (``planner``: asked, used, the leg's route, the reason of a fallback to
  the grid path, :mod:`~spcopyro.robot.navigation.hierarchy`), and the fit it came from.

Stamps are 0 (``stamp: {sec: 0, nanosec: 0}``: "latest" to tf2). ``frame_id`` is the map frame
(``map`` unless given; a robot whose tf frames carry a prefix passes e.g. ``robot1/map``).
Poses are planar: z = 0, roll = pitch = 0.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from spcopyro._util.outputs import StagedOutput, stage_marked_folder
from spcopyro.robot.nav2 import check_frame, grid_record, write_commented_yaml
from spcopyro.robot.navigation.planning import NavigationPlan

__all__ = [
    "PLAN_MARKER",
    "path_message",
    "pose_stamped",
    "waypoints_goal",
    "write_plan",
]

PLAN_MARKER = "navigate.json"
"""A folder holding it was written by :func:`write_plan`: the only kind ``overwrite`` replaces."""


def pose_stamped(x: float, y: float, yaw: float, frame: str = "map") -> dict[str, object]:
    """The fields of a ``geometry_msgs/PoseStamped`` at (x, y) facing ``yaw`` (radians)."""
    return {
        "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": frame},
        "pose": {
            "position": {"x": round(float(x), 6), "y": round(float(y), 6), "z": 0.0},
            "orientation": {
                "x": 0.0,
                "y": 0.0,
                "z": float(math.sin(yaw / 2)),
                "w": float(math.cos(yaw / 2)),
            },
        },
    }


def path_message(plan: NavigationPlan, frame: str = "map") -> dict[str, object]:
    """The fields of a ``nav_msgs/Path`` of the plan's path."""
    poses = [
        pose_stamped(x, y, t, frame) for (x, y), t in zip(plan.path_xy, plan.path_yaw, strict=True)
    ]
    return {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": frame}, "poses": poses}


def waypoints_goal(plan: NavigationPlan, frame: str = "map") -> dict[str, object]:
    """The goal of ``nav2_msgs/action/FollowWaypoints``: ``poses``, one per stop in order."""
    return {"poses": [pose_stamped(*stop.xy, stop.yaw, frame) for stop in plan.stops]}


def planner_record(plan: NavigationPlan) -> dict[str, object]:
    """How the path was planned (``navigate.json``'s ``planner``): asked and used, the lengths,
    and per leg its route over the place graph and why it fell back to the grid path."""
    names = plan.places.places if plan.places is not None else ()
    return {
        "asked": plan.planner,
        "used": plan.planned,
        "length_m": plan.length,
        "grid_length_m": plan.grid_length,
        "border_margin_m": plan.margin,
        "legs": [
            {"to": stop.word, "route": list(leg.places),
             "words": [names[i].name for i in leg.places], "planner": leg.planner,
             "fallback": leg.reason, "length_m": leg.length, "grid_length_m": leg.grid_length}
            for stop, leg in zip(plan.stops, plan.legs, strict=True)
        ],
    }  # fmt: skip


def summary(
    plan: NavigationPlan,
    frame: str,
    source: str | None,
    *,
    word_notes: Mapping[str, str] | None = None,
    saved_words: Sequence[tuple[str, str]] = (),
) -> dict[str, object]:
    """What ``navigate.json`` holds. ``word_notes``: per place as the instruction spells it,
    why it was read as another word of the vocabulary (``-corridor``: ``corridor``; a stop's
    ``word_note``, null when none); ``saved_words``: (saved word, the word it was read as) of a
    fit saved by an older spcopyro (``stove.``: ``stove``; ``saved_words_read_as``)."""
    word_notes = word_notes or {}
    grid = plan.planning.grid
    stops = []
    for stop in plan.stops:
        stops.append({
            "word": stop.word,
            "said": stop.shown,  # as the instruction spells it ("TV")
            "word_note": word_notes.get(stop.shown),  # "-corridor" read as "corridor": why
            "via": stop.via,
            "x": stop.xy[0],
            "y": stop.xy[1],
            "yaw": stop.yaw,
            "probability": stop.choice.candidate.probability,
            "ambiguous": stop.choice.ambiguous,
            # where's odds over the runner-up concept; null: one concept, no runner-up
            "where_odds": stop.choice.where_odds if math.isfinite(stop.choice.where_odds) else None,
            "close_to_guess": stop.choice.close_to_guess,
            # the other words where answers with this stop's concept, [word, p] most probable first
            "shared_with": [[w, p] for w, p in stop.choice.shared_with],
            "candidates": [
                {"x": c.xy[0], "y": c.xy[1], "probability": c.probability, "area_m2": c.area,
                 "distance_m": c.distance if c.reachable else None, "reachable": c.reachable}
                for c in stop.choice.candidates
            ],
            "notes": list(stop.choice.notes),
        })  # fmt: skip
    return {
        "source": None if source is None else str(Path(source).resolve()),
        "instruction": plan.instruction.text,
        "places": list(plan.instruction.places),
        "ignored_words": list(plan.instruction.ignored),
        "saved_words_read_as": [{"saved": old, "word": new} for old, new in saved_words],
        "start": list(plan.start),
        "radius": plan.radius,
        "clearance": "hard: cells closer to a non-free cell than the radius are excluded",
        "prior": plan.prior,
        "frame_id": frame,
        "length_m": plan.length,
        "poses": len(plan.path_xy),
        "stops": stops,
        "route": {
            "places": list(plan.route),
            "words": list(plan.route_words),
            "from": plan.route_from,
        },
        "planner": planner_record(plan),
        "place_graph": plan.places.to_json() if plan.places is not None else None,
        "map": grid_record(grid),
    }


def stage_plan_folder(out: str | os.PathLike[str], overwrite: bool = False) -> StagedOutput:
    """The staging folder of a plan written to ``out``: an existing ``out`` needs ``overwrite``
    and must be an earlier plan (:func:`~spcopyro._util.outputs.stage_marked_folder`)."""
    return stage_marked_folder(
        out, overwrite, option="--out", marker=PLAN_MARKER, writer="navigate"
    )


def write_plan(
    plan: NavigationPlan,
    out: str | os.PathLike[str],
    *,
    frame: str = "map",
    overwrite: bool = False,
    source: str | os.PathLike[str] | None = None,
    figure: bool = True,
    staged: StagedOutput | None = None,
    word_notes: Mapping[str, str] | None = None,
    saved_words: Sequence[tuple[str, str]] = (),
) -> dict[str, Path]:
    """Write the plan's files into ``out`` (module docstring); their final paths by name.
    ``staged``: :func:`stage_plan_folder` of ``out``, made before planning (so that a folder
    that cannot be written is refused before any plan is printed); made here if None.
    ``word_notes``, ``saved_words``: how the instruction's and the fit's words were read, kept in
    ``navigate.json`` (:func:`summary`)."""
    frame = check_frame(frame)
    staged = stage_plan_folder(out, overwrite) if staged is None else staged
    names = {}
    with staged:
        folder = staged.path
        goal = plan.goal
        write_commented_yaml(folder / "goal.yaml", pose_stamped(*goal.xy, goal.yaw, frame),
              f"geometry_msgs/PoseStamped: the goal of {plan.instruction.text!r} (spcopyro "
              "navigate)")  # fmt: skip
        write_commented_yaml(folder / "path.yaml", path_message(plan, frame),
              "nav_msgs/Path (spcopyro navigate)")  # fmt: skip
        write_commented_yaml(folder / "waypoints.yaml", waypoints_goal(plan, frame),
              "nav2_msgs/action/FollowWaypoints goal: the instruction's stops in order "
              "(spcopyro navigate)")  # fmt: skip
        with open(folder / "path.csv", "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["index", "x", "y", "yaw", "distance_m"])
            steps = np.hypot(*np.diff(plan.path_xy, axis=0).T) if len(plan.path_xy) > 1 else []
            along = np.concatenate([[0.0], np.cumsum(steps)])
            for k, ((x, y), t) in enumerate(zip(plan.path_xy, plan.path_yaw, strict=True)):
                writer.writerow([k, f"{x:.4f}", f"{y:.4f}", f"{t:.6f}", f"{along[k]:.4f}"])
        if figure:
            from spcopyro.robot.navigation.figure import plot_plan

            plot_plan(plan, folder / "navigate.png")
        record = summary(plan, frame, None if source is None else str(source),
                         word_notes=word_notes, saved_words=saved_words)  # fmt: skip
        (folder / PLAN_MARKER).write_text(json.dumps(record, indent=2) + "\n")
        staged.commit()
    for name in ("goal.yaml", "path.yaml", "path.csv", "waypoints.yaml", "navigate.png",
                 PLAN_MARKER):  # fmt: skip
        if (staged.out / name).exists():
            names[name] = staged.out / name
    return names
