"""Reading and writing the single files of a house folder in the public dataset layout.

The helpers behind :func:`spcopyro.data.load_house` and :func:`spcopyro.data.save_house`: numeric
CSV files (one row per line), St.csv's line of utterances, the per-trial ``pose_K.csv`` /
``word_K.csv`` files and the camera image folders ``img_K/`` (the files of further modalities,
``modality_<name>.csv``: :mod:`~spcopyro.data.modality_files`). A malformed file raises
:class:`~spcopyro.data.observations.DataFormatError` naming the file, the 1-based line and
column and the offending value (shortened when long: :func:`spcopyro._util.messages.echo`).
``tests/test_loader_fuzz.py`` corrupts a house's files at random to check that nothing else
escapes.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from spcopyro._util.messages import echo, listed
from spcopyro.data.observations import DataFormatError
from spcopyro.data.text import hidden_words_warning, tokenize, unsegmented

logger = logging.getLogger("spcopyro")

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")  # camera images looked for in ROOM/img_K/
_POSE_XY_ATOL = 1e-6  # metres: pose_K.csv x, y must agree with Xtx.csv / Xty.csv to this


def _read_text(path: Path) -> str:
    """The file's text (UTF-8, a byte-order mark dropped); DataFormatError naming the line and
    the bytes where it is not UTF-8."""
    content = path.read_bytes()
    if content[:2] in (b"\xff\xfe", b"\xfe\xff"):  # Excel's "Unicode text", Notepad's "Unicode"
        raise DataFormatError(
            path, "UTF-16 text (its byte-order mark), not UTF-8: save it as UTF-8"
        )
    try:
        return content.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = content[: error.start].count(b"\n") + 1
        raise DataFormatError(
            path,
            f"not UTF-8 text ({error.reason})",
            line=line,
            value=content[error.start : error.end],
        ) from None


def _read_lines(path: Path) -> list[str]:
    """The file's lines (no line ends: LF, CRLF, or CR alone in a file without LF, as the old
    Mac line ends of Excel's "CSV (Macintosh)"); blank lines at the end are dropped."""
    if not path.is_file():
        raise FileNotFoundError(f"{path}: required file not found")
    text = _read_text(path)
    lines = [line.rstrip("\r") for line in text.split("\n" if "\n" in text else "\r")]
    while lines and not lines[-1].strip():
        lines.pop()
    return lines


_NUMBER = re.compile(
    r"\s*[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?\s*|\s*[+-]?(inf|infinity|nan)\s*",
    re.IGNORECASE,
)  # a plain decimal number: no digit separators (1_000), no digits of other scripts


def _parse_number(path: Path, text: str, line: int, column: int | None) -> float:
    try:
        if _NUMBER.fullmatch(text) is None:
            raise ValueError(text)
        value = float(text)
    except ValueError:
        raise DataFormatError(
            path, "not a number", line=line, column=column, value=text.strip()
        ) from None
    if not math.isfinite(value):
        raise DataFormatError(path, "not finite", line=line, column=column, value=text.strip())
    return value


_ROW = re.compile(rf"(?:{_NUMBER.pattern})(?:,(?:{_NUMBER.pattern}))*", re.IGNORECASE)
"""A line of comma-separated :data:`_NUMBER` s (one match a line, not one a number)."""


def _read_matrix(path: Path, columns: int | None = None, names: str = "") -> np.ndarray:
    """Comma-separated numbers, one row per line; every row the same length -> ``[R, C]``
    (``names``: what the ``columns`` are, for the message about a row of another length).

    A well-formed file is checked a line at a time and converted at once (the public houses'
    Ft.csv: 45,000 numbers); any other goes through the number-by-number reading, which names
    the line, column and value that is wrong.
    """
    lines = _read_lines(path)
    if lines and all(_ROW.fullmatch(line) for line in lines):
        width = lines[0].count(",") + 1
        if all(line.count(",") + 1 == width for line in lines) and columns in (None, width):
            values = np.array([float(t) for t in ",".join(lines).split(",")], dtype=np.float64)
            if np.isfinite(values).all():
                return values.reshape(len(lines), width)
    rows: list[list[float]] = []
    width = columns
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            raise DataFormatError(path, "empty line", line=number, value=line)
        fields = line.split(",")
        if width is None:
            width = len(fields)
        hint = _separator_hint(line)
        if (width == 1 and _DECIMAL_COMMA.fullmatch(line)) or (  # Xtx.csv's -1,18 for -1.18
            width == 2 and len(fields) == 1 and _DECIMAL_COMMA.fullmatch(lines[0])
        ):  # a one-column Ft.csv's 0,25 then a 1
            hint = (" (a decimal comma, as a spreadsheet in some languages writes it: these files "
                    "write decimals with a point)")  # fmt: skip
        if len(fields) != width:
            raise DataFormatError(
                path,
                f"row has {len(fields)} values, expected {width}{names}{hint}",
                line=number,
                value=line,
            )
        try:
            row = [_parse_number(path, text, number, c) for c, text in enumerate(fields, 1)]
        except DataFormatError as error:
            if number == 1 and not hint and _is_header(fields):  # x,y,qz,qw or Xtx
                raise DataFormatError(
                    path,
                    "not a number (a header line? these files have none: their first line is "
                    "the first row of numbers)",
                    line=1,
                    column=error.column,
                    value=error.value,
                ) from None
            trailing = line.rstrip().endswith(",")  # the hint holds for the last, empty value
            if not hint or (trailing and error.column != len(fields)):
                raise
            raise DataFormatError(path, f"not a number{hint}", line=number, value=line) from None
        rows.append(row)
    return np.array(rows, dtype=np.float64).reshape(len(rows), width or 0)


_LETTER = re.compile(r"[^\W\d_]")


def _is_header(fields: Sequence[str]) -> bool:
    """Whether a first line's ``fields`` read as column names (``x,y,qz,qw``, ``Xtx``,
    ``class_0,class_1``): none of them a number, and a letter in one."""
    return not any(_NUMBER.fullmatch(f) for f in fields) and any(map(_LETTER.search, fields))


_SEPARATORS = {" ": "spaces", "\t": "tabs", ";": "semicolons"}
_DECIMAL_COMMA = re.compile(r"\s*[+-]?[0-9]+,[0-9]+([eE][+-]?[0-9]+)?\s*")  # one number: -1,18


def _separator_hint(line: str) -> str:
    """A hint for a line of numbers separated by something other than commas (np.savetxt's
    spaces, a spreadsheet's tabs or semicolons) or ending with a comma, else ``""``."""
    if ";" in line and "," in line:  # a spreadsheet's decimal commas: 0,5;1,25
        return (
            " (semicolons and decimal commas, as a spreadsheet in some languages writes them: "
            "these files separate numbers with commas and write decimals with a point)"
        )
    if line.rstrip().endswith(","):
        return " (the line ends with a comma: these files end a row with its last number)"
    if "," in line:
        return ""
    for separator, name in _SEPARATORS.items():
        parts = line.strip().split(separator)
        if len(parts) > 1 and all(_NUMBER.fullmatch(part) for part in parts if part.strip()):
            return (
                f" (numbers separated by {name}: these files separate them with commas, as "
                "np.savetxt(path, values, delimiter=',') writes them)"
            )
    return ""


_WHOLE_PAIR = re.compile(r"\s*([0-9]+),([0-9]+)\s*")  # 0,25: a decimal comma, or two counts


def refuse_decimal_commas(path: Path) -> None:
    """DataFormatError, naming the line and the value, for a file of one number a line written
    with decimal commas (``0,25``, as a spreadsheet in some languages writes it), which reads as
    two columns of whole numbers: every line two whole numbers, and the second written with a
    leading zero (``0,05``: no count is written so), or every line a value in [0, 1] read with
    its comma as a point (``0,25``, ``1,0``; not all 0 or 1, as two columns of counts may be)."""
    lines = _read_lines(path)  # no blank line: _read_matrix read it
    pairs = [_WHOLE_PAIR.fullmatch(line) for line in lines]
    if not lines or not all(pairs):
        return
    fractions = [(m.group(1), m.group(2)) for m in pairs if m is not None]
    padded = next((k for k, (_, f) in enumerate(fractions) if len(f) > 1 and f[0] == "0"), None)
    unit = all(w == "0" or (w == "1" and not f.strip("0")) for w, f in fractions)
    if padded is None and not (unit and any(f not in ("0", "1") for _, f in fractions)):
        return
    line = (
        padded
        if padded is not None
        else next(k for k, (_, f) in enumerate(fractions) if f not in ("0", "1"))
    )
    raise DataFormatError(
        path,
        "two whole numbers a line, as one number a line written with decimal commas reads (a "
        "spreadsheet in some languages writes 0.25 as 0,25): these files write decimals with a "
        "point; two counts a line are written 0.0,25.0 to say so",
        line=line + 1,
        value=lines[line],
    )


def read_pose_file(path: Path) -> np.ndarray:
    """A trial's ``pose_K.csv``: ``[n, 4]`` rows ``x, y, qz, qw``, one per image of the trial;
    DataFormatError naming the line and value of a header, a number that does not read or a
    row of another length. ``spcopyro features`` reads it as :func:`load_house` does."""
    return _read_matrix(path, columns=4, names=" (x, y, qz, qw)")


ROW_SUM_TOLERANCE = 0.1
"""How far from 1 an Ft.csv row may sum before loading warns of it (:func:`read_features`). A
row is a histogram of class probabilities (the public houses' sum to 1 within 1e-6, softmax
rows within float rounding) and weighs as many images as it sums to. A tenth either way passes
unsaid; percentages (rows of 100), counts, a row scaled by mistake, or flat histograms written
with too few decimals (205 classes at two decimals sum to about 0.85) are warned of."""


def _row_sum_warning(path: Path, sums: np.ndarray) -> str:
    """The warning for Ft.csv rows whose ``sums`` ``[T]`` are nonzero and further than
    :data:`ROW_SUM_TOLERANCE` from 1, or ``""`` where there are none."""
    off = np.flatnonzero((sums > 0) & (np.abs(sums - 1.0) > ROW_SUM_TOLERANCE))  # [n]
    if not off.size:
        return ""
    shown = [f"line {i + 1}: {sums[i]:.6g}" for i in off.tolist()]
    nonzero = sums[sums > 0]  # [m]
    percent = bool(np.all(np.abs(nonzero - 100.0) <= 100.0 * ROW_SUM_TOLERANCE))
    return (
        f"{path}: {off.size} of {sums.size} image feature rows do not sum to 1 ({listed(shown, 3)})"
        ": a row is a histogram of class probabilities, and one that sums to s weighs as much as "
        "s images against the words; "
        + ("percentages? divide every value by 100" if percent else
           "scale each row to sum to 1 (f / f.sum(axis=1, keepdims=True)) unless that weight "
           "is meant")
    )  # fmt: skip


def read_features(path: Path) -> np.ndarray:
    """``[T, K]`` Ft.csv's image features, checked: DataFormatError for an empty file or a
    negative feature; warnings (logger ``spcopyro``) for all-zero rows, rows that do not sum to
    about 1 (:data:`ROW_SUM_TOLERANCE`) and a single column."""
    features = _read_matrix(path)  # [T, K]
    if features.shape[1] == 2 and (features == np.round(features)).all():
        refuse_decimal_commas(path)  # a one-column file's 0,25 reads as 0 and 25
    if features.shape[0] == 0:
        raise DataFormatError(path, "holds no image features (empty file)")
    if (features < 0).any():
        row, col = np.argwhere(features < 0)[0]
        raise DataFormatError(
            path,
            "negative image feature (a row is a histogram of class probabilities, each >= 0: "
            "logits or log-probabilities need a softmax or exp first)",
            line=int(row) + 1,
            column=int(col) + 1,
            value=float(features[row, col]),
        )
    sums = features.sum(axis=1)  # [T]
    zero_rows = np.flatnonzero(sums == 0)  # [z]
    if zero_rows.size:  # issue 22 item 4: an all-zero Ft.csv used to fit without a word
        every = zero_rows.size == features.shape[0]
        logger.warning(
            "%s: %s image feature rows are all zero (%s): %s",
            path,
            "all" if every else f"{zero_rows.size} of {features.shape[0]}",
            "lines " + listed([str(r + 1) for r in zero_rows.tolist()], 5),
            "the images carry no information (was the feature extraction run?)"
            if every
            else "those images carry no information",
        )
    if features.shape[1] == 1:  # a class id or a score per image, not a histogram
        logger.warning(
            "%s: one column: a row is a histogram over image classes, one column per class "
            "(spcopyro features writes them), and over a single class every image says the "
            "same: the images carry no information (a class id per image? write it as a row "
            "with 1 in that class's column)",
            path,
        )
    else:  # percentages or counts weigh an image as 100 or n images, silently
        off = _row_sum_warning(path, sums)
        if off:
            logger.warning("%s", off)
    return features


_FT_HINT = (" (Ft.csv has a row per image: after new images, e.g. a re-import, make it again "
            "with spcopyro features HOUSE --out HOUSE/Ft.csv --overwrite)")  # fmt: skip


_ST_HINT = (" (St.csv separates utterances with commas: a sentence with a comma in it is two "
            "entries)")  # fmt: skip


def _read_column(path: Path, expected: int, data_file: Path) -> np.ndarray:
    """One number per line -> ``[R]``; R must equal ``expected`` (the rows of ``data_file``)."""
    values = _read_matrix(path, columns=1)[:, 0]  # [R]
    if values.shape[0] != expected:
        raise DataFormatError(
            path,
            f"holds {values.shape[0]} values but {data_file.name} holds {expected} entries"
            + (_FT_HINT if data_file.name == "Ft.csv" else "")
            + (_ST_HINT if data_file.name == "St.csv" and values.shape[0] < expected else ""),
        )
    return values


def _read_utterances_line(path: Path) -> tuple[tuple[str, ...], ...]:
    """St.csv: one line of comma-separated utterances, each tokenised."""
    lines = _read_lines(path)
    if len(lines) > 1:  # one utterance a line, as word_K.csv holds them
        raise DataFormatError(
            path,
            "must be one line of comma-separated utterances (one a line is word_K.csv's layout: "
            "join the lines with commas)",
            line=2,
            value=lines[1],
        )
    if not lines or not lines[0].strip():
        raise DataFormatError(
            path,
            "holds no words (empty vocabulary); a house where nothing was heard yet leaves out "
            "St.csv, StXtx.csv, StXty.csv and word_K.csv (it is fitted on its images alone)",
        )
    utterances, unspaced = [], []
    entries = lines[0].split(",")
    for entry_number, entry in enumerate(entries, start=1):
        tokens = tokenize(entry)
        if not tokens:
            hint = (
                " (the line ends with a comma: St.csv puts commas between utterances, none after "
                "the last)"
                if entry_number == len(entries) > 1 and not entry.strip()
                else f" (an utterance is placed by line {entry_number} of StXtx.csv and "
                "StXty.csv: remove it there too, or write what was said)"
            )
            raise DataFormatError(
                path, f"utterance {entry_number} holds no words{hint}", line=1, value=entry
            )
        if any(unsegmented(token) for token in tokens):
            unspaced.append(f"utterance {entry_number} {echo(entry.strip())}")
        utterances.append(tokens)
    hidden = hidden_words_warning(utterances, path)
    if hidden:  # 'kit\u200bchen' prints as 'kitchen' but is another word
        logger.warning("%s", hidden)
    if unspaced:  # ここは台所です: one word, heard nowhere else (docs/data.md)
        logger.warning(
            "%s, line 1: %d utterance(s) look like sentences written without spaces, each read "
            "as one word: %s (nothing splits such text: write it with spaces between its "
            "words, as MeCab's mecab -Owakati does)", path, len(unspaced), listed(unspaced, 3),
        )  # fmt: skip
    return tuple(utterances)


def _trial_id(path: Path, digits: str, kind: str, found: dict[int, Path]) -> int:
    """The trial id K of ``<kind>_K``; DataFormatError if it does not fit int64 or a file (or
    folder) of ``found`` has the same K written differently (``pose_1.csv``, ``pose_01.csv``)."""
    trial = int(digits)
    if trial >= 2**63:
        raise DataFormatError(path, f"{kind} trial id does not fit a 64-bit integer", value=digits)
    if trial in found:
        raise DataFormatError(
            path, f"trial {trial} has two {kind} entries (also {found[trial].name})", value=digits
        )
    return trial


def _trial_files(room: Path, prefix: str) -> dict[int, Path]:
    """``ROOM/<prefix>_K.csv`` by trial id K (ascending); a file whose name starts like one but
    is not ``<prefix>_<digits>.csv`` is logged as ignored."""
    pattern = re.compile(rf"{prefix}_([0-9]+)\.csv")
    found: dict[int, Path] = {}
    for entry in sorted(room.iterdir()):
        match = pattern.fullmatch(entry.name)
        if match and entry.is_file():
            found[_trial_id(entry, match.group(1), f"{prefix}_K.csv", found)] = entry
        elif entry.name.startswith(f"{prefix}_") and entry.name.lower().endswith(".csv"):
            logger.warning("%s: ignored (a trial file is named %s_<digits>.csv)", entry, prefix)
    return dict(sorted(found.items()))


def _read_trials(
    room: Path,
    image_xy: np.ndarray,
    utterances: tuple[tuple[str, ...], ...],
    files: dict[str, Path],
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, list[int], list[int]]:
    """image_trial [T], word_trial [U], image_yaw [T] or None, trial ids, images per trial."""
    num_images, num_utterances = image_xy.shape[0], len(utterances)
    poses, words = _trial_files(room, "pose"), _trial_files(room, "word")
    if not poses and not words:
        return (
            np.zeros(num_images, dtype=np.int64),
            np.zeros(num_utterances, dtype=np.int64),
            None,
            [0],
            [num_images],
        )
    without_images = num_images == 0 and not poses  # a house of words only: trials by word files
    without_words = num_utterances == 0 and not words  # a house of images only: by pose files
    for have, other, kind in ((poses, words, "word"), (words, poses, "pose")):
        missing = sorted(set(have) - set(other))
        if missing and not without_images and not (kind == "word" and without_words):
            raise DataFormatError(
                room / f"{kind}_{missing[0]}.csv",
                f"missing: trial{'s' if len(missing) > 1 else ''} "
                f"{', '.join(map(str, missing))} ha{'ve' if len(missing) > 1 else 's'} a "
                f"{'pose' if kind == 'word' else 'word'} file but no {kind} file",
            )
    trials = list(words if without_images else poses)
    pose_rows = [np.zeros((0, 4)) if without_images else read_pose_file(poses[k]) for k in trials]
    image_counts = [p.shape[0] for p in pose_rows]
    if sum(image_counts) != num_images:
        raise DataFormatError(
            files["Ft"],
            f"holds {num_images} rows but the pose files hold {sum(image_counts)} ("
            + ", ".join(f"{poses[k].name}: {n}" for k, n in zip(trials, image_counts, strict=True))
            + ")",
            value=num_images,
        )
    pose = np.concatenate(pose_rows, axis=0)  # [T, 4] x, y, qz, qw
    first_row = np.cumsum([0, *image_counts])  # [n_trials + 1] first image of each trial

    def locate(i: int) -> tuple[Path, int]:
        """Pose file and 1-based line of image i."""
        k = int(np.searchsorted(first_row, i, side="right")) - 1
        return poses[trials[k]], i - int(first_row[k]) + 1

    mismatch = ~np.isclose(pose[:, :2], image_xy, rtol=0.0, atol=_POSE_XY_ATOL).all(axis=1)
    if mismatch.any():
        i = int(np.flatnonzero(mismatch)[0])
        path, line = locate(i)
        raise DataFormatError(
            path,
            f"x, y differ from {files['Xtx'].name}/{files['Xty'].name} line {i + 1} "
            f"({image_xy[i].tolist()})",
            line=line,
            value=pose[i, :2].tolist(),
        )
    zero = (pose[:, 2] == 0) & (pose[:, 3] == 0)
    if zero.any():
        i = int(np.flatnonzero(zero)[0])
        path, line = locate(i)
        raise DataFormatError(
            path,
            "quaternion (qz, qw) is zero",
            line=line,
            value=pose[i].tolist(),
        )
    yaw = None if without_images else 2.0 * np.arctan2(pose[:, 2], pose[:, 3])  # [T] about z

    said: dict[int, list[tuple[str, list[str]]]] = {}  # trial -> its lines and their tokens
    for k in trials:
        said[k] = []
        for number, line in enumerate(_read_lines(words[k]) if k in words else (), start=1):
            tokens = tokenize(line)
            if not tokens:
                raise DataFormatError(words[k], "utterance holds no words", line=number, value=line)
            said[k].append((line, tokens))
    word_counts = [len(said[k]) for k in trials]
    # The counts first: an empty or short word file was reported as the first line after it
    # that no longer matched St.csv.
    if sum(word_counts) != num_utterances:
        comma = next(
            (f"; {words[k].name} line {n} holds a comma, which St.csv reads as the end of an "
             f"utterance (write it without): {echo(line)}"
             for k in trials for n, (line, _) in enumerate(said[k], start=1) if "," in line),
            "",
        )  # fmt: skip
        raise DataFormatError(
            files["St"],
            f"holds {num_utterances} utterances but the word files hold {sum(word_counts)} ("
            + ", ".join(f"{words[k].name}: {n}" for k, n in zip(trials, word_counts, strict=True))
            + f"){comma}",
            value=num_utterances,
        )
    position = 0
    for k in trials:
        for number, (line, tokens) in enumerate(said[k], start=1):
            if tokens != utterances[position]:
                raise DataFormatError(
                    words[k],
                    f"differs from {files['St'].name} utterance {position + 1} "
                    f"({echo(' '.join(utterances[position]))})",
                    line=number,
                    value=line,
                )
            position += 1
    trial_ids = np.array(trials, dtype=np.int64)  # [n_trials]
    return (
        np.repeat(trial_ids, image_counts),
        np.repeat(trial_ids, word_counts),
        yaw,
        trials,
        image_counts,
    )


def _image_paths(
    room: Path, trials: Sequence[int], counts: Sequence[int]
) -> tuple[Path, ...] | None:
    """Camera images ROOM/img_K/* (sorted by name) for every trial, or None (logged) if absent
    or inconsistent with the rows of Ft.csv."""
    folders: dict[int, Path] = {}
    for entry in sorted(room.iterdir()):
        if entry.is_dir() and (m := re.fullmatch(r"img_([0-9]+)", entry.name)):
            try:
                folders[_trial_id(entry, m.group(1), "img_K", folders)] = entry
            except DataFormatError as error:
                logger.warning("%s; image_paths left None", error)
                return None
    if not folders:
        return None
    poses = {
        int(m.group(1)): entry.name
        for entry in room.iterdir()
        if (m := re.fullmatch(r"pose_([0-9]+)\.csv", entry.name)) and entry.is_file()
    }  # the file that gives each trial's count of images (else Ft.csv's rows)
    paths: list[Path] = []
    for k, n in zip(trials, counts, strict=True):
        folder = folders.get(k)
        if folder is None:
            if n == 0:
                continue
            logger.warning("%s: no folder img_%d for trial %d; image_paths left None", room, k, k)
            return None
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if len(files) != n:
            counted = (
                f"{poses[k]} holds {n} poses, one per image of trial {k}"
                if k in poses
                else f"Ft.csv holds {n} rows"
            )
            logger.warning(
                "%s holds %d images but %s: the images are not paired with Ft.csv's rows "
                "(image_paths left None)",
                folder,
                len(files),
                counted,
            )
            return None
        paths.extend(files)
    extra = sorted(set(folders) - set(trials))
    if extra:
        missing = f"; there is no pose_{extra[0]}.csv" if poses else ""
        logger.warning(
            "%s: img_%d belongs to no trial of the house (its trials: %s%s); image_paths left "
            "None", room, extra[0], ", ".join(map(str, trials)), missing,
        )  # fmt: skip
        return None
    return tuple(paths)


def _format_float(value: float) -> str:
    return repr(float(value))  # shortest string that reads back to the same float


def _write_lines(path: Path, lines: Iterable[str], trailing_newline: bool = True) -> None:
    text = "\n".join(lines)
    if trailing_newline and text:
        text += "\n"
    path.write_text(text, encoding="utf-8")
