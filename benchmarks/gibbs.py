#!/usr/bin/env python
r"""Performance benchmark of the SpCoMapping Gibbs sampler (paper Algorithm 1).

One *iteration* is what :func:`spcopyro.gibbs.sweep.gibbs_sweep` does: every free cell's label
drawn from its full conditional (eq. 13),

.. math::

    p(C_i = l \mid \text{rest}) \propto \pi_l \, e^{\gamma n_l(i)}
        \prod_{t \in i} \theta_{l, f_t} \, w_{l, S_t},

then pi, theta and w from their conjugate Dirichlet conditionals (eqs. 14-17). The benchmark
measures, in one run:

1. **Per house** (the five public houses, ``paper-dp``, L = 120): milliseconds per iteration of
   each sweep backend ("torch", "numba" when installed) against
   :func:`reference_loop.per_cell_sweep`, a straightforward per-cell implementation of
   Algorithm 1 (a Python loop over the free cells in raster order, as the released code works;
   ``benchmarks/reference_loop.py``), timed in the same process.
2. **Headline run**: 5000 iterations of room2ldk4 through :func:`~spcopyro.gibbs.run.run_gibbs`
   with the fastest backend, in a fresh subprocess, reporting the real wall time and the process's
   resident-set high-water mark (``ru_maxrss``).
3. **Scaling**: synthetic maps (:meth:`~spcopyro.synthetic.HouseSpec.scaled`) from ~1e4 to ~1e6
   free cells at L = 120, and L in (10, 120, 500) at ~1e5 cells: ms per sweep and ns per cell.
4. **Quality against time**: adjusted Rand index of the label map against the ground truth of the
   default synthetic house after 10, 100, 1000, 5000 sweeps, with the cumulative seconds.
   Sections 1-4 run each map under ``spcopyro fit``'s thread policy (one torch thread below
   50,000 free cells, torch's own count above; ``--torch-threads N``: N), printed per row.
5. **Run loop against kernel** (issue 15): per preset, 5000 sweeps of the bare compiled sweep
   against a 5000-sweep ``run_gibbs`` of the same chain (:mod:`gibbs_run_loop`).
6. **Whole fits** (issue 15): ``spcopyro fit`` of room2ldk4 for 5000 sweeps in a fresh process
   per preset (the released code's values first): ms per sweep from the fit's own trace, the
   per-cell loop's seconds per iteration under the same preset timed here, and the fixed cost
   outside the sweeps (:mod:`fixed_cost`).
7. **Many chains** (issue 15): 4 chains side by side against one after another, in process, and
   ``spcopyro fit --chains 4`` against four single fits.

The per-cell loop is the only baseline a ratio is taken against; the released script's loop was
measured elsewhere (issue 15: 0.41-0.52 s an iteration on room2ldk4, about 1.5x slower than the
per-cell loop) and is only quoted, never divided by.

Usage::

    python benchmarks/gibbs.py                       # full run (several minutes)
    python benchmarks/gibbs.py --quick               # smoke test, well under a minute
    python benchmarks/gibbs.py --backends torch --skip-baseline --out /tmp/gibbs.json

It prints a plain-text table to stdout (progress goes to stderr) and writes every number, with
machine information, to a JSON file.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import resource
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from bench_cli import COUNT, WAIT, dataset_root, run_main
from bench_setup import (
    HEADLINE_HOUSE,
    SEED,
    _try,
    embedded_default_house,
    load_headline_house,
    make_problem,
    time_backend,
    time_per_cell,
)
from fixed_cost import import_seconds, preset_arguments, warm_bytecode, warm_kernels
from gibbs_report import (
    PRESET,
    TARGET_CHAINS_RATIO,
    TARGET_FIT_MS_PER_SWEEP,
    TARGET_FIT_SPEEDUP,
    TARGET_FIXED_SECONDS,
    TARGET_HEADLINE_SECONDS,
    TARGET_NS_PER_CELL,
    TARGET_PEAK_BYTES,
    TARGET_RUN_OVER_KERNEL,
    TARGET_SPEEDUP,
    evaluate_targets,
    render,
)
from gibbs_run_loop import chains_as_fits, chains_in_process, kernel_and_run, whole_fit
from gibbs_scaling import bench_quality, bench_scaling
from machine import (
    available_backends,
    busy_cpu_seconds,
    machine_info,
    own_cpu_seconds,
    progress,
    wait_until_idle,
)

from spcopyro._util.threads import resolve_threads, torch_threads
from spcopyro.config import SpCoSettings, preset
from spcopyro.data import House, list_houses, load_house
from spcopyro.gibbs import GibbsOptions, run_gibbs

KNOWN_BACKENDS = ("torch", "numba")
SCRIPT_DIR = Path(__file__).resolve().parent
RUN_LOOP_PRESETS = ("paper-dp", "paper-dirichlet", "original-code", "auto")
"""Every preset, for the run loop against the kernel (paper-dirichlet with L = 10 concepts)."""
FIT_PRESETS = ("original-code", "paper-dp", "auto")
"""The presets of the whole fits: the released code's values first (the headline)."""

MEMORY_NOTE = (
    "peak_rss is the resident-set high-water mark (getrusage(RUSAGE_SELF).ru_maxrss) of a fresh "
    "Python process that imports spcopyro (torch, pyro), loads the house, builds the model data "
    "and runs run_gibbs for the whole headline run; it includes the interpreter and the torch "
    "runtime. rss_after_import and rss_before_run are the same high-water mark read after the "
    "imports and just before run_gibbs, so peak_rss - rss_before_run bounds what the run itself "
    "added; rss_now_* are the resident set (VmRSS) right before and after run_gibbs."
)


# ---------------------------------------------------------------------------------------------
# Sizes of a full and a quick run
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BenchSizes:
    """How much work each section does."""

    house_warmup: int  # sweeps before timing a backend on a house (includes any JIT compile)
    house_sweeps: int  # timed sweeps per backend and house
    baseline_sweeps: int  # timed sweeps of the per-cell loop per house
    headline_sweeps: int  # run_gibbs sweeps of the headline run
    scaling_sides: tuple[int, ...]  # synthetic map sides (cells) for the cell-count series
    scaling_num_concepts: tuple[int, ...]  # L values of the L series
    scaling_l_side: int  # map side of the L series
    scaling_budget_s: float  # seconds of timed sweeps per scaling point (at least 3 sweeps)
    quality_checkpoints: tuple[int, ...]  # sweeps after which the ARI is taken
    quality_gammas: tuple[float | None, ...]  # None: the preset's gamma
    run_loop_sweeps: int  # sweeps of the bare kernel and of run_gibbs, per preset
    run_loop_block: int  # the two alternate in blocks of this many sweeps
    fit_sweeps: int  # sweeps of each whole `spcopyro fit` (a fresh process)
    chains: int  # chains of the many-chains section
    chains_sweeps: int  # their sweeps in process
    chains_fit_sweeps: int  # their sweeps as `fit --chains K` against K single fits
    chains_fit_repeats: int  # that comparison's alternated repeats (the median ratio is judged)


FULL = BenchSizes(
    house_warmup=10,
    house_sweeps=200,
    baseline_sweeps=3,
    headline_sweeps=5000,
    scaling_sides=(110, 185, 334, 580, 1050),  # ~1e4, 3e4, 1e5, 3e5, 1e6 free cells
    scaling_num_concepts=(10, 120, 500),
    scaling_l_side=334,
    scaling_budget_s=2.0,
    quality_checkpoints=(10, 100, 1000, 5000),
    quality_gammas=(None, 3.0, 2.1),
    run_loop_sweeps=5000,
    run_loop_block=250,
    fit_sweeps=5000,
    chains=4,
    chains_sweeps=1000,
    chains_fit_sweeps=5000,
    chains_fit_repeats=3,
)
QUICK = BenchSizes(
    house_warmup=2,
    house_sweeps=5,
    baseline_sweeps=1,
    headline_sweeps=20,
    scaling_sides=(40, 80),
    scaling_num_concepts=(10, 120),
    scaling_l_side=60,
    scaling_budget_s=0.05,
    quality_checkpoints=(5, 20),
    quality_gammas=(None,),
    run_loop_sweeps=20,
    run_loop_block=5,
    fit_sweeps=3,
    chains=2,
    chains_sweeps=5,
    chains_fit_sweeps=2,
    chains_fit_repeats=1,
)


# ---------------------------------------------------------------------------------------------
# Sections
# ---------------------------------------------------------------------------------------------


def bench_houses(
    dataset: Path | None,
    backends: Sequence[str],
    sizes: BenchSizes,
    skip_baseline: bool,
    threads: int | str = "auto",
) -> list[dict[str, Any]]:
    """Per-house ms per iteration of every backend (under ``threads``: fit's policy by default),
    the per-cell baseline and the speed-ups."""
    if dataset is None:
        return []
    settings = preset(PRESET)
    results = []
    for name in list_houses(dataset):
        problem = make_problem(load_house(dataset / name), settings)
        entry: dict[str, Any] = {
            "house": name,
            "free_cells": problem.data.num_free,
            "observed_cells": int(problem.data.obs_cells.shape[0]),
            "backends": {},
        }
        with torch_threads(resolve_threads(threads, problem.data.num_free)) as used:
            entry["torch_threads"] = used
            for backend in backends:
                progress(f"[houses] {name}: {backend}, {sizes.house_sweeps} sweeps, {used} thr")
                entry["backends"][backend] = _try(
                    f"{name} {backend}",
                    lambda b=backend, p=problem: time_backend(
                        p, b, warmup=sizes.house_warmup, sweeps=sizes.house_sweeps
                    ),
                )
        if not skip_baseline:
            progress(f"[houses] {name}: per-cell loop, {sizes.baseline_sweeps} sweeps")
            entry["per_cell"] = time_per_cell(problem, sizes.baseline_sweeps)
        timed = {b: r for b, r in entry["backends"].items() if "error" not in r}
        if timed:
            best = min(timed, key=lambda b: timed[b]["ms_per_iteration"])
            entry["fastest_backend"] = best
            entry["projected_5000_s"] = {
                b: 5000 * r["ms_per_iteration"] / 1e3 for b, r in timed.items()
            }
            if "per_cell" in entry:
                baseline_ms = 1e3 * entry["per_cell"]["seconds_per_iteration"]
                entry["speedup"] = {
                    b: baseline_ms / r["ms_per_iteration"] for b, r in timed.items()
                }
        results.append(entry)
    return results


def _max_rss_bytes() -> int:
    """This process's resident-set high-water mark (Linux reports KiB, macOS bytes)."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss) if sys.platform == "darwin" else int(rss) * 1024


def _current_rss_bytes() -> int | None:
    """This process's resident set now (Linux /proc/self/status VmRSS), else None."""
    status = Path("/proc/self/status")
    if not status.is_file():
        return None
    for line in status.read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024  # kB
    return None


def child_run(
    dataset: Path | None, backend: str, sweeps: int, threads: int | str = "auto"
) -> dict[str, Any]:
    """The headline run, meant for a fresh process: load, run_gibbs (under ``threads``: fit's
    policy by default), time and peak memory."""
    rss_after_import = _max_rss_bytes()
    t0 = time.perf_counter()
    problem = make_problem(load_headline_house(dataset), preset(PRESET))
    setup_s = time.perf_counter() - t0
    rss_before_run, rss_now_before_run = _max_rss_bytes(), _current_rss_bytes()
    with torch_threads(resolve_threads(threads, problem.data.num_free)) as used:
        t0 = time.perf_counter()
        run = run_gibbs(
            problem.data,
            problem.config,
            sweeps,
            options=GibbsOptions(backend=backend),
            seed=SEED,
            progress=False,
        )
        wall_s = time.perf_counter() - t0
    rss_now_after_run = _current_rss_bytes()
    return {
        "house": problem.name,
        "torch_threads": used,
        "free_cells": problem.data.num_free,
        "backend": backend,
        "sweeps": sweeps,
        "setup_s": setup_s,
        "wall_s": wall_s,
        "ms_per_iteration": 1e3 * wall_s / sweeps,
        "first_sweep_s": float(run.seconds[0]),
        "after_first_sweep_s": float(run.seconds[-1] - run.seconds[0]),
        "final_concepts": int(run.num_concepts[-1]),
        "final_log_joint": float(run.log_joint[-1]),
        "rss_after_import_bytes": rss_after_import,
        "rss_before_run_bytes": rss_before_run,
        "peak_rss_bytes": _max_rss_bytes(),
        "rss_now_before_run_bytes": rss_now_before_run,
        "rss_now_after_run_bytes": rss_now_after_run,
    }


def bench_headline(
    dataset: Path | None, backend: str, sweeps: int, threads: int | str = "auto"
) -> dict[str, Any]:
    """Run :func:`child_run` in a fresh interpreter and collect its JSON line."""
    command = [sys.executable, str(Path(__file__).resolve()), "--child-run", backend]
    command += ["--child-sweeps", str(sweeps)]
    if threads != "auto":
        command += ["--torch-threads", str(threads)]
    if dataset is None:
        command.append("--no-dataset")
    else:
        command += ["--dataset", str(dataset)]
    progress(f"[headline] {sweeps} sweeps, backend {backend}, in a subprocess")
    t0 = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    process_s = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(
            f"headline subprocess {' '.join(command)} exited with {done.returncode}:\n"
            f"{done.stderr[-3000:]}"
        )
    lines = done.stdout.strip().splitlines()
    if not lines:
        raise RuntimeError(f"headline subprocess printed nothing; stderr:\n{done.stderr[-3000:]}")
    result = json.loads(lines[-1])
    result["process_s"] = process_s  # interpreter start + imports + setup + run
    result["memory_note"] = MEMORY_NOTE
    result["synthetic_stand_in"] = dataset is None
    return result


# ---------------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------------


def _preset_settings(name: str) -> SpCoSettings:
    """A preset's settings; paper-dirichlet (the number of concepts known) with L = 10."""
    return preset(name, num_concepts=10) if name == "paper-dirichlet" else preset(name)


def bench_run_loop(
    house: House, backend: str, sizes: BenchSizes, threads: int | str = "auto"
) -> list[dict[str, Any]]:
    """Per preset: S bare kernel sweeps against a run_gibbs of S sweeps, the same chain."""
    results = []
    for name in RUN_LOOP_PRESETS:
        problem = make_problem(house, _preset_settings(name))
        progress(f"[run loop] {name}: {sizes.run_loop_sweeps} sweeps, kernel and run_gibbs")
        entry = _try(
            f"run loop {name}",
            lambda p=problem: kernel_and_run(
                p.data, p.config, sizes.run_loop_sweeps, backend=backend,
                block=sizes.run_loop_block, threads=threads,
            ),
        )  # fmt: skip
        results.append({"preset": name, "house": house.name, **entry})
    return results


def bench_fits(
    dataset: Path | None, house: House, sizes: BenchSizes, skip_baseline: bool
) -> list[dict[str, Any]]:
    """Whole `spcopyro fit` runs of the headline house per preset (fresh processes), each with
    the per-cell loop's seconds per iteration under the same preset, measured here."""
    path = None if dataset is None else dataset / HEADLINE_HOUSE
    results = []
    for name in FIT_PRESETS:
        progress(f"[whole fit] {name}: spcopyro fit, {sizes.fit_sweeps} sweeps, a fresh process")
        entry: dict[str, Any] = {"preset": name, "house": HEADLINE_HOUSE if path else None}
        entry.update(_try(f"whole fit {name}", lambda n=name: whole_fit(path, n, sizes.fit_sweeps)))
        if not skip_baseline and "error" not in entry:  # on the house the fit fitted
            fitted = house if path is not None else embedded_default_house()
            problem = make_problem(fitted, _preset_settings(name))
            entry["per_cell"] = time_per_cell(problem, sizes.baseline_sweeps)
            per_cell_ms = 1e3 * entry["per_cell"]["seconds_per_iteration"]
            entry["speedup_vs_per_cell"] = per_cell_ms / entry["ms_per_sweep"]
        results.append(entry)
    return results


def bench_chains(
    dataset: Path | None, house: House, backend: str, sizes: BenchSizes
) -> dict[str, Any]:
    """K chains together against one after another (in process), and `fit --chains K` against
    K single fits (fresh processes), preset original-code."""
    name = FIT_PRESETS[0]
    problem = make_problem(house, _preset_settings(name))
    progress(f"[chains] {sizes.chains} chains x {sizes.chains_sweeps} sweeps in process")
    path = None if dataset is None else dataset / HEADLINE_HOUSE
    in_process = _try(
        "chains in process",
        lambda: chains_in_process(
            problem.data,
            problem.config,
            sizes.chains,
            sizes.chains_sweeps,
            backend=backend,
            processes_of=("-" if dataset is None else str(dataset), name),
        ),
    )
    progress(f"[chains] fit --chains {sizes.chains} against {sizes.chains} single fits")
    as_fits = _try(
        "chains as fits",
        lambda: chains_as_fits(
            path, name, sizes.chains, sizes.chains_fit_sweeps, sizes.chains_fit_repeats
        ),
    )
    gpu = (
        "a CUDA device is present: benchmarks/batched_gpu.py measures the batched sweep on it"
        if torch.cuda.is_available()
        else "no CUDA device on this machine: benchmarks/batched_gpu.py measures the batched "
        "sweep on the CPU only"
    )
    return {"preset": name, "in_process": in_process, "as_fits": as_fits, "gpu": gpu}


@contextlib.contextmanager
def measure_contention(
    record: dict[str, dict[str, float | None]], name: str, wait_idle_s: float = 0.0
) -> Iterator[None]:
    """Record the wall time of a section and the CPU time OTHER processes used meanwhile
    (after waiting for an idle machine first, with ``--wait-idle``).

    other = (busy CPU time of the whole machine) - (this process + its children); a value well
    above 0 means the timings of that section competed with other work for the CPUs.
    """
    waited = wait_until_idle(wait_idle_s)
    busy0, own0, wall0 = busy_cpu_seconds(), own_cpu_seconds(), time.perf_counter()
    try:
        yield
    finally:
        busy1, own1 = busy_cpu_seconds(), own_cpu_seconds()
        other = None
        if busy0 is not None and busy1 is not None:
            other = max(0.0, (busy1 - busy0) - (own1 - own0))
        record[name] = {
            "wall_s": time.perf_counter() - wall0,
            "other_cpu_s": other,
            "waited_for_idle_s": waited,
        }


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description="Benchmark the SpCoMapping Gibbs sampler (see the module docstring)."
    )
    parser.add_argument("--quick", action="store_true", help="tiny sizes, a few sweeps (< 60 s)")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="JSON output (default benchmarks/gibbs_results.json, gibbs_quick.json with --quick)",
    )
    parser.add_argument(
        "--backends",
        default=",".join(KNOWN_BACKENDS),
        help="comma-separated sweep backends to time (default: torch,numba; missing ones are "
        "skipped with a note)",
    )
    parser.add_argument(
        "--skip-baseline", action="store_true", help="do not time the per-cell Python loop"
    )
    parser.add_argument(
        "--dataset", type=Path, default=None, help="dataset root (default: find_dataset_root())"
    )
    parser.add_argument("--no-dataset", action="store_true", help="synthetic maps only")
    parser.add_argument(
        "--torch-threads",
        type=COUNT,
        default=None,
        help="torch threads of the per-house, headline, scaling and quality rows (default: "
        "fit's thread policy, one below 50,000 free cells)",
    )
    parser.add_argument(
        "--wait-idle",
        type=WAIT,
        default=0.0,
        metavar="SECONDS",
        help="before each section wait up to this long for other processes to leave the CPUs "
        "(default 0: do not wait)",
    )
    parser.add_argument("--child-run", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--child-sweeps", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    names = [b.strip() for b in args.backends.split(",") if b.strip()]
    unknown = [b for b in names if b not in KNOWN_BACKENDS]
    if unknown or not names:
        parser.error(f"--backends {args.backends!r}: choose from {', '.join(KNOWN_BACKENDS)}")
    args.backend_list = list(dict.fromkeys(names))
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if args.torch_threads is not None:
        torch.set_num_threads(args.torch_threads)
    if args.no_dataset:
        dataset = None
    else:
        dataset = dataset_root(args.dataset, without="per-house timings skipped")
    # The timed rows run under fit's thread policy, or --torch-threads's count where given.
    threads: int | str = "auto" if args.torch_threads is None else args.torch_threads
    if args.child_run is not None:
        print(json.dumps(child_run(dataset, args.child_run, args.child_sweeps, threads)))
        return 0

    started = time.perf_counter()
    sizes = QUICK if args.quick else FULL
    out_path = args.out or SCRIPT_DIR / ("gibbs_quick.json" if args.quick else "gibbs_results.json")
    backends, notes = available_backends(args.backend_list)
    for name, note in notes.items():
        progress(f"backend {name}: {note}")
    if not backends:
        raise SystemExit(f"none of the backends {args.backend_list} can be loaded: {notes}")

    results: dict[str, Any] = {
        "quick": args.quick,
        "preset": PRESET,
        "seed": SEED,
        "argv": sys.argv if argv is None else list(argv),
        "machine": machine_info(),
        "dataset": None if dataset is None else str(dataset),
        "backends": backends,
        "backend_notes": notes,
        "sizes": {k: v for k, v in vars(sizes).items()},
        "targets_definition": {
            "speedup": TARGET_SPEEDUP,
            "headline_seconds": TARGET_HEADLINE_SECONDS,
            "peak_bytes": TARGET_PEAK_BYTES,
            "run_over_kernel": TARGET_RUN_OVER_KERNEL,
            "fixed_seconds": TARGET_FIXED_SECONDS,
            "ns_per_cell": TARGET_NS_PER_CELL,
            "fit_ms_per_sweep": TARGET_FIT_MS_PER_SWEEP,
            "fit_speedup": TARGET_FIT_SPEEDUP,
            "chains_ratio": TARGET_CHAINS_RATIO,
        },
    }
    results["scaling_threads"] = threads  # the policy of every in-process row and the headline
    contention: dict[str, dict[str, float | None]] = {}
    results["contention"] = contention
    with measure_contention(contention, "houses", args.wait_idle):
        results["houses"] = bench_houses(dataset, backends, sizes, args.skip_baseline, threads)

    # The fastest backend on the headline house (or on the first scaling map without data).
    headline_entry = next((h for h in results["houses"] if h["house"] == HEADLINE_HOUSE), None)
    if headline_entry is None or "fastest_backend" not in headline_entry:
        probe = make_problem(load_headline_house(None), preset(PRESET))
        timed = {
            b: _try(f"probe {b}", lambda b=b: time_backend(probe, b, warmup=2, sweeps=5))
            for b in backends
        }
        timed = {b: r for b, r in timed.items() if "error" not in r}
        fastest = min(timed, key=lambda b: timed[b]["ms_per_iteration"]) if timed else backends[0]
    else:
        fastest = headline_entry["fastest_backend"]
    results["fastest_backend"] = fastest

    with measure_contention(contention, "headline", args.wait_idle):
        results["headline"] = _try(
            "headline run",
            lambda: bench_headline(dataset, fastest, sizes.headline_sweeps, threads),
        )
    headline_house = load_headline_house(dataset)
    compiled = "numba" if "numba" in backends else fastest
    with measure_contention(contention, "run loop", args.wait_idle):
        results["run_loop"] = bench_run_loop(headline_house, compiled, sizes, threads)
    with measure_contention(contention, "whole fits", args.wait_idle):
        results["bytecode"] = warm_bytecode()  # the fits' processes use the .pyc cache
        results["import_floor"] = import_seconds(("pass", "torch"))  # the fixed cost's floor
        path = None if dataset is None else dataset / HEADLINE_HOUSE  # kernels cached, untimed:
        results["numba_warm_s"] = warm_kernels({n: preset_arguments(path, n) for n in FIT_PRESETS})
        results["fits"] = bench_fits(dataset, headline_house, sizes, args.skip_baseline)
    with measure_contention(contention, "chains", args.wait_idle):
        results["chains"] = bench_chains(dataset, headline_house, compiled, sizes)
    with measure_contention(contention, "scaling", args.wait_idle):
        results["scaling"] = bench_scaling(dataset, backends, sizes, threads)
    with measure_contention(contention, "quality", args.wait_idle):
        results["quality"] = bench_quality(fastest, sizes, threads)
    results["targets"] = evaluate_targets(results)
    results["total_s"] = time.perf_counter() - started
    results["out"] = str(out_path)

    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(json.dumps(results, indent=2) + "\n")
    print(render(results))
    return 0


if __name__ == "__main__":
    run_main(main)
