"""Shared fixtures: a fixed seed per test, the public dataset (skipped when absent), the
Gibbs sweep backends (each test taking ``backend`` runs once per backend) and the benchmark
tests' imported scripts (``script``, ``keep_torch_threads``)."""

from __future__ import annotations

import importlib
import logging
import os
import signal
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
import torch
from benchmark_setup import BENCHMARKS

from spcopyro._util.threads import torch_threads
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


@pytest.fixture(autouse=True)
def _logging_restored():
    """The "spcopyro" logger's level and logging's global disable as they were before the test:
    a benchmark script's main() (tests/test_benchmarks_*.py) quiets them for its tables, and a
    later test's caplog then caught nothing (the suite's result depended on its order)."""
    logger = logging.getLogger("spcopyro")
    level, disabled = logger.level, logging.root.manager.disable
    yield
    logger.setLevel(level)
    logging.disable(disabled)


def _package_environment() -> dict[str, str]:
    """The variables that change what the package does: ``CI`` (bars) and ``SPCOPYRO_*``."""
    return {k: v for k, v in os.environ.items() if k == "CI" or k.startswith("SPCOPYRO_")}


@pytest.fixture(autouse=True)
def _environment_restored():
    """The package's environment variables as they were before the test: a benchmark main()
    run in process once left ``CI=1`` (its ``os.environ.setdefault``), which switched every later
    test's progress bars off (test_postprocessing_progress failed in the whole suite, passed
    alone); the ``script`` fixture (below) now sets it through monkeypatch. Other
    variables are left alone: importing torch or numba sets some of its own (KMP_*, ...)."""
    before = _package_environment()
    yield
    after = _package_environment()
    if after != before:
        for key in after.keys() - before.keys():
            del os.environ[key]
        os.environ.update(before)


@pytest.fixture(autouse=True)
def _no_dask_offload_thread_left():
    """A test that ran a LocalCluster in this process leaves dask.distributed's offload thread
    running (a module-level ThreadPoolExecutor): any later test that forks chain processes is
    then refused them (spcopyro._util.forking: no other thread may run at a fork), so the
    suite's result depended on the order of its tests. After such a test the executor is shut
    down and replaced by a fresh one, which starts its thread only when next used."""
    yield
    utils = sys.modules.get("distributed.utils")
    executor = getattr(utils, "_offload_executor", None)
    if executor is not None and getattr(executor, "_threads", None):
        executor.shutdown(wait=True)
        utils._offload_executor = ThreadPoolExecutor(
            max_workers=1, thread_name_prefix="Dask-Offload"
        )


@pytest.fixture
def ctrl_c_raises():
    """SIGINT raises KeyboardInterrupt in the test, as in an interactive Python, even where the
    test runner was started with SIGINT ignored (a background job of a shell without job
    control, ``nohup``: the ignore is inherited); the previous handler comes back after."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


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


@pytest.fixture(scope="module")
def one_torch_thread():
    """One torch intra-op thread for a module of small tensors (its tests use it through
    ``pytestmark = pytest.mark.usefixtures("one_torch_thread")``): on a loaded machine torch's
    thread pool makes a softmax of a [5, 2] tensor 5000x slower than computing it."""
    with torch_threads(1):
        yield


@pytest.fixture(scope="module")
def memoized_house():
    """(house, model data, model config): a small synthetic house with an open plan (~1000 free
    cells) at L = 8, the map of the memoized-VI tests (both of its paths)."""
    import logging

    from spcopyro.config import preset
    from spcopyro.fit.house import prepare_model_data
    from spcopyro.synthetic import HouseSpec, make_house

    logging.disable(logging.WARNING)  # the Potts critical-coupling note
    house = make_house(seed=1, spec=HouseSpec(height=36, width=44, num_rooms=3, num_open_plan=1))
    settings = preset("original-code", num_concepts=8, gamma=2.1)
    _, data = prepare_model_data(house, settings)
    logging.disable(logging.NOTSET)
    return house, data, settings.model


@pytest.fixture(scope="module")
def home(tmp_path_factory) -> Path:
    """A small synthetic house of three rooms (seed 2, 36 x 44 cells) written in the dataset
    layout once per module: its room folder (for the ``fit`` command's tests)."""
    from spcopyro.synthetic import HouseSpec, write_synthetic

    root = tmp_path_factory.mktemp("data")
    return write_synthetic(root, seed=2, spec=HouseSpec(height=36, width=44, num_rooms=3))


@pytest.fixture
def map_yaml(tmp_path) -> Path:
    """The import-bag tests' map (tests/bag_maps.py): a 60 x 60 free map at 0.1 m, origin
    (-3, -3), so x, y in [-3, 3) m, saved as ``tmp_path/maps/floor.yaml``."""
    from bag_maps import save_free_map

    return save_free_map(tmp_path / "maps")


@pytest.fixture
def no_download(monkeypatch, tmp_path):
    """An empty torch cache of the test's own (``$TORCH_HOME``), and any download attempt fails
    loudly: the features' tests use it (``pytestmark``)."""
    import torch

    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch_home"))

    def refuse(url, *args, **kwargs):
        raise AssertionError(f"a test tried to download {url}")

    monkeypatch.setattr(torch.hub, "download_url_to_file", refuse)


@pytest.fixture
def script(monkeypatch):
    """Import a benchmark script by name (``script("gibbs")``). ``CI=1`` as the scripts' own
    ``os.environ.setdefault("CI", "1")`` would set it (online_update.py, stochastic_vi.py: no bars
    in them or their children), but through monkeypatch, so that it ends with the test."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setenv("CI", "1")
    return importlib.import_module


@pytest.fixture
def keep_torch_threads():
    """Some scripts set torch's thread count before they check their houses: restore it."""
    import torch

    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)
