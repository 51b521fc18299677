"""What the study tests (tests/test_study*.py) set up alike: small houses, the tiny studies
they run, and a LocalCluster for a study too short to start one by itself."""

from __future__ import annotations

import pytest


def on_a_cluster(monkeypatch: pytest.MonkeyPatch) -> None:
    """``run_study(workers > 1)`` starts its (real or fake) LocalCluster even for a study of a
    few short cells, which it runs in its own process otherwise
    (:func:`spcopyro.study.order.cluster_pays`): the tests of the cluster's path run tiny
    studies."""
    from spcopyro.study import run as study_run

    monkeypatch.setattr(study_run, "cluster_pays", lambda predicted, workers: True)
