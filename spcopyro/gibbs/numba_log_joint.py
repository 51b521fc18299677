r"""The per-sweep log joint of a hard labelling, compiled: what the run loop records every sweep.

:func:`log_joint_variable_numba` equals :func:`spcopyro.likelihood.log_joint_variable` for [N]
labels (tested to rounding),

.. math::

    (a_\pi - 1) \sum_l \log\pi_l + \sum_m (a_m - 1) \sum_{l,k} \log\phi_{m,lk}
    + \sum_l m_l \log\pi_l + \gamma E(C) + \sum_m \sum_{i \in \text{obs}} x_i \cdot
    \log\phi_{m, C_i},

from the concept sizes m_l and E(C) that the compiled sweep counted while drawing the labels
(:mod:`spcopyro.gibbs.numba_labels`), in one compiled pass over each table and over the observed
cells: a few microseconds where the torch expression's dozen small operations cost ~0.1 ms, which
at a sweep of about a millisecond was most of the run loop's own cost (issue 15).
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

from spcopyro.config import SpCoConfig
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


def log_joint_variable_numba(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    label_counts: torch.Tensor,
    agreements: torch.Tensor | float,
) -> float:
    """:func:`spcopyro.likelihood.log_joint_variable` of a hard labelling, compiled (module doc).

    ``label_counts`` [L] and ``agreements`` E(C) are the labelling's, as the backend's
    ``label_counts`` / ``potts_agreements`` give them.
    """
    names = [modality.name for modality in data.modalities]
    total = _log_joint_variable(
        _array(state.log_pi),
        _array(label_counts),
        float(config.pi_concentration),
        _array(state.labels, np.int64),
        _array(data.obs_cells, np.int64),
        tuple(_array(table) for table in state.log_emissions),
        tuple(_array(modality.counts) for modality in data.modalities),
        np.array([config.concentration(name) for name in names], dtype=np.float64),
        np.array([config.uses(name) for name in names], dtype=np.bool_),
    )
    return total + float(config.gamma) * float(agreements)
