"""A finished fit that Ctrl-C stopped while ``spcopyro fit`` wrote its outputs, kept so that
``--resume`` writes them without running the fit again: a fit of a method other than Gibbs, one
or several (``--chains K``), or an ``--update`` of any method.

A variational fit's checkpoint (:mod:`spcopyro.guides.checkpoint`) is saved by the driver that
Ctrl-C stops; once its iterations have all run, its result is made and the outputs are written
(seconds on a large map: result.npz, the uncertainty, the figures), and a Ctrl-C there lost the
finished fit. :func:`save_finished_fit` then keeps the results themselves in
``OUT.checkpoint.npz`` (one ``.npz`` written whole or not at all): every fit's (``--chains K``:
the outputs compare them, ``chains.json``) and which one is kept, as the run made them before
writing anything, with the warnings the run had given by then (``config.json``'s), and
:func:`load_finished_fit` gives them back to a run with ``--resume`` of the same fit, which writes
the outputs from them: the same files as the run never stopped would have written. Gibbs chains
that are no ``--update`` keep their finished chains instead
(:class:`~spcopyro.fit.gibbs_chains.FitCheckpoint`), whose resume makes the results again.

The file, K fits, N free cells, L concepts (a file of one fit is as this module wrote it before
it kept several: no ``fits`` or ``kept`` in its record, no ``chains`` or ``update`` in its
request):

=========================  =====================================================================
``result_NAME``            each array of the first fit's ``result.npz``
                           (:meth:`~spcopyro.results.result.SpCoResult.save`), e.g.
                           ``result_labels`` [N] int64, ``result_marginals`` [N, L] float64
``resultK_NAME``           the same of fit K (1 to K - 1), where there are several
``settings``               JSON: the first fit's ``config.json`` settings and provenance
``settingsK``              JSON: the same of fit K (1 to K - 1)
``said``                   JSON: the warnings the run gave before its outputs were written
``record``                 JSON: format, what the file is, the method, the fits (``fits``: K),
                           the one kept (``kept``: 0 to K - 1), and the fit asked for
                           (``request``: method, options, settings, sweeps, chains, seed, start,
                           estimate, the fit it updates and a digest of its result.npz, a
                           fingerprint of the house as loaded), checked on resuming
=========================  =====================================================================
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from spcopyro._util.digests import file_sha256
from spcopyro.cli.fit_resume import keeps_finished_fit

if TYPE_CHECKING:
    from spcopyro.cli.fit_job import FitJob
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
    results: Sequence[SpCoResult],
    kept: int,
    said: list[str],
    *,
    on_map: House,
    settings: SpCoSettings,
    options: object | None,
) -> Path:
    """Keep ``results`` (every fit's, as the run made them, before the outputs), which one is
    ``kept`` and ``said`` in ``path``, replacing any file there atomically; ``on_map``: the
    house as loaded, ``settings`` and ``options`` as resolved before the fit (the request a
    resume must match). The fits are on the model grid: ``--refine`` refines Gibbs fits that
    are no ``--update`` only, whose finished chains are kept instead."""
    from spcopyro._util.npz import write_npz
    from spcopyro._util.outputs import replace_file

    arrays: dict[str, np.ndarray] = {}
    for k, result in enumerate(results):
        arrays.update({_prefix(k) + name: array for name, array in result._arrays().items()})
        arrays[_settings_key(k)] = np.array(json.dumps(result.settings_json()))
    record = {"format": FORMAT, "version": VERSION, "what": WHAT, "method": args.method,
              "fits": len(results), "kept": int(kept),
              "request": _request(args, on_map, settings, options)}  # fmt: skip
    arrays["said"] = np.array(json.dumps(list(said)))
    arrays["record"] = np.array(json.dumps(record))
    return replace_file(path, lambda file: write_npz(file, arrays))


def load_finished_fit(
    path: str | os.PathLike[str],
    args: argparse.Namespace,
    *,
    model: House,
    on_map: House,
    settings: SpCoSettings,
    options: object | None,
) -> tuple[list[SpCoResult], int, list[str]]:
    """The results kept in ``path`` (every fit's, on ``model``'s grid), the one kept (an
    index) and the warnings its run gave; ValueError naming each difference when it was made
    for another fit than this one's (``args``, the house as loaded ``on_map``, the resolved
    ``settings`` and ``options``), or when it is damaged."""
    from spcopyro._util.outputs import DAMAGED_FILE_ERRORS, read_npz
    from spcopyro.gibbs.checkpoint import differences
    from spcopyro.results.result import SpCoResult

    record = _record(path)
    asked = record.get("request", {})  # a file of one fit, as first written: no chains, update
    asked = {"chains": 1, "update": None, **asked} if isinstance(asked, dict) else {}
    problems = differences(asked, _request(args, on_map, settings, options))
    if problems:
        raise ValueError(f"--resume {path}: a finished fit made for other data or settings: "
                         + "; ".join(problems))  # fmt: skip
    try:
        fits, kept = int(record.get("fits", 1)), int(record.get("kept", 0))  # type: ignore[call-overload]
        if not 0 <= kept < fits:
            raise IndexError(f"fit {kept} kept of {fits}")
        results = []
        with read_npz(Path(path)) as z:
            for k in range(fits):
                prefix = _prefix(k)
                arrays = {n[len(prefix) :]: z[n] for n in z.files if n.startswith(prefix)}
                saved = json.loads(str(z[_settings_key(k)]))
                results.append(SpCoResult._from_saved(Path(path), Path(path), arrays, saved,
                                                      grid=model.grid))  # fmt: skip
            said = json.loads(str(z["said"]))
    except (KeyError, TypeError, ValueError, AttributeError, IndexError,
            *DAMAGED_FILE_ERRORS) as error:  # fmt: skip
        raise ValueError(f"{path}: a damaged finished fit ({type(error).__name__}: {error}); "
                         "run the fit again without --resume") from None  # fmt: skip
    return results, kept, [str(line) for line in said]


def keep_finished(job: FitJob) -> Path | None:
    """``fit``'s finished fit (``job.finished``: every fit's result, the one kept, the warnings)
    kept in ``OUT.checkpoint.npz`` when Ctrl-C stops the writing of its outputs; None where none
    is kept (no fit finished, Gibbs chains that keep their own checkpoint, or another fit
    :func:`~spcopyro.cli.fit_resume.keeps_finished_fit` keeps not, or the file could not be
    written)."""
    from spcopyro._util.outputs import checkpoint_path

    if job.finished is None or not keeps_finished_fit(job.args):
        return None
    results, kept, said = job.finished
    try:
        return save_finished_fit(
            checkpoint_path(job.staged.out), job.args, results, kept, said, on_map=job.map_house,
            settings=job.settings, options=job.options,
        )  # fmt: skip
    except OSError:  # a full disk: the line says the fit is lost, as it was
        return None


def restore_finished(job: FitJob) -> tuple[list[SpCoResult], int] | None:
    """The finished fit ``--resume`` names, where it names one (else None: a fit runs), for
    ``fit`` to write: every fit's result and the one kept; ``job`` then holds the warnings its
    run had given (``config.json``'s, as that run would have written them)."""
    args = job.args
    if not resumes_finished_fit(args):
        return None
    results, kept, said = load_finished_fit(
        args.resume, args, model=job.house, on_map=job.map_house, settings=job.settings,
        options=job.options,
    )  # fmt: skip
    job.said[:] = said  # the same list: the warnings from here on are added to it
    return results, kept


def _prefix(k: int) -> str:
    """The prefix of fit ``k``'s arrays: ``result_`` (the first, as a file of one fit has it),
    ``result1_``, ``result2_``, ..."""
    return PREFIX if k == 0 else f"result{k}_"


def _settings_key(k: int) -> str:
    """The key of fit ``k``'s ``config.json`` settings: ``settings``, ``settings1``, ..."""
    return "settings" if k == 0 else f"settings{k}"


def _record(path: str | os.PathLike[str]) -> dict[str, object]:
    """The JSON record of the checkpoint file ``path`` (ValueError unless a finished fit's)."""
    from spcopyro.gibbs.checkpoint import checkpoint_record, open_checkpoint

    with open_checkpoint(path) as z:
        return checkpoint_record(path, z, form=FORMAT, version=VERSION, kind="finished fit")


def _request(
    args: argparse.Namespace, on_map: House, settings: SpCoSettings, options: object | None
) -> dict[str, object]:
    """What makes a fit this fit, as JSON: the method and its options, the settings, the
    iterations, the fits (``--chains``), the seed, the start, the estimate, the refinement, the
    fit it updates and the house."""
    given = dataclasses.asdict(options) if dataclasses.is_dataclass(options) else None
    request = {
        "method": args.method, "options": given, "model": settings.model.to_json(),
        "data_preparation": settings.data.to_json(), "sweeps": args.sweeps,
        "chains": 1 if args.chains is None else int(args.chains),
        "seed": args.seed, "init": args.init, "init_from": args.init_from,
        "marginal_samples": args.marginal_samples, "point_estimate": args.point_estimate,
        "refine": args.refine, "update": _updated(args.update),
        "house_sha256": _fingerprint(on_map),
    }  # fmt: skip
    return json.loads(json.dumps(request, default=str))


def _updated(update: str | None) -> dict[str, str] | None:
    """The fit ``--update`` continues: its folder as given and the sha256 (hex) of its
    result.npz, the state the update started from (None: no ``--update``)."""
    if update is None:
        return None
    return {"fit": str(update), "result_sha256": file_sha256(Path(update) / "result.npz")}


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
