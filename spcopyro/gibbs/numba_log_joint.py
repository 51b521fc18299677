r"""The run loop's per-sweep record on the compiled backend: the log joint and the concepts in use.

The log joint's state-dependent part (:func:`spcopyro.likelihood.log_joint_variable` for [N]
labels; tested equal to rounding),

.. math::

    (a_\pi - 1) \sum_l \log\pi_l + \sum_m (a_m - 1) \sum_{l,k} \log\phi_{m,lk}
    + \sum_l m_l \log\pi_l + \gamma E(C) + \sum_m \sum_{i \in \text{obs}} x_i \cdot
    \log\phi_{m, C_i},

is computed by the compiled sweep itself, right after it drew the state, from the concept sizes
m_l and E(C) it counted while drawing the labels (:mod:`spcopyro.gibbs.numba_labels`) and the
numpy tables at hand (:func:`remember_sweep`); :func:`trace_numba` then only looks it up and
adds gamma E(C) under the chain's own gamma (an annealing sweep draws under a smaller one). The
record is keyed by the state's very tensors and their in-place version counters, and by the
concentrations it used: a state another move changed, or one under other hyperparameters, is
computed afresh. At a sweep of about a millisecond, the torch expression's dozen small
operations (~0.1 ms) and even the conversions of a separate compiled call (~40 us) were most of
what the run loop added to the kernel (issue 15).
"""

from __future__ import annotations

import threading
import weakref
from typing import NamedTuple

import numpy as np
import torch
from numba import njit

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.numba_labels import agreements_of
from spcopyro.gibbs.state import GibbsState
from spcopyro.model import ModelData


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _log_joint_variable(
    log_pi: np.ndarray,
    label_counts: np.ndarray,
    pi_concentration: float,
    labels: np.ndarray,
    obs_cells: np.ndarray,
    tables: tuple,
    counts: tuple,
    concentrations: np.ndarray,
    used: np.ndarray,
) -> float:
    """The module docstring's sum without gamma E(C). ``tables`` [L, K_m] and ``counts``
    [M, K_m]: one per modality; ``concentrations``, ``used``: [number of modalities].

    The sums may be reassociated (vectorised): a sequential float sum over 25k entries is
    latency-bound at ~4 cycles an entry; the value differs from the torch sum in the last bits.
    """
    total = 0.0
    for l in range(log_pi.shape[0]):
        total += (pi_concentration - 1.0 + label_counts[l]) * log_pi[l]
    for index in range(len(tables)):
        log_phi, x = tables[index], counts[index]
        prior = 0.0
        for l in range(log_phi.shape[0]):
            for k in range(log_phi.shape[1]):
                prior += log_phi[l, k]
        total += (concentrations[index] - 1.0) * prior
        if used[index]:
            for m in range(x.shape[0]):
                c = labels[obs_cells[m]]
                for k in range(x.shape[1]):
                    total += x[m, k] * log_phi[c, k]
    return total


def _array(tensor: torch.Tensor, dtype: type = np.float64) -> np.ndarray:
    """A C-contiguous numpy view of a CPU tensor (a copy only if dtype or layout differ)."""
    return np.ascontiguousarray(tensor.detach().numpy(), dtype=dtype)


def _parameters(data: ModelData, config: SpCoConfig) -> tuple[np.ndarray, np.ndarray]:
    """(concentrations, used) [number of modalities] of ``config`` for ``data``'s modalities."""
    names = [modality.name for modality in data.modalities]
    return (
        np.array([config.concentration(name) for name in names], dtype=np.float64),
        np.array([config.uses(name) for name in names], dtype=np.bool_),
    )


def log_joint_variable_numba(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    label_counts: np.ndarray,
    agreements: float,
) -> float:
    """:func:`spcopyro.likelihood.log_joint_variable` of a hard labelling, compiled (module doc).

    ``label_counts`` [L] (cells per concept) and ``agreements`` E(C) are the labelling's.
    """
    concentrations, used = _parameters(data, config)
    total = _log_joint_variable(
        _array(state.log_pi), np.asarray(label_counts, dtype=np.float64),
        float(config.pi_concentration), _array(state.labels, np.int64),
        _array(data.obs_cells, np.int64), tuple(_array(table) for table in state.log_emissions),
        tuple(_array(modality.counts) for modality in data.modalities), concentrations, used,
    )  # fmt: skip
    return total + float(config.gamma) * float(agreements)


class _SweepRecord(NamedTuple):
    """What a compiled sweep knows about the state it returned (module docstring)."""

    tensors: tuple[weakref.ref, ...]  # labels, log pi, then each log emission table
    versions: tuple[int, ...]  # their in-place version counters then
    pairs: weakref.ref  # the data's [P, 2] pairs the agreements count
    agreements: int  # E(C)
    label_counts: np.ndarray  # [L] float64 cells per concept
    concentrations: tuple[float, ...]  # (a_pi, a_m..., used_m...) the variable part was taken at
    variable: float  # the log joint's variable part without gamma E(C)


_RECORDS_KEPT = 64
# id(labels tensor) -> its record (oldest first). Chains advancing in threads
# (spcopyro.gibbs.chains) share it: changes hold the lock.
_records: dict[int, _SweepRecord] = {}
_records_lock = threading.Lock()


def _tensors(state: GibbsState) -> tuple[torch.Tensor, ...]:
    return (state.labels, state.log_pi, *state.log_emissions)


def _key(config: SpCoConfig, concentrations: np.ndarray, used: np.ndarray) -> tuple[float, ...]:
    """What a recorded log joint depends on besides the state: (a_pi, a_m..., used_m...), from
    :func:`_parameters`' ``concentrations`` and ``used``."""
    return (float(config.pi_concentration), *concentrations.tolist(), *used.tolist())


def remember_sweep(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    agreements: int,
    label_counts: np.ndarray,
    obs_cells: np.ndarray,
    counts: tuple[np.ndarray, ...],
    labels: np.ndarray,
) -> None:
    """Record the state a compiled sweep just drew: its E(C), concept sizes [L] and the log
    joint's variable part under ``config``'s concentrations, computed here from the sweep's own
    arrays (``labels`` [N] or longer, any integer type; ``counts`` [M, K_m] per modality)."""
    concentrations, used = _parameters(data, config)
    variable = _log_joint_variable(
        state.log_pi.numpy(), label_counts, float(config.pi_concentration), labels, obs_cells,
        tuple(table.numpy() for table in state.log_emissions), counts, concentrations, used,
    )  # fmt: skip
    tensors = _tensors(state)
    record = _SweepRecord(
        tuple(weakref.ref(t) for t in tensors), tuple(t._version for t in tensors),
        weakref.ref(data.pairs), int(agreements), label_counts,
        _key(config, concentrations, used), variable,
    )  # fmt: skip
    with _records_lock:
        while len(_records) >= _RECORDS_KEPT:
            del _records[next(iter(_records))]
        _records[id(state.labels)] = record


def _recall(labels: torch.Tensor, pairs: torch.Tensor | None = None) -> _SweepRecord | None:
    """The record of the sweep that returned ``labels`` if they were not changed in place since
    (and, given ``pairs``, its agreements were counted on these pairs)."""
    record = _records.get(id(labels))
    if record is None or record.tensors[0]() is not labels or record.versions[0] != labels._version:
        return None
    if pairs is not None and record.pairs() is not pairs:
        return None
    return record


def _same_state(record: _SweepRecord, state: GibbsState) -> bool:
    tensors = _tensors(state)
    return len(tensors) == len(record.tensors) and all(
        ref() is t and t._version == version
        for ref, t, version in zip(record.tensors, tensors, record.versions, strict=True)
    )


def trace_numba(state: GibbsState, data: ModelData, config: SpCoConfig) -> tuple[float, int]:
    """(:func:`spcopyro.likelihood.log_joint_variable` at ``state`` under ``config``, concepts in
    use): looked up when a compiled sweep returned this very state (module docstring), else
    computed (compiled) from a recount."""
    record = _recall(state.labels, data.pairs)
    if record is not None and record.label_counts.shape[0] == config.num_concepts:
        counts, agreements = record.label_counts, record.agreements
        current = _key(config, *_parameters(data, config))
        if _same_state(record, state) and record.concentrations == current:
            value = record.variable + float(config.gamma) * agreements
            return value, int(np.count_nonzero(counts))
    else:
        labels = _array(state.labels, np.int64)
        counts = np.bincount(labels, minlength=config.num_concepts).astype(np.float64)
        agreements = agreements_of(labels, _array(data.pairs, np.int64))
    value = log_joint_variable_numba(state, data, config, counts, agreements)
    return value, int(np.count_nonzero(counts))


def potts_agreements_numba(labels: torch.Tensor, pairs: torch.Tensor) -> torch.Tensor:
    """E(C) of :func:`spcopyro.model.potts_agreements` (float64 scalar), compiled (or what the
    sweep that returned ``labels`` counted)."""
    record = _recall(labels, pairs)
    if record is not None:
        return torch.tensor(float(record.agreements), dtype=torch.float64)
    total = agreements_of(_array(labels, np.int64), _array(pairs, np.int64))
    return torch.tensor(float(total), dtype=torch.float64)


def label_counts_numba(labels: torch.Tensor, num_concepts: int) -> torch.Tensor:
    """[L] int64 cells per concept (``torch.bincount(labels, minlength=L)``), or what the sweep
    that returned ``labels`` counted."""
    record = _recall(labels)
    if record is not None and record.label_counts.shape[0] == num_concepts:
        return torch.from_numpy(record.label_counts.astype(np.int64))
    return torch.bincount(labels, minlength=num_concepts)
