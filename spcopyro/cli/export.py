"""The ``spcopyro export`` command: a fitted semantic map as Nav2 costmap-filter masks.

``spcopyro export OUT --nav2 DIR --word kitchen --mode keepout`` reads the fit in OUT and writes
into DIR the map, the semantic map and, per word, a filter mask with its parameter files
(:mod:`spcopyro.robot.nav2`). :func:`add_parser` registers it on the main parser's subparsers.
"""

from __future__ import annotations

import argparse
import sys

from spcopyro._util.arguments import number_type
from spcopyro.cli.common import _HelpFormatter

__all__ = ["add_parser"]


_probability = number_type(
    lambda v: 0.0 < v <= 1.0, lambda text: f"must be a probability in (0, 1], got {text!r}"
)
_percent = number_type(
    lambda v: 0.0 <= v <= 100.0, lambda text: f"must be a percentage in [0, 100], got {text!r}"
)


def _min_speed(value: str) -> float:
    """``--min-speed``: a percentage in [1, 100]: Nav2 reads a 0 % limit as no limit."""
    number = _percent(value)
    if number < 1.0:
        raise argparse.ArgumentTypeError(
            f"must be at least 1 (percent): Nav2 reads a 0 % limit as no limit, got {value!r}"
        )
    return number


def _keeps_out_nothing(result, word: str, args: argparse.Namespace) -> str:
    """Why a keepout mask of ``word`` holds no cell, and what to do."""
    if args.threshold is None:
        return "the mask keeps out no cell: the where-answer's region is empty"
    from spcopyro.results.uncertainty import where_probability

    highest = float(where_probability(result, word, args.prior).max(initial=0.0))
    return (
        f"the mask keeps out no cell: no free cell's probability of being the place reaches "
        f"--threshold {args.threshold:g} (the highest is {highest:.4g}); lower --threshold"
    )


def _what_cells(mask, free, args: argparse.Namespace) -> str:
    """What the cells a mask line counts get: kept out, or slowed, with the speed limits the
    written mask sets on them (read back as Nav2 decodes it: limit = 100 - value percent): the
    limit falls from --max-speed where p(cell is the place) = 0 to --min-speed where it is 1,
    so a word whose place is uncertain slows the robot far less than --min-speed."""
    if mask.mode == "keepout":
        return "kept out"
    from spcopyro.maps import load_filter_mask

    values = load_filter_mask(mask.mask_yaml).values[free]  # [N] 0: no limit
    limits = 100 - values[values > 0].astype(int)  # [cells] percent
    if len(limits) == 0:
        return "slowed"
    span = f"{limits.min()}%" if limits.min() == limits.max() else (
        f"{limits.min()}-{limits.max()}%")  # fmt: skip
    return (f"slowed, to {span} of the maximum speed ({args.max_speed:g}% where p(cell is the "
            f"place) = 0, down to {args.min_speed:g}% where it is 1)")  # fmt: skip


def _export(args: argparse.Namespace) -> int:
    from spcopyro.cli.common import load_fit, load_robot_map
    from spcopyro.results.result import UnknownWordError
    from spcopyro.robot.nav2 import DEFAULT_MAX_SPEED, DEFAULT_MIN_SPEED, export_nav2

    if args.threshold is not None and args.mode != "keepout":
        print("error: --threshold applies to --mode keepout only", file=sys.stderr)
        return 2
    speeds = [f"--{n}-speed" for n in ("min", "max") if getattr(args, f"{n}_speed") is not None]
    if speeds and args.mode != "speed":
        print(f"error: {' and '.join(speeds)} {'apply' if len(speeds) > 1 else 'applies'} to "
              "--mode speed only", file=sys.stderr)  # fmt: skip
        return 2
    args.min_speed = DEFAULT_MIN_SPEED if args.min_speed is None else args.min_speed
    args.max_speed = DEFAULT_MAX_SPEED if args.max_speed is None else args.max_speed
    if args.min_speed > args.max_speed:
        print(f"error: --min-speed {args.min_speed:g} exceeds --max-speed {args.max_speed:g}",
              file=sys.stderr)  # fmt: skip
        return 2
    result, saved = load_fit(args.result, args.word or ())  # a saved 'stove.' is 'stove', said
    robot_map_yaml, robot_map = load_robot_map(result, args.result) or (None, None)
    try:
        export = export_nav2(
            result, args.nav2, args.word or (), mode=args.mode, prior=args.prior,
            threshold=args.threshold, min_speed=args.min_speed, max_speed=args.max_speed,
            overwrite=args.overwrite, source=args.result, namespace=args.namespace,
            robot_map=robot_map, frame=args.frame,
        )  # fmt: skip
    except UnknownWordError as error:
        print(f"error: {error.args[0]}", file=sys.stderr)
        return 2
    from spcopyro.cli.common import other_word_note
    from spcopyro.results.semantic_map import word_key

    for word in dict.fromkeys(args.word or ()):  # --word=-tv: the mask is tv's, and it says so
        note = other_word_note(word, word_key(result.vocabulary, word), saved)
        if note:
            print(f"warning: {note}", file=sys.stderr)
    free = result.grid.num_free
    print(f"wrote {export.map_yaml} and {export.semantic_map_yaml}")
    if robot_map is not None:
        print(f"the main map is {robot_map_yaml}, the robot's map the fit's "
              f"{result.grid.resolution:g} m cells were coarsened from; the semantic map and "
              "the masks are on the fit's cells")  # fmt: skip
    for mask in export.masks:
        how = f"concept {mask.concept}" if mask.concept is not None else "per-cell probability"
        print(f"{mask.mode} mask for {mask.word!r} ({how}): {mask.cells} of {free} free cells "
              f"{_what_cells(mask, result.grid.free, args)} -> {mask.mask_yaml}, params "
              f"{mask.params_yaml}")  # fmt: skip
        for warning in mask.warnings:
            print(f"warning: {mask.word!r}: {warning}", file=sys.stderr)
        if mask.mode == "keepout" and mask.cells == 0:
            print(f"warning: {mask.word!r}: {_keeps_out_nothing(result, mask.word, args)}",
                  file=sys.stderr)  # fmt: skip
    if not export.masks:
        print("no --word given: wrote the map and the semantic map only (--word WORD adds a "
              "mask and its costmap filter entries)")  # fmt: skip
    if args.mode == "speed" and len(export.masks) > 1:
        print(f"warning: {len(export.masks)} speed filters publish on one speed_limit topic: "
              "each publishes only when its own limit changes, so the limit in force is "
              "whichever changed last; run one speed word per export (or give each filter "
              "its own speed_limit_topic)", file=sys.stderr)  # fmt: skip
    if export.costmap_filters_yaml is not None:  # None: no word, no filter to merge
        print(f"costmap plugin entries for nav2_params.yaml: {export.costmap_filters_yaml}")
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``export`` on the main parser's subparsers."""
    p = subparsers.add_parser(
        "export",
        help="write a fitted semantic map as Nav2 costmap-filter masks (keepout or speed)",
        formatter_class=_HelpFormatter,
    )
    p.add_argument("result", help="output folder of `spcopyro fit`")
    p.add_argument(
        "--nav2",
        required=True,
        metavar="DIR",
        help="folder to write the map, the semantic map and the masks into",
    )
    p.add_argument(
        "--word",
        action="extend",
        nargs="+",
        metavar="WORD",
        help="word(s) whose place gets a mask (repeatable; default: none, only the "
        "maps are written)",
    )
    p.add_argument(
        "--mode",
        choices=("keepout", "speed"),
        default="keepout",
        help="keepout: the place is lethal (KeepoutFilter); speed: a speed limit that "
        "falls with the probability of being in the place (SpeedFilter)",
    )
    p.add_argument(
        "--prior",
        choices=("area", "pi"),
        default="area",
        help="p(C) of the where-answer (as in `spcopyro where`)",
    )
    p.add_argument(
        "--threshold",
        type=_probability,
        help="keepout: the place is every free cell whose probability of being the "
        "word's place is at least this (default: the where-answer's region)",
    )
    p.add_argument(
        "--min-speed",
        type=_min_speed,
        help="speed: limit in percent of the maximum speed where the probability is 1; at "
        "least 1 (Nav2 reads a 0 %% limit as no limit) (default: 30)",
    )
    p.add_argument(
        "--max-speed",
        type=_percent,
        help="speed: limit in percent where the probability is 0 (100: no limit) (default: 100)",
    )
    p.add_argument("--namespace", metavar="NS",
                   help="the robot's ROS namespace: the masks', filter infos' and speed limit's "
                        "topics become /NS/... (default: none, absolute topics)")  # fmt: skip
    p.add_argument("--frame", default="map",
                   help="tf frame of the masks (their mask servers' frame_id): the robot's map "
                        "frame, e.g. robot1/map for a robot whose tf frames carry a prefix; a "
                        "costmap filter whose mask frame is not in the tf tree gets no "
                        "mask")  # fmt: skip
    p.add_argument("--overwrite", action="store_true", help="replace an earlier export in DIR")
    p.set_defaults(func=_export)
