#!/usr/bin/env python
r"""Fixed cost of a whole ``spcopyro fit`` (issue #15 item 2): what a user's fit spends outside
the Gibbs sweeps -- starting the interpreter, the imports, loading the house, building the model
data, starting the chain, writing the outputs (labels, json, figures).

Every run is ``python -m spcopyro fit DATA --preset P --sweeps S --seed 0 --out TMP
[--no-figures]`` in a fresh subprocess (``CI=1``: no progress bars), this checkout's package
first on ``PYTHONPATH``. Per run it reports the wall seconds the subprocess took and the fit's
own breakdown, which ``fit`` writes to ``$SPCOPYRO_TIMINGS`` (:mod:`spcopyro._util.timings`):

* ``startup``: launch to the start of ``fit``'s own work -- the interpreter, the imports, the
  argument parser (the launch time taken here, the start by the fit, both ``time.time()``);
* ``load``, ``settings``, ``summary``, ``fit``, ``save``, ``figures``, ``report``, ``commit``:
  the fit's phases (``fit`` holds ``sweeps``, the trace's cumulative seconds of the sweeps, the
  first of which loads the compiled kernel from numba's cache; ``fit - sweeps`` is the model
  data, the chain's start and the chain's outputs);
* ``exit``: the rest of the wall (the fit's end to the process's exit, interpreter shutdown).

**Fixed cost**, two ways:

* *direct* (the headline, judged against the target): the wall of the longer run less its sweeps
  at their steady cost, ``wall - S * (sweeps(S) - sweep1) / (S - 1)``, from the fit's own trace
  (``sweep1``: the first sweep's seconds, which hold the kernel's load from numba's cache, so
  that load counts as fixed);
* *extrapolated*: the wall extrapolated to 0 sweeps from the runs of S1 < S2 sweeps,
  ``wall(S1) - S1 * (wall(S2) - wall(S1)) / (S2 - S1)``. It needs no trace but takes the noise
  of two processes' walls, and a cost that depends on the chain's state as well as its length
  (preset ``auto``'s point estimate over the 50 kept label maps: a chain of 1 sweep keeps one
  map, a less settled chain has more distinct maps to search) lands in the slope.

S1, S2 are 1 and 201 by default (:data:`SWEEPS`; from 100 sweeps on a fit keeps its 50 maps).
Each configuration is run ``--repeats`` times and the fastest run kept (the least disturbed by
other load on the machine).

**Start-up of the questions** (issue 25 item 2): ``spcopyro --help``, ``where`` and ``export``
on a saved fit, each timed as a whole process (``python -m spcopyro ...``, launch to exit), the
fastest of ``--repeats`` runs, beside ``python -c pass`` timed in the same run (the interpreter's
own start, which no command can go under). The saved fit is a default fit of the same house with
:data:`STARTUP_FIT_SWEEPS` sweeps (``--no-figures``); the word asked is its first concept's top
word. Each command is run once more to list the heavy modules (torch, pyro, numba) it imported,
which should be none. ``show`` of the house is in the table for information: it draws with
matplotlib, whose import alone is most of its time, and is not held to the target.

Usage::

    python benchmarks/fixed_cost.py                  # room2ldk4, presets paper-dp and auto
    python benchmarks/fixed_cost.py --quick          # smoke test: 1 and 3 sweeps, no repeats
    python benchmarks/fixed_cost.py --dataset /path/to/spcomapping --house room1dk5
    python benchmarks/fixed_cost.py --startup-only   # only the start-up of the questions

Without the public dataset it fits the embedded synthetic default house and says so. It prints a
table and writes every number to ``benchmarks/fixed_cost.json`` (``fixed_cost_quick.json`` with
``--quick``, ``startup.json`` with ``--startup-only``). :func:`measure_fixed_cost` is what
``benchmarks/gibbs.py`` can call.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench_cli import (
    COUNT,
    dataset_root,
    house_folder,
    preset_names,
    quick_or,
    results_path,
    run_main,
)

SCRIPT_DIR = Path(__file__).resolve().parent
EMBEDDED_LABEL = "embedded synthetic default house"  # what is fitted without a house folder
ROOT = SCRIPT_DIR.parent
TARGET_SECONDS = 2.0  # issue #15 item 2: under 2 s outside the sweeps (room2ldk4)
SWEEPS = (1, 201)
"""Default run lengths S1, S2 (module docstring)."""
PHASES = ("load", "settings", "summary", "fit", "save", "figures", "report", "commit")
STARTUP_TARGET_SECONDS = 0.5  # issue 25 item 2: --help, where, export as whole processes
STARTUP_FIT_SWEEPS = 20
"""Sweeps of the fit the start-up questions are asked of (its files, not its quality, matter)."""
HEAVY = ("torch", "pyro", "numba")
_REPORT_HEAVY = (
    "import atexit, runpy, sys; atexit.register(lambda: print('heavy:', ','.join(m for m in "
    f"{HEAVY!r} if m in sys.modules), file=sys.stderr)); sys.argv[0] = 'spcopyro'; "
    "runpy.run_module('spcopyro', run_name='__main__')"
)
"""``python -c`` program running ``spcopyro`` that lists on stderr, at exit, the heavy modules
it imported."""


BYTECODE_VARIABLE = "PYTHONDONTWRITEBYTECODE"
"""Cleared for the timed processes: set (as in some sandboxes and CI), no ``.pyc`` is written
for this checkout's ``spcopyro``, so every process compiles all of its modules again (``--help``
0.375 s against 0.219 s with the cache, on 2026-12-05), which a user's Python does once."""


def _environment() -> dict[str, str]:
    """The timed processes' environment: this one's, ``CI=1``, this checkout first on
    ``PYTHONPATH``, and :data:`BYTECODE_VARIABLE` removed (the bytecode cache a user has).
    ``PYTHONSAFEPATH=1`` (Python 3.11's ``-P``; Python 3.10 ignores it, so there the guard does
    nothing): ``python -m spcopyro`` and ``python -c`` put the working directory before
    ``PYTHONPATH``, so the script of another checkout (a worktree of the code before a change)
    run from this one's root timed this one's package."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, "CI": "1", "PYTHONPATH": path, "PYTHONSAFEPATH": "1"}
    env.pop(BYTECODE_VARIABLE, None)
    return env


def warm_bytecode() -> dict[str, Any]:
    """Compile this checkout's ``spcopyro`` to its bytecode cache (``__pycache__``, git-ignored)
    before anything is timed, as a user's first run does, and say so for the JSON: the parent's
    :data:`BYTECODE_VARIABLE` (cleared for the children) and the compile's seconds."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "compileall", "-q", str(ROOT / "spcopyro")],
                          capture_output=True, text=True, env=_environment())  # fmt: skip
    return {
        "parent_" + BYTECODE_VARIABLE: os.environ.get(BYTECODE_VARIABLE),
        "children": f"{BYTECODE_VARIABLE} cleared: they read and write the .pyc cache",
        "compileall_s": time.perf_counter() - start,
        "compileall_ok": done.returncode == 0,
    }


def bytecode_note(bytecode: dict[str, Any]) -> str:
    """One line on the processes' bytecode cache (:func:`warm_bytecode`'s record)."""
    parent = bytecode["parent_" + BYTECODE_VARIABLE]
    was = f"{BYTECODE_VARIABLE}={parent} here, cleared for them" if parent else "as here"
    return (f"bytecode: the timed processes use the .pyc cache ({was}; spcopyro compiled first, "
            f"{bytecode['compileall_s']:.1f} s)")  # fmt: skip


WARM_SWEEPS = 50
"""Sweeps of each untimed warm-up fit (:func:`warm_kernels`): enough that the moves a preset makes
in a fifth of its sweeps (split-merge, region relabel) run at least once (0.8^50 ~ 1e-5 that one
does not)."""


def warm_kernels(fits: dict[str, Sequence[str]]) -> dict[str, float]:
    """Fill numba's on-disk kernel cache before anything is timed, as any fit after a user's
    first would find it: each of ``fits`` (a name -> ``spcopyro fit`` arguments without
    ``--sweeps`` and ``--out``) run once, untimed, for :data:`WARM_SWEEPS` sweeps without figures.
    Returns each one's wall seconds, for the JSON.

    A kernel is compiled by the first process that calls it after install (or after its source
    changed) and loaded from the cache after that: the split-merge kernels compiled inside the
    timed ``auto`` fit of a fresh checkout's ``benchmarks/gibbs.py`` (2026-12-05 12:47 UTC) and
    made its first sweep 2.1 s instead of 0.2 s, counted as fixed cost."""
    seconds = {}
    for name, arguments in fits.items():
        start = time.perf_counter()
        run_fit_process([*arguments, "--sweeps", str(WARM_SWEEPS), "--no-figures"], timeout=900)
        seconds[name] = time.perf_counter() - start
    return seconds


def warm_note(warm: dict[str, float]) -> str:
    """One line on :func:`warm_kernels`' fits."""
    each = ", ".join(f"{name} {s:.1f} s" for name, s in warm.items())
    return (
        f"numba: kernels cached first by an untimed {WARM_SWEEPS}-sweep fit per "
        f"configuration ({each})"
    )


def preset_arguments(data: Path | None, preset: str, seed: int = 0) -> list[str]:
    """``spcopyro fit`` arguments of a fit of ``data`` (None: the embedded house) under
    ``preset`` with ``seed``: :func:`fit_once`'s, before its sweeps and figures."""
    return [*([str(data)] if data is not None else []), "--preset", preset, "--seed", str(seed)]


def run_fit_process(
    arguments: Sequence[str], timeout: float
) -> tuple[dict[str, Any], float, float, list[str]]:
    """``spcopyro fit ARGUMENTS --out TMP`` in a fresh subprocess with ``$SPCOPYRO_TIMINGS`` set:
    (its timings record, its wall seconds, its start-up seconds up to entering ``main``, the
    names of the PNGs it wrote). RuntimeError with its stderr if it fails."""
    with tempfile.TemporaryDirectory(prefix="spcopyro-fit-process-") as tmp:
        timings = Path(tmp) / "timings.json"
        out = Path(tmp) / "out"
        command = [sys.executable, "-m", "spcopyro", "fit", *arguments, "--out", str(out)]
        env = {**_environment(), "SPCOPYRO_TIMINGS": str(timings)}
        launched = time.time()
        start = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=timeout)
        wall = time.perf_counter() - start
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(command)} failed ({done.returncode}):\n"
                               f"{done.stderr[-3000:]}")  # fmt: skip
        record = json.loads(timings.read_text())
        pngs = sorted(p.name for p in out.glob("*.png"))
    return record, wall, record["entered"] - launched, pngs


def fit_once(
    data: Path | None,
    preset: str,
    sweeps: int,
    figures: bool,
    seed: int = 0,
    extra: Sequence[str] = (),
) -> dict[str, Any]:
    """One ``spcopyro fit`` in a fresh subprocess (``extra``: more of its arguments): its wall
    seconds and its phases."""
    arguments = [*preset_arguments(data, preset, seed), "--sweeps", str(sweeps),
                 *([] if figures else ["--no-figures"]), *extra]  # fmt: skip
    record, wall, startup, pngs = run_fit_process(arguments, timeout=900)
    seconds = dict(record["seconds"])
    row: dict[str, Any] = {
        "sweeps": sweeps,
        "with_figures": figures,
        "wall": wall,
        "startup": startup,
        **{name: seconds.get(name, 0.0) for name in PHASES},
        "sweep_seconds": record["sweep_seconds"],
        "first_sweep_seconds": record["first_sweep_seconds"],
        "exit": wall - startup - record["total"],
        "pngs": pngs,
        "imported": record.get("imported", []),  # of spcopyro._util.timings.OPTIONAL_HEAVY
        "seconds_parts": dict(record.get("parts", {})),  # the fit's inner phases (all chains)
    }
    row["fit_outside_sweeps"] = row["fit"] - row["sweep_seconds"]
    row["wall_outside_sweeps"] = wall - row["sweep_seconds"]
    steady = row["sweep_seconds"] - row["first_sweep_seconds"]  # sweeps 2..S
    row["fixed_direct"] = wall - sweeps * steady / (sweeps - 1) if sweeps > 1 else None
    return row


def _house_folder(dataset_root: Path | str | None, house: str) -> Path | None:
    """The folder of ``house`` in the dataset, or None (the embedded synthetic default house)
    when there is no dataset or it lacks the house."""
    data = None if dataset_root is None else Path(dataset_root) / house
    return data if data is not None and data.is_dir() else None


def measure_fixed_cost(
    dataset_root: Path | str | None,
    house: str = "room2ldk4",
    preset: str = "paper-dp",
    sweeps: tuple[int, int] = SWEEPS,
    figures: bool = True,
    repeats: int = 1,
) -> dict[str, Any]:
    """Fixed cost of ``spcopyro fit`` of ``house`` under ``preset``: runs of ``sweeps[0]`` and
    ``sweeps[1]`` sweeps (each the fastest of ``repeats``), the fixed cost extrapolated to 0
    sweeps (see the module docstring) and the seconds per sweep. ``dataset_root`` None or
    without ``house``: the embedded synthetic default house (``house`` in the result says so).
    """
    low, high = sweeps
    if not 1 <= low < high:
        raise ValueError(f"sweeps must be two counts 1 <= S1 < S2, got {sweeps}")
    data = _house_folder(dataset_root, house)
    runs = []
    for count in (low, high):
        tries = [fit_once(data, preset, count, figures) for _ in range(max(repeats, 1))]
        runs.append(min(tries, key=lambda r: r["wall"]))
    per_sweep = (runs[1]["wall"] - runs[0]["wall"]) / (high - low)
    fixed = runs[0]["wall"] - low * per_sweep
    return {
        "house": house if data is not None else EMBEDDED_LABEL,
        "data": None if data is None else str(data),
        "preset": preset,
        "figures": figures,
        "repeats": max(repeats, 1),
        "runs": runs,
        "seconds_per_sweep": per_sweep,
        "fixed_cost": runs[1]["fixed_direct"],
        "fixed_cost_method": f"wall of the {high}-sweep run less {high} steady sweeps (trace)",
        "fixed_cost_extrapolated": fixed,
        "extrapolation": f"wall extrapolated to 0 sweeps from {low} and {high} sweeps",
        "target_seconds": TARGET_SECONDS,
        "meets_target": runs[1]["fixed_direct"] < TARGET_SECONDS,
    }


def render(results: Sequence[dict[str, Any]], imports: dict[str, float] | None = None) -> str:
    """The table: one line per run, then the fixed cost of every configuration, each beside the
    floor timed in the same run (``imports``: :func:`import_seconds`' ``pass`` and ``torch``)."""
    headers = ["preset", "figs", "sweeps", "wall", "startup", "load", "settings", "summary",
               "fit-sw", "sweeps s", "save", "figures", "report", "commit", "exit",
               "fixed"]  # fmt: skip
    rows = []
    for result in results:
        for run in result["runs"]:
            rows.append([result["preset"], "yes" if result["figures"] else "no",
                         str(run["sweeps"]), f"{run['wall']:.2f}", f"{run['startup']:.2f}",
                         *(f"{run[k]:.2f}" for k in ("load", "settings", "summary")),
                         f"{run['fit_outside_sweeps']:.2f}", f"{run['sweep_seconds']:.2f}",
                         *(f"{run[k]:.2f}" for k in ("save", "figures", "report", "commit")),
                         f"{run['exit']:.2f}", "-" if run["fixed_direct"] is None
                         else f"{run['fixed_direct']:.2f}"])  # fmt: skip
    title = (f"house: {results[0]['house']}; seconds, fastest of {results[0]['repeats']} "
             "run(s) each (fit-sw: the fit phase less its sweeps; fixed: the wall less the "
             "sweeps at their steady cost)")  # fmt: skip
    lines = [title, _table(headers, rows), ""]
    floor = imports or {}
    baseline = (f"same run: import torch alone {floor['torch']:.2f} s, python -c pass "
                f"{floor['pass']:.2f} s" if "torch" in floor and "pass" in floor
                else "import torch not timed in this run")  # fmt: skip
    for result in results:
        verdict = "PASS" if result["meets_target"] else "FAIL"
        lines.append(
            f"fixed cost {result['preset']:<9} figures {'on ' if result['figures'] else 'off'}: "
            f"{result['fixed_cost']:.2f} s direct, {result['fixed_cost_extrapolated']:.2f} s "
            f"extrapolated ({1e3 * result['seconds_per_sweep']:.2f} ms a sweep between the runs)"
            f"  target < {result['target_seconds']:g} s: {verdict} ({baseline})"
        )
    return "\n".join(lines)


def _table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    widths = [max(len(str(c)) for c in column) for column in zip(headers, *rows, strict=True)]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(
            [str(cells[0]).ljust(widths[0])]
            + [str(c).rjust(w) for c, w in zip(cells[1:], widths[1:], strict=True)]
        )

    return "\n".join([line(headers), "  ".join("-" * w for w in widths), *map(line, rows)])


def _startup_commands(data: Path | None, fit: Path, word: str, tmp: Path) -> dict[str, list[str]]:
    """The commands of the start-up table (arguments of ``spcopyro``), by name."""
    return {
        "--help": ["--help"],
        "where": ["where", str(fit), word],
        "export": ["export", str(fit), "--nav2", str(tmp / "nav2"), "--word", word, "--overwrite"],
        "show (info)": [
            "show",
            *([str(data)] if data is not None else []),
            "--out",
            str(tmp / "house.png"),
        ],
    }


def measure_startup(data: Path | None, repeats: int = 3) -> dict[str, Any]:
    """Wall seconds of ``spcopyro --help``, ``where``, ``export`` and ``show`` as whole processes
    (each the fastest of ``repeats``) and of ``python -c pass`` in the same run, on a fit of
    ``data`` (None: the embedded synthetic default house) saved first; the heavy modules each
    imported. See the module docstring."""
    env = _environment()
    with tempfile.TemporaryDirectory(prefix="spcopyro-startup-") as name:
        tmp = Path(name)
        fit = tmp / "fit"
        command = [sys.executable, "-m", "spcopyro", "fit", *([str(data)] if data else [])]
        command += ["--sweeps", str(STARTUP_FIT_SWEEPS), "--no-figures", "--out", str(fit)]
        subprocess.run(command, check=True, capture_output=True, env=env, timeout=900)
        concepts = json.loads((fit / "concepts.json").read_text())
        word = next(c["top_words"][0][0] for c in concepts if c["top_words"])
        programs = {"python -c pass": [sys.executable, "-c", "pass"]}
        for label, args in _startup_commands(data, fit, word, tmp).items():
            programs[label] = [sys.executable, "-m", "spcopyro", *args]
        rows = []
        for label, program in programs.items():
            walls = []
            for _ in range(max(repeats, 1)):
                start = time.perf_counter()
                done = subprocess.run(program, capture_output=True, text=True, env=env,
                                      timeout=300)  # fmt: skip
                walls.append(time.perf_counter() - start)
                if done.returncode != 0:
                    raise RuntimeError(f"{' '.join(program)} failed ({done.returncode}):\n"
                                       f"{done.stderr[-3000:]}")  # fmt: skip
            heavy = None
            if program[1:3] == ["-m", "spcopyro"]:
                again = subprocess.run([sys.executable, "-c", _REPORT_HEAVY, *program[3:]],
                                       capture_output=True, text=True, env=env,
                                       timeout=300)  # fmt: skip
                lines = [x for x in again.stderr.splitlines() if x.startswith("heavy:")]
                heavy = [m for m in lines[-1].removeprefix("heavy:").strip().split(",") if m]
            judged = label in ("--help", "where", "export")
            rows.append({
                "command": label,
                "argv": program[1:],
                "seconds": min(walls),
                "median_seconds": sorted(walls)[len(walls) // 2],
                "runs": walls,
                "heavy_imported": heavy,
                "judged": judged,
                "meets_target": min(walls) < STARTUP_TARGET_SECONDS if judged else None,
            })  # fmt: skip
    return {
        "house": str(data) if data is not None else EMBEDDED_LABEL,
        "word": word,
        "fit_sweeps": STARTUP_FIT_SWEEPS,
        "repeats": max(repeats, 1),
        "target_seconds": STARTUP_TARGET_SECONDS,
        "commands": rows,
        "meets_target": all(r["meets_target"] for r in rows if r["judged"]),
        "no_heavy_imports": all(
            not r["heavy_imported"] for r in rows if r["heavy_imported"] is not None
        ),
    }


def render_startup(startup: dict[str, Any]) -> str:
    """The start-up table: seconds of each command, less ``python -c pass``, verdicts."""
    baseline = startup["commands"][0]["seconds"]
    rows = []
    for row in startup["commands"]:
        heavy = row["heavy_imported"]
        verdict = "-" if not row["judged"] else "PASS" if row["meets_target"] else "FAIL"
        rows.append([row["command"], f"{row['seconds']:.3f}", f"{row['median_seconds']:.3f}",
                     f"{row['seconds'] - baseline:+.3f}",
                     "-" if heavy is None else ",".join(heavy) or "none", verdict])  # fmt: skip
    title = (f"start-up of the questions as whole processes (house: {startup['house']}; a "
             f"fit of {startup['fit_sweeps']} sweeps, word {startup['word']!r}; seconds, fastest "
             f"and median of {startup['repeats']}; target < {startup['target_seconds']:g} "
             "s)")  # fmt: skip
    headers = ["command", "fastest", "median", "vs pass", "torch/pyro/numba", "target"]
    return "\n".join([title, _table(headers, rows)])


IMPORTS = ("pass", "numpy", "torch", "numba", "pyro", "matplotlib.figure", "spcopyro.cli.main")
"""The modules :func:`import_seconds` times by default (``pass``: the interpreter alone)."""


def import_seconds(modules: Sequence[str] = IMPORTS) -> dict[str, float]:
    """Wall seconds of ``python -c 'import M'`` in a fresh interpreter, for the heavy modules a
    fit may import (the floor under the fixed cost: ``torch`` alone is most of it)."""
    seconds = {}
    for module in modules:
        statement = module if module == "pass" else f"import {module}"
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", statement], check=True, env=_environment())
        seconds[module] = time.perf_counter() - start
    return seconds


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description="Fixed cost of spcopyro fit (module docstring).")
    parser.add_argument("--quick", action="store_true",
                        help="smoke test: paper-dp, 1 and 3 sweeps, no figures, 1 run")  # fmt: skip
    parser.add_argument("--dataset", type=Path, default=None,
                        help="dataset root (default: find_dataset_root())")  # fmt: skip
    parser.add_argument("--house",
                        help="house of the dataset (default room2ldk4; without the dataset the "
                             "embedded synthetic default house)")  # fmt: skip
    parser.add_argument("--presets", type=preset_names, default=None,
                        help="comma-separated presets (default paper-dp,auto; --quick: "
                             "paper-dp)")  # fmt: skip
    parser.add_argument("--sweeps", type=COUNT, nargs=2, default=None, metavar=("S1", "S2"),
                        help="the two run lengths the fixed cost is extrapolated from, S1 < S2 "
                             f"(default {SWEEPS[0]} {SWEEPS[1]}; --quick: 1 3)")  # fmt: skip
    parser.add_argument("--repeats", type=COUNT, default=None,
                        help="runs per configuration (default 3; --quick: 1)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=None,
                        help="JSON output (default benchmarks/fixed_cost.json, fixed_cost_quick."
                             "json with --quick, startup.json with --startup-only, "
                             "startup_quick.json with both)")  # fmt: skip
    parser.add_argument("--startup-only", action="store_true",
                        help="only the start-up of --help, where, export and show (no fits "
                             "timed)")  # fmt: skip
    args = parser.parse_args(argv)
    args.presets = quick_or(args.presets, args.quick, "paper-dp", "paper-dp,auto")
    args.sweeps = tuple(quick_or(args.sweeps, args.quick, (1, 3), SWEEPS))
    if not args.sweeps[0] < args.sweeps[1]:
        parser.error(f"argument --sweeps: S1 < S2, got {args.sweeps[0]} {args.sweeps[1]}")
    args.repeats = quick_or(args.repeats, args.quick, 1, 3)
    return args


def results_file(args: argparse.Namespace) -> Path:
    """``--out``, else benchmarks/fixed_cost.json, or startup.json with ``--startup-only``;
    NAME_quick.json under ``--quick`` (a quick --startup-only run wrote its one repeat over the
    full run's startup.json)."""
    return results_path(args.out, "startup" if args.startup_only else "fixed_cost", args.quick)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    without = None if args.house else "the embedded synthetic default house is fitted"
    dataset = dataset_root(args.dataset, without=without, needed_by=f"--house {args.house}")
    if args.house:  # asked for by name: there, or an error
        house_folder(dataset, args.house, "--house")
    house = args.house or "room2ldk4"
    folder = _house_folder(dataset, house)  # None: the embedded house
    label = house if folder is not None else f"the {EMBEDDED_LABEL}"
    presets = [p.strip() for p in args.presets.split(",") if p.strip()]
    sweeps, repeats = args.sweeps, args.repeats
    figures = [False] if args.quick else [True, False]
    bytecode = warm_bytecode()
    warm = {} if args.startup_only else warm_kernels(
        {p: preset_arguments(folder, p) for p in presets})  # fmt: skip
    results = []
    for preset in [] if args.startup_only else presets:
        for with_figures in figures:
            print(f"fitting {label} ({preset}, figures {with_figures}) ...", file=sys.stderr)
            results.append(measure_fixed_cost(dataset, house, preset, sweeps,
                                              with_figures, repeats))  # fmt: skip
    print(f"start-up of the questions on {label} ...", file=sys.stderr)
    startup = measure_startup(folder, repeats)
    # the floor under the fixed cost, timed in this run (--quick: the interpreter and torch only)
    imports = {} if args.startup_only else import_seconds(("pass", "torch") if args.quick
                                                          else IMPORTS)  # fmt: skip
    if results:
        print(render(results, imports) + "\n")
    print(render_startup(startup))
    if imports:
        print("\nimport alone, fresh interpreter (s): "
              + ", ".join(f"{m} {s:.2f}" for m, s in imports.items()))  # fmt: skip
    if folder is None:
        print(f"note: the public dataset was not found: the {EMBEDDED_LABEL} was fitted")
    print(bytecode_note(bytecode))
    if warm:
        print(warm_note(warm))
    record = {
        "machine": {
            "python": sys.version.split()[0],
            "platform": platform.platform(),
            "cpu_count": os.cpu_count(),
        },  # fmt: skip
        "bytecode": bytecode,
        "numba_warm_s": warm,
        "results": results,
        "startup": startup,
        "import_seconds": imports,
    }
    out = results_file(args)
    out.write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    run_main(main)
