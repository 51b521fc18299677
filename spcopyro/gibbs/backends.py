"""What a sweep backend supplies, and the two there are: the readable PyTorch reference and the
compiled numba one. Both sample the same distribution (tested) from different random streams."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Protocol

import torch

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.options import BACKENDS
from spcopyro.gibbs.state import GibbsState, SweepPlan
from spcopyro.gibbs.sweep import gibbs_sweep
from spcopyro.likelihood import log_joint_variable
from spcopyro.model import ModelData, potts_agreements


class SweepBackend(Protocol):
    """One implementation of Algorithm 1's sweep.

    ``sweep`` draws every cell label from eq. (13), colour block by colour block, then pi and
    each modality's distributions from eqs. (14)-(17) -- redrawing, with probability
    1 - ``unobserved_refresh``, only the rows of concepts holding an observed cell
    (:func:`spcopyro.gibbs.sweep.concepts_to_refresh`). Moves and schedules around the sweep
    (cluster moves, annealing) are composed once, in :func:`spcopyro.gibbs.sampler.step`.
    ``potts_agreements`` is E(C) (the compiled backend has it from the sweep that drew the
    labels); ``trace`` is the per-sweep record: :func:`spcopyro.likelihood.log_joint_variable`
    at a state and its number of concepts in use (compiled in the numba backend).
    """

    name: str

    def sweep(
        self,
        state: GibbsState,
        data: ModelData,
        config: SpCoConfig,
        generator: torch.Generator,
        plan: SweepPlan | None,
        unobserved_refresh: float,
    ) -> GibbsState: ...

    def potts_agreements(self, labels: torch.Tensor, pairs: torch.Tensor) -> torch.Tensor: ...

    def trace(
        self, state: GibbsState, data: ModelData, config: SpCoConfig
    ) -> tuple[float, int]: ...


class TorchBackend:
    """The reference: :func:`spcopyro.gibbs.sweep.gibbs_sweep`."""

    name = "torch"

    def sweep(self, state, data, config, generator, plan, unobserved_refresh):  # noqa: D102
        return gibbs_sweep(state, data, config, generator, plan, unobserved_refresh)

    def potts_agreements(self, labels, pairs):  # noqa: D102
        return potts_agreements(labels, pairs)

    def trace(self, state, data, config):  # noqa: D102
        counts = torch.bincount(state.labels, minlength=config.num_concepts)  # [L]
        agreements = potts_agreements(state.labels, data.pairs)
        value = log_joint_variable(state.labels, state.log_pi, state.log_emissions, data, config,
                                   counts, agreements)  # fmt: skip
        return float(value), int((counts > 0).sum())


class NumbaBackend:
    """The compiled sweep: :func:`spcopyro.gibbs.numba_sweep.gibbs_sweep_numba`."""

    name = "numba"

    def __init__(self) -> None:
        # ImportError without numba (get_backend relies on it).
        from spcopyro.gibbs.numba_sweep import (
            gibbs_sweep_numba,
            potts_agreements_numba,
            trace_numba,
        )

        self._sweep, self._trace = gibbs_sweep_numba, trace_numba
        self._potts_agreements = potts_agreements_numba

    def sweep(self, state, data, config, generator, plan, unobserved_refresh):  # noqa: D102
        return self._sweep(state, data, config, generator, plan, unobserved_refresh)

    def potts_agreements(self, labels, pairs):  # noqa: D102
        return self._potts_agreements(labels, pairs)

    def trace(self, state, data, config):  # noqa: D102
        return self._trace(state, data, config)


def globals_sampler(backend_name: str) -> Callable[..., tuple]:
    """The backend's draw of pi and every modality's distributions given the labels (eqs.
    14-17): ``f(labels, data, config, generator) -> (log pi, log emissions)``."""
    if backend_name == "numba":
        from spcopyro.gibbs.numba_sweep import sample_globals_numba

        return sample_globals_numba
    from spcopyro.gibbs.sweep import sample_globals

    return sample_globals


def label_sampler(backend_name: str) -> Callable[..., torch.Tensor]:
    """The backend's label-only sweep: ``f(state, data, config, generator, plan) -> [N]``."""
    if backend_name == "numba":
        from spcopyro.gibbs.numba_sweep import sample_labels_numba

        return sample_labels_numba
    from spcopyro.gibbs.sweep import sample_labels

    return sample_labels


def get_backend(backend: str = "auto") -> SweepBackend:
    """The backend named ``backend``: ``"torch"``, ``"numba"`` (needs the optional ``numba``
    package: ImportError without it) or ``"auto"`` (numba when installed, else torch)."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS}")
    if backend == "torch":
        return TorchBackend()
    try:
        return NumbaBackend()
    except ImportError:
        if backend == "numba":
            raise ImportError(
                "backend 'numba' needs the numba package: pip install 'spcopyro[fast]'"
            ) from None
        return TorchBackend()


def numba_compile_pending() -> bool:
    """Whether the compiled sweep's code is not in numba's cache yet (the first run after
    installing compiles it, which takes seconds before the first sweep ends). False when numba
    is missing or its cache cannot be inspected (an internal of numba's, so never an error)."""
    try:
        from spcopyro.gibbs.numba_labels import compact_labels

        return not os.path.exists(compact_labels._cache._cache_file._index_path)
    except Exception:  # noqa: BLE001 - a hint for the progress bar, nothing depends on it
        return False
