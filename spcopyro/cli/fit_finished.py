"""A finished fit that Ctrl-C stopped while ``spcopyro fit`` wrote its outputs, kept so that
``--resume`` writes them without running the fit again.

A variational fit's checkpoint (:mod:`spcopyro.guides.checkpoint`) is saved by the driver that
Ctrl-C stops; once its iterations have all run, its result is made and the outputs are written
(seconds on a large map: result.npz, the uncertainty, the figures), and a Ctrl-C there lost the
finished fit. :func:`save_finished_fit` then keeps the result itself in ``OUT.checkpoint.npz``
(one ``.npz`` written whole or not at all), as the run made it before writing anything, with the
warnings the run had given by then (``config.json``'s), and :func:`load_finished_fit` gives it back
to a run with ``--resume`` of the same fit, which writes the outputs from it: the same files as the
run never stopped would have written. Gibbs fits keep their finished chains instead
(:class:`~spcopyro.fit.gibbs_chains.FitCheckpoint`), whose resume makes the result again.

The file, N free cells, L concepts:

=========================  =====================================================================
``result_NAME``            each array of the result's ``result.npz``
                           (:meth:`~spcopyro.results.result.SpCoResult.save`), e.g.
                           ``result_labels`` [N] int64, ``result_marginals`` [N, L] float64
``settings``               JSON: the result's ``config.json`` settings and provenance
``said``                   JSON: the warnings the run gave before its outputs were written
``record``                 JSON: format, what the file is, the method, and the fit asked for
                           (``request``: method, options, settings, sweeps, seed, start,
                           estimate, a fingerprint of the house as loaded), checked on resuming
=========================  =====================================================================
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from spcopyro.cli.fit_resume import keeps_finished_fit

if TYPE_CHECKING:
    from typing import Any as FitJob  # spcopyro.cli.fit.FitJob, which imports this module

    from spcopyro.config import SpCoSettings
    from spcopyro.data import House
    from spcopyro.results.result import SpCoResult

__all__ = [
    "is_finished_fit", "keep_finished", "load_finished_fit",
    "restore_finished", "resumes_finished_fit", "save_finished_fit",
]  # fmt: skip

FORMAT = "spcopyro-finished-fit"
VERSION = 1
WHAT = (
    "the finished result of a spcopyro fit stopped while its outputs were written -- not a "
    "result folder: write them with `spcopyro fit DATA --out OUT ... --resume THIS_FILE`"
)
PREFIX = "result_"


def resumes_finished_fit(args: argparse.Namespace) -> bool:
    """Whether ``--resume`` names a finished fit's file that this fit may write
    (:func:`~spcopyro.cli.fit_resume.keeps_finished_fit`; a vi-gibbs fit, which keeps no other
    checkpoint, too)."""
    return args.resume is not None and keeps_finished_fit(args) and is_finished_fit(args.resume)


def is_finished_fit(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a readable finished-fit file (not a checkpoint of iterations)."""
    try:
        return _record(path).get("format") == FORMAT
    except (OSError, ValueError):
        return False


def save_finished_fit(
    path: Path,
    args: argparse.Namespace,
    result: SpCoResult,
    said: list[str],
    *,
    on_map: House,
    settings: SpCoSettings,
    options: object | None,
) -> Path:
    """Keep ``result`` (as the fit made it, before the outputs) and ``said`` in ``path``,
    replacing any file there atomically; ``on_map``: the house as loaded, ``settings`` and
    ``options`` as resolved before the fit (the request a resume must match). The fit is on
    the model grid: ``--refine`` refines Gibbs fits only, whose finished chains are kept
    instead."""
    from spcopyro._util.outputs import replace_file

    arrays = {PREFIX + name: array for name, array in result._arrays().items()}
    record = {"format": FORMAT, "version": VERSION, "what": WHAT, "method": args.method,
              "request": _request(args, on_map, settings, options)}  # fmt: skip
    arrays["settings"] = np.array(json.dumps(result.settings_json()))
    arrays["said"] = np.array(json.dumps(list(said)))
    arrays["record"] = np.array(json.dumps(record))
    return replace_file(path, lambda file: np.savez_compressed(file, **arrays))


def load_finished_fit(
    path: str | os.PathLike[str],
    args: argparse.Namespace,
    *,
    model: House,
    on_map: House,
    settings: SpCoSettings,
    options: object | None,
) -> tuple[SpCoResult, list[str]]:
    """The result kept in ``path`` (on ``model``'s grid) and the warnings its run gave;
    ValueError naming each difference when it was made for another fit than this one's
    (``args``, the house as loaded ``on_map``, the resolved ``settings`` and ``options``), or
    when it is damaged."""
    from spcopyro._util.outputs import DAMAGED_FILE_ERRORS, read_npz
    from spcopyro.gibbs.checkpoint import differences
    from spcopyro.results.result import SpCoResult

    record = _record(path)
    problems = differences(record.get("request", {}), _request(args, on_map, settings, options))
    if problems:
        raise ValueError(f"--resume {path}: a finished fit made for other data or settings: "
                         + "; ".join(problems))  # fmt: skip
    try:
        with read_npz(Path(path)) as z:
            arrays = {k[len(PREFIX) :]: z[k] for k in z.files if k.startswith(PREFIX)}
            saved, said = json.loads(str(z["settings"])), json.loads(str(z["said"]))
        result = SpCoResult._from_saved(Path(path), Path(path), arrays, saved, grid=model.grid)
    except (KeyError, TypeError, ValueError, AttributeError, IndexError,
            *DAMAGED_FILE_ERRORS) as error:  # fmt: skip
        raise ValueError(f"{path}: a damaged finished fit ({type(error).__name__}: {error}); "
                         "run the fit again without --resume") from None  # fmt: skip
    return result, [str(line) for line in said]


def keep_finished(job: FitJob) -> Path | None:
    """``fit``'s finished fit (``job.finished``) kept in ``OUT.checkpoint.npz`` when Ctrl-C
    stops the writing of its outputs; None where none is kept (no fit finished, a Gibbs fit, or
    one :func:`~spcopyro.cli.fit_resume.keeps_finished_fit` keeps not, or the file could not be
    written)."""
    from spcopyro._util.outputs import checkpoint_path

    if job.finished is None or not keeps_finished_fit(job.args):
        return None
    result, said = job.finished
    try:
        return save_finished_fit(
            checkpoint_path(job.staged.out), job.args, result, said, on_map=job.map_house,
            settings=job.settings, options=job.options,
        )  # fmt: skip
    except OSError:  # a full disk: the line says the fit is lost, as it was
        return None


def restore_finished(job: FitJob) -> SpCoResult | None:
    """The finished fit ``--resume`` names, where it names one (else None: a fit runs), for
    ``fit`` to write; ``job`` then holds the warnings its run had given (``config.json``'s, as
    that run would have written them)."""
    args = job.args
    if not resumes_finished_fit(args):
        return None
    result, said = load_finished_fit(
        args.resume, args, model=job.house, on_map=job.map_house, settings=job.settings,
        options=job.options,
    )  # fmt: skip
    job.said[:] = said  # the same list: the warnings from here on are added to it
    return result


def _record(path: str | os.PathLike[str]) -> dict[str, object]:
    """The JSON record of the checkpoint file ``path`` (ValueError unless a finished fit's)."""
    from spcopyro.gibbs.checkpoint import checkpoint_record, open_checkpoint

    with open_checkpoint(path) as z:
        return checkpoint_record(path, z, form=FORMAT, version=VERSION, kind="finished fit")


def _request(
    args: argparse.Namespace, on_map: House, settings: SpCoSettings, options: object | None
) -> dict[str, object]:
    """What makes a fit this fit, as JSON: the method and its options, the settings, the
    iterations, the seed, the start, the estimate, the refinement and the house."""
    given = dataclasses.asdict(options) if dataclasses.is_dataclass(options) else None
    request = {
        "method": args.method, "options": given, "model": settings.model.to_json(),
        "data_preparation": dataclasses.asdict(settings.data), "sweeps": args.sweeps,
        "seed": args.seed, "init": args.init, "init_from": args.init_from,
        "marginal_samples": args.marginal_samples, "point_estimate": args.point_estimate,
        "refine": args.refine, "house_sha256": _fingerprint(on_map),
    }  # fmt: skip
    return json.loads(json.dumps(request, default=str))


def _fingerprint(house: House) -> str:
    """sha256 (hex) of the house as loaded: its map's cells, resolution and origin, its
    observations and truth (not where they were read from)."""
    digest = hashlib.sha256()

    def add(value: object) -> None:
        if isinstance(value, np.ndarray):
            digest.update(f"{value.dtype.str}{value.shape};".encode())
            digest.update(np.ascontiguousarray(value).tobytes())
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            for field in dataclasses.fields(value):
                if field.name not in ("source", "image_paths"):
                    digest.update(f"{field.name}=".encode())
                    add(getattr(value, field.name))
        elif isinstance(value, tuple | list):
            digest.update(f"[{len(value)}".encode())
            for item in value:
                add(item)
        else:
            digest.update(f"{value!r};".encode())

    add(house)
    return digest.hexdigest()
