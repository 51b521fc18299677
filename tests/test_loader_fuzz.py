"""A fuzz test of the loaders: corrupted house folders give a clear error or a correct load.

A small house with two trials, a further modality, ground truth and its map is written once by
:func:`spcopyro.data.save_house` (the map by :func:`spcopyro.maps.save_map`). Then a seeded
generator (:class:`random.Random`, no extra dependency) applies random corruptions to its files
-- lines dropped, duplicated or cut, numbers replaced by garbage, NaN, inf, 1e308 or negative
values, columns deleted or added, files emptied, deleted, swapped or filled with bytes that are
not UTF-8, yaml keys renamed and values replaced, the map image deleted or damaged -- a few
hundred times, and :func:`spcopyro.data.load_house` must, every time, either

* raise one of the documented errors (``DataFormatError``, ``MapFormatError``, ``ValueError``,
  ``FileNotFoundError``) whose message names a file of the house (no other exception type, no
  error from deep inside numpy that leaves the reader guessing which file is wrong), or
* load, with exactly as many images, utterances, further observations and images per trial as
  the corrupted files hold, counted here independently from the files' text.

The cases that found loader bugs are pinned as regression tests at the end.
"""

from __future__ import annotations

import random
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from spcopyro._util.messages import echo
from spcopyro.data import (
    DataFormatError,
    House,
    ModalityObservations,
    Observations,
    load_house,
    save_house,
)
from spcopyro.maps import FREE, OCCUPIED, MapFormatError, OccupancyGrid

NAME = "room"
CASES = 300
CLEAR_ERRORS = (DataFormatError, MapFormatError, ValueError, FileNotFoundError)

GARBAGE_NUMBERS = (
    "abc", "nan", "NaN", "inf", "-inf", "Infinity", "1e308", "-1e308", "1e309", "-1", "-0.5",
    "", " ", "0x10", "1,5", "1;5", "\x00", "\ufeff1", "１", "1_000", "--1", "1e", ".", "+",
    "1e-320",
)  # fmt: skip
GARBAGE_YAML_VALUES = (
    "abc", "-1", "0", ".nan", ".inf", "[1, 2]", "{a: 1}", "", "1e308", "null", "true", "2",
    "[.inf, 0, 0]", "[0, 0]", "'0.05'", "[0, 0, 0.5]", "\t", "!!binary AAAA", "&a 1", "*b",
    "0.5", "missing.pgm", "../room/Ft.csv", "/nonexistent/map.pgm",
)  # fmt: skip
YAML_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode")


def small_house() -> House:
    """A 6 x 8 map, 7 images (K = 4) and 5 utterances over two trials, a further modality of 3
    observations, ground truth with two categories."""
    occupancy = np.full((6, 8), OCCUPIED, dtype=np.int8)
    occupancy[1:5, 1:7] = FREE
    grid = OccupancyGrid(occupancy, resolution=0.5, origin=(-1.0, -1.0, 0.0))
    rng = np.random.default_rng(0)
    features = rng.dirichlet(np.ones(4), size=7)  # [7, 4]
    image_xy = np.column_stack([rng.uniform(-0.4, 1.9, 7), rng.uniform(-0.4, 0.9, 7)])  # [7, 2]
    word_xy = np.column_stack([rng.uniform(-0.4, 1.9, 5), rng.uniform(-0.4, 0.9, 5)])  # [5, 2]
    objects = ModalityObservations(
        name="objects",
        items=("cup", "chair"),
        positions=image_xy[:3],
        trials=np.array([0, 0, 1]),
        counts=np.array([[1.0, 0.0], [2.0, 1.0], [0.0, 3.0]]),
    )
    observations = Observations(
        image_features=features,
        image_xy=image_xy,
        image_trial=np.array([0, 0, 0, 0, 1, 1, 1]),
        utterances=(("kitchen",), ("here", "is", "the", "kitchen"), ("bed",), ("bed",), ("sofa",)),
        word_xy=word_xy,
        word_trial=np.array([0, 0, 1, 1, 1]),
        image_yaw=rng.uniform(-3.0, 3.0, 7),
        modalities=(objects,),
    )
    truth = np.where(occupancy == FREE, 0, -1)
    truth[1:5, 4:7] = 1
    return House(NAME, grid, observations, truth=truth, category_names=("kitchen", "bedroom"))


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> dict[str, bytes]:
    """The house's files (path relative to the dataset root -> bytes), as save_house wrote them."""
    root = tmp_path_factory.mktemp("pristine")
    save_house(small_house(), root)
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def write_tree(root: Path, files: dict[str, bytes]) -> None:
    if root.exists():
        shutil.rmtree(root)
    for name, content in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content)
    (root / NAME).mkdir(parents=True, exist_ok=True)


# ------------------------------------------------------------------------------ corruptions


def _lines(content: bytes) -> list[str]:
    return content.decode("utf-8", errors="surrogateescape").split("\n")


def _join(lines: list[str]) -> bytes:
    return "\n".join(lines).encode("utf-8", errors="surrogateescape")


def _pick_line(rng: random.Random, lines: list[str]) -> int:
    return rng.randrange(len(lines)) if lines else 0


def drop_line(rng, content):
    lines = _lines(content)
    if lines:
        del lines[_pick_line(rng, lines)]
    return _join(lines)


def duplicate_line(rng, content):
    lines = _lines(content)
    if lines:
        i = _pick_line(rng, lines)
        lines.insert(i, lines[i])
    return _join(lines)


def cut_line(rng, content):
    lines = _lines(content)
    if lines:
        i = _pick_line(rng, lines)
        lines[i] = lines[i][: rng.randrange(len(lines[i]) + 1)]
    return _join(lines)


def truncate_file(rng, content):
    return content[: rng.randrange(len(content) + 1)]


def replace_number(rng, content):
    lines = _lines(content)
    if lines:
        i = _pick_line(rng, lines)
        fields = lines[i].split(",")
        fields[rng.randrange(len(fields))] = rng.choice(GARBAGE_NUMBERS)
        lines[i] = ",".join(fields)
    return _join(lines)


def delete_column(rng, content):
    lines = _lines(content)
    column = rng.randrange(4)
    every = rng.random() < 0.5
    chosen = _pick_line(rng, lines)
    for i, line in enumerate(lines):
        fields = line.split(",")
        if (every or i == chosen) and column < len(fields) and line:
            del fields[column]
            lines[i] = ",".join(fields)
    return _join(lines)


def add_column(rng, content):
    lines = _lines(content)
    value = rng.choice(("0.5", "0", "x", ""))
    every = rng.random() < 0.5
    chosen = _pick_line(rng, lines)
    for i, line in enumerate(lines):
        if (every or i == chosen) and line:
            lines[i] = f"{line},{value}"
    return _join(lines)


def empty_file(rng, content):
    return rng.choice((b"", b"\n", b"  \n\n", b","))


def binary_garbage(rng, content):
    garbage = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40)))
    at = rng.randrange(len(content) + 1)
    return content[:at] + garbage + content[at:]


def yaml_value(rng, content):
    lines = _lines(content)
    keyed = [i for i, line in enumerate(lines) if ":" in line]
    if keyed:
        i = rng.choice(keyed)
        key = lines[i].split(":", 1)[0]
        lines[i] = f"{key}: {rng.choice(GARBAGE_YAML_VALUES)}"
    return _join(lines)


def yaml_key(rng, content):
    lines = _lines(content)
    keyed = [i for i, line in enumerate(lines) if ":" in line]
    if keyed:
        i = rng.choice(keyed)
        value = lines[i].split(":", 1)[1]
        key = rng.choice((*YAML_KEYS, "Image", "resolution ", "", "- image", "? x"))
        lines[i] = f"{key}:{value}"
    return _join(lines)


def crlf_and_bom(rng, content):
    """Windows line ends and a byte-order mark: harmless, the file must read the same."""
    return b"\xef\xbb\xbf" + content.replace(b"\n", b"\r\n")


def renamed(rng: random.Random, name: str) -> str:
    """Another name for a file: a trial number written differently, or a bad modality name."""
    folder, _, base = name.rpartition("/")
    stem, dot, suffix = base.partition(".")
    prefix, _, number = stem.rpartition("_")
    if number.isdigit():
        other = rng.choice((f"0{number}", "99999999999999999999", str(int(number) + 7), "-1",
                            f"{number} ", "x"))  # fmt: skip
        return f"{folder}/{prefix}_{other}{dot}{suffix}"
    if stem.startswith("modality_"):
        other = rng.choice(("Objects", "images", "", "9lives", "objects2"))
        return f"{folder}/modality_{other}{dot}{suffix}"
    return f"{folder}/{stem}{rng.choice(('.txt', '.CSV', '_old'))}{dot}{suffix}"


TEXT_CORRUPTIONS = (
    drop_line, duplicate_line, cut_line, truncate_file, replace_number, replace_number,
    delete_column, add_column, empty_file, binary_garbage, crlf_and_bom,
)  # fmt: skip
YAML_CORRUPTIONS = (yaml_value, yaml_value, yaml_key, drop_line, duplicate_line, cut_line,
                    binary_garbage, empty_file)  # fmt: skip


def no_bytes(rng, content):
    return b""


BINARY_CORRUPTIONS = (truncate_file, binary_garbage, no_bytes)


def corrupt(rng: random.Random, files: dict[str, bytes]) -> tuple[dict[str, bytes], list[str]]:
    """1-3 random corruptions of ``files``; returns the new files and what was done."""
    files = dict(files)
    done = []
    for _ in range(rng.choice((1, 1, 1, 2, 3))):
        name = rng.choice(sorted(files))
        kind = rng.random()
        if kind < 0.06:
            del files[name]
            done.append(f"deleted {name}")
            continue
        if kind < 0.12:
            other = rng.choice(sorted(files))
            files[name], files[other] = files[other], files[name]
            done.append(f"swapped {name} and {other}")
            continue
        if kind < 0.22:
            other = renamed(rng, name)
            copy = kind < 0.18  # a stray copy beside the file (a backup), or a renamed file
            files[other] = files[name] if copy else files.pop(name)
            done.append(f"{'copied' if copy else 'renamed'} {name} to {other}")
            continue
        if name.endswith((".yaml", ".yml")):
            pool = YAML_CORRUPTIONS
        elif name.endswith((".csv", ".json")):
            pool = TEXT_CORRUPTIONS
        else:
            pool = BINARY_CORRUPTIONS
        operation = rng.choice(pool)
        files[name] = operation(rng, files[name])
        done.append(f"{operation.__name__} {name}")
    return files, done


# ------------------------------------------------------------------------------ independent counts


def _data_lines(content: bytes) -> list[str]:
    """The lines of a CSV file that hold something (a trailing newline or blank end ignored)."""
    return [line for line in content.decode("utf-8-sig").split("\n") if line.strip()]


def expected_counts(files: dict[str, bytes]) -> dict[str, object]:
    """What a correct load must report, counted from the files' text alone."""
    room = NAME + "/"
    st = files[room + "St.csv"].decode("utf-8-sig").split("\n")[0]
    pose_files = {  # trial id -> lines, as the layout names them: pose_<digits>.csv
        int(match.group(1)): _data_lines(content)
        for name, content in files.items()
        if (match := re.fullmatch(rf"{room}pose_([0-9]+)\.csv", name))
    }
    modalities = {
        name[len(room) + 9 : -4]: len(_data_lines(content)) - 1
        for name, content in files.items()
        if name.startswith(room + "modality_")
    }
    return {
        "images": len(_data_lines(files[room + "Ft.csv"])),
        "utterances": len(st.split(",")),
        "images per trial": [len(pose_files[k]) for k in sorted(pose_files)],
        "modalities": modalities,
    }


def loaded_counts(house: House) -> dict[str, object]:
    obs = house.observations
    trials = np.unique(obs.image_trial) if obs.image_yaw is not None else []
    return {
        "images": obs.num_images,
        "utterances": obs.num_utterances,
        "images per trial": [int((obs.image_trial == k).sum()) for k in trials],
        "modalities": {m.name: m.num_observations for m in obs.modalities},
    }


def check_case(root: Path, files: dict[str, bytes], done: list[str]) -> str:
    """Load the corrupted house: a clear error naming a file of the house by its path (one
    that is there, or one the message says is missing), or a load with the right counts.
    Returns "error" or "loaded"."""
    write_tree(root, files)
    try:
        house = load_house(root / NAME)
    except CLEAR_ERRORS as error:
        message = str(error)
        named = re.findall(re.escape(str(root)) + r"/([\w.]+/[\w.]+)", message)
        assert named, (done, type(error), message)
        for name in named:
            assert name in files or "missing" in message or "not found" in message, (
                done,
                message,
            )
        return "error"
    except Exception as error:  # noqa: BLE001 - the point: nothing else may escape
        raise AssertionError(f"{done}: {type(error).__name__} escaped: {error}") from error
    assert loaded_counts(house) == expected_counts(files), done
    return "loaded"


def test_loaders_survive_random_corruption(pristine, tmp_path):
    rng = random.Random(20261122)
    outcomes = {"error": 0, "loaded": 0}
    for _ in range(CASES):
        files, done = corrupt(rng, pristine)
        outcomes[check_case(tmp_path / "house", files, done)] += 1
    # both outcomes occur: the corruptions are neither all fatal nor all harmless
    assert outcomes["error"] > CASES // 2 and outcomes["loaded"] > 10, outcomes


def test_the_pristine_house_loads(pristine, tmp_path):
    assert check_case(tmp_path / "house", pristine, ["nothing"]) == "loaded"


# ------------------------------------------------------------------------------ what it found


@pytest.fixture
def room(pristine, tmp_path) -> Path:
    """The pristine house written afresh; returns its room folder."""
    write_tree(tmp_path / "house", pristine)
    return tmp_path / "house" / NAME


def test_a_file_that_is_not_utf8_names_the_file_and_line(room):
    # found by the fuzz: UnicodeDecodeError escaped, naming no file
    lines = (room / "Ft.csv").read_bytes().split(b"\n")
    lines[2] = lines[2][:5] + b"\xff" + lines[2][5:]
    (room / "Ft.csv").write_bytes(b"\n".join(lines))
    with pytest.raises(DataFormatError, match=r"Ft\.csv, line 3: not UTF-8 text .*: b'\\xff'"):
        load_house(room)
    (room / "Ft.csv").write_bytes(b"\n".join(lines[:2] + lines[3:]))  # Ft fine, Xtx now longer
    (room / "categories.json").write_bytes(b'["kitchen", "b\xe9droom"]')
    with pytest.raises(
        DataFormatError,
        match=r"Xtx\.csv: holds 7 values but Ft\.csv holds 6"
        r" entries \(Ft\.csv has a row per image: .* spcopyro features HOUSE",
    ):
        load_house(room)  # a stale Ft.csv (new images) names the command that remakes it
    (room / "Ft.csv").write_bytes(b"\n".join(lines[:2] + [lines[3]] + lines[3:]))
    with pytest.raises(DataFormatError, match=r"categories\.json, line 1: not UTF-8"):
        load_house(room)


def test_an_empty_truth_file_is_a_data_format_error(room):
    # found by the fuzz: numpy's EOFError escaped
    (room / "truth.npy").write_bytes(b"")
    with pytest.raises(DataFormatError, match=r"truth\.npy: not a numeric \.npy array"):
        load_house(room)


@pytest.mark.parametrize("kind", ["pose", "word"])
def test_two_files_for_one_trial_are_an_error(room, kind):
    # found by the fuzz: of pose_1.csv and pose_01.csv, one was silently ignored
    shutil.copyfile(room / f"{kind}_1.csv", room / f"{kind}_01.csv")
    with pytest.raises(DataFormatError, match=rf"trial 1 has two {kind}_K\.csv entries"):
        load_house(room)


def test_a_trial_id_beyond_int64_is_an_error(room):
    for kind in ("pose", "word"):
        (room / f"{kind}_1.csv").rename(room / f"{kind}_99999999999999999999.csv")
    with pytest.raises(DataFormatError, match=r"pose_99999999999999999999\.csv: .*64-bit"):
        load_house(room)


def test_a_misnamed_trial_file_is_reported(room, caplog):
    shutil.copyfile(room / "pose_1.csv", room / "pose_1 (copy).csv")
    with caplog.at_level("WARNING", logger="spcopyro"):
        house = load_house(room)
    assert house.observations.num_images == 7
    assert "pose_1 (copy).csv: ignored" in caplog.text


@pytest.mark.parametrize("text", ["1_000", "１", "٣", "0x10"])
def test_numbers_are_plain_decimals(room, text):
    # "1_000" and digits of other scripts used to read as numbers (float() takes them)
    lines = (room / "Xtx.csv").read_text().split("\n")
    lines[1] = text
    (room / "Xtx.csv").write_text("\n".join(lines))
    with pytest.raises(DataFormatError, match=r"Xtx\.csv, line 2, column 1: not a number"):
        load_house(room)


def test_a_damaged_map_image_is_one_clear_error(room, capfd):
    (room.parent / "map" / f"{NAME}.pgm").write_bytes(b"P5\n8 6\n255\n\x01")
    with pytest.raises(MapFormatError, match=r"room\.yaml:\d+: key 'image': .* not a readable"):
        load_house(room)
    assert "imdecode" not in capfd.readouterr().err  # OpenCV's own log line is kept quiet


# ------------------------------------------------------------------------------ short echoes


def test_echo_keeps_short_values_and_cuts_long_ones():
    assert echo("0.1,abc") == "'0.1,abc'"
    assert echo([1.0, 2.0]) == "[1.0, 2.0]"
    line = ",".join(["0.0048"] * 205)  # a ragged Ft.csv row: 1434 characters
    assert echo(line) == f"{line[:80]!r}... (205 values, {len(line)} characters)"
    assert echo("x" * 81) == f"{'x' * 80!r}... (81 characters)"
    numbers = [0.5] * 1000
    assert echo(numbers).startswith("[0.5, 0.5") and "... (1000 entries, " in echo(numbers)
    assert len(echo(numbers)) < 120


def test_a_ragged_row_is_echoed_short(room):
    lines = (room / "Ft.csv").read_text().split("\n")
    lines[1] = ",".join(["0.0048"] * 205)
    (room / "Ft.csv").write_text("\n".join(lines))
    with pytest.raises(DataFormatError) as error:
        load_house(room)
    message = str(error.value)
    assert "Ft.csv, line 2: row has 205 values, expected 4" in message
    assert message.endswith("... (205 values, 1434 characters)")
    assert len(message.replace(str(room), "")) < 200  # the line itself is 1434 characters


def test_a_long_map_yaml_value_is_echoed_short(room):
    yaml_path = room.parent / "map" / f"{NAME}.yaml"
    text = yaml_path.read_text()
    start = text.index("origin:")
    end = text.index("\n", start)
    yaml_path.write_text(text[:start] + f"origin: {[0.0] * 1000}" + text[end:])
    with pytest.raises(MapFormatError, match=r"key 'origin' must be .*\.\.\. \(1000 entries") as e:
        load_house(room)
    assert len(str(e.value).replace(str(yaml_path), "")) < 250


def test_the_labels_file_of_features_head_says_the_same(tmp_path):
    from spcopyro.features.images import read_labelled_images

    labels = tmp_path / "labels.csv"
    labels.write_bytes(b"a.jpg,kitchen\nb.jpg,b\xe9droom\n")
    with pytest.raises(ValueError, match=r"labels\.csv: not UTF-8 text"):
        read_labelled_images(labels)
    labels.write_text("a.jpg,kitchen\n" + ",".join(["b.jpg"] * 300) + "\n")
    with pytest.raises(ValueError, match=r"labels\.csv, line 2: .*\.\.\. \(300 values, 1799 char"):
        read_labelled_images(labels)


def test_a_far_off_position_names_its_file_and_line(room):
    """Issue 22 item 10: a 1e308 position gave "xy is too far from the map origin to index a
    cell" without a file or line."""
    lines = (room / "StXty.csv").read_text().splitlines()
    lines[2] = "1e308"
    (room / "StXty.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DataFormatError, match=r"StXty\.csv, line 3: a position farther than"):
        load_house(room)


def test_a_huge_feature_is_told_under_the_runs_feature_scaling(room, tmp_path, capsys):
    """Issue 22 item 10: the 1e308 error named 'probability' under a floor100 run (the house
    summary counted with the default scaling first)."""
    from spcopyro.cli.main import main

    lines = (room / "Ft.csv").read_text().splitlines()
    row = lines[1].split(",")
    row[0] = "1e308"
    lines[1] = ",".join(row)
    (room / "Ft.csv").write_text("\n".join(lines) + "\n")
    argv = ["fit", str(room), "--out", str(tmp_path / "out"), "--sweeps", "2", "--preset", "auto"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Ft.csv, line 2, column 1" in err and "feature_scaling='floor100'" in err
