"""Houses of the public SpCoMapping dataset layout: finding, loading and saving them.

:func:`load_house` reads a house folder (see the dataset's README.md) into a :class:`House` (its
map, its :class:`~spcopyro.data.observations.Observations` and optional ground truth) and
:func:`save_house` writes one; :func:`find_dataset_root` and :func:`list_houses` find the data
set. Malformed files raise :class:`~spcopyro.data.observations.DataFormatError` naming the file,
the 1-based line and the offending value.
"""

from __future__ import annotations

import json
import logging
import os
import re
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spcopyro._util.interrupts import remove_tree
from spcopyro._util.messages import echo
from spcopyro.data.dataset_files import (
    IMAGE_SUFFIXES,
    _format_float,
    _image_paths,
    _read_column,
    _read_text,
    _read_trials,
    _read_utterances_line,
    _write_lines,
    read_features,
)
from spcopyro.data.modality_files import MODALITY_FILE, modality_lines, read_modalities
from spcopyro.data.observations import (
    _MISSING,
    DataFormatError,
    Observations,
    hidden_words_told,
)
from spcopyro.data.text import tokenize
from spcopyro.maps.grid import OccupancyGrid
from spcopyro.maps.map_server import MAX_MAP_COORDINATE, load_map, stage_map

__all__ = [
    "House",
    "find_dataset_root",
    "is_house_folder",
    "list_houses",
    "load_house",
    "save_house",
]


def find_dataset_root(path: str | os.PathLike[str] | None = None) -> Path | None:
    """The public dataset folder (the one holding ``map/``), resolved.

    Looked for in order: ``path`` if given (FileNotFoundError if it does not exist or holds no
    ``map/``); ``$SPCOPYRO_DATA`` if set (FileNotFoundError likewise);
    ``../shared/data/spcomapping`` relative to the current directory; the same relative to the
    project root (the folder above the spcopyro package). None if no candidate holds a ``map/``
    folder.
    """
    explicit = [(Path(path), "path")] if path is not None else []
    env = os.environ.get("SPCOPYRO_DATA")
    if not explicit and env:
        explicit = [(Path(env), "$SPCOPYRO_DATA")]
    for root, how in explicit:
        if not root.exists():
            raise FileNotFoundError(f"dataset folder {root} (from {how}) does not exist")
        if not (root / "map").is_dir():
            raise FileNotFoundError(f"dataset folder {root} (from {how}) holds no map/ folder")
        return root.resolve()
    relative = Path("..") / "shared" / "data" / "spcomapping"
    for base in (Path.cwd(), Path(__file__).resolve().parents[2]):
        root = base / relative
        if (root / "map").is_dir():
            return root.resolve()
    return None


def is_house_folder(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` holds a house's observations (``Ft.csv`` or ``St.csv``): what tells a
    house folder from a dataset's root, its ``map/`` or a fit's output folder in messages."""
    return any((Path(path) / name).is_file() for name in ("Ft.csv", "St.csv"))


def list_houses(root: str | os.PathLike[str]) -> list[str]:
    """Names of the room folders under ``root`` that have a map ``root/map/NAME.yaml``, sorted."""
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"dataset folder {root} does not exist")
    return sorted(
        entry.name
        for entry in root.iterdir()
        if entry.is_dir()
        and entry.name != "map"
        and (root / "map" / f"{entry.name}.yaml").is_file()
    )


@dataclass(frozen=True, eq=False)
class House:
    """A house: its map, what the robot observed in it, and optional ground truth.

    ``truth`` is ``[H, W]`` int64, the ground-truth category of each free cell (an index into
    ``category_names`` when given, -1 for unlabelled free cells) and -1 on every non-free cell.
    """

    name: str
    grid: OccupancyGrid
    observations: Observations
    truth: np.ndarray | None = None  # [H, W] int64, -1 off free
    category_names: tuple[str, ...] | None = None
    source: Path | None = None  # the room folder

    def __post_init__(self) -> None:
        if not self.name or self.name in (".", "..", "map") or re.search(r"[/\\]", self.name):
            raise ValueError(f"House.name={self.name!r}: not usable as a room folder name")
        if self.category_names is not None:
            names = tuple(self.category_names)
            if not all(isinstance(n, str) for n in names):
                raise ValueError(f"House.category_names must be strings: {names!r}")
            object.__setattr__(self, "category_names", names)
        if self.truth is not None:
            object.__setattr__(
                self,
                "truth",
                _check_truth(self.truth, self.grid, self.category_names, None, self.name),
            )
        if self.source is not None:
            object.__setattr__(self, "source", Path(self.source))


def _check_truth(
    truth: np.ndarray,
    grid: OccupancyGrid,
    category_names: tuple[str, ...] | None,
    path: Path | None,
    name: str,
) -> np.ndarray:
    """Validated ``[H, W]`` int64 truth; DataFormatError naming ``path`` (ValueError if None).
    Labels off free space on a map that is itself the cause (:func:`_map_refusal_first`) get
    the map's refusal instead, naming its yaml's lines; ``name``: the house's."""

    def fail(problem: str, value: object = _MISSING) -> Exception:
        if path is not None:
            return DataFormatError(path, problem, value=value)
        suffix = "" if value is _MISSING else f": {echo(value)}"
        return ValueError(f"truth: {problem}{suffix}")

    raw = np.asarray(truth)
    if raw.dtype.kind not in "iu":
        raise fail("ground truth must hold integers, got dtype", str(raw.dtype))
    labels = raw.astype(np.int64)  # [H, W]
    if labels.shape != tuple(grid.shape):
        raise fail(f"shape differs from the map's {tuple(grid.shape)}", labels.shape)
    if labels.size and labels.min() < -1:
        raise fail("category ids must be >= -1, found", int(labels.min()))
    if category_names is not None and labels.size and labels.max() >= len(category_names):
        raise fail(f"category id out of range for {len(category_names)} names", int(labels.max()))
    off_free = ~np.asarray(grid.free, dtype=bool) & (labels != -1)  # [H, W] bool
    if off_free.any():
        cells = np.argwhere(off_free)  # [n, 2] (row, col)
        _map_refusal_first(grid, name, cells, path)
        row, col = cells[0]
        raise fail(
            f"{int(off_free.sum())} non-free cell(s) carry a category (must be -1); first at "
            f"(row {row}, col {col})",
            int(labels[row, col]),
        )
    return labels


def _map_refusal_first(
    grid: OccupancyGrid, name: str, cells: np.ndarray, path: Path | None
) -> None:
    """ValueError with the map's own refusal where the map, not the truth, is why the truth's
    labelled ``cells`` ``[n, 2]`` (row, col) are not free: it has no free cell
    (:func:`~spcopyro.maps.free_space.check_free_cells`, the fit's refusal), or its ``negate``
    inverts free space: the truth labels the cells the other ``negate`` frees
    (:func:`~spcopyro.maps.free_space.truth_negate_hint`, the yaml's ``negate`` line and value).
    The truth's own refusal came first and hid the cause."""
    from spcopyro.maps.free_space import check_free_cells, truth_negate_hint  # reads the map

    check_free_cells(grid, f"house {name!r}")
    hint = truth_negate_hint(grid, cells)
    if hint:
        labels = str(path) if path is not None else "the truth"
        raise ValueError(
            f"house {name!r}: the map's free space reads as occupied: {hint}, and {labels} "
            f"labels {len(cells)} of its non-free cells, most of them free with that negate"
        )


MAX_COORDINATE = MAX_MAP_COORDINATE
"""Metres: a world position farther than this from the map's frame origin (1000 km) is a data
error, named with its file and line (issue 22 item 10), not a map-indexing failure later.
:func:`~spcopyro.maps.load_map` refuses a map lying wholly beyond the same bound."""


def _where_maps_are(yaml_path: Path) -> str:
    """How a house's map is found, and the maps there are (a copied or renamed house folder
    keeps the old name's map)."""
    folder = yaml_path.parent
    maps = sorted(p.name for p in folder.glob("*.yaml")) if folder.is_dir() else []
    there = f"the maps there: {', '.join(maps)}" if maps else f"no map in {folder}"
    if not folder.is_dir():
        there = f"there is no folder {folder}"
    return (
        f": a house's map is map/NAME.yaml beside its folder, NAME the folder's name "
        f"({there}); a copied or renamed house needs its map copied or renamed with it"
    )


def _check_both_modalities(room: Path, files: dict[str, Path]) -> bool:
    """Whether the house has images: False for a house of words only (none of Ft.csv, Xtx.csv,
    Xty.csv, pose_K.csv, no camera image in ``img_K/``: a robot without a camera). Else
    FileNotFoundError saying what a missing Ft.csv or St.csv holds, and how to make Ft.csv from
    camera images in ``img_K/`` (was: only "required file not found")."""
    if not files["Ft"].is_file():
        images = any(
            p.suffix.lower() in IMAGE_SUFFIXES
            for folder in room.glob("img_*")
            if folder.is_dir()
            for p in folder.iterdir()
        )
        image_files = [files[k].name for k in ("Xtx", "Xty") if files[k].is_file()]
        image_files += sorted(p.name for p in room.glob("pose_*.csv"))
        if not images and not image_files and files["St"].is_file():
            return False
        how = (
            f"make it from the camera images in its img_K/ folders: spcopyro features {room} "
            f"--out {files['Ft']}"
            if images
            else f"{', '.join(image_files)} {'give' if len(image_files) > 1 else 'gives'} "
            "image positions but no features: spcopyro "
            "features IMAGES --out Ft.csv makes Ft.csv from a folder of images"
        )
        raise FileNotFoundError(
            f"{files['Ft']}: required file not found (the image features; {how})"
        )
    if not files["St"].is_file():
        word_files = [files[k].name for k in ("StXtx", "StXty") if files[k].is_file()]
        word_files += sorted(p.name for p in room.glob("word_*.csv"))
        if not word_files:  # a house of images only (no speech yet): none of the words' files
            return True
        raise FileNotFoundError(
            f"{files['St']}: required file not found (the words heard, one line of "
            f"comma-separated utterances; {', '.join(word_files)} "
            f"{'is' if len(word_files) == 1 else 'are'} here without it)"
        )
    return True


def load_house(
    room_dir: str | os.PathLike[str], map_yaml: str | os.PathLike[str] | None = None
) -> House:
    """Read a house in the public SpCoMapping dataset layout (see the dataset's README.md).

    ``room_dir`` = ``ROOT/NAME``; the map is ``ROOT/map/NAME.yaml`` unless ``map_yaml`` is given.
    Files (ROOM/...):

    * ``Ft.csv`` (required): one image per row, K comma-separated features >= 0, K the same in
      every row; ``Xtx.csv``, ``Xty.csv`` (required): world x / y of each row, one per line.
      A house of words only (a robot without a camera) has none of them, no ``pose_K.csv`` and
      no image in ``img_K/``: its images are ``[0, 1]`` (warned), its trials the word files'.
    * ``St.csv``: one line of comma-separated utterances (trailing newline optional),
      each tokenised with :func:`tokenize` (an entry may be a sentence); ``StXtx.csv``,
      ``StXty.csv``: world x / y of each utterance, one per line. A house of images only (a
      robot that has heard nothing yet) has none of them and no ``word_K.csv``: it has no
      utterances (warned; V = 0) and is fitted on its images.
    * ``pose_K.csv`` / ``word_K.csv`` (optional, K = trial id, in pairs): their row / line counts
      split images / utterances into trials in order of K, and must add up to the Ft.csv rows /
      St.csv utterances; pose rows are ``x, y, qz, qw`` (x, y equal to Xtx/Xty), giving
      ``image_yaw = 2 atan2(qz, qw)``; word lines must repeat St.csv's utterances. Absent: all
      observations are trial 0 and ``image_yaw`` is None.
    * ``img_K/`` (optional): camera images, sorted by name, one per Ft row of trial K
      (:data:`IMAGE_SUFFIXES`); a count mismatch logs a warning and leaves ``image_paths`` None.
    * ``truth.npy`` ``[H, W]`` int and ``categories.json`` (list of names) (optional, written by
      the synthetic generator): ground-truth category per cell, -1 off free.
    * ``modality_<name>.csv`` (optional, any number): a further modality
      (:class:`~spcopyro.data.observations.ModalityObservations`, ``<name>`` a lower-case
      identifier other than images and words): a header line ``trial,x,y,<item1>,<item2>,...``
      naming the K >= 1 distinct items, then one observation per line: its trial id (an integer
      >= 0), world x, y and K counts >= 0. ``observations.modalities`` holds them sorted by name.

    Raises:
        FileNotFoundError: a required file (or the map) is missing; the message names it.
        DataFormatError: a malformed file: non-numeric, NaN / inf or negative features, rows of
            different lengths, empty Ft.csv or St.csv, position files whose length differs from
            their data file, pose / word files inconsistent with Ft.csv / St.csv, truth.npy
            whose shape differs from the map, a modality file with a bad name, header, trial id,
            number or negative count, a file that is not UTF-8 text, two files for one trial
            (``pose_1.csv`` and ``pose_01.csv``); the message names file, 1-based line and value
            (a long value or line shortened: :func:`spcopyro._util.messages.echo`). Numbers are
            plain
            decimals (``1e-3``, ``nan`` and ``inf`` read, then rejected as not finite; ``1_000``
            or digits of other scripts do not read).
    """
    room = Path(room_dir)
    if room.exists() and not room.is_dir():
        raise NotADirectoryError(
            f"{room} is a file, not a room folder: give the folder that holds Ft.csv, St.csv, "
            "Xtx.csv, ... (its map in ../map/NAME.yaml)"
        )
    if not room.is_dir():
        raise FileNotFoundError(f"room folder {room} does not exist")
    name = room.resolve().name
    yaml_path = Path(map_yaml) if map_yaml is not None else room.parent / "map" / f"{name}.yaml"
    if not yaml_path.is_file():
        houses = sorted(
            p.name for p in room.iterdir() if p.is_dir() and is_house_folder(p)
        )  # a dataset's root given for one of its houses
        if houses and map_yaml is None:  # the user gave a dataset's root: say that first
            raise FileNotFoundError(
                f"{room} is not a house folder but holds house folders ({', '.join(houses)}): "
                f"give one of them, e.g. {room / houses[0]}"
            )
        if map_yaml is None and not is_house_folder(room):
            raise FileNotFoundError(
                f"{room} is not a house folder: it holds no Ft.csv or St.csv (a house folder "
                "holds its observations, its map in ../map/NAME.yaml)"
            )
        raise FileNotFoundError(
            f"{yaml_path}: map of house {name!r} not found"
            + ("" if map_yaml is not None else _where_maps_are(yaml_path))
        )
    grid = load_map(yaml_path)

    files = {key: room / f"{key}.csv" for key in ("Ft", "Xtx", "Xty", "St", "StXtx", "StXty")}
    if _check_both_modalities(room, files):
        features = read_features(files["Ft"])  # [T, K]
        num_images = features.shape[0]
        image_xy = np.stack(
            [
                _read_column(files["Xtx"], num_images, files["Ft"]),
                _read_column(files["Xty"], num_images, files["Ft"]),
            ],
            axis=1,
        )  # [T, 2]
    else:  # a robot without a camera: the words alone place the concepts
        logging.getLogger("spcopyro").warning(
            "%s: no images (no Ft.csv, Xtx.csv, Xty.csv, pose_K.csv or img_K/): the house is "
            "fitted on its words alone",
            room,
        )
        features, image_xy = np.zeros((0, 1)), np.zeros((0, 2))  # [0, K = 1], [0, 2]
    if files["St"].is_file():
        utterances = _read_utterances_line(files["St"])
        word_xy = np.stack(
            [
                _read_column(files["StXtx"], len(utterances), files["St"]),
                _read_column(files["StXty"], len(utterances), files["St"]),
            ],
            axis=1,
        )  # [U, 2]
    else:  # a robot that has heard nothing yet: the images alone place the concepts
        logging.getLogger("spcopyro").warning(
            "%s: no words (no St.csv, StXtx.csv, StXty.csv or word_K.csv): the house is fitted "
            "on its images alone, and where / navigate have no word to answer",
            room,
        )
        utterances, word_xy = (), np.zeros((0, 2))  # [U = 0, 2]
    for positions, (x_file, y_file) in (
        (image_xy, (files["Xtx"], files["Xty"])),
        (word_xy, (files["StXtx"], files["StXty"])),
    ):
        far = np.abs(positions) > MAX_COORDINATE  # [n, 2] bool
        if far.any():
            row, axis = np.argwhere(far)[0]
            raise DataFormatError(
                (x_file, y_file)[axis],
                f"a position farther than {MAX_COORDINATE:g} m from the map's frame origin "
                "(a unit or parsing error?)",
                line=int(row) + 1,
                value=float(positions[row, axis]),
            )
    image_trial, word_trial, image_yaw, trial_ids, images_per_trial = _read_trials(
        room, image_xy, utterances, files
    )
    image_paths = _image_paths(room, trial_ids, images_per_trial)
    modalities = read_modalities(room)
    with hidden_words_told():  # the St.csv reader named them with the file and line
        observations = Observations(
            image_features=features,
            image_xy=image_xy,
            image_trial=image_trial,
            utterances=utterances,
            word_xy=word_xy,
            word_trial=word_trial,
            image_yaw=image_yaw,
            image_paths=image_paths,
            modalities=modalities,
        )

    category_names = None
    categories_path = room / "categories.json"
    if categories_path.is_file():
        try:
            names = json.loads(_read_text(categories_path))
        except json.JSONDecodeError as error:
            raise DataFormatError(
                categories_path, f"not valid JSON ({error.msg})", line=error.lineno
            ) from None
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise DataFormatError(categories_path, "must be a JSON list of strings", value=names)
        category_names = tuple(names)
    truth = None
    truth_path = room / "truth.npy"
    if truth_path.is_file():
        try:
            raw = np.load(truth_path, allow_pickle=False)
        except (ValueError, EOFError) as error:  # EOFError: an empty file
            raise DataFormatError(truth_path, f"not a numeric .npy array ({error})") from None
        truth = _check_truth(raw, grid, category_names, truth_path, name)
    return House(
        name=name,
        grid=grid,
        observations=observations,
        truth=truth,
        category_names=category_names,
        source=room.resolve(),
    )


_MANAGED_FILES = (
    "Ft.csv",
    "Xtx.csv",
    "Xty.csv",
    "St.csv",
    "StXtx.csv",
    "StXty.csv",
    "truth.npy",
    "categories.json",
    "rooms.npy",  # simulate --map's rooms (spcopyro.robot.map_simulation): another house's
    "rooms.json",  # rooms once a house of the same name is written over them
)


def save_house(
    house: House,
    root: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    extra: Callable[[Path], object] | None = None,
) -> Path:
    """Write ``house`` in the dataset layout under ``root``; the inverse of :func:`load_house`.

    Writes ``root/map/NAME.{pgm,yaml}`` (:func:`spcopyro.maps.save_map`) and ``root/NAME/`` with
    Ft.csv, Xtx.csv, Xty.csv (none for a house without images), St.csv (tokens joined by single
    spaces, utterances comma separated, no trailing newline, like the original), StXtx.csv,
    StXty.csv (none for a house without utterances), one ``pose_K.csv`` (``x, y, qz, qw``; yaw 0
    when unknown; none without images) and ``word_K.csv`` (none without utterances) per trial K
    of the images and utterances, copies of the camera images as ``img_K/NNNNN.ext`` when
    ``image_paths`` is known, truth.npy + categories.json when present, and one
    ``modality_<name>.csv`` per further modality (see :func:`load_house`). Floats are written
    with ``repr`` (they read back exactly); yaw goes through the quaternion, so it reads back
    to within rounding, wrapped to (-pi, pi].

    Raises:
        ValueError: no image feature classes (K = 0); observations not grouped by trial in
            ascending order; a token that would not read back as itself (a comma, whitespace,
            upper case or edge punctuation).
        FileExistsError: ``root/NAME`` is not empty or the map exists, and ``overwrite`` is
            False. With ``overwrite`` the files this function writes (and stale pose_K, word_K,
            img_K, modality_<name>, and the rooms.npy and rooms.json that ``simulate --map``
            writes beside them) are replaced; other files are left alone.

    The folder is written beside ``root/NAME`` and moved into place with the map's files, all
    at once (:func:`~spcopyro._util.folder_commit.commit_folder`): an error or a Ctrl-C leaves the
    house there before (or none) as it was. ``extra(folder)`` writes further files into the
    folder before that (``simulate --map``'s rooms). The images are copied before it too, so a
    house loaded from ``root/NAME`` may be written over it.

    Returns:
        The room folder ``root/NAME``.
    """
    obs = house.observations
    if obs.num_feature_classes == 0:
        raise ValueError(f"save_house({house.name!r}): no image feature classes (K = 0)")
    for name, trial in (("image_trial", obs.image_trial), ("word_trial", obs.word_trial)):
        if (np.diff(trial) < 0).any():
            raise ValueError(
                f"save_house({house.name!r}): {name} is not in ascending order; the files store "
                "observations trial after trial"
            )
    for u, tokens in enumerate(obs.utterances):
        for token in tokens:
            if "," in token:
                raise ValueError(
                    f"save_house({house.name!r}): utterance {u} token {token!r} contains a comma "
                    "(St.csv separates utterances with commas)"
                )
            if tokenize(token) != (token,):
                raise ValueError(
                    f"save_house({house.name!r}): utterance {u} token {token!r} would read back "
                    f"as {tokenize(token)!r}"
                )

    for source in obs.image_paths or ():
        if source.suffix.lower() not in IMAGE_SUFFIXES:
            raise ValueError(
                f"save_house({house.name!r}): image {source} is not one of {IMAGE_SUFFIXES}"
            )

    root = Path(root)
    room = root / house.name
    map_yaml = root / "map" / f"{house.name}.yaml"
    if (room.exists() and any(room.iterdir())) or map_yaml.exists():
        if not overwrite:
            raise FileExistsError(f"{room} (or {map_yaml}) already exists; pass overwrite=True")
    from spcopyro._util.folder_commit import commit_folder  # not on --help's path
    from spcopyro._util.outputs import staging_folder

    staging = staging_folder(room)  # the house written beside ROOM, moved in whole
    try:
        _write_room(house, staging)
        if extra is not None:
            extra(staging)
        with stage_map(house.grid, map_yaml) as map_files:
            commit_folder(staging, room, _Saved(), map_files)  # with the map, as one
    finally:
        remove_tree(staging)  # not there after the commit; a Ctrl-C meanwhile is one
    return room


def _write_room(house: House, room: Path) -> None:
    """The files of :func:`save_house` in the (new, empty) folder ``room``."""
    obs = house.observations
    with_images = obs.num_images > 0  # else a house of words only: no Ft.csv, no pose_K.csv
    with_words = obs.num_utterances > 0  # else a house of images only: no St.csv, no word_K.csv
    fmt = _format_float
    if with_images:
        features = obs.image_features.tolist()
        _write_lines(room / "Ft.csv", (",".join(map(fmt, row)) for row in features))
        _write_lines(room / "Xtx.csv", map(fmt, obs.image_xy[:, 0].tolist()))
        _write_lines(room / "Xty.csv", map(fmt, obs.image_xy[:, 1].tolist()))
    sentences = [" ".join(tokens) for tokens in obs.utterances]
    if with_words:
        _write_lines(room / "St.csv", [",".join(sentences)], trailing_newline=False)
        _write_lines(room / "StXtx.csv", map(fmt, obs.word_xy[:, 0].tolist()))
        _write_lines(room / "StXty.csv", map(fmt, obs.word_xy[:, 1].tolist()))

    yaw = obs.image_yaw if obs.image_yaw is not None else np.zeros(obs.num_images)  # [T]
    pose = np.stack(
        [obs.image_xy[:, 0], obs.image_xy[:, 1], np.sin(yaw / 2), np.cos(yaw / 2)], axis=1
    )  # [T, 4]
    for k in np.union1d(obs.image_trial, obs.word_trial).tolist():  # trials of images, words
        in_trial = np.flatnonzero(obs.image_trial == k)  # [n_k]
        if with_images:
            rows = pose[in_trial].tolist()
            _write_lines(room / f"pose_{k}.csv", (",".join(map(fmt, row)) for row in rows))
        if with_words:
            _write_lines(
                room / f"word_{k}.csv",
                (s for s, t in zip(sentences, obs.word_trial, strict=True) if t == k),
            )
        if obs.image_paths is not None and in_trial.size:
            folder = room / f"img_{k}"
            folder.mkdir()
            for number, i in enumerate(in_trial, start=1):
                source = obs.image_paths[i]
                shutil.copyfile(source, folder / f"{number:05d}{source.suffix.lower()}")

    for modality in obs.modalities:
        _write_lines(room / f"modality_{modality.name}.csv", modality_lines(modality))

    if house.truth is not None:
        np.save(room / "truth.npy", np.asarray(house.truth, dtype=np.int64))
    if house.category_names is not None:
        (room / "categories.json").write_text(
            json.dumps(list(house.category_names), indent=1) + "\n", encoding="utf-8"
        )


class _Saved:
    """The entries :func:`save_house` writes (or replaces: stale ``pose_K``, ``img_K``, ...):
    ``in`` for :func:`~spcopyro._util.folder_commit.carry_over`, which keeps the others."""

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and bool(
            name in _MANAGED_FILES
            or re.fullmatch(r"(pose|word)_[0-9]+\.csv|img_[0-9]+", name)
            or MODALITY_FILE.fullmatch(name)
        )
