"""A study's data: where each source's files are, their digest, and the house a cell fits.

:func:`resolve_source` turns a public house's or a map's name into an absolute path (in the
process that plans the study; a worker on another machine needs the same path, e.g. a shared
file system). :func:`data_digest` is the part of a cell's key that stands for its data: the
sha256 of the files for a public house or a map (so a changed file runs the cell again), and of
the generator's inputs (HouseSpec or MapTour, seed) for a drawn house -- the package version,
also in the key, stands for the generator's code. :func:`load_cell_data` is what a worker runs:
it loads or draws the house itself, holds out a trial when asked and finds the truth.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spcopyro.data import House, Observations, find_dataset_root, load_house
from spcopyro.data.dataset import is_house_folder, list_houses
from spcopyro.experiments.public_truth import public_truth
from spcopyro.experiments.table import PUBLIC_CATEGORIES, heldout_folds
from spcopyro.maps import load_map
from spcopyro.maps.map_server import read_occupancy_yaml
from spcopyro.maps.map_yaml import MapFormatError, read_map_yaml
from spcopyro.robot.map_simulation import simulate_on_map
from spcopyro.study.spec import DataSource
from spcopyro.synthetic import make_house

__all__ = ["CellData", "data_digest", "files_hash", "load_cell_data", "resolve_source"]


def resolve_source(data: DataSource, root: str | Path | None = None) -> DataSource:
    """``data`` with a public house's folder or a map's yaml as an absolute path. A bare name
    is looked up under the dataset root (``root``, else :func:`find_dataset_root`:
    ``$SPCOPYRO_DATA``, ...); FileNotFoundError names what is missing."""
    if data.kind == "synthetic":
        return data
    target = Path(data.target).expanduser()
    found = None
    if not target.exists() and len(target.parts) == 1:  # a name of the public dataset
        found = find_dataset_root(root)
        if found is None:
            raise FileNotFoundError(
                f"data source {data.name!r}: {data.target!r} is not a path and no dataset root "
                "was found (set $SPCOPYRO_DATA or pass --data)"
            )
        target = found / data.target if data.kind == "public" else found / "map" / data.target
        if data.kind == "map" and target.suffix != ".yaml":
            target = target.with_suffix(".yaml")
    if not target.exists():
        raise FileNotFoundError(
            f"data source {data.name!r}: {target} does not exist"
            + ("" if found is None else _names_under(found, data.kind))
        )
    if data.kind == "public" and not is_house_folder(target):  # each cell failed at run time
        what = "a file" if target.is_file() else "a folder without Ft.csv or St.csv"
        raise FileNotFoundError(f"data source {data.name!r}: {target} is {what}, not a house "
                                "folder (a house folder holds its observations, Ft.csv and "
                                "St.csv, its map in ../map/NAME.yaml)")  # fmt: skip
    if data.kind == "map":  # every cell of a map that does not read failed at run time
        try:  # read and refused as load_map reads and refuses it, but for the loaders named
            spec = read_occupancy_yaml(target, others=_NO_MAP_SOURCE)
        except MapFormatError as error:
            raise ValueError(f"data source {data.name!r}: {error}") from None
        image = spec.image
        if not image.is_file():
            raise FileNotFoundError(f"data source {data.name!r}: {target} names the image "
                                    f"{image}, which does not exist")  # fmt: skip
    return dataclasses.replace(data, target=str(target.resolve()))


_NO_MAP_SOURCE = (
    "a study's map source is read by load_map (its tours are drawn on an occupancy map): a "
    "costmap filter mask or a semantic label map cannot be one"
)
"""The end of a map source's refusal of a mode (:func:`~spcopyro.maps.map_server.load_map`'s
names the loaders of those maps, which read no map source)."""


def _names_under(root: Path, kind: str) -> str:
    """What a name looked up under the dataset ``root`` could have been: its houses (``public``)
    or its maps (``map``), for the message of a name it does not hold."""
    if kind == "public":
        return f" (the dataset {root} holds the houses {list_houses(root)})"
    maps = sorted(path.stem for path in (root / "map").glob("*.yaml"))
    return f" (the dataset {root} holds the maps {maps})"


def _map_files(yaml_path: Path) -> list[Path]:
    """A map's yaml and the image its ``image:`` names (relative to the yaml's folder, as
    map_server reads it), whatever its name and extension; the yaml alone when it does not
    parse or its image is missing (:func:`resolve_source` refuses such a map first). Its
    warnings are not said again: :func:`resolve_source` read the yaml and said them."""
    try:
        image = read_map_yaml(yaml_path, warn=False).image
    except MapFormatError:
        return [yaml_path]
    return [yaml_path, image] if image.is_file() else [yaml_path]


def _files_of(data: DataSource) -> list[Path]:
    """The files a public house or a map is read from."""
    target = Path(data.target)
    if data.kind == "map":
        return _map_files(target)
    files = sorted(p for p in target.iterdir() if p.is_file())
    files += sorted(target.parent.glob(f"map/{target.name}.*"))
    return files


def files_hash(data: DataSource) -> hashlib._Hash:
    """sha256 fed with the files of a public house or a map (nothing for a synthetic house):
    what :func:`data_digest` starts from; ``data`` resolved. Made once per source, it spares
    reading a house's files again for each of its seeds (a study of many seeds)."""
    digest = hashlib.sha256()
    if data.kind != "synthetic":
        for path in _files_of(data):
            digest.update(f"{path.name}:{path.stat().st_size};".encode())
            digest.update(path.read_bytes())
    return digest


def data_digest(data: DataSource, seed: int, files: hashlib._Hash | None = None) -> str:
    """sha256 (hex) of a cell's data (module docstring); ``data`` resolved. ``files``: its
    :func:`files_hash`, when made already (left unchanged)."""
    digest = (files_hash(data) if files is None else files).copy()
    house_seed = seed if data.house_seed is None else data.house_seed
    inputs: dict[str, object] = {"kind": data.kind, "heldout": data.heldout}
    if data.kind == "synthetic":
        inputs.update(spec=dataclasses.asdict(data.house_spec()), seed=house_seed)
    elif data.kind == "map":
        inputs.update(tour=dataclasses.asdict(data.map_tour()), seed=house_seed)
    if data.heldout:
        inputs["fold_seed"] = seed  # the held-out trial is seed mod trials
    digest.update(json.dumps(inputs, sort_keys=True, default=str).encode())
    return digest.hexdigest()


@dataclass
class CellData:
    """What a cell fits and is scored against."""

    house: House
    """The house the fit sees (without the held-out trial)."""
    full: House
    """The house with every trial (the truth is drawn on it)."""
    truth: np.ndarray | None
    """[H, W] category per map cell (-1: not scored), or None."""
    categories: tuple[str, ...] | None
    """The truth's category names (matching rate), or None."""
    num_categories: int | None
    """L of a finite prior (``paper-dirichlet``)."""
    test: Observations | None = None
    held_out_trial: int | None = None


def load_cell_data(data: DataSource, seed: int) -> CellData:
    """The house of ``data`` for the cell of ``seed`` (drawn, simulated or loaded)."""
    house_seed = seed if data.house_seed is None else data.house_seed
    if data.kind == "synthetic":
        house = make_house(seed=house_seed, spec=data.house_spec(), name=data.name)
        truth, categories = house.truth, house.category_names
    elif data.kind == "map":
        house = simulate_on_map(
            load_map(data.target), seed=house_seed, tour=data.map_tour(), name=data.name
        ).house
        truth, categories = house.truth, house.category_names
    else:
        house = load_house(data.target)
        found = public_truth(house)
        truth, categories = found.labels, None  # its categories are words, not category names
    if data.kind == "public":
        num_categories = PUBLIC_CATEGORIES.get(Path(data.target).name)
    else:
        num_categories = len(categories) if categories else None
    loaded = CellData(house, house, truth, categories, num_categories)
    if data.heldout:
        folds = list(heldout_folds(house))
        _, loaded.held_out_trial, loaded.house, loaded.test = folds[seed % len(folds)]
    return loaded
