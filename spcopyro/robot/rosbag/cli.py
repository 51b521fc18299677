"""The ``spcopyro import-bag`` and ``spcopyro simulate-bag`` commands.

:func:`add_parser` registers both on the main parser's subparsers; rosbags is imported only when
one of them runs (a clear error naming ``pip install "spcopyro[ros]"`` when it is absent).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from spcopyro._util.arguments import integer_at_least, non_negative_number, seed
from spcopyro._util.interrupts import sigterm_as_interrupt
from spcopyro.robot.rosbag.bag import DEFAULT_ROS_DISTRO, ROS_DISTROS

__all__ = ["add_parser"]

PRINTED_SKIPS = 50  # skipped observations printed (all are in skipped.csv)


def _quote(path: object) -> str:
    """``path`` as a shell word (quoted when it holds a space or another special character)."""
    return shlex.quote(str(path))


def _name(value: str) -> str:
    """A topic or frame option: not empty (nor only slashes)."""
    if not value.strip("/ "):
        raise argparse.ArgumentTypeError(f"must name a topic or frame, got {value!r}")
    return value


def _image_side(value: str) -> int:
    """``--image-size``: an integer in 1 .. MAX_IMAGE_SIDE (a usage error naming the value)."""
    from spcopyro.robot.rosbag.synthetic import MAX_IMAGE_SIDE

    number = integer_at_least(1)(value)
    if number > MAX_IMAGE_SIDE:
        raise argparse.ArgumentTypeError(f"must be at most {MAX_IMAGE_SIDE} pixels, got {value!r}")
    return number


def _print_skipped(skipped, where: str) -> None:
    """The skipped observations on stderr: how many, ``where`` they are listed, the first
    :data:`PRINTED_SKIPS` with their stamps and reasons."""
    print(f"skipped {len(skipped)} observation(s) ({where}):", file=sys.stderr)
    for observation in skipped[:PRINTED_SKIPS]:
        print(f"  {observation.line()}", file=sys.stderr)
    if len(skipped) > PRINTED_SKIPS:
        print(f"  ... and {len(skipped) - PRINTED_SKIPS} more", file=sys.stderr)


@sigterm_as_interrupt()  # `timeout`, systemd: the house and map stay whole (commit_folder)
def _import_bag(args: argparse.Namespace) -> int:
    from spcopyro.robot.rosbag.bag import RosbagsMissingError
    from spcopyro.robot.rosbag.importer import ImportOptions, NothingLeftError, import_bags
    from spcopyro.robot.rosbag.mcap_schemas import RosbagsInternalsError

    options = ImportOptions(
        pose_topic=args.pose_topic,
        pose_tf=tuple(args.pose_tf) if args.pose_tf else None,
        image_topic=args.image_topic,
        words_topic=args.words_topic,
        min_distance=args.min_distance,
        min_interval=args.min_interval,
        pose_tolerance=args.pose_tolerance,
        ros_distro=args.ros_distro,
        map_frame=args.map_frame,
        image_bits=args.image_bits,
        image_time=args.image_time,
    )
    try:
        report = import_bags(
            args.bags,
            args.map,
            args.out,
            options,
            first_trial=args.first_trial,
            overwrite=args.overwrite,
        )
    except (RosbagsMissingError, RosbagsInternalsError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except NothingLeftError as error:  # the skipped observations are the reason: shown first
        if error.skipped:
            _print_skipped(error.skipped, "nothing was written: the import failed")
        raise
    print(f"pose from        {options.pose_source} (tolerance {options.pose_tolerance:g} s)")
    versions = {t.get("ros_version") for t in report.trials}
    if 1 in versions:  # --ros-distro does not apply: a ROS 1 bag holds its definitions
        print("ROS 1 types      each bag's own (a ROS 1 bag stores its message definitions)")
    if 2 in versions:
        print(f"ROS 2 types      {options.ros_distro} (for bags that store no message "
              "definitions)")  # fmt: skip
    frames = sorted({str(t.get("pose_frame") or "(none given)") for t in report.trials})
    print(f"pose frame       {', '.join(frames)} (the map's: {options.map_frame})")
    via = sorted({str(t["pose_frame_via_tf"]) for t in report.trials if t["pose_frame_via_tf"]})
    if via:  # poses in another frame, placed on the map through the bag's tf
        print(f"pose frame -> map through tf {', '.join(via)}")
    print(report.text())
    if report.skipped:
        _print_skipped(report.skipped, f"all listed in {report.out / 'skipped.csv'}")
    print(f"wrote {report.out} (map: {report.map_yaml})")
    if report.kept and report.images_unchanged:
        print(f"--overwrite kept {', '.join(report.kept)} in {report.out}, which import-bag "
              "did not write; the images are the replaced import's, byte for byte")  # fmt: skip
    elif report.kept:
        print(f"warning: --overwrite kept {', '.join(report.kept)} in {report.out}, which "
              "import-bag did not write; the images differ from the replaced import's, so "
              "what was made from those (Ft.csv of spcopyro features) does not describe these: "
              "write it again", file=sys.stderr)  # fmt: skip
    if report.map_replaced:
        print(f"warning: --overwrite replaced the map {report.map_yaml} of the earlier import "
              f"in {report.out}: it was not {args.map}'s map (it differed, or could not be "
              "read)", file=sys.stderr)  # fmt: skip
    _print_next(report)
    return 0


def _fit_out(house: Path) -> Path:
    """Where the printed ``fit`` writes: ``out/NAME`` (the README's walk: ``data/house`` ->
    ``out/house``), outside the data folder; another name where that would be ``house`` or
    overlap it."""
    there = house.resolve()
    for candidate in (Path("out") / house.name, Path(f"{house.name}-fit"),
                      house.parent.parent / f"{house.name}-fit"):  # fmt: skip
        here = candidate.resolve()
        if here != there and there not in here.parents and here not in there.parents:
            return candidate
    return house.parent.parent / f"{house.name}-fit-out"


def _print_next(report) -> None:
    """The commands to run next, as they work when pasted (a path with spaces quoted):
    ``features`` where images were kept, naming its weights (:func:`features_command`), and
    ``fit``, its output outside the data folder (:func:`_fit_out`)."""
    from spcopyro.features.cli import features_command

    out = report.out
    images = sum(int(t.get("images_kept") or 0) for t in report.trials)
    if images:  # a house of words only has no Ft.csv to write
        command, note = features_command(out, out / "Ft.csv")
        print(f"  next: {command}")
        if note:
            print(f"        ({note})")
    fit = f"spcopyro fit {_quote(out)} --out {_quote(_fit_out(out))}"
    print(f"  {'then' if images else 'next'}: {fit}")


def _house_out(bags: Path) -> Path:
    """Where the printed ``import-bag`` writes the house: ``data/house`` beside the bags folder,
    not in it (the README's walk: ``--out bags`` -> ``data/house``, its map then at
    ``data/map/house.yaml``); ``data/house-2``, ``data/house-3``, ... where that folder or its
    map is there already (import-bag would refuse it without ``--overwrite``)."""
    data = bags.parent / "data"
    k = 1
    while True:
        name = "house" if k == 1 else f"house-{k}"
        if not (data / name).exists() and not (data / "map" / f"{name}.yaml").exists():
            return data / name
        k += 1


def _simulate_bag(args: argparse.Namespace) -> int:
    from spcopyro.robot.rosbag.bag import RosbagsMissingError
    from spcopyro.robot.rosbag.synthetic import write_synthetic_bags

    if args.ros == 1 and args.storage is not None:
        raise ValueError(
            f"--storage {args.storage} applies to ROS 2 bags only (a ROS 1 bag is one .bag "
            "file): leave it out, or pass --ros 2"
        )
    try:
        result = write_synthetic_bags(
            args.out,
            seed=args.seed,
            ros=args.ros,
            storage=args.storage or "sqlite3",
            image_format=args.image_format,
            image_size=tuple(args.image_size),
            trials=args.trials,
        )
    except RosbagsMissingError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    for bag in result.bags:
        print(f"wrote {bag}")
    print(f"wrote {result.map_yaml}")
    bags = " ".join(_quote(b) for b in result.bags)
    house = _quote(_house_out(Path(args.out)))
    chosen = sorted(set(args.trials or ()))  # the bags' trials, in the order written
    first = f" --first-trial {chosen[0]}" if chosen and chosen[0] else ""
    print(f"  import with: spcopyro import-bag {bags} --map {_quote(result.map_yaml)} "
          f"--image-topic {result.image_topic}{first} --out {house}")  # fmt: skip
    if chosen and chosen != list(range(chosen[0], chosen[0] + len(chosen))):
        print(f"  (import-bag numbers its bags' trials one after another from --first-trial: "
              f"trials {', '.join(map(str, chosen))} come in as "
              f"{', '.join(str(chosen[0] + k) for k in range(len(chosen)))})")  # fmt: skip
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``import-bag`` and ``simulate-bag``."""
    p = subparsers.add_parser(
        "import-bag",
        help="a robot's rosbags (ROS 1 or 2) -> a house folder in the dataset layout",
        description=(
            "Read poses, camera images and utterances from ROS 1 (.bag) or ROS 2 (sqlite3 or "
            "mcap) bags, one trial per bag, and write a house folder OUT (img_K/, pose_K.csv, "
            "word_K.csv, Xtx/Xty, St/StXtx/StXty, skipped.csv) with the map at "
            "OUT/../map/NAME.yaml. Each image and utterance gets the pose interpolated at its "
            "timestamp; those without a pose within --pose-tolerance are reported and listed in "
            "skipped.csv. Then: spcopyro features OUT --out OUT/Ft.csv; spcopyro fit OUT."
        ),
    )
    p.add_argument("bags", nargs="+", metavar="BAG",
                   help="a ROS 1 .bag file, or a ROS 2 bag folder (or its .db3 / .mcap file); "
                        "several: trials K, K+1, ... in this order")  # fmt: skip
    p.add_argument("--map", required=True, help="map_server yaml of the map the robot used")
    p.add_argument("--out", required=True, help="house folder to write (its name names the house)")
    p.add_argument("--pose-topic", type=_name, default="/amcl_pose",
                   help="PoseWithCovarianceStamped, Odometry or PoseStamped topic in the map "
                        "frame, or one the bag's tf links to it (default /amcl_pose)")  # fmt: skip
    p.add_argument("--pose-tf", type=_name, nargs=2, metavar=("PARENT", "CHILD"),
                   help="take the pose of frame CHILD in frame PARENT from /tf and /tf_static "
                        "instead (e.g. map base_link; default: off, the pose topic)")  # fmt: skip
    p.add_argument(
        "--image-topic",
        type=_name,
        default="/camera/image",
        help="sensor_msgs/Image or CompressedImage topic (default /camera/image)",
    )
    p.add_argument(
        "--words-topic",
        type=_name,
        default="/speech",
        help="std_msgs/String topic of utterances: words or sentences (default /speech)",
    )
    p.add_argument(
        "--min-distance",
        type=non_negative_number("distance is metres"),
        default=0.0,
        help="keep an image only this many metres from the last kept one (default 0)",
    )
    p.add_argument(
        "--min-interval",
        type=non_negative_number("interval is seconds"),
        default=0.0,
        help="keep an image only this many seconds after the last kept one (default 0)",
    )
    p.add_argument("--pose-tolerance", type=non_negative_number("tolerance is seconds"),
                   default=0.5,
                   help="seconds from an observation to the nearest pose sample; farther ones "
                        "are skipped and reported (default 0.5)")  # fmt: skip
    p.add_argument(
        "--first-trial",
        type=integer_at_least(0),
        default=0,
        help="trial id of the first bag (default 0)",
    )
    p.add_argument(
        "--map-frame",
        type=_name,
        default="map",
        help="the map's frame: a pose topic whose header names another frame (odom) is "
        "placed on the map through the bag's tf chain from this frame to it, and is an error "
        "without one (default map)",
    )
    p.add_argument("--image-bits", type=int, choices=(8, 10, 12, 14, 16), default=None,
                   help="a 16-bit camera's bit depth: its images are scaled from it to 8 bits "
                        "(default: each image from the depth its largest value needs, which "
                        "brightens dark frames; the import says when depths differ)")  # fmt: skip
    p.add_argument("--image-time", choices=("header", "record"), default="header",
                   help="an image's time: its header stamp (a zero one: when the bag recorded "
                        "it), or record: when the bag recorded it, for a camera that stamps on "
                        "another clock than the poses (default header)")  # fmt: skip
    p.add_argument("--ros-distro", choices=ROS_DISTROS, default=DEFAULT_ROS_DISTRO,
                   help="ROS 2 distribution whose message definitions read a bag that stores "
                        "none (Foxy, Galactic and Humble sqlite3 bags; a bag's own definitions "
                        f"win) (default {DEFAULT_ROS_DISTRO})")  # fmt: skip
    p.add_argument("--overwrite", action="store_true",
                   help="replace OUT (only a folder import-bag wrote) and its map; anything in "
                        "OUT that import did not write (Ft.csv, notes) is kept and "
                        "named")  # fmt: skip
    p.set_defaults(func=_import_bag)

    p = subparsers.add_parser(
        "simulate-bag",
        help="record the synthetic house as rosbags (one per trial) with its map",
        description=(
            "Write the synthetic house of --seed as bags: /amcl_pose, /odom, /tf, /tf_static, "
            "camera images coloured by room category, and /speech utterances; plus "
            "OUT/map.yaml. Import them with spcopyro import-bag."
        ),
    )
    p.add_argument("--out", required=True, help="folder for the bags and map.yaml")
    p.add_argument("--seed", type=seed, default=0, help="seed of the synthetic house (default 0)")
    p.add_argument("--ros", type=int, choices=(1, 2), default=2, help="ROS version (default 2)")
    p.add_argument("--storage", choices=("sqlite3", "mcap"),
                   help="ROS 2 storage (default sqlite3; not for --ros 1)")  # fmt: skip
    p.add_argument("--image-format", choices=("raw", "jpeg", "png"), default="jpeg",
                   help="raw: sensor_msgs/Image on /camera/image; jpeg, png: CompressedImage on "
                        "/camera/image/compressed (default jpeg)")  # fmt: skip
    p.add_argument("--image-size", type=_image_side, nargs=2, default=(48, 64),
                   metavar=("H", "W"),
                   help="image height and width in pixels, each at most 8192 "
                        "(default 48 64)")  # fmt: skip
    p.add_argument("--trials", type=int, nargs="+", metavar="K",
                   help="record only these trials of the house (default: all)")  # fmt: skip
    p.set_defaults(func=_simulate_bag)
