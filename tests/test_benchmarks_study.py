"""The benchmarks of the study runner (issue 26): study_order.py (both cell orders on a
LocalCluster, the same numbers) and study_dask.py (a LocalCluster against in-process: its
tables compared cell by cell, its verdict). The --quick runs need the study extra
(dask.distributed) and skip without it.

--quick runs are smoke tests: their numbers are never asserted here. The other tests import
a script from benchmarks/ (the ``script`` fixture, tests/conftest.py: their folder on
sys.path, as when they run) and call its functions on small inputs.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from benchmark_setup import ROOT, run_benchmark


@pytest.mark.slow
def test_study_order_benchmark_quick(tmp_path):
    """Both orders on a LocalCluster, alternated, the same numbers (benchmarks/study_order.py)."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    out = tmp_path / "study_order.json"
    done = run_benchmark("study_order.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert [run["order"] for run in results["runs"]][:2] == ["table", "longest first"]
    assert results["same_numbers"] is True and "mean wall" in done.stdout


def test_study_tables_name_the_cells_and_columns_that_differ(script):
    """study_order.py judged 'same numbers' by the whole tables and once said False with no
    word of where; the timing columns of observations-off runs were compared too."""
    study_dask = script("study_dask")
    row = {"key": "a" * 20, "ari": 0.5, "source_digest": "x"}
    assert study_dask.differences([row], [dict(row)]) == []
    found = study_dask.differences([row], [{**row, "source_digest": "y"}])
    assert found == ["aaaaaaaaaaaa source_digest: 'x' != 'y'"]
    assert study_dask.differences([row], []) == [f"{'a' * 20}: missing from the other table"]
    assert {"seconds_off", "cpu_seconds_off"} <= set(study_dask.TIMING)


def test_study_dask_judges_one_pair_too(script):
    """study_dask.py --quick (and --pairs 1, a README command line) printed the ratio and
    'target <= 0.6' but no PASS/FAIL: the verdict came only with two pairs or more."""
    study_dask = script("study_dask")
    one = study_dask.verdict_lines(2.8, True, [(1.3, 3.6)])
    assert one[-1].startswith("one pair, ratio 2.77 (target <= 0.6): FAIL"), one
    many = study_dask.verdict_lines(0.5, True, [(10.0, 5.0), (10.0, 7.0), (10.0, 5.5)])
    assert many[-1] == "median ratio 0.55 (target <= 0.6): PASS", many


@pytest.mark.slow
def test_dask_benchmark_quick(tmp_path):
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    out = tmp_path / "study_dask.json"
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "study_dask.py"), "--quick", "--pairs", "2",
         "--out", str(out)],
        capture_output=True, text=True, timeout=600, env=env,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert results["in_process"]["seconds"] > 0 and results["local_cluster"]["seconds"] > 0
    assert results["same_numbers"] is True
    assert results["cells_in_cluster"]["seconds"] > 0  # the cells' own seconds, both runs
    assert "the cells themselves" in done.stdout
    assert len(results["pair_ratios"]) == 2 and "median ratio" in done.stdout
