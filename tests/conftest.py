"""Shared fixtures: a fixed seed per test, and the public dataset (skipped when absent)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import torch

# Default location of the public dataset, relative to the project root (see README).
DEFAULT_DATASET = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "spcomapping"
HOUSES = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")


def find_dataset() -> Path | None:
    """The dataset folder named by $SPCOPYRO_DATA, else ../shared/data/spcomapping, else None."""
    env = os.environ.get("SPCOPYRO_DATA")
    root = Path(env) if env else DEFAULT_DATASET
    return root.resolve() if (root / "map").is_dir() else None


@pytest.fixture
def dataset_root() -> Path:
    root = find_dataset()
    if root is None:
        pytest.skip(
            "public SpCoMapping dataset not found: set SPCOPYRO_DATA or place it at "
            f"{DEFAULT_DATASET} (clone EmergentSystemLabStudent/Dataset_of_SpCoMapping)"
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
