"""Saving an interrupted variational fit to a file and going on from it.

A variational method's state is, up to what it can recompute, its q(C): CAVI's global factors
are a function of q (eqs. 14-17 in expectation), memoized VI's memo is q summed block by block,
LBP's beliefs are its q. A checkpoint therefore keeps q and the driver's record of the
iterations so far (:class:`~spcopyro.inference.driver.Trajectory`), and the run goes on with
the method started at that q, its new iterations numbered on from the record
(:class:`~spcopyro.inference.protocol.Resumption`). For CAVI's torch backend the state *is* q
and its factors, so the continued run equals the run never stopped; the other methods go on
from the same q with what they rebuild from it (CAVI's compiled backend its active set, LBP its
messages, memoized VI its memo and block order, SVI its optimiser's moments): a warm start
at the objective reached, not the same iterates.

One ``.npz`` file (written whole or not at all: :func:`spcopyro._util.outputs.replace_file`), N
free cells, L concepts, S iterations done:

=============================  =================================================================
``marginals``                  [N, L] float64 q(C_i = l) after iteration S - 1
``objective`` / ``gammas``     [S] float64 the driver's record
``num_concepts``               [S] int64
``seconds``                    [S] float64 cumulative wall-clock seconds
``label_samples``              [S', N] int16 kept label maps, with ``sample_iterations`` [S']
``record``                     JSON: format, what the file is, the method and its options, the
                               model's settings, the data's fingerprint, the caller's settings
=============================  =================================================================

:func:`load_variational` refuses a checkpoint made for another method, options, model
settings, data or caller's settings, naming what differs, as Gibbs checkpoints do
(:mod:`spcopyro.gibbs.checkpoint`); options a resumed run does not read (its start's: svi's
``label_smoothing``) are not compared, and options that depend on the start are compared as
they ran (:meth:`~spcopyro.guides.svi_method.SVIOptions.for_start`, as
:class:`~spcopyro.fit.variational_checkpoint.VariationalSaving` passes them).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import torch

from spcopyro._util.messages import setting
from spcopyro._util.npz import write_npz
from spcopyro._util.outputs import DAMAGED_FILE_ERRORS, replace_file
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.checkpoint import (
    checkpoint_record,
    data_differences,
    data_fingerprint,
    differences,
    open_checkpoint,
)
from spcopyro.inference.driver import Trajectory
from spcopyro.inference.protocol import Resumption, resume_ignores
from spcopyro.model import DTYPE, ModelData

FORMAT = "spcopyro-variational-checkpoint"
VERSION = 1
WHAT = (
    "the q(C) of an interrupted spcopyro variational fit -- not a result: continue it with "
    "`spcopyro fit DATA --out OUT ... --resume THIS_FILE` (or spcopyro.guides.checkpoint."
    "load_variational)"
)
RECORDS = ("objective", "num_concepts", "seconds", "gammas")


class CheckpointMismatchError(ValueError):
    """A variational checkpoint made for another fit (:func:`load_variational`): another
    method, options, model settings, data or caller's settings. The message names each
    difference; ``options`` are the names of the method's options among them (top-level
    fields, as the checkpoint and the options here differ: what a caller may explain, e.g.
    :class:`~spcopyro.fit.variational_checkpoint.VariationalSaving` an option left to the
    start, in ``note``, said after the differences)."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        problems: Sequence[str],
        options: Sequence[str] = (),
        note: str = "",
    ) -> None:
        said = f"{path} was made for other data or settings: " + "; ".join(problems)
        super().__init__(f"{said} ({note})" if note else said)
        self.path = Path(path)
        self.problems = tuple(problems)
        self.options = tuple(options)
        self.note = note


def _header(method: str, options: object, config: SpCoConfig, data: ModelData) -> dict:
    from spcopyro.guides.lbp_method import LBPOptions, resolve_lbp_backend

    fields = dataclasses.asdict(options) if dataclasses.is_dataclass(options) else {}
    fields = _resumed_fields(fields, options)
    if isinstance(options, LBPOptions) and options.backend == "auto":  # torch at gamma D > 300
        fields["backend"] = resolve_lbp_backend(options, data, config)
    return {
        "method": method,
        "options": _backends_resolved(fields),  # what ran: "auto" the one it chose
        "model": config.to_json(),
        "data_sha256": data_fingerprint(data),
    }


def _differing_keys(saved: Mapping[str, object], here: Mapping[str, object]) -> list[str]:
    """The keys whose values differ between two records, compared as JSON values (as
    :func:`~spcopyro.gibbs.checkpoint.differences` compares them: a tuple here is the list
    saved)."""
    old, new = json.loads(json.dumps(dict(saved))), json.loads(json.dumps(dict(here)))
    return [key for key in sorted(set(old) | set(new)) if old.get(key) != new.get(key)]


def _resumed_fields(fields: Mapping[str, object], options: object) -> dict[str, object]:
    """``fields`` (``options``' or a checkpoint's record of them) without those a resumed run
    does not read (:func:`~spcopyro.inference.protocol.resume_ignores`: svi's
    ``label_smoothing``, the start's, which a checkpoint from before 2026-12-05 recorded as 0.9
    against None now)."""
    ignored = resume_ignores(options)
    return {key: value for key, value in fields.items() if key not in ignored}


def _backends_resolved(options: Mapping[str, object]) -> dict[str, object]:
    """``options`` (a dataclass's fields) with each ``backend`` of ``"auto"``, at any depth,
    the backend it runs here (:func:`~spcopyro.guides.run.resolve_backend`): a fit run with
    ``auto`` resumes with the backend that ran named, and the other way round."""
    from spcopyro.guides.run import resolve_backend

    return {
        key: _backends_resolved(value) if isinstance(value, Mapping)
        else resolve_backend("auto") if key == "backend" and value == "auto" else value
        for key, value in options.items()
    }  # fmt: skip


def save_variational(
    path: str | os.PathLike[str],
    marginals: torch.Tensor,
    trajectory: Trajectory,
    *,
    method: str,
    options: object,
    config: SpCoConfig,
    data: ModelData,
    record: Mapping[str, object] | None = None,
) -> Path:
    """Write q(C) ``marginals`` ``[N, L]`` and the ``trajectory`` so far into ``path``,
    replacing any file there atomically. ``record``: the caller's settings, checked on loading."""
    if marginals.shape != (data.num_free, config.num_concepts):
        raise ValueError(
            f"marginals must be [{data.num_free}, {config.num_concepts}], "
            f"got {tuple(marginals.shape)}"
        )
    arrays: dict[str, np.ndarray] = {
        "marginals": marginals.detach().to(DTYPE).numpy(),
        "objective": trajectory.objective.astype(np.float64),
        "num_concepts": trajectory.num_concepts.astype(np.int64),
        "seconds": trajectory.seconds.astype(np.float64),
        "gammas": trajectory.gammas.astype(np.float64),
    }
    if trajectory.label_samples is not None:
        arrays["label_samples"] = trajectory.label_samples
        arrays["sample_iterations"] = trajectory.sample_iterations.astype(np.int64)
    header = {
        "format": FORMAT,
        "version": VERSION,
        "what": WHAT,
        **_header(method, options, config, data),
        "iterations_done": len(trajectory.objective),
        "caller": dict(record or {}),
    }
    arrays["record"] = np.array(json.dumps(header))
    return replace_file(path, lambda file: write_npz(file, arrays))  # savez_compressed's file


def is_variational_checkpoint(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a readable variational checkpoint (a Gibbs one is not)."""
    try:
        with open_checkpoint(path) as z:
            return checkpoint_record(path, z, form=FORMAT, version=VERSION) is not None
    except (OSError, ValueError):
        return False


def load_variational(
    path: str | os.PathLike[str],
    data: ModelData,
    config: SpCoConfig,
    *,
    method: str,
    options: object,
    record: Mapping[str, object] | None = None,
) -> Resumption:
    """The q(C) and record saved in ``path``, for ``InferenceMethod.run(..., resume=...)``.

    Raises:
        FileNotFoundError: no file at ``path``.
        ValueError: ``path`` is not a variational checkpoint or is damaged.
        CheckpointMismatchError: (a ValueError) ``path`` was made for another method, options,
            model settings (``config``), ``data`` or caller's settings (``record``); the
            message names what differs, its ``options`` the options among them.
    """
    path = Path(path)
    with open_checkpoint(path) as z:
        saved = checkpoint_record(path, z, form=FORMAT, version=VERSION,
                                  kind="variational checkpoint")  # fmt: skip
        here = _header(method, options, config, data)
        if saved["method"] != method:  # its options and record are another method's too
            raise CheckpointMismatchError(path, [
                f"method: {saved['method']!r} in the checkpoint, {method!r} here: resume it with "
                + setting(f"method={saved['method']!r}", f"--method {saved['method']}")
            ])  # fmt: skip
        problems = data_differences(saved["data_sha256"], data)
        problems += differences(saved["model"], here["model"])
        ours = _backends_resolved(_resumed_fields(saved["options"], options))  # what it reads
        problems += differences(ours, here["options"])
        if record is not None:
            problems += differences(saved["caller"], record)
        if problems:
            raise CheckpointMismatchError(path, problems, _differing_keys(ours, here["options"]))
        try:
            marginals = torch.from_numpy(z["marginals"].astype(np.float64))  # [N, L]
            columns = [z[name] for name in RECORDS]
            samples = z["label_samples"] if "label_samples" in z.files else None
            sampled = z["sample_iterations"] if samples is not None else None
        except (KeyError, *DAMAGED_FILE_ERRORS) as error:
            raise ValueError(f"{path}: a damaged checkpoint ({error})") from None
    if marginals.shape != (data.num_free, config.num_concepts):
        raise ValueError(f"{path}: a damaged checkpoint (q(C) of shape {tuple(marginals.shape)})")
    objective, used, seconds, gammas = columns
    trajectory = Trajectory(
        None, objective.astype(np.float64), used.astype(np.int64), seconds.astype(np.float64),
        gammas.astype(np.float64), samples, None if sampled is None else sampled.astype(np.int64),
        f"resumed after {len(objective)} iterations",
    )  # fmt: skip
    return Resumption(marginals, trajectory)
