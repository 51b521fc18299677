"""Choice of sweep implementation: the readable PyTorch reference or the compiled numba one."""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import torch

from spcopyro.gibbs.state import GibbsState
from spcopyro.gibbs.sweep import gibbs_sweep
from spcopyro.model import potts_agreements

SweepFunction = Callable[..., GibbsState]
BACKENDS = ("auto", "torch", "numba")


def sweep_function(backend: str = "auto") -> SweepFunction:
    """The sweep implementation: ``"torch"`` (the readable reference, :func:`gibbs_sweep`),
    ``"numba"`` (compiled, same distribution; needs the optional ``numba`` package) or ``"auto"``
    (numba when installed). Both take ``(state, data, config, generator, plan)``.
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS}")
    if backend == "torch":
        return gibbs_sweep
    try:
        from spcopyro.gibbs.numba_sweep import gibbs_sweep_numba
    except ImportError:
        if backend == "numba":
            raise ImportError(
                "backend 'numba' needs the numba package: pip install 'spcopyro[fast]'"
            ) from None
        return gibbs_sweep
    return gibbs_sweep_numba


class Backend(NamedTuple):
    """A sweep implementation and the matching Potts statistic E(C) (for the per-sweep trace)."""

    name: str
    sweep: SweepFunction
    potts_agreements: Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


def get_backend(backend: str = "auto") -> Backend:
    """The :class:`Backend` named ``backend`` (see :func:`sweep_function`)."""
    sweep = sweep_function(backend)
    if sweep is gibbs_sweep:
        return Backend("torch", gibbs_sweep, potts_agreements)
    from spcopyro.gibbs.numba_sweep import potts_agreements_numba

    return Backend("numba", sweep, potts_agreements_numba)
