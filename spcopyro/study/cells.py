"""The grid of a study: one :class:`Cell` per (variant or baseline, data, method, seed).

A cell's :attr:`~Cell.key` is the sha256 of its full input -- the data's digest
(:func:`spcopyro.study.sources.data_digest`), the resolved model settings, the method and its
resolved options, the fit's keyword arguments, the iterations, the seed and the package version
-- and not of its names: renaming a variant or a data source reruns nothing, changing any value
that reaches the fit reruns exactly the cells it reaches. The cache
(:mod:`spcopyro.study.run`) stores each finished cell's scores under that key.

The code is in the key only through ``__version__``. What else of the code made a cell is in its
record: :func:`source_digest`, a digest of every ``spcopyro/**/*.py`` file of the process that
ran the cell (a worker's own, on a cluster). Keeping it out of the key keeps a study's hours of
cells when a comment or an unrelated module changes; :func:`spcopyro.study.run.run_study` names
the finished cells another source computed and runs them again only when asked
(``rerun_stale``, ``--rerun-stale``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from spcopyro import __version__
from spcopyro.experiments.ablation_variants import Variant
from spcopyro.experiments.methods import SPCOA_OPTIONS
from spcopyro.study.lines import file_line
from spcopyro.study.sources import data_digest, files_hash, resolve_source
from spcopyro.study.spec import DataSource, Study, given_twice

__all__ = ["BASELINE_METHOD", "Cell", "cells_of", "package_digest", "source_digest"]

BASELINE_METHOD = "baseline"
"""The method column of a baseline row: a :class:`Cell` of no variant is made with it
(:func:`cells_of`), and :func:`spcopyro.study.maps.row_name` names such a row by its baseline
alone."""


@dataclass(frozen=True)
class Cell:
    """One fit of a study and how it is scored. Picklable: it travels to the workers, which
    load its data themselves."""

    variant: Variant | None  # None: a baseline
    row: str  # the variant's or the baseline's name
    data: DataSource  # resolved (absolute paths)
    method: str  # an inference method of spcopyro.fit.registry, or BASELINE_METHOD
    seed: int
    sweeps: int
    spcoa_iterations: int
    observations_off: bool = False
    """Also fit with the observations off (a variant cell of a study that asks for it)."""
    scoring: str = "study"
    """``study`` (:mod:`spcopyro.study.evaluate`) or ``comparison``
    (:mod:`spcopyro.study.comparison_cell`)."""
    ari_every: int = 0
    """Keep the ARI against the truth every this many iterations in the trace (variants)."""
    key: str = ""

    def inputs(self) -> dict[str, object]:
        """The cell's input columns of the table (names and values)."""
        variant, public = self.variant, self.data.kind == "public"
        return {
            "key": self.key,
            "variant": self.row,
            "data": self.data.name,
            "method": self.method,
            "seed": self.seed,
            "data_kind": self.data.kind,
            "data_source": Path(self.data.target).name if public else self.data.target,
            "house_seed": self.seed if self.data.house_seed is None else self.data.house_seed,
            "heldout": self.data.heldout,
            "sweeps": self.sweeps,
            "observations_off": self.observations_off,
            "scoring": self.scoring,
            "preset": variant.preset if variant else "",
            "overrides": variant.describe().partition(":")[2] if variant else "",
            "version": __version__,
        }


def package_digest(package: Path) -> str:
    """The first 16 hex digits of the sha256 over every ``*.py`` file under ``package``, by
    path relative to it and content, in path order."""
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


_SOURCE_DIGEST = package_digest(Path(__file__).resolve().parents[1])
"""This process's :func:`source_digest`, read when this module is imported (about 200 files,
~20 ms): a source file edited while the study runs does not change the digest its cells
record (it was read from disk when the first cell finished, so it described the edited files,
not the code the process had imported)."""


def source_digest() -> str:
    """The digest of this process's spcopyro source (:func:`package_digest` of the package's
    folder), read once, when the study's code was imported (a worker's when it imported it):
    the code the process runs, not what the files hold later."""
    return _SOURCE_DIGEST


def _settings_json(variant: Variant) -> dict[str, object]:
    """Everything of the variant that reaches the fit, resolved (preset values included);
    ``num_concepts`` of a finite prior comes from the data, whose digest is in the key."""
    settings = variant.spco_settings(None)
    return {
        "model": dataclasses.asdict(settings.model),
        "data": settings.data.to_json(),
        "options": dataclasses.asdict(variant.method_options()),  # type: ignore[call-overload]
        "fit": dict(variant.fit),
    }


def cell_key(cell: Cell, digest: str, settings: dict[str, object] | None = None) -> str:
    """sha256 (hex) of the cell's full input (module docstring, :func:`_cell_inputs`).
    ``settings``: the variant's :func:`_settings_json`, when made already (the same for all of a
    variant's seeds)."""
    text = json.dumps(_cell_inputs(cell, digest, settings), sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def _cell_inputs(
    cell: Cell, digest: str, settings: dict[str, object] | None = None
) -> dict[str, object]:
    """The cell's full input that :func:`cell_key` hashes (``digest``: its data's)."""
    if cell.variant is None:
        inputs: dict[str, object] = {"baseline": cell.row}
        if cell.row == "C-spcoa":  # the only baseline that iterates, and has options
            inputs["spcoa_iterations"] = cell.spcoa_iterations
            inputs["spcoa_options"] = dict(SPCOA_OPTIONS)  # what _fit_spcoa passes fit_spcoa
    else:
        if settings is None:
            settings = _settings_json(cell.variant)
        inputs = {"settings": settings, "sweeps": cell.sweeps}
        if cell.observations_off:  # only when asked: earlier cells keep their keys
            inputs["observations_off"] = True
        if cell.scoring != "study":
            inputs["scoring"] = cell.scoring
        if cell.ari_every:  # only when asked: earlier cells keep their keys
            inputs["ari_every"] = cell.ari_every
    inputs.update(method=cell.method, seed=cell.seed, data=digest, version=__version__)
    return inputs


def _resolved(study: Study, data: DataSource, root: str | Path | None) -> DataSource:
    """:func:`resolve_source`, its error naming the study file, the line and the value (it
    named the source only); a relative path missing from the current folder but found beside
    the study file says so."""
    try:
        return resolve_source(data, root)
    except (OSError, ValueError) as error:
        where = f"[data.{data.name}] {data.kind}"
        message = f"{file_line(study.source, where)}: {where} = {data.target!r}: {error}"
        target = Path(data.target).expanduser()
        beside = Path(study.source).parent / target
        if not target.is_absolute() and not target.exists() and beside.exists():
            message += (f" (a relative path is read from the current folder {Path.cwd()}, not "
                        f"the study file's: give {beside.resolve()})")  # fmt: skip
        raise type(error)(message) from None


def cells_of(study: Study, root: str | Path | None = None) -> list[Cell]:
    """Every cell of ``study`` with its key, in table order: data, seed, variant, method, then
    the baselines. Public houses and maps are found (under ``root`` or the dataset root) and
    digested here, once per source and seed."""
    sources = [_resolved(study, data, root) for data in study.data]
    cells = []
    settings: dict[tuple[str, str], dict[str, object]] = {}  # per variant and method: once
    for data in sources:
        files = files_hash(data)  # once per source, not per seed
        for seed in study.seeds if data.seeds is None else data.seeds:
            digest = data_digest(data, seed, files)
            planned: list[Cell] = []
            for variant in study.variants:
                methods = study.methods or (variant.method,)
                for method in methods:
                    changed = dataclasses.replace(variant, method=method)
                    sweeps = study.sweeps_for(method, variant.name)
                    planned.append(Cell(changed, variant.name, data, method, seed, sweeps,
                                        study.spcoa_iterations, study.observations_off,
                                        study.scoring, study.ari_every))  # fmt: skip
            for baseline in study.baselines:  # iterations: SpCoA's; the others have none
                iterations = study.spcoa_iterations if baseline == "C-spcoa" else 0
                planned.append(Cell(None, baseline, data, BASELINE_METHOD, seed, iterations,
                                    study.spcoa_iterations))  # fmt: skip
            for c in planned:
                if c.variant is not None and (c.row, c.method) not in settings:
                    settings[c.row, c.method] = _settings_json(c.variant)
            cells += [
                dataclasses.replace(c, key=cell_key(c, digest, settings.get((c.row, c.method))))
                for c in planned
            ]
    rows = [(c.row, c.data.name, c.method, c.seed) for c in cells]
    twice = given_twice(rows)
    if twice is not None:  # its rows would be run and counted twice
        row, data, method, seed = twice  # type: ignore[misc]
        raise ValueError(f"study {study.name!r}: the cell {row} / {data} / {method} / seed "
                         f"{seed} is given twice (a variant, baseline, method, data source or "
                         "seed named twice)")  # fmt: skip
    return cells
