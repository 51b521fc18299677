"""What the benchmark scripts share: the machine they ran on, its other load, plain tables.

``gibbs.py`` and ``threads.py`` import it (run as scripts, their folder is on ``sys.path``).
"""

from __future__ import annotations

import datetime
import os
import platform
import resource
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from spcopyro.gibbs.backends import get_backend


def progress(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def busy_cpu_seconds() -> float | None:
    """CPU seconds all processes have spent busy since boot (Linux /proc/stat), else None."""
    stat = Path("/proc/stat")
    if not stat.is_file():
        return None
    fields = stat.read_text().splitlines()[0].split()[1:]  # cpu user nice system idle iowait ...
    ticks = [int(v) for v in fields]
    busy = sum(ticks) - ticks[3] - (ticks[4] if len(ticks) > 4 else 0)  # minus idle, iowait
    return busy / os.sysconf("SC_CLK_TCK")


def own_cpu_seconds() -> float:
    """CPU seconds of this process and its finished children."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def wait_until_idle(
    max_wait_s: float, window_s: float = 2.0, max_other_cores: float = 0.1
) -> float:
    """Wait (at most ``max_wait_s``) until other processes use under ``max_other_cores`` CPUs
    for two consecutive ``window_s`` windows. Returns the seconds waited (0 if not asked)."""
    if max_wait_s <= 0 or busy_cpu_seconds() is None:
        return 0.0
    started = time.perf_counter()
    quiet = 0
    while time.perf_counter() - started < max_wait_s and quiet < 2:
        busy0, own0 = busy_cpu_seconds(), own_cpu_seconds()
        time.sleep(window_s)
        other = (busy_cpu_seconds() - busy0) - (own_cpu_seconds() - own0)  # type: ignore[operator]
        quiet = quiet + 1 if other < max_other_cores * window_s else 0
    waited = time.perf_counter() - started
    if quiet < 2:
        progress(f"  machine still busy after waiting {waited:.0f} s; measuring anyway")
    return waited


def available_backends(requested: Sequence[str]) -> tuple[list[str], dict[str, str]]:
    """The requested backends that load, and why each other one does not."""
    usable, notes = [], {}
    for name in requested:
        try:
            get_backend(name)
        except Exception as error:  # noqa: BLE001 - a missing or broken backend is reported
            notes[name] = f"{type(error).__name__}: {error}"
        else:
            usable.append(name)
    return usable, notes


def machine_info() -> dict[str, Any]:
    """CPU, library versions and thread counts."""
    try:
        import numba

        numba_version: str | None = numba.__version__
        numba_threads: int | None = int(numba.config.NUMBA_NUM_THREADS)
    except ImportError:
        numba_version, numba_threads = None, None
    cpu_model = platform.processor() or None
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                cpu_model = line.split(":", 1)[1].strip()
                break
    affinity = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "hostname": platform.node(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cpu_model": cpu_model,
        "cpu_count": os.cpu_count(),
        "cpus_usable": None if affinity is None else len(affinity),
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "numpy": np.__version__,
        "numba": numba_version,
        "numba_threads": numba_threads,
        "env": {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS",
                                               "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")},
        "load_average_1_5_15min": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
    }  # fmt: skip


def format_table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A plain-text table, columns right-aligned except the first."""
    widths = [max(len(str(c)) for c in column) for column in zip(headers, *rows, strict=True)]

    def line(cells: Sequence[str]) -> str:
        first = str(cells[0]).ljust(widths[0])
        rest = [str(c).rjust(w) for c, w in zip(cells[1:], widths[1:], strict=True)]
        return "  ".join([first, *rest])

    rule = "  ".join("-" * w for w in widths)
    return "\n".join([line(headers), rule, *(line(r) for r in rows)])
