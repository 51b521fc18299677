"""The compiled path of memoized VI (spcopyro.guides.numba_memoized) against its torch path:
the same q, memo sums and ELBO trace after a few passes (several blocks a step, several local
sweeps, float32 and float64 storage), and the backend selection with and without numba."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import torch

from spcopyro.guides.memoized import (
    StochasticOptions,
    compact_initial_q,
    compiled_path,
    run_stochastic,
    start_state,
)

try:  # the compiled path is the fast extra's; the torch path's tests run without it
    from spcopyro.guides import numba_memoized
except ImportError:
    numba_memoized = None
needs_numba = pytest.mark.skipif(numba_memoized is None, reason="numba is not installed (.[fast])")


def run(data, config, backend: str, dtype: str, **changes):
    options = StochasticOptions(block_size=12, tolerance=0.0, dtype=dtype, backend=backend,
                                **changes)  # fmt: skip
    generator = torch.Generator().manual_seed(0)
    q = compact_initial_q(data, config, generator, dtype=getattr(torch, dtype))
    result = run_stochastic(data, config, 4, q=q, generator=generator, options=options,
                            progress=False)  # fmt: skip
    return result


@needs_numba
@pytest.mark.parametrize(
    ("dtype", "changes", "tolerance"),
    [
        ("float64", {}, 1e-12),
        ("float64", {"blocks_per_step": 3, "local_sweeps": 2, "anneal_passes": 2}, 1e-12),
        ("float32", {"blocks_per_step": 2}, 1e-5),
    ],
)
def test_numba_equals_the_torch_path(memoized_house, dtype, changes, tolerance):
    _, data, config = memoized_house
    reference = run(data, config, "torch", dtype, **changes)
    compiled = run(data, config, "numba", dtype, **changes)
    torch.testing.assert_close(compiled.q, reference.q, rtol=0, atol=tolerance)
    np.testing.assert_allclose(compiled.objective, reference.objective, rtol=tolerance)
    torch.testing.assert_close(compiled.factors.pi, reference.factors.pi, rtol=tolerance,
                               atol=0)  # fmt: skip


def test_backend_selection(memoized_house, monkeypatch):
    _, data, config = memoized_house
    q = compact_initial_q(data, config, torch.Generator().manual_seed(0))
    torch_state = start_state(data, config, q, StochasticOptions(backend="torch"))
    assert compiled_path("torch") is None and torch_state.local_rows is None
    auto = start_state(data, config, q, StochasticOptions())
    assert (auto.local_rows is None) == (numba_memoized is None)
    if auto.local_rows is not None:
        assert (auto.local_rows == -1).all() and auto.nbytes()["scratch"] == 8 * data.num_free
    with pytest.raises(ValueError, match="StochasticOptions.backend="):
        StochasticOptions(backend="gpu")
    monkeypatch.setitem(sys.modules, "spcopyro.guides.numba_memoized", None)  # numba missing
    assert compiled_path("auto") is None
    with pytest.raises(ImportError):
        compiled_path("numba")
    result = run(data, config, "auto", "float64")
    assert np.isfinite(result.objective).all()
