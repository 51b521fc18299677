"""``spcopyro simulate``: write a synthetic house (a drawn one, :mod:`spcopyro.synthetic`) or a
simulated tour of a map_server map (``--map``: :mod:`spcopyro.robot.map_simulation`) in the public
dataset's layout, and print the ``fit`` command for it. Its parser (:func:`add_parser`) imports
neither torch nor the synthetic package: the command imports them when it runs."""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
import re
import shlex
from pathlib import Path

from spcopyro._util.arguments import integer_at_least, number_type, positive_number, seed
from spcopyro._util.interrupts import sigterm_as_interrupt
from spcopyro._util.messages import plural
from spcopyro.cli.out_names import house_name
from spcopyro.data.text import fold_word

_positive_int = integer_at_least(1)  # --size and --rooms
_share = number_type(lambda v: 0 <= v <= 1, lambda text: f"{text!r}: a share from 0 to 1")


MAX_SIMULATED_CELLS = 1_000_000
"""``simulate --size H W``: the largest drawn house, in cells (1000 x 1000). The dense setting
draws one that size in about 12 s on a shared 2-core machine (sparse and open-plan in about 1 s);
time and memory grow faster than the area beyond it (a million by a million ran for minutes
without a word)."""


@sigterm_as_interrupt()  # `timeout`, systemd: the house and map stay whole (commit_folder)
def _simulate(args: argparse.Namespace) -> int:
    from spcopyro._util.outputs import check_folder_path

    if not args.out.strip():
        raise ValueError("--out '': an empty folder name (give . for this folder)")
    check_folder_path(args.out, f"--out {args.out}")  # it failed after the draw
    if args.map is not None:
        if args.density != "dense" or args.rooms is not None:
            raise ValueError("--density and --rooms draw a synthetic house; --map tours a map")
        return _simulate_on_map(args)
    for option, value in (("--categories", args.categories), ("--door-width", args.door_width),
                          ("--min-room-area", args.min_room_area)):  # fmt: skip
        if value is not None:
            raise ValueError(f"{option} needs --map (the synthetic house draws its own rooms)")
    if args.size and args.size[0] * args.size[1] > MAX_SIMULATED_CELLS:
        height, width = args.size
        raise ValueError(
            f"--size {height} {width}: {height * width:,} cells is over the limit of "
            f"{MAX_SIMULATED_CELLS:,} (e.g. 1000 x 1000); draw a smaller house"
        )
    if args.density == "open-plan" and args.rooms is not None and args.rooms < 2:
        raise ValueError(
            f"--rooms {args.rooms}: an open-plan house has at least 2 rooms, the open plan and "
            "a walled room beside it (default 4)"
        )
    args.name = house_name(args.name, args.map)  # synthetic (no --map here)
    try:
        return _simulate_house(args)
    except ValueError as error:  # the library names its fields, the command its flags
        message = str(error).replace("lower num_rooms or min_room_size, or enlarge the map",
                                     "lower --rooms or enlarge --size")  # fmt: skip
        if message.startswith("HouseSpec height x width") and args.size:
            message = (f"--size {args.size[0]} {args.size[1]}: too small: "
                       + message.removeprefix("HouseSpec height x width "))  # fmt: skip
        share = re.match(r"^HouseSpec\.open_plan_share ([\d.]+) cuts (.*) min_room_size \((\d+)\)$",
                         message)  # fmt: skip
        if share and args.size:  # --size too small for the open plan's share of the house
            message = (f"--size {args.size[0]} {args.size[1]}: too small for --density "
                       f"open-plan: its open plan's share {share[1]} of the house cuts "
                       f"{share[2]} {share[3]} cells (a room's least side); "
                       "enlarge --size")  # fmt: skip
        drawn = f"--density {args.density} draws \\1 rooms:"  # a field the user never gave
        message = re.sub(r"^HouseSpec\.num_rooms (\d+):",
                         "--rooms \\1:" if args.rooms is not None else drawn, message)  # fmt: skip
        raise ValueError(message) from None


def _simulate_house(args: argparse.Namespace) -> int:
    from spcopyro.synthetic import HouseSpec, write_synthetic
    from spcopyro.synthetic.spec import EMBEDDED_DOORWAY_WIDTH

    if args.density in ("sparse", "open-plan"):  # HouseSpec.public_like / HouseSpec.open_plan
        changes: dict[str, object] = dict(sentence_fraction=args.sentences)
        if args.size:
            changes.update(height=args.size[0], width=args.size[1])
        if args.rooms is not None:
            changes["num_rooms"] = args.rooms
        factory = HouseSpec.public_like if args.density == "sparse" else HouseSpec.open_plan
        spec = factory(**changes)
    else:
        # The embedded default house (HouseSpec.embedded: doorways a robot fits through), or
        # one of its size; `spcopyro fit` without DATA fits the same house as this seed's.
        spec = (
            HouseSpec.scaled(
                *args.size, sentence_fraction=args.sentences, doorway_width=EMBEDDED_DOORWAY_WIDTH
            )  # fmt: skip
            if args.size
            else HouseSpec.embedded(sentence_fraction=args.sentences)
        )
        if args.rooms is not None:
            spec = dataclasses.replace(spec, num_rooms=args.rooms)
    try:
        room = write_synthetic(args.out, seed=args.seed, spec=spec, name=args.name,
                               overwrite=args.overwrite)  # fmt: skip
    except FileExistsError as error:  # the library names its keyword, the command its flag
        raise FileExistsError(
            str(error).replace("pass overwrite=True", "pass --overwrite to replace it")
        ) from None
    if spec.num_rooms == 1:  # as simulate --map warns of a map that stays one room
        how = "--rooms 1" if args.rooms is not None else f"--size {spec.height} {spec.width}"
        logging.getLogger("spcopyro").warning(
            f"{room}: one room ({how}): the simulated truth has one category, so a fit's ARI "
            "against it says nothing; give --rooms 2 or more (and a --size that holds them)"
        )
    print(f"wrote synthetic house (seed {args.seed}) to {room}")
    print(f"  fit it with: {_fit_command(room, args.out)}")
    return 0


def _fit_command(room: Path, out: str) -> str:
    """The ``fit`` command a simulated house is fitted with, quoted for a shell (a folder
    with a space was printed as two words)."""
    return shlex.join(["spcopyro", "fit", str(room), "--out", str(Path(out) / "fit")])


def _door_width(text: str) -> float | str:
    """``--door-width``: ``auto`` or a positive number of metres."""
    if text == "auto":
        return text
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is neither auto nor metres") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: a door width must be > 0 metres")
    return value


def _simulate_on_map(args: argparse.Namespace) -> int:
    from spcopyro.robot.map_simulation import COMMAND_OPTIONS, MapTour, write_simulated_map

    if args.size:
        raise ValueError("--size and --map exclude each other: the map gives the size")
    tour = MapTour(sentence_fraction=args.sentences)
    if args.door_width is not None:
        tour = dataclasses.replace(tour, door_width=args.door_width)
    if args.min_room_area is not None:
        tour = dataclasses.replace(tour, min_room_area=args.min_room_area)
    if args.categories is not None:
        # read as where reads words (Kitchen, a full-width ＫＩＴＣＨＥＮ: kitchen)
        names = tuple(fold_word(c.strip()) for c in args.categories.split(","))
        if not all(names):
            raise ValueError(
                f"--categories {args.categories!r}: an empty name (two commas in a row, or one "
                "at an end); give one name per comma"
            )
        tour = dataclasses.replace(tour, categories=names)
    try:
        room, simulated = write_simulated_map(args.map, args.out, seed=args.seed, tour=tour,
                                              name=args.name, overwrite=args.overwrite,
                                              options=COMMAND_OPTIONS)  # fmt: skip
    except FileExistsError as error:
        raise FileExistsError(
            str(error).replace("pass overwrite=True", "pass --overwrite to replace it")
        ) from None
    house = simulated.house
    print(f"wrote a simulated tour of {args.map} (seed {args.seed}) to {room}: "
          f"{plural(int(simulated.room_category.size), 'room')}, "
          f"{house.observations.num_images} images, "
          f"{house.observations.num_utterances} utterances")  # fmt: skip
    how = "given" if isinstance(tour.door_width, float) else "read from the map"
    print(f"  rooms cut at doorways up to {simulated.door_width:g} m wide ({how})")
    names = house.category_names or ()
    for r, c in enumerate(simulated.room_category.tolist()):
        cells = int((simulated.rooms == r).sum())
        print(f"  room {r}: {names[c]} ({cells * house.grid.resolution**2:.1f} m^2)")
    print(f"  fit it with: {_fit_command(room, args.out)}")
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``simulate`` (its options and their help, as ``spcopyro simulate --help``
    lists them)."""
    p = subparsers.add_parser(
        "simulate", help="write a synthetic house in the public dataset's layout"
    )
    p.add_argument("--out", required=True, help="root folder (gets map/ and NAME/)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the house's random draws")
    p.add_argument("--name", help="the house's folder name (NAME; default: synthetic, or the "
                   "--map file's name)")  # fmt: skip
    p.add_argument("--size", type=_positive_int, nargs=2, metavar=("H", "W"),
                   help="map size in cells, at most 1,000,000 in all; the number of rooms grows "
                        "with the area (dense; sparse and open-plan keep theirs: --rooms) "
                        "(default: 60 x 80 cells, 5 rooms)")  # fmt: skip
    p.add_argument("--density", choices=("dense", "sparse", "open-plan"), default="dense",
                   help="dense: the embedded default house (HouseSpec.embedded: 4.9%% of the free "
                        "cells observed, doorways 0.7-0.9 m); sparse: as "
                        "sparse as the public houses (HouseSpec.public_like: 0.05 m cells, "
                        "~23,500 free, ~70 observed, 0.3%%); open-plan: as sparse, 65%% of it "
                        "one walled space holding living, dining and kitchen with no wall "
                        "between them, plus 3 small walled rooms "
                        "(HouseSpec.open_plan)")  # fmt: skip
    p.add_argument("--rooms", type=_positive_int, help="walled rooms (default: the setting's own; "
                   "open-plan: 4, one of them the open plan)")  # fmt: skip
    p.add_argument("--sentences", type=_share, default=0.0,
                   help="share of utterances given as sentences (tf-idf setting)")  # fmt: skip
    p.add_argument("--overwrite", action="store_true",
                   help="replace a house of the same name under --out")  # fmt: skip
    p.add_argument("--map", metavar="MAP.yaml",
                   help="simulate a tour on this map_server map instead of a drawn house: "
                        "rooms from a room segmentation of its free space (default: draw a "
                        "house)")  # fmt: skip
    p.add_argument("--categories", metavar="A,B,...",
                   help="with --map: the rooms' categories, one per room, cycled (default: "
                        "kitchen,living,bedroom,bathroom,toilet,entrance,...)")  # fmt: skip
    p.add_argument("--door-width", type=_door_width,
                   help="with --map: metres; doorways up to about this wide separate rooms, or "
                        "auto: read from the map, the one of 0.75, 1, ..., 3 m at which the "
                        "room count rises the most (1.5 to 2.25 m on the public dataset's houses) "
                        "(default: auto)")  # fmt: skip
    p.add_argument("--min-room-area", type=positive_number("area is square metres"),
                   help="with --map: square metres; smaller free segments are not visited and "
                        "have no ground truth (default: 1)")  # fmt: skip
    p.set_defaults(func=_simulate)
