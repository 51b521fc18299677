"""Choice of sweep implementation: the readable PyTorch reference or the compiled numba one."""

from __future__ import annotations

from collections.abc import Callable

from spcopyro.gibbs.state import GibbsState
from spcopyro.gibbs.sweep import gibbs_sweep

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
