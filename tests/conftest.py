"""Shared fixtures: a fixed seed per test, the public dataset (skipped when absent) and the
Gibbs sweep backends (each test taking ``backend`` runs once per backend)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from spcopyro.data import find_dataset_root
from spcopyro.gibbs.backends import SweepBackend, get_backend

HOUSES = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")


@pytest.fixture
def dataset_root() -> Path:
    """The public dataset ($SPCOPYRO_DATA or ../shared/data/spcomapping); skips when absent."""
    try:
        root = find_dataset_root()
    except FileNotFoundError as error:
        pytest.skip(f"public SpCoMapping dataset not usable: {error}")
    if root is None:
        pytest.skip(
            "public SpCoMapping dataset not found: set SPCOPYRO_DATA or place it at "
            "../shared/data/spcomapping (clone EmergentSystemLabStudent/Dataset_of_SpCoMapping)"
        )
    return root


@pytest.fixture(autouse=True)
def _fixed_seed():
    """Every test starts from the same global RNG state."""
    torch.manual_seed(0)
    np.random.seed(0)  # noqa: NPY002 - legacy global state, reset for code that uses it
    yield


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture(params=["torch", "numba"])
def backend(request) -> SweepBackend:
    """A sweep backend (:func:`spcopyro.gibbs.backends.get_backend`): the torch reference, then
    the compiled numba one, skipped where the optional numba package is not installed."""
    if request.param == "numba":
        pytest.importorskip(
            "numba", reason="numba is not installed: the compiled backend (spcopyro[fast]) is "
            "tested only where it is"
        )  # fmt: skip
    return get_backend(request.param)
