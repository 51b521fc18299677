"""What ``spcopyro import-bag`` reports: the observations it skipped and why, and per trial
what it read, kept and left out (:class:`BagImportReport`, whose :meth:`~BagImportReport.text`
the command prints), and ``skipped.csv`` (:func:`write_skipped`).

:func:`spcopyro.robot.rosbag.importer.import_bags` fills them: an image or utterance without a
pose, an image that does not decode and an utterance without a word are each a
:class:`SkippedObservation`, listed with its timestamp; images thinned by ``min_distance`` /
``min_interval`` are counted per trial.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from spcopyro._util.messages import plural

__all__ = ["BagImportReport", "SkippedObservation", "image_clock_note", "write_skipped"]


def image_clock_note(t: dict[str, object]) -> str | None:
    """What a trial's ``image_clock`` (:func:`~spcopyro.robot.rosbag.poses.image_clock`: the
    camera's stamps on another clock than the poses') means and what to do; None without one.
    ``t``: the trial's counts. ``--image-time record`` is named only where it places the images
    better, its ``kind`` ``"clocks"`` (an offset beyond
    :data:`~spcopyro.robot.rosbag.poses.PLAUSIBLE_DELAY`, or no image posed); for ``"delay"``
    it would move images rightly stamped later by their transport delay."""
    clock = t.get("image_clock")
    if not clock:
        return None
    (a, b), (p, q), offset = clock["stamps"], clock["poses"], clock["offset"]
    stamps = f"trial {t['trial']} ({t['bag']}): the image stamps ({a:.3f}..{b:.3f} s) are"
    poses = f"({clock['pose_source']}: {p:.3f}..{q:.3f} s)"
    two_clocks = (
        "the camera and the poses appear to stamp on different clocks (one on simulated time, "
        "use_sim_time, the other on the wall clock?)"
    )
    if offset is None:  # the record times as far apart as the stamps
        return (
            f"{stamps} apart from the poses' {poses}: {two_clocks}, and the bag recorded them as "
            "far apart (--image-time record would not place them either); record again with "
            "every node on one clock"
        )
    how = f"{abs(offset):.3f} s {'ahead of' if offset > 0 else 'behind'} the poses'"
    if clock["kind"] == "delay":
        return (
            f"{stamps} {how} at the same record time {poses}: a difference in transport delay "
            "to the recorder (the images' or the poses') or a clock skew between machines. The "
            "import places each image at its header stamp, right for a delay (--image-time "
            "record would move each image later by its own delay); for a skew, synchronise the "
            "machines' clocks (chrony, NTP) and record again"
        )
    return (
        f"{stamps} {how} at the same record time {poses}: {two_clocks}. The import places an "
        "image at its header stamp; --image-time record places it at the time the bag recorded "
        "it (on the poses' clock), or record again with every node on one clock"
    )


@dataclass(frozen=True)
class SkippedObservation:
    """An image or utterance left out, with its timestamp and why."""

    trial: int
    bag: str
    topic: str
    kind: str  # "image" or "utterance"
    stamp: float  # seconds
    reason: str

    def line(self) -> str:
        return (
            f"trial {self.trial} {self.kind} at {self.stamp:.6f} s on {self.topic}: {self.reason}"
        )


@dataclass(frozen=True)
class BagImportReport:
    """What :func:`~spcopyro.robot.rosbag.importer.import_bags` wrote: the house folder, the
    map, and per trial the counts."""

    out: Path
    map_yaml: Path
    trials: tuple[dict[str, object], ...]
    skipped: tuple[SkippedObservation, ...]
    kept: tuple[str, ...] = ()
    """With ``overwrite``: the entries of the replaced folder that its import did not write
    (``Ft.csv`` of ``spcopyro features``, notes), carried into the new one."""
    map_replaced: bool = False
    """With ``overwrite``: ``map_yaml`` held the replaced import's different map."""
    images_unchanged: bool = False
    """With ``overwrite``: the images are the replaced import's, byte for byte (so a kept
    ``Ft.csv`` still describes them)."""

    def text(self) -> str:
        lines = []
        for t in self.trials:
            if t.get("poses_merged"):
                lines.append(
                    f"trial {t['trial']} ({t['bag']}): {t['poses_merged']} pose sample(s) "
                    "repeated the previous one's stamp and were merged into it (the first "
                    "kept): the bag's stamps are coarser than its pose rate"
                )
            for kind, what in (("poses", "pose sample(s)"), ("images", "image(s)")):
                if late := t.get(f"{kind}_out_of_order"):
                    lines.append(
                        f"trial {t['trial']} ({t['bag']}): {late} {what} came after one "
                        "stamped later (arrived late) and were taken in stamp order"
                    )
            if len(depths := t.get("image_bits") or []) > 1:
                lines.append(
                    f"trial {t['trial']} ({t['bag']}): its 16-bit images were scaled from "
                    f"{depths[0]} to {depths[-1]} bits, each from the depth its largest value "
                    f"needs, so darker frames came out brighter: --image-bits {depths[-1]} "
                    "scales them all alike"
                )
            if (offset := t.get("record_clock_offset")) is not None:
                lines.append(
                    f"trial {t['trial']} ({t['bag']}): the pose stamps are "
                    f"{abs(offset):.3f} s {'behind' if offset > 0 else 'ahead of'} the bag's "
                    "record times (another clock: simulated time?); the utterances and images "
                    "without a stamp "
                    f"({t['unstamped_moved_to_stamp_clock']}) were placed on the stamps' clock"
                )
            for kind in ("images", "utterances"):
                if unread := t.get(f"{kind}_unread"):
                    read = t[f"{kind}_in_bag"]
                    lines.append(
                        f"trial {t['trial']} ({t['bag']}): the bag's index counts "
                        f"{read + unread} {kind[:-1]} message(s), {read} could be read: "
                        f"{unread} are counted in its metadata.yaml only (not written when "
                        "recorded?)"
                    )
            if (warning := self._unread_pieces(t)) is not None:
                lines.append(warning)
            if note := image_clock_note(t):
                lines.append(f"warning: {note}")
            if t.get("pose_frame_via_tf"):
                lines.append(
                    f"trial {t['trial']} ({t['bag']}): poses in frame {t['pose_frame']} placed "
                    f"on the map through tf {t['pose_frame_via_tf']}"
                )
            lines.append(
                f"trial {t['trial']} ({t['bag']}): images {t['images_kept']} kept of "
                f"{t['images_in_bag']} ({t['images_no_pose']} without pose, "
                f"{t['images_thinned']} thinned by --min-distance/--min-interval, "
                f"{t['images_undecodable']} undecodable); utterances {t['utterances_kept']} of "
                f"{t['utterances_in_bag']} ({t['utterances_no_pose']} without pose, "
                f"{t['utterances_empty']} without words)"
            )
        return "\n".join(lines)

    def _unread_pieces(self, t: dict[str, object]) -> str | None:
        """The warning of trial ``t``, a storage file of a split ROS 2 recording given alone,
        that the recording's other pieces (``storage_files_not_read``) were not read; once per
        import for pieces of one recording given as bags of their own (each trial lists the same
        pieces not given), at the first of them; None for the others and without such pieces."""
        others = list(t.get("storage_files_not_read") or [])  # type: ignore[call-overload]
        if not others:
            return None
        folder = Path(str(t["bag"])).parent
        given = [
            u
            for u in self.trials
            if Path(str(u["bag"])).parent == folder and u.get("storage_files_not_read") == others
        ]
        if given[0] is not t:
            return None
        if len(given) == 1:
            return (
                f"warning: trial {t['trial']} ({t['bag']}): {folder} holds {len(others)} more "
                f"storage file(s) of its recording ({', '.join(others)}; rosbag2 split it), not "
                "read: give the folder to read the whole recording as one trial (without its "
                "metadata.yaml, `ros2 bag reindex` writes one)"
            )
        trials = ", ".join(str(u["trial"]) for u in given)
        names = ", ".join(Path(str(u["bag"])).name for u in given)
        more, them = plural(len(others), "more piece"), "it" if len(others) == 1 else "them"
        return (
            f"warning: trials {trials} ({names}) are pieces of one recording (rosbag2 split "
            f"it), each read as a trial of its own; {folder} holds {more} of it, not given, not "
            f"read: {', '.join(others)} (give {them} too to read the rest of the recording)"
        )


def write_skipped(path: Path, skipped: Sequence[SkippedObservation]) -> None:
    """``skipped.csv``: one row per skipped observation (``trial,bag,topic,kind,stamp,reason``;
    the stamp in seconds, to the nanosecond)."""
    import csv

    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["trial", "bag", "topic", "kind", "stamp", "reason"])
        for s in skipped:
            writer.writerow([s.trial, s.bag, s.topic, s.kind, f"{s.stamp:.9f}", s.reason])
