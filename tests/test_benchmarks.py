"""The benchmarks run (smoke test with --quick); their numbers are never asserted here."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.slow
def test_gibbs_benchmark_quick(tmp_path):
    out = tmp_path / "gibbs.json"
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / "gibbs.py"), "--quick", "--out", str(out)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Targets" in done.stdout
    results = json.loads(out.read_text())
    assert results["machine"]["cpu_count"] >= 1


@pytest.mark.slow
def test_features_benchmark_quick(tmp_path):
    out = tmp_path / "features.json"
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / "features.py"), "--quick", "--out", str(out)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert out.is_file() and json.loads(out.read_text())
