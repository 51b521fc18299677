#!/usr/bin/env python
r"""The whole default fit, end to end (issue 25, "Done when"): for the embedded house and each
public house, one ``spcopyro fit [HOUSE]`` with the default settings (preset, start, merge moves,
point estimate, 50 kept label maps, 5000 sweeps, figures) as a fresh process, its wall time split
into

* **start-up**: launch to the start of ``fit``'s own work (the interpreter, the imports, the
  argument parser);
* **data**: loading the house, the settings, the summary, the model data and the chain's start
  (``load``, ``settings``, ``summary``, and the ``fit`` phase less its sweeps and its
  post-processing);
* **sweeps**: the wall of the chain's sweeps (``advance_chains``, the run loop included; for a
  fit the default refines on the map's cells, :mod:`spcopyro.fit.refine`, both stages' sweeps,
  and ``S`` below counts both);
* **post-processing** (what issue 25 item 1 holds to the time of 500 sweeps): the point
  estimate over the kept label maps, the agreement map, the label frequencies, the posterior
  means and the result (``result``), the uncertainty and agreement maps written, and the
  figures (the ``figures`` phase: what is left of their imports, each figure the fit's own
  process draws -- those of the child forked for them, the semantic map first, are not in its
  timings -- the wait for that child, and for the figures' prefetch thread, if it had not
  finished with the sweeps);
* **outputs and exit**: writing the result's files (``save`` less the maps), the printed report,
  moving OUT into place, and the interpreter's exit.

What the fit does on its figures' prefetch thread while the chains run (the figures' imports and
``house.png``, :mod:`spcopyro.cli.fit_figures`) is in the sweeps' wall; its own seconds are shown
beside it (``overlapped``), not added.

The parts come from the fit's own clock (:mod:`spcopyro._util.timings`: the phases and the parts
timed with ``timed``, written to ``$SPCOPYRO_TIMINGS``). The target (issue 25 item 1): the
post-processing at most the time of 500 sweeps of the same run (``500 / S`` of its sweeps).

Then the start-up of ``spcopyro --help``, ``where`` and ``export`` on a saved fit as whole
processes (target < 0.5 s each; ``benchmarks/fixed_cost.py``'s :func:`measure_startup`, beside
``python -c pass`` in the same run).

Usage::

    python benchmarks/end_to_end.py                       # embedded house + every public house
    python benchmarks/end_to_end.py --houses embedded,room2ldk4 --repeats 2
    python benchmarks/end_to_end.py --quick               # smoke test: 200 sweeps, embedded only

Prints a table and writes every number to ``benchmarks/end_to_end.json`` (``--out``; git-ignored).
Each house is fitted ``--repeats`` times and the run of the least post-processing kept (the least
disturbed by other load; its sweeps are those of the same run).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

SCRIPT_DIR = Path(__file__).resolve().parent
sys.path.insert(0, str(SCRIPT_DIR))

from bench_cli import COUNT, check_houses, dataset_root, fail, quick_or, results_path, run_main  # noqa: E402  (scripts beside this one)
from fixed_cost import (  # noqa: E402
    _table,
    bytecode_note,
    measure_startup,
    render_startup,
    run_fit_process,
    warm_bytecode,
    warm_kernels,
    warm_note,
)

EMBEDDED = "embedded"
PUBLIC = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")
REFERENCE_SWEEPS = 500  # issue 25 item 1: post-processing <= the time of 500 sweeps
DATA_PHASES = ("load", "settings", "summary")
IN_FIT_POST = ("point_estimate", "agreement", "label_frequencies", "posterior_means", "result")
"""The parts of the ``fit`` phase after the sweeps (:mod:`spcopyro._util.timings`)."""
OVERLAPPED = ("prefetch imports", "prefetch house")
"""Parts done on the figures' prefetch thread, during the sweeps."""


def fit_default(data: Path | None, sweeps: int | None, seed: int = 0) -> dict[str, Any]:
    """One default ``spcopyro fit`` of ``data`` (None: the embedded house) in a fresh process:
    its wall seconds split as the module docstring says."""
    arguments = [
        *([str(data)] if data is not None else []),
        *([] if sweeps is None else ["--sweeps", str(sweeps)]),
        "--seed",
        str(seed),
    ]
    record, wall, startup, pngs = run_fit_process(arguments, timeout=1800)
    return split(record, wall, startup, pngs)


def split(record: dict[str, Any], wall: float, startup: float, pngs: Sequence[str] = ()) -> dict:
    """The start-up, data, sweeps, post-processing and outputs of one fit from its timings
    ``record`` (the module docstring)."""
    seconds, parts = record["seconds"], record.get("parts", {})
    sweeps = parts["sweeps"]
    in_fit_post = {name: parts.get(name, 0.0) for name in IN_FIT_POST}
    fit_rest = seconds["fit"] - sweeps - sum(in_fit_post.values())  # model data, chain start
    data = sum(seconds.get(name, 0.0) for name in DATA_PHASES) + fit_rest
    maps = parts.get("uncertainty", 0.0)  # inside the "save" phase
    post = {**in_fit_post, "maps": maps, "figures": seconds.get("figures", 0.0)}
    exit_seconds = wall - startup - record["total"]
    outputs = {"save": seconds.get("save", 0.0) - maps, "report": seconds.get("report", 0.0),
               "commit": seconds.get("commit", 0.0), "exit": exit_seconds}  # fmt: skip
    figures = {k.removeprefix("figure "): v for k, v in parts.items() if k.startswith("figure ")}
    figures["prefetch wait"] = parts.get("prefetch wait", 0.0)
    count = int(record["sweeps"])
    reference = sweeps * REFERENCE_SWEEPS / count
    total_post = sum(post.values())
    return {
        "wall": wall,
        "startup": startup,
        "data": data,
        "data_parts": {
            **{n: seconds.get(n, 0.0) for n in DATA_PHASES},
            "model_data": parts.get("model_data", 0.0),
            "chain_start": parts.get("chain_start", 0.0),
        },  # fmt: skip
        "sweeps": sweeps,
        "sweep_count": count,
        "sweeps_trace": record.get("sweep_seconds"),
        "post": total_post,
        "post_parts": post,
        "outputs": sum(outputs.values()),
        "output_parts": outputs,
        "overlapped": {name: parts.get(name, 0.0) for name in OVERLAPPED},
        "figures": figures,
        "reference_sweeps": REFERENCE_SWEEPS,
        "reference_seconds": reference,
        "post_over_reference": total_post / reference,
        "meets_target": total_post <= reference,
        "pngs": list(pngs),
        "parts": parts,
        "seconds": seconds,
    }


def house_path(root: Path | None, name: str) -> Path | None:
    """The folder of a public house (None for the embedded house)."""
    if name == EMBEDDED:
        return None
    if root is None or not (root / name).is_dir():
        raise FileNotFoundError(f"house {name!r}: no public dataset folder {root}/{name}")
    return root / name


def render(rows: Sequence[dict[str, Any]]) -> str:
    """The table: per house, the wall split, the post-processing by part and the verdict."""
    headers = ["house", "wall", "startup", "data", "sweeps", "post", "out+exit",
               f"{REFERENCE_SWEEPS} sw", "post/ref", "pt est", "agree", "freq", "maps",
               "figures", "overlap", "target"]  # fmt: skip
    table = []
    for row in rows:
        r, p = row["fit"], row["fit"]["post_parts"]
        freq = p["label_frequencies"] + p["posterior_means"] + p["result"]
        table.append([row["house"], *(f"{r[k]:.2f}" for k in ("wall", "startup", "data",
                      "sweeps", "post", "outputs", "reference_seconds")),
                      f"{r['post_over_reference']:.2f}",
                      *(f"{p[k]:.2f}" for k in ("point_estimate", "agreement")), f"{freq:.2f}",
                      *(f"{p[k]:.2f}" for k in ("maps", "figures")),
                      f"{sum(r['overlapped'].values()):.2f}",
                      "PASS" if r["meets_target"] else "FAIL"])  # fmt: skip
    names = sorted({k for row in rows for k in row["fit"]["figures"]})
    figure_rows = [[row["house"], *(f"{row['fit']['figures'].get(k, 0.0):.2f}" for k in names),
                    *(f"{v:.2f}" for v in row["fit"]["overlapped"].values())]
                   for row in rows]  # fmt: skip
    return "\n".join([
        "default fit as a whole process (wall seconds; sweeps: their wall in the run, "
        f"{REFERENCE_SWEEPS} sw: {REFERENCE_SWEEPS}/S of it; post: point estimate, agreement, "
        "label frequencies (freq, with the posterior means), uncertainty/agreement maps, figures; "
        "out+exit: the result's files, report, exit; overlap: the figures' prefetch thread "
        "during the sweeps, not added)",
        _table(headers, table),
        "",
        "figures by part (seconds; the last two on the prefetch thread, during the sweeps)",
        _table(["house", *names, *OVERLAPPED], figure_rows),
    ])  # fmt: skip


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description="The whole default fit, end to end.")
    parser.add_argument("--houses",
                        help="comma-separated: 'embedded' and public house names (default: "
                             "embedded and the five, public ones skipped with a note without the "
                             "dataset; --quick: embedded)")  # fmt: skip
    parser.add_argument("--dataset", type=Path, default=None,
                        help="dataset root (default: find_dataset_root())")  # fmt: skip
    parser.add_argument("--sweeps", type=COUNT, default=None,
                        help="sweeps of each fit (default: the fit's own default; --quick: "
                             "200)")  # fmt: skip
    parser.add_argument("--repeats", type=COUNT, default=1,
                        help="fits per house (least post kept)")  # fmt: skip
    parser.add_argument("--startup-repeats", type=COUNT, default=None,
                        help="runs of each start-up command (fastest kept; default 3, --quick: "
                             "1)")  # fmt: skip
    parser.add_argument("--no-startup", action="store_true", help="skip the start-up table")
    parser.add_argument("--quick", action="store_true",
                        help="smoke test: the embedded house, 200 sweeps, 1 run")  # fmt: skip
    parser.add_argument("--out", type=Path, default=None,
                        help="JSON output (default benchmarks/end_to_end.json, "
                        "end_to_end_quick.json with --quick)")  # fmt: skip
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    every = ",".join((EMBEDDED, *PUBLIC))
    houses = [h.strip() for h in quick_or(args.houses, args.quick, EMBEDDED, every).split(",")]
    houses = [h for h in houses if h]
    if not houses:  # not a PASS "on every house" of none
        fail(f"--houses {args.houses!r}: no house named")
    named = args.houses is not None and set(houses) != {EMBEDDED}  # there, or an error
    public = ", ".join(h for h in houses if h != EMBEDDED)
    without = None if named else (f"skipped {public}" if public else "the embedded house only")
    root = dataset_root(args.dataset, without=without,
                        needed_by=f"--houses {','.join(houses)}")  # fmt: skip
    if named:
        check_houses(root, houses, synthetic=(EMBEDDED,))
    sweeps = quick_or(args.sweeps, args.quick, 200, None)
    repeats, startup_repeats = args.repeats, quick_or(args.startup_repeats, args.quick, 1, 3)
    if root is None:  # dataset_root's note named the houses skipped: one line, not two
        houses = [h for h in houses if h == EMBEDDED]
    bytecode = warm_bytecode()  # the children use the .pyc cache, as a user's Python does
    paths = {house: house_path(root, house) for house in houses}  # numba's cache filled, untimed
    warm = warm_kernels({h: [str(p)] if p is not None else [] for h, p in paths.items()})
    rows = []
    for house, data in paths.items():
        tries = []
        for k in range(repeats):
            print(f"fitting {house} ({k + 1} of {repeats}) ...", file=sys.stderr)
            tries.append(fit_default(data, sweeps))
        rows.append({"house": house, "data": None if data is None else str(data),
                     "fit": min(tries, key=lambda r: r["post"]), "tries": tries})  # fmt: skip
    startup = None
    if not args.no_startup:
        first = next((h for h in houses if h != EMBEDDED), EMBEDDED)
        print(f"start-up of the questions on {first} ...", file=sys.stderr)
        startup = measure_startup(house_path(root, first), startup_repeats)
    print(render(rows))
    if startup is not None:
        print("\n" + render_startup(startup))
    print(bytecode_note(bytecode))
    print(warm_note(warm))
    verdict = all(row["fit"]["meets_target"] for row in rows)
    print(f"\npost-processing <= {REFERENCE_SWEEPS} sweeps on every house: "
          f"{'PASS' if verdict else 'FAIL'}")  # fmt: skip
    if startup is not None:
        print(f"start-up of --help, where, export < {startup['target_seconds']:g} s: "
              f"{'PASS' if startup['meets_target'] else 'FAIL'}")  # fmt: skip
    record = {
        "machine": {
            "python": sys.version.split()[0],
            "platform": platform.platform(),
            "cpu_count": os.cpu_count(),
            "load_average": os.getloadavg(),
        },  # fmt: skip
        "bytecode": bytecode,
        "numba_warm_s": warm,
        "sweeps": sweeps,
        "repeats": repeats,
        "houses": rows,
        "post_meets_target": verdict,
        "startup": startup,
    }
    out = results_path(args.out, "end_to_end", args.quick)
    out.write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    run_main(main)
