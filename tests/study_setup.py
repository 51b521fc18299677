"""What the study tests (tests/test_study*.py) set up alike: small houses, the tiny studies
they run, and a LocalCluster for a study too short to start one by itself."""

from __future__ import annotations

from pathlib import Path

import pytest


def on_a_cluster(monkeypatch: pytest.MonkeyPatch) -> None:
    """``run_study(workers > 1)`` starts its (real or fake) LocalCluster even for a study of a
    few short cells, which it runs in its own process otherwise
    (:func:`spcopyro.study.order.cluster_pays`): the tests of the cluster's path run tiny
    studies."""
    from spcopyro.study import run as study_run

    monkeypatch.setattr(study_run, "cluster_pays", lambda predicted, workers: True)


SMALL_HOUSE: dict[str, object] = {
    "synthetic": "default", "height": 24, "width": 30, "num_rooms": 2, "num_trials": 2,
    "min_room_size": 8,
}  # fmt: skip
"""The studies' small synthetic house (24 x 30 cells, 2 rooms, 2 trials): a cell of a few
sweeps on it takes well under a second."""


def small_house(**fields: object) -> dict[str, object]:
    """:data:`SMALL_HOUSE` with ``fields`` (a data table of ``study_from_dict``): a field given
    keeps its place, a new one comes last, and None leaves the field out (HouseSpec's own
    default)."""
    house = {**SMALL_HOUSE, **fields}
    return {key: value for key, value in house.items() if value is not None}


def small_house_toml(table: str = "small", **fields: object) -> str:
    """The ``[data.TABLE]`` table of :func:`small_house` as a study file writes it."""
    import json

    lines = [f"[data.{table}]"]
    lines += [f"{key} = {json.dumps(value)}" for key, value in small_house(**fields).items()]
    return "\n".join(lines) + "\n"


TINY = """
[study]
name = "tiny"
seeds = 2
sweeps = 8
baselines = ["F-geometry"]

[variants.og3]
preset = "original-code"
gamma = 3.0

[variants.dp]
preset = "paper-dp"

""" + small_house_toml(heldout=True)
"""The tiny study of tests/test_study_runs.py, test_study_spec.py and test_study_qa.py: two
variants (8 sweeps) and a baseline at 2 seeds, 6 cells on :func:`small_house`, held out."""

TINY_DICT = {
    "study": {"name": "tiny", "seeds": 2, "sweeps": 8, "baselines": ["F-geometry"]},
    "variants": {"og3": {"preset": "original-code", "gamma": 3.0}, "dp": {"preset": "paper-dp"}},
    "data": {"small": small_house(heldout=True)},
}  # fmt: skip
""":data:`TINY` as the Python dict ``study_from_dict`` reads."""


def _write(tmp_path: Path, text: str = TINY, name: str = "tiny.toml") -> Path:
    """``text`` (the tiny study's file) written as ``tmp_path / name``: its path."""
    path = tmp_path / name
    path.write_text(text)
    return path


def one_variant_study(name: str, seeds: int = 2, sweeps: int = 2, **house: object):
    """A study of one variant (``paper-dp``) on :func:`small_house` (``house``'s fields)."""
    from spcopyro.study.spec import study_from_dict

    return study_from_dict({
        "study": {"name": name, "seeds": seeds, "sweeps": sweeps},
        "variants": {"a": {"preset": "paper-dp"}},
        "data": {"small": small_house(**house)},
    })  # fmt: skip


def fake_cluster(monkeypatch: pytest.MonkeyPatch, start: type) -> None:
    """``run_study(workers > 1)``'s LocalCluster replaced by ``start`` (a stand-in of
    :class:`~spcopyro.study.local_cluster.ClusterStart`: ``start(workers, on_ready)``,
    ``wait()``, ``close(now=...)``), with a stand-in ``distributed`` module (the optional
    dependency) whose ``as_completed`` yields the futures as given."""
    import sys
    import types

    from spcopyro.study import run as study_run

    fake = types.ModuleType("distributed")
    fake.as_completed = iter  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "distributed", fake)
    monkeypatch.setattr(study_run, "dask_installed", lambda: True)
    monkeypatch.setattr(study_run, "ClusterStart", start)


def counting_start(started: list[int]) -> type:
    """A stand-in ClusterStart (:func:`fake_cluster`) that appends the workers asked for to
    ``started`` and does nothing else: for the runs that must start no cluster."""

    class CountingStart:
        def __init__(self, workers: int, on_ready: object = None) -> None:
            started.append(workers)

        def wait(self) -> None:
            return None

        def close(self, **kwargs: object) -> None:
            pass

    return CountingStart
