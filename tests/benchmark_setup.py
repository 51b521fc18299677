"""What the benchmark tests (tests/test_benchmarks_*.py) share: this checkout's root and its
benchmarks/ folder, a script's ``--quick`` run, and the exception a stub raises where a script
would start measuring. Their fixtures ``script`` and ``keep_torch_threads`` are in conftest.py.

The ``--quick`` runs go in a subprocess that imports this checkout's ``spcopyro`` (its root first
on PYTHONPATH), whichever copy the environment has installed.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"


def run_benchmark(script: str, out: Path) -> subprocess.CompletedProcess:
    """``python benchmarks/SCRIPT --quick --out OUT`` on this checkout's package."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    return subprocess.run(
        [sys.executable, str(BENCHMARKS / script), "--quick", "--out", str(out)],
        capture_output=True, text=True, timeout=600, env={**os.environ, "PYTHONPATH": path},
    )  # fmt: skip


class _Measuring(Exception):
    """Raised where a script would start measuring."""
