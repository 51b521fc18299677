"""The ``spcopyro navigate`` command: from an instruction to a goal pose and a path.

``spcopyro navigate OUT "go to the bedroom via the corridor" --start X,Y --out DIR`` reads the
fit in OUT, plans (:mod:`spcopyro.robot.navigation`) and prints the stops, the candidates of an
ambiguous word and the path's length; with ``--out`` it writes goal.yaml, path.yaml, path.csv,
waypoints.yaml, navigate.png and navigate.json (:mod:`spcopyro.robot.navigation.outputs`).
:func:`add_parser` registers it; nothing heavy is imported before the command runs.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING

from spcopyro._util.arguments import non_negative_number
from spcopyro._util.messages import area_text, plural
from spcopyro.cli.common import _HelpFormatter, figure_file, refuse_fit_files
from spcopyro.cli.out_names import graph_json

if TYPE_CHECKING:
    from spcopyro._util.outputs import StagedOutput
    from spcopyro.results.result import SpCoResult
    from spcopyro.results.saved_vocabulary import SavedVocabulary
    from spcopyro.robot.navigation.planning import NavigationPlan

__all__ = ["add_parser"]

UNREACHABLE_EXIT = 3
"""Exit status when no place of a word can be reached (bad input is 2, as everywhere)."""


def _point(text: str) -> tuple[float, float]:
    """``--start X,Y`` in metres."""
    parts = text.replace(" ", "").split(",")
    try:
        x, y = (float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give X,Y in metres, e.g. 1.5,-2") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise argparse.ArgumentTypeError(f"{text!r}: X and Y must be finite")
    return x, y


def _navigate(args: argparse.Namespace) -> int:
    from spcopyro.cli.common import load_fit
    from spcopyro.robot.navigation.goals import instruction_words
    from spcopyro.robot.navigation.outputs import check_frame

    check_frame(args.frame)
    # an older fit's 'stove.' is 'stove', and it says so, naming the instruction's words that
    # spell a saved word ('go to the -stove' on a fit that saved '-stove'), as where does
    result, saved = load_fit(args.result, instruction_words(args.instruction))
    staged = None
    if args.out:  # refused (an existing folder without --overwrite) before a plan is printed
        from spcopyro.robot.navigation.outputs import stage_plan_folder

        staged = stage_plan_folder(args.out, args.overwrite)
    try:
        return _plan_and_print(args, result, staged, saved)
    finally:
        if staged is not None:
            staged.discard()  # nothing once committed


def _plan_and_print(
    args: argparse.Namespace,
    result: SpCoResult,
    staged: StagedOutput | None,
    saved: SavedVocabulary | None = None,
) -> int:
    """Plan ``args.instruction`` on ``result``, print it, and write it into ``staged``;
    ``saved``: the fit's vocabulary as read (:func:`~spcopyro.cli.common.load_fit`): a place
    said as a saved word is not called another word, and the saved words read as others are
    kept in navigate.json with the places read as other words."""
    from spcopyro.cli.common import load_robot_map
    from spcopyro.results.where import shared_concept_note
    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.goals import UnreachableGoalError

    grid, planning_on = None, None
    if args.map:
        from spcopyro.maps import load_map

        grid = load_map(args.map)
    elif (robot_map := load_robot_map(result, args.result)) is not None:
        map_yaml, grid = robot_map
        planning_on = (f"planning on {map_yaml}, the map the fit's {result.grid.resolution:g} m "
                       "cells were coarsened from (--map to choose another)")  # fmt: skip
    try:
        plan = navigate(result, args.instruction, args.start, radius=args.radius,
                        strict=args.strict, prior=args.prior, grid=grid,
                        planner=args.planner)  # fmt: skip
    except UnreachableGoalError as error:
        print(f"error: {error}", file=sys.stderr)
        return UNREACHABLE_EXIT
    if planning_on:  # only over a plan: an unknown word or a bad --start is the only output
        print(planning_on)
    if plan.instruction.ignored:
        print(f"warning: ignored (not in the fit's vocabulary, nothing close): "
              f"{', '.join(plan.instruction.ignored)}", file=sys.stderr)  # fmt: skip
    from spcopyro.cli.common import other_word_note

    word_notes = {}  # per place as said: why it was read as another word (navigate.json too)
    for stop in plan.stops:  # "go to the -tv": planned for tv, and it says so
        note = other_word_note(stop.shown, stop.word, saved)  # as where's: saved '-tv' is no note
        if note and stop.shown not in word_notes:
            word_notes[stop.shown] = note
            print(f"warning: {note}", file=sys.stderr)
    order = " -> ".join(f"{s.shown}{' (via)' if s.via else ''}" for s in plan.stops)
    print(f"instruction {plan.instruction.text!r}: {order}")
    for stop in plan.stops:
        choice = stop.choice
        print(
            f"{stop.shown}: goal x={stop.xy[0]:.2f} y={stop.xy[1]:.2f} yaw={stop.yaw:.2f} "
            f"(goal cell: p(cell is the place) = {choice.candidate.probability:.3f}; "
            f"{area_text(choice.candidate.area)} m^2 of the place the robot fits in)"
        )
        if choice.ambiguous:
            print(
                f"  ambiguous: {sum(c.reachable for c in choice.candidates)} separate regions "
                "of near-equal probability; the nearer is taken (--strict refuses):"
            )
            for c in choice.candidates:
                if c.reachable:
                    mark = "*" if c.node == choice.node else " "
                    print(f"  {mark} x={c.xy[0]:.2f} y={c.xy[1]:.2f} p(cell is the place) = "
                          f"{c.probability:.3f}, {area_text(c.area)} m^2, "
                          f"{c.distance:.2f} m away")  # fmt: skip
        shared = shared_concept_note(choice.concept, choice.shared_with)
        if shared:  # as where's note: 'toilet' answered by the living room's concept
            print(f"  note: {shared}")
        for note in choice.notes:
            print(f"warning: {note}", file=sys.stderr)
    if plan.off_map:  # the stops' p counts the map's concepts only: as where's line says it
        from spcopyro.results.uncertainty import unmapped_note

        print(f"note: {unmapped_note(result)}")  # computed once per result (plan.off_map's)
    if plan.route:
        how = "" if plan.route_from == "graph" else " (the places the path crosses)"
        print(f"route: {' -> '.join(plan.route_names)}{how}")  # names told apart
    _print_planner(plan)
    print(f"path: {plural(len(plan.path_xy), 'pose')}, {plan.length:.2f} m, clearance "
          f"{plan.radius:g} m from walls (frame {args.frame})")  # fmt: skip
    if args.out:
        from spcopyro.robot.navigation.outputs import write_plan

        written = write_plan(plan, args.out, frame=args.frame, overwrite=args.overwrite,
                             source=args.result, figure=not args.no_figure, staged=staged,
                             word_notes=word_notes,
                             saved_words=() if saved is None else saved.renamed)  # fmt: skip
        print(f"wrote {', '.join(p.name for p in written.values())} to "
              f"{next(iter(written.values())).parent}")  # fmt: skip
    return 0


def _print_planner(plan: NavigationPlan) -> None:
    """How the path was planned: hierarchical, asked for the grid, or fallen back (and why)."""
    if plan.planner == "grid":
        print("planner: grid (asked): the shortest path over every cell the robot fits on")
    elif plan.planned == "hierarchical":
        print(f"planner: hierarchical: the route over the place graph, then the grid path kept "
              f"to its places ({plan.length:.2f} m; the shortest grid path "
              f"{plan.grid_length:.2f} m)")  # fmt: skip
    else:
        print(f"planner: {plan.planned} (hierarchical asked; fell back to the shortest grid "
              f"path on {len(plan.fallbacks)} of {len(plan.legs)} legs):")  # fmt: skip
        for reason in plan.fallbacks:
            print(f"  {reason}")


def show_graph(args: argparse.Namespace) -> int:
    """``spcopyro show OUT --graph --out graph.png``: the fit's place graph drawn over its map,
    and the graph as JSON beside the PNG, named after it (``graph.json``)."""
    import json

    from spcopyro._util.outputs import replace_text
    from spcopyro.cli.common import load_fit
    from spcopyro.results.concept_names import answered_words
    from spcopyro.robot.navigation.figure import plot_place_graph
    from spcopyro.robot.navigation.places import place_graph

    if not args.data:
        raise ValueError("show --graph: give the output folder of `spcopyro fit`")
    figure = figure_file(args.out)
    # the figure and its JSON never replace the fit's files (--out OUT/config.png: config.json)
    refuse_fit_files(args.data, args.out, [figure, graph_json(figure)])
    result, _ = load_fit(args.data)  # places named as the tokenizer reads words now
    graph = place_graph(result, min_area=args.min_area)
    png = plot_place_graph(result, graph, args.out)
    written = graph_json(png)  # X.png -> X.json: two graphs in one folder keep both
    replace_text(written, json.dumps(graph.to_json(), indent=2) + "\n")  # whole or not at all
    doors = sum(e.doorway for e in graph.passages)
    dropped = graph.dropped_text("m^2")  # as the figure's title: "" where none was left out
    if dropped:
        dropped = f"; {dropped} ({graph.dropped_area:.2f} m^2)"
    print(f"{plural(len(graph.places), 'place')}, {plural(len(graph.passages), 'passage')} "
          f"({plural(doors, 'doorway')}){dropped}")  # fmt: skip
    answers = answered_words(result)  # every word, also those heard only off the map
    for place in graph.places:
        near = [e.b if e.a == place.id else e.a for e in graph.passages
                if place.id in (e.a, e.b)]  # fmt: skip
        print(f"  {place.id}: {place.name} ({place.area_text} m^2) at x={place.centroid[0]:.2f} "
              f"y={place.centroid[1]:.2f}, next to {near or 'nothing'}")  # fmt: skip
        if place.words or answers:  # named by where's answer, which may not be the top word
            asked = ", ".join(answers.get(place.concept, ())) or "none"
            print(f"     concept {place.concept}, top words {', '.join(place.words) or 'none'}; "
                  f"where answers it for: {asked}")  # fmt: skip
    print(f"wrote {png} and {written}")
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``navigate`` on the main parser's subparsers."""
    p = subparsers.add_parser(
        "navigate",
        help="plan a goal pose and a path for an instruction ('go to the bedroom via the "
        "corridor') from a fitted result",
        formatter_class=_HelpFormatter,
    )
    p.add_argument("result", help="output folder of `spcopyro fit`")
    p.add_argument("instruction", help="the instruction; its place words are visited in order, "
                   "a place after 'via' before the destination said before it; one that says "
                   "to keep away from a place ('not the kitchen', 'kitchen no bedroom') is "
                   "refused: every place named is visited")  # fmt: skip
    p.add_argument("--start", type=_point, required=True, metavar="X,Y",
                   help="the robot's position in the map frame, metres")  # fmt: skip
    p.add_argument("--radius", type=non_negative_number("radius is metres"), default=0.2,
                   metavar="M", help="the robot's radius: cells closer than this to a wall or "
                   "unknown space are never entered")  # fmt: skip
    p.add_argument("--map", metavar="MAP.yaml",
                   help="plan on this map_server map (the robot's map in the fit's frame, e.g. "
                        "the one a coarse fit was made from, whose doorways coarsening narrows) "
                        "(default: for a coarse fit, the map it was coarsened from: its "
                        "robot_map.yaml, or for an older fit DATA/../map/HOUSE.yaml when it is "
                        "still there; else the fit's own grid); refused if its free space "
                        "covers less than 80%% of the fit's free cells: not the fit's "
                        "map")  # fmt: skip
    p.add_argument("--strict", action="store_true",
                   help="an ambiguous word (two separate regions of near-equal probability, "
                        "or an answer `spcopyro where` warns is not clearly more probable "
                        "than the runner-up concept, odds under 3) is an error instead of "
                        "taking the nearer or likelier")  # fmt: skip
    p.add_argument("--planner", choices=("hierarchical", "grid"), default="hierarchical",
                   help="hierarchical: the route over the place graph first, then the grid path "
                        "kept to the route's places (the shortest grid path, with the reason, "
                        "where that does not exist); grid: the shortest grid path")  # fmt: skip
    p.add_argument("--prior", choices=("area", "pi"), default="area",
                   help="p(C) of the word's place (as in `spcopyro where`)")  # fmt: skip
    p.add_argument(
        "--out",
        metavar="DIR",
        help="write goal.yaml, path.yaml, path.csv, "
        "waypoints.yaml, navigate.png, navigate.json here (default: print only)",
    )
    p.add_argument("--frame", default="map", help="frame_id of the poses (the map frame)")
    p.add_argument("--no-figure", action="store_true", help="do not draw navigate.png")
    p.add_argument("--overwrite", action="store_true", help="replace an earlier plan in DIR")
    p.set_defaults(func=_navigate)
