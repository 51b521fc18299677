"""What only the compiled (numba) backend has: its own normal draws, its input checks, and how the
backend is chosen with and without numba.

Its distribution is tested beside the torch reference's, by the tests taking the ``backend``
fixture (``test_gibbs_conditionals.py``: label and global draws, log-gamma draws, the sweep's
contract; ``test_gibbs_joint.py``: Geweke's joint test).
"""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest
import torch

pytest.importorskip("numba")

from gibbs_problems import config, random_problem  # noqa: E402
from scipy import stats  # noqa: E402

from spcopyro.gibbs.backends import NumbaBackend, TorchBackend, get_backend  # noqa: E402
from spcopyro.gibbs.numba_sweep import (  # noqa: E402
    gibbs_sweep_numba,
    sample_globals_numba,
    sample_standard_normal_numba,
)
from spcopyro.gibbs.sampler import init  # noqa: E402
from spcopyro.gibbs.state import make_sweep_plan  # noqa: E402


def test_ziggurat_normals_match_the_normal_distribution_tails_included():
    z = sample_standard_normal_numba(2_000_000, seed=20)  # [2e6]
    assert stats.kstest(z, "norm").pvalue > 1e-3
    # The ziggurat's base strip and tail (|z| > 3.4426) are separate code paths: count them.
    for lo, hi in ((3.4426, np.inf), (-np.inf, -3.4426), (2.0, 3.4426), (-3.4426, -2.0)):
        p = stats.norm.cdf(hi) - stats.norm.cdf(lo)
        hits = ((z > lo) & (z < hi)).sum()
        assert abs(hits - p * z.size) < 4.5 * np.sqrt(p * z.size), (lo, hi, hits, p * z.size)


def test_invalid_input_raises_clear_errors():
    cfg = config()
    _, data = random_problem(seed=18)
    generator = torch.Generator().manual_seed(19)
    state = init(data, cfg, generator)
    bad = state.labels.clone()
    bad[4] = cfg.num_concepts
    with pytest.raises(ValueError, match=r"labels\[4\] = 3 lies outside \[0, 3\)"):
        gibbs_sweep_numba(state._replace(labels=bad), data, cfg, generator)
    narrow = state._replace(log_emissions=(state.log_theta[:, :1], state.log_w))  # theta [L, 1]
    with pytest.raises(ValueError, match="log_emissions of 'images' has shape"):
        gibbs_sweep_numba(narrow, data, cfg, generator)
    with pytest.raises(ValueError, match="has 1 tables for 2 modalities"):
        gibbs_sweep_numba(state._replace(log_emissions=state.log_emissions[:1]), data, cfg,
                          generator)  # fmt: skip
    _, other = random_problem(seed=18, num_observed=4)
    with pytest.raises(ValueError, match="observed rows do not match"):
        gibbs_sweep_numba(state, data, cfg, generator, make_sweep_plan(other))
    with pytest.raises(ValueError, match=r"gamma \* connectivity must be <= 700"):
        cfg.replace(gamma=200.0)  # exp(gamma D) would overflow: the config refuses it
    nan_words = data.with_counts("words", data.word_counts * float("nan"))
    with pytest.raises(ValueError, match="log-likelihood is not finite"):
        gibbs_sweep_numba(state, nan_words, cfg, generator)


def test_negative_counts_name_the_concentration_and_its_value():
    cfg = config()
    _, data = random_problem(seed=18)
    generator = torch.Generator().manual_seed(19)
    state = init(data, cfg, generator)
    negative = data.with_counts("images", -10.0 * data.image_counts)  # chi = 1: Dir(< 0)
    with pytest.raises(ValueError, match=r"concentration of theta\[\d+, \d+\] is -\d"):
        sample_globals_numba(state.labels, negative, cfg, generator)


def test_backend_choice_and_import_error_without_numba(monkeypatch):
    assert isinstance(get_backend("numba"), NumbaBackend) and get_backend("numba").name == "numba"
    assert isinstance(get_backend("auto"), NumbaBackend)
    assert isinstance(get_backend("torch"), TorchBackend) and get_backend("torch").name == "torch"
    with pytest.raises(ValueError, match="unknown backend 'jax'"):
        get_backend("jax")
    monkeypatch.setitem(sys.modules, "numba", None)  # as if numba were not installed
    monkeypatch.delitem(sys.modules, "spcopyro.gibbs.numba_sweep")
    with pytest.raises(ImportError):
        importlib.import_module("spcopyro.gibbs.numba_sweep")
    assert isinstance(get_backend("auto"), TorchBackend)
    with pytest.raises(ImportError, match="needs the numba package"):
        get_backend("numba")
