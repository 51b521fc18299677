"""The compiled sweep's background table (spcopyro.gibbs.numba_background): its centring of the
logits equals the numpy steps it replaced to the bit, and a non-finite row is named."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem

pytest.importorskip("numba")

from spcopyro.gibbs.numba_background import _centre_rows, background_table  # noqa: E402
from spcopyro.gibbs.sampler import init  # noqa: E402
from spcopyro.gibbs.state import GibbsState  # noqa: E402


def _numpy_centre(logits: np.ndarray, log_pi: np.ndarray) -> np.ndarray:
    """The table's steps as numpy wrote them before _centre_rows."""
    logits = logits.copy()
    logits[-1] = 0.0
    logits += log_pi
    logits -= logits.max(axis=1, keepdims=True)
    return logits


def test_centre_rows_is_the_numpy_steps_to_the_bit():
    rng = np.random.default_rng(0)
    for scale in (1e-3, 1.0, 1e3, 1e12):
        logits = rng.normal(size=(40, 120)) * scale  # [M + 1, L]
        logits[3, :7] = -np.inf  # a concept with zero probability in one row
        logits[5] = rng.normal(size=120) * 1e-300  # subnormal differences
        log_pi = rng.normal(size=120) * scale
        expected = _numpy_centre(logits, log_pi)
        out = logits.copy()
        assert _centre_rows(out, log_pi) == -1
        assert np.array_equal(out.view(np.uint64), expected.view(np.uint64)), scale


@pytest.mark.parametrize(
    ("row", "value"),
    [(2, np.nan), (2, np.inf), (0, np.nan), (4, -np.inf)],
)
def test_centre_rows_names_the_first_non_finite_row(row, value):
    logits = np.zeros((6, 5))  # [M + 1, L]
    log_pi = np.zeros(5)
    if value == -np.inf:
        logits[row] = value  # every concept impossible: no finite maximum
    else:
        logits[row, 3] = value
        logits[row + 1, 1] = value  # a later bad row is not the one named
    assert _centre_rows(logits, log_pi) == row


def test_background_table_names_the_row_a_nan_reaches():
    grid, data = random_problem(1)
    cfg = config()
    state = init(data, cfg, torch.Generator().manual_seed(2))
    table = background_table(state, data, cfg)  # [M + 1, L + D]
    assert np.isfinite(table).all() and (table[:, : cfg.num_concepts].max(axis=1) == 1.0).all()
    bad_counts = data.modality("images").counts.clone()
    bad_counts[3, 0] = np.nan
    with pytest.raises(ValueError, match="observed cell in row 3 of data.obs_cells"):
        background_table(state, data.with_counts("images", bad_counts), cfg)
    log_pi = state.log_pi.clone()
    log_pi[1] = np.nan
    nan_pi = GibbsState(state.labels, log_pi, state.log_emissions)
    with pytest.raises(ValueError, match="not finite for the observed cell in row 0"):
        background_table(nan_pi, data, cfg)  # every row holds pi: the first is named
