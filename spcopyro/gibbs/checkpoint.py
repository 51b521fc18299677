"""Saving Gibbs chains to a file and loading them back: how an interrupted fit goes on.

A checkpoint is one ``.npz`` file (written whole or not at all:
:func:`spcopyro._util.outputs.replace_file`) holding, for each chain k that had started, everything
a
:class:`~spcopyro.gibbs.run.GibbsChain` needs to continue exactly as if it had never stopped
(N free cells, L concepts, S sweeps done, M_m items of modality m):

=========================================  ====================================================
``chain{k}.labels``                        [N] int64 labels of the last completed sweep
``chain{k}.log_pi``                        [L] float64 log pi
``chain{k}.log_emission{m}``               [L, K_m] float64 log distributions, per modality m
``chain{k}.generator``                     [5056] uint8 the torch generator's state
``chain{k}.log_joint`` / ``num_concepts``  [S] float64 / int64: the trace so far
``chain{k}.seconds``                       [S] float64 cumulative wall-clock seconds
``chain{k}.best_labels`` ...               the best state visited (int16 labels), if any
``chain{k}.label_samples``                 [S', N] int16 kept label maps, if any
``chain{k}.hyperparameters``               [S, H] float64 sampled hyperparameters per sweep
                                           (only when ``GibbsOptions.hyper`` samples them)
=========================================  ====================================================

With sampled hyperparameters, each chain's entry of the record also holds ``model_current``,
the chain's model config at its last sweep (the values it continues from).

and ``record``, a JSON text: the format, what the file is (an interrupted fit, *not* a result),
the model's settings (:meth:`~spcopyro.config.SpCoConfig.to_json`), the sampler's options and
the backend that ran, a fingerprint of the model data (:func:`data_fingerprint`), per chain the
sweeps done and the best sweep, and whatever the caller adds (the fit's own settings).

:func:`load_chains` refuses a checkpoint made for other data, model settings, options, backend
(the backends draw different random streams) or caller's settings, naming what differs. Since
the generator's state is saved with the chain, chain k interrupted after s sweeps and continued
to S is bit for bit chain k run to S at once (tested on both backends).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import torch

from spcopyro._util.messages import setting
from spcopyro._util.npz import write_npz
from spcopyro._util.outputs import DAMAGED_FILE_ERRORS, read_npz, replace_file
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import LABEL_DTYPE, GibbsChain
from spcopyro.gibbs.state import GibbsState, make_sweep_plan
from spcopyro.likelihood import log_joint_constant
from spcopyro.model import ModelData

FORMAT = "spcopyro-gibbs-checkpoint"
VERSION = 1
WHAT = (
    "the state of an interrupted spcopyro Gibbs fit -- not a result: continue it with "
    "`spcopyro fit DATA --out OUT ... --resume THIS_FILE` (or spcopyro.gibbs.checkpoint."
    "load_chains)"
)


def data_fingerprint(data: ModelData) -> str:
    """sha256 (hex) of what the model conditions on: the map's neighbour graph, the observed
    cells and every modality's name and counts -- equal exactly when the data are."""
    digest = hashlib.sha256()

    def add(name: str, tensor: torch.Tensor) -> None:
        array = np.ascontiguousarray(tensor.detach().cpu().numpy())
        digest.update(f"{name}:{array.dtype.str}:{array.shape};".encode())
        digest.update(array.tobytes())

    digest.update(f"free:{data.num_free};".encode())
    add("neighbours", data.neighbours)
    add("pairs", data.pairs)
    add("obs_cells", data.obs_cells)
    for modality in data.modalities:
        add(f"modality {modality.name}", modality.counts)
    return digest.hexdigest()


def _options_record(options: GibbsOptions) -> dict[str, object]:
    """The options that change the draws: all but the backend option (compared resolved)."""
    values = dataclasses.asdict(options)
    values.pop("backend")
    return values


def differences(
    saved: Mapping[str, object], current: Mapping[str, object], prefix: str = ""
) -> list[str]:
    """``"NAME: A in the checkpoint, B here"`` for every key whose values differ; within two
    mappings, for each of their keys that differ (``"data_preparation.cell_size: ..."``: the
    two whole mappings left the reader to find the difference)."""
    old: dict[str, object] = json.loads(json.dumps(dict(saved)))
    new: dict[str, object] = json.loads(json.dumps(dict(current)))
    found = []
    for key in sorted(set(old) | set(new)):
        a, b = old.get(key), new.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            found += differences(a, b, f"{prefix}{key}.")
        elif a != b:
            found.append(f"{prefix}{key}: {a!r} in the checkpoint, {b!r} here")
    return found


def save_chains(
    chains: Sequence[GibbsChain | None],
    path: str | os.PathLike[str],
    *,
    record: Mapping[str, object] | None = None,
) -> Path:
    """Write ``chains`` (None: a chain not started yet) into the checkpoint ``path``, replacing
    any file there atomically. ``record``: the caller's settings, checked by :func:`load_chains`.
    All chains must share their data, model settings and options."""
    started = [chain for chain in chains if chain is not None]
    if not started:
        raise ValueError("save_chains needs at least one started chain")
    first = started[0]
    for chain in started[1:]:
        if (chain.data is not first.data or chain.config != first.config
                or chain.options != first.options):  # fmt: skip
            raise ValueError("save_chains: the chains must share data, config and options")
    arrays: dict[str, np.ndarray] = {}
    per_chain: list[dict[str, object] | None] = []
    for k, chain in enumerate(chains):
        if chain is None:
            per_chain.append(None)
            continue
        entry: dict[str, object] = {"sweeps_done": chain.sweeps_done,
                                    "best_sweep": chain.best_sweep}  # fmt: skip
        if chain.current is not None:
            entry["model_current"] = chain.current.to_json()
        per_chain.append(entry)
        arrays.update(_state_arrays(f"chain{k}.", chain.state))
        arrays[f"chain{k}.generator"] = chain.generator.get_state().numpy()
        arrays[f"chain{k}.log_joint"] = np.asarray(chain.log_joint, dtype=np.float64)
        arrays[f"chain{k}.num_concepts"] = np.asarray(chain.num_concepts, dtype=np.int64)
        arrays[f"chain{k}.seconds"] = np.asarray(chain.seconds, dtype=np.float64)
        if chain.best_state is not None:
            arrays.update(_state_arrays(f"chain{k}.best_", chain.best_state))
        if chain.label_samples:
            arrays[f"chain{k}.label_samples"] = chain.sample_stack()  # no copy
            arrays[f"chain{k}.sample_sweeps"] = np.asarray(chain.sample_sweeps, dtype=np.int64)
        if chain.hyper_trace:
            arrays[f"chain{k}.hyperparameters"] = np.asarray(chain.hyper_trace, dtype=np.float64)
    header = {
        "format": FORMAT,
        "version": VERSION,
        "what": WHAT,
        "model": first.config.to_json(),
        "options": dataclasses.asdict(first.options),
        "backend_used": first.backend.name,
        "data_sha256": data_fingerprint(first.data),
        "modalities": [m.name for m in first.data.modalities],
        "chains": per_chain,
        "caller": dict(record or {}),
    }
    arrays["record"] = np.array(json.dumps(header))
    return replace_file(path, lambda file: write_npz(file, arrays))  # savez_compressed's file


def _state_arrays(prefix: str, state: GibbsState) -> dict[str, np.ndarray]:
    arrays = {f"{prefix}labels": state.labels.numpy(), f"{prefix}log_pi": state.log_pi.numpy()}
    for m, table in enumerate(state.log_emissions):
        arrays[f"{prefix}log_emission{m}"] = table.numpy()
    return arrays


def read_record(path: str | os.PathLike[str]) -> dict[str, object]:
    """The JSON record of the checkpoint ``path`` (ValueError if it is not one)."""
    with open_checkpoint(path) as z:
        return checkpoint_record(path, z)


def open_checkpoint(path: str | os.PathLike[str]) -> np.lib.npyio.NpzFile:
    """The checkpoint file ``path`` opened (FileNotFoundError if there is none, ValueError if it
    is not an ``.npz`` file)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint file")
    try:
        return read_npz(path)
    except DAMAGED_FILE_ERRORS as error:
        raise ValueError(f"{path}: not a spcopyro checkpoint ({error})") from None


def checkpoint_record(
    path: str | os.PathLike[str],
    z: np.lib.npyio.NpzFile,
    *,
    form: str = FORMAT,
    version: int = VERSION,
    kind: str = "spcopyro checkpoint",
) -> dict[str, object]:
    """The JSON record of the opened checkpoint ``z``; ValueError unless it is of format
    ``form`` and ``version`` (``kind`` names what was expected: the Gibbs chains' by default;
    :mod:`spcopyro.guides.checkpoint` reads a variational fit's the same way)."""
    try:
        record = json.loads(str(z["record"]))
    except (KeyError, *DAMAGED_FILE_ERRORS):
        record = None
    if not isinstance(record, dict) or record.get("format") != form:
        made_by = _method_of(record)
        if made_by is not None:  # the other kind of spcopyro checkpoint: name its method
            raise ValueError(
                f"{path}: the checkpoint of an interrupted {made_by!r} fit, which this method "
                "cannot continue: resume it with "
                + setting(f"method={made_by!r}", f"--method {made_by}")
            )
        raise ValueError(f"{path}: not a {kind} (no {form} record)")
    if record.get("version") != version:
        raise ValueError(
            f"{path}: checkpoint version {record.get('version')!r}; this spcopyro reads "
            f"version {version}"
        )
    return record


def _method_of(record: object) -> str | None:
    """The method whose interrupted fit a spcopyro checkpoint's ``record`` holds (a variational
    one's ``method``, Gibbs chains' caller's), or None if it is no spcopyro checkpoint."""
    if not isinstance(record, dict) or not str(record.get("format", "")).startswith("spcopyro-"):
        return None
    caller = record.get("caller")
    method = record.get("method") or (caller.get("method") if isinstance(caller, dict) else None)
    if method is None and record.get("format") == FORMAT:
        method = "gibbs"  # chains saved without a caller's record
    return method if isinstance(method, str) else None


def data_differences(saved_sha256: object, data: ModelData) -> list[str]:
    """``["the data differ (...)"]`` when the fingerprint a checkpoint saved is not ``data``'s
    (:func:`data_fingerprint`), else ``[]``."""
    here = data_fingerprint(data)
    if saved_sha256 == here:
        return []
    return [
        f"the data differ (model data fingerprint {str(saved_sha256)[:12]} in the checkpoint, "
        f"{here[:12]} here)"
    ]


def load_chains(
    path: str | os.PathLike[str],
    data: ModelData,
    config: SpCoConfig,
    options: GibbsOptions,
    *,
    record: Mapping[str, object] | None = None,
) -> list[GibbsChain | None]:
    """The chains saved in ``path``, ready for :func:`~spcopyro.gibbs.run.advance` (None for a
    chain that had not started).

    Raises:
        ValueError: ``path`` is not a checkpoint, or was made for other ``data``, model settings
            (``config``), sampler options, backend, or caller's settings (``record``, compared
            with what :func:`save_chains` was given); the message names what differs.
    """
    with open_checkpoint(path) as z:
        saved = checkpoint_record(path, z)
        problems = data_differences(saved["data_sha256"], data)
        problems += differences(saved["model"], config.to_json())  # type: ignore[arg-type]
        problems += differences(
            _options_record(GibbsOptions(**saved["options"])),  # type: ignore[arg-type]
            _options_record(options),
        )
        backend = get_backend(options.backend)
        if saved["backend_used"] != backend.name:
            used = saved["backend_used"]
            problems.append(
                f"backend: {used!r} ran the checkpoint's chains, {backend.name!r} "
                "would continue them (the backends draw different random streams: pass "
                f"{setting(f'backend={used!r}', f'--backend {used}')})"
            )
        if record is not None:
            problems += differences(saved["caller"], record)  # type: ignore[arg-type]
        if problems:
            raise ValueError(f"{path} was made for other data or settings: " + "; ".join(problems))
        try:
            return [
                None if entry is None else _chain(z, k, entry, data, config, options)
                for k, entry in enumerate(saved["chains"])  # type: ignore[arg-type]
            ]
        except (KeyError, RuntimeError, TypeError, IndexError, *DAMAGED_FILE_ERRORS) as error:
            raise ValueError(f"{path}: a damaged checkpoint ({error})") from None


def _chain(
    z: np.lib.npyio.NpzFile,
    k: int,
    entry: Mapping[str, object],
    data: ModelData,
    config: SpCoConfig,
    options: GibbsOptions,
) -> GibbsChain:
    prefix = f"chain{k}."
    state = _state(z, prefix, data, config)
    done, best_sweep = int(entry["sweeps_done"]), int(entry["best_sweep"])  # type: ignore[arg-type]
    log_joint = z[f"{prefix}log_joint"].astype(np.float64)  # [S]
    num_concepts = z[f"{prefix}num_concepts"].astype(np.int64)  # [S]
    seconds = z[f"{prefix}seconds"].astype(np.float64)  # [S]
    if not (len(log_joint) == len(num_concepts) == len(seconds) == done) or best_sweep >= done:
        raise ValueError(f"chain {k}: its trace does not hold its {done} sweeps")
    best_state = None
    if f"{prefix}best_labels" in z.files:
        best_state = _state(z, f"{prefix}best_", data, config)
        best_state = best_state._replace(labels=best_state.labels.to(LABEL_DTYPE))
    samples = z[f"{prefix}label_samples"] if f"{prefix}label_samples" in z.files else None
    generator = torch.Generator()
    generator.set_state(torch.from_numpy(z[f"{prefix}generator"].astype(np.uint8)))
    current = None
    if entry.get("model_current") is not None:
        current = SpCoConfig(**entry["model_current"])  # type: ignore[arg-type]
    hyper_trace: list[list[float]] = []
    if f"{prefix}hyperparameters" in z.files:
        hyper_trace = z[f"{prefix}hyperparameters"].astype(np.float64).tolist()
    if options.hyper.active and len(hyper_trace) != done:
        raise ValueError(f"chain {k}: its hyperparameter trace does not hold its {done} sweeps")
    return GibbsChain(
        data=data,
        config=config,
        options=options,
        generator=generator,
        backend=get_backend(options.backend),
        plan=make_sweep_plan(data),
        state=state,
        constant=float(log_joint_constant(data, config if current is None else current)),
        sweeps_done=done,
        best_value=float(log_joint[best_sweep]) if best_sweep >= 0 else -np.inf,
        best_state=best_state,
        best_sweep=best_sweep,
        log_joint=log_joint.tolist(),
        num_concepts=num_concepts.tolist(),
        seconds=seconds.tolist(),
        label_samples=[] if samples is None else [row.copy() for row in samples],
        sample_sweeps=[] if samples is None else z[f"{prefix}sample_sweeps"].tolist(),
        current=current,
        hyper_trace=hyper_trace,
    )


def _state(z: np.lib.npyio.NpzFile, prefix: str, data: ModelData, config: SpCoConfig) -> GibbsState:
    """The state saved under ``prefix``, its shapes checked against the data and settings."""
    labels = z[f"{prefix}labels"]  # [N]
    log_pi = z[f"{prefix}log_pi"]  # [L]
    L = config.num_concepts
    if labels.shape != (data.num_free,) or log_pi.shape != (L,):
        raise ValueError(f"{prefix}labels {labels.shape} / log_pi {log_pi.shape} do not fit")
    tables = []
    for m, modality in enumerate(data.modalities):
        table = z[f"{prefix}log_emission{m}"]  # [L, K_m]
        if table.shape != (L, modality.counts.shape[1]):
            raise ValueError(f"{prefix}log_emission{m} has shape {table.shape}")
        tables.append(torch.from_numpy(table.astype(np.float64)))
    return GibbsState(
        torch.from_numpy(labels.astype(np.int64)),
        torch.from_numpy(log_pi.astype(np.float64)),
        tuple(tables),
    )


def save_chain(
    chain: GibbsChain,
    path: str | os.PathLike[str],
    *,
    record: Mapping[str, object] | None = None,
) -> Path:
    """:func:`save_chains` of one chain."""
    return save_chains([chain], path, record=record)


def load_chain(
    path: str | os.PathLike[str],
    data: ModelData,
    config: SpCoConfig,
    options: GibbsOptions = GibbsOptions(),
    *,
    record: Mapping[str, object] | None = None,
) -> GibbsChain:
    """The one chain saved in ``path`` (:func:`load_chains`; ValueError if it holds several)."""
    chains = load_chains(path, data, config, options, record=record)
    if len(chains) != 1 or chains[0] is None:
        raise ValueError(f"{path} holds {len(chains)} chains, not one: use load_chains")
    return chains[0]
