"""The study commands import torch, pyro and the study's code as ``spcopyro fit`` does: with the
cyclic garbage collector paused, then frozen (:mod:`spcopyro._util.collector`): about 600
collections, 0.7-0.8 s, of ``import spcopyro.study.run`` on a 2-core machine. So does the
forkserver the LocalCluster's workers are forked from (:mod:`spcopyro.study.worker_imports`)."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from study_setup import small_house_toml

from spcopyro._util import collector
from spcopyro.cli.main import main

ROOT = Path(__file__).resolve().parents[1]

STUDY = """
[study]
name = "frozen"
seeds = 1
sweeps = 2

[variants.a]
preset = "original-code"

""" + small_house_toml(num_trials=1)


def _recording(monkeypatch) -> list[str]:
    asked: list[str] = []
    real = collector.import_frozen
    monkeypatch.setattr(collector, "import_frozen", lambda name: asked.append(name) or real(name))
    return asked


def test_the_study_command_imports_the_study_frozen(tmp_path, monkeypatch, capsys):
    asked = _recording(monkeypatch)
    path = tmp_path / "frozen.toml"
    path.write_text(STUDY)
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--dry-run"]) == 0
    assert asked[:1] == ["spcopyro.study.run"]


def test_experiment_ablation_and_compare_inference_import_the_study_frozen(monkeypatch):
    """Their common wrapper (``_stoppable``) imports the study engine frozen first."""
    from spcopyro.study import commands

    asked = _recording(monkeypatch)
    assert commands._stoppable(lambda args: 17)(argparse.Namespace(workers=1)) == 17
    assert asked == ["spcopyro.study.run"]


_WORKER_IMPORTS = """
import gc, json, sys, types
from spcopyro.study.local_cluster import WORKER_PRELOAD
sys.modules.setdefault("distributed", types.ModuleType("distributed"))  # optional: a stand-in
collections = []  # those once torch's import began (it is in sys.modules from its start)
gc.callbacks.append(lambda phase, info: phase == "start" and "torch" in sys.modules
                    and collections.append(info["generation"]))
for name in WORKER_PRELOAD:  # as multiprocessing's forkserver imports its preload
    __import__(name)
count = len(collections)
print(json.dumps({"during": collections[:count], "enabled": gc.isenabled(),
                  "frozen": gc.get_freeze_count(), "preload": list(WORKER_PRELOAD),
                  "evaluate": "spcopyro.study.evaluate" in sys.modules}))
"""


def test_the_workers_forkserver_imports_the_cells_code_frozen():
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, "PYTHONPATH": path, "CI": "1"}
    done = subprocess.run([sys.executable, "-c", _WORKER_IMPORTS], capture_output=True,
                          text=True, env=env, timeout=300, check=True)  # fmt: skip
    record = json.loads(done.stdout.strip().splitlines()[-1])
    assert record["preload"] == ["spcopyro.study.worker_imports"]
    assert record["evaluate"]
    assert record["during"] == []
    assert record["enabled"]
    assert record["frozen"] > 100_000
