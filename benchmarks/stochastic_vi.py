#!/usr/bin/env python
r"""Benchmark of memoized VI on spatial blocks (``--method stochastic-vi``) on maps of 10^6 cells.

:mod:`spcopyro.guides.memoized` visits the map one batch of square tiles at a time: the
tiles' q(C) are updated colour class by colour class against their boundary, their cached
expected statistics are swapped, and the global Dirichlet factors are the prior plus the sum of
all tiles' statistics (Hughes & Sudderth 2013). One *pass* visits every tile once. Measured in
one run:

1. **Small houses, against full-batch CAVI**
   (:func:`~spcopyro.guides.run.run_variational`, float64 q): the synthetic default house
   and an easy one (30 images per room and trial, no open plan), the same settings, start and
   annealing for every row: final ELBO, ARI against the ground truth, seconds, seconds per pass.
2. **A synthetic map of ~10^6 free cells** (:meth:`HouseSpec.scaled(1050, 1050)
   <spcopyro.synthetic.HouseSpec.scaled>`: ~1100 rooms, ~42k observed cells), in a fresh
   process: setup time, seconds per pass, the ELBO and the ARI after every pass, the time to a
   stable ELBO (a pass at full gamma raising it by < 1e-4 relative) and to a stable ARI (within
   0.01 of the final one from then on), the resident-set high-water mark (VmHWM) after
   the imports, after building the model data, after building the tiles and memo, and at the end,
   and the bytes of the run's own tensors (q, the tile index, the memo) and of the model data.
3. **The baseline at 10^6 cells**: a few iterations of full-batch CAVI (float64 q, the default
   backend: the compiled sparse update where numba imports) in its own fresh process: seconds
   per iteration (median after the first, which loads the kernels) and peak resident set.

Usage::

    python benchmarks/stochastic_vi.py              # full run (several minutes)
    python benchmarks/stochastic_vi.py --quick      # smoke test (~1e4 cells), well under a minute

It prints a plain-text table to stdout (progress goes to stderr) and writes every number, with
machine information, to a JSON file (default ``benchmarks/stochastic_vi_results.json``).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import resource
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from bench_cli import COUNT, INDEX, quick_or, run_main
from machine import busy_cpu_seconds, format_table, machine_info, own_cpu_seconds, progress

from spcopyro._util.arguments import integer_at_least

SCRIPT_DIR = Path(__file__).resolve().parent
SEED = 0
PRESET = "original-code"  # chi = 1, beta = 0.1: the observations are informative
GAMMA = 2.1
MIN_SIDE = 20  # HouseSpec.scaled's smallest: a 12-cell room inside the 3-cell margin and wall
STABLE_ELBO = 1e-4  # relative ELBO rise of a pass below which the ELBO counts as stable
STABLE_ARI = 0.01  # the ARI counts as stable once it stays within this of its final value

MEMORY_NOTE = (
    "peak_rss is the resident-set high-water mark (VmHWM of /proc/self/status) of a fresh "
    "process that imports spcopyro, draws the house, builds the model data and runs; it includes "
    "the interpreter, torch, and drawing the house (its observations, the per-cell counts). "
    "rss_after_data and rss_after_setup are the same high-water mark read after the model data "
    "and after the tiles and memo were built, so peak_rss - rss_after_data bounds what the "
    "inference added (it includes the benchmark's own copy of every pass's labels, int8 [N] "
    "per pass, for the ARI after the run). tensor_bytes are the run's own tensors."
)


def _max_rss_bytes() -> int:
    """This process's resident-set high-water mark: VmHWM of /proc/self/status (Linux; the
    peak of this process image only -- ``ru_maxrss`` after a fork and exec also counts the
    parent's resident set at the fork), else ``ru_maxrss``."""
    status = Path("/proc/self/status")
    if status.is_file():
        for line in status.read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024  # kB
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss) if sys.platform == "darwin" else int(rss) * 1024


def _mib(value: float | None) -> str:
    return "-" if value is None else f"{value / 2**20:.0f}"


def _problem(side: int | None, easy: bool = False, num_concepts: int = 20):
    """(house, model data, config, [N] truth) of a synthetic house: the default one (side None)
    or ``HouseSpec.scaled(side, side)``."""
    from spcopyro.config import preset
    from spcopyro.fit.house import prepare_model_data
    from spcopyro.synthetic import HouseSpec, make_house

    if side is None:
        spec = HouseSpec(images_per_room_per_trial=30, num_open_plan=0) if easy else HouseSpec()
    else:
        spec = HouseSpec.scaled(side, side)
    house = make_house(seed=SEED, spec=spec)
    settings = preset(PRESET, num_concepts=num_concepts, gamma=GAMMA)
    logging.disable(logging.WARNING)  # config notes
    _, data = prepare_model_data(house, settings)
    logging.disable(logging.NOTSET)
    return house, data, settings.model, house.truth[house.grid.free]


def _ari(truth: np.ndarray, labels: np.ndarray) -> float:
    from sklearn.metrics import adjusted_rand_score

    known = truth >= 0
    return float(adjusted_rand_score(truth[known], labels[known]))


def _stable(values: np.ndarray, aris: np.ndarray, gammas: np.ndarray, gamma: float):
    """0-based passes at which the ELBO and the ARI became stable (None if never)."""
    elbo_pass = None
    for p in range(1, len(values)):
        if gammas[p - 1] == gamma and abs(values[p] - values[p - 1]) < STABLE_ELBO * abs(values[p]):
            elbo_pass = p
            break
    off = np.abs(aris - aris[-1]) > STABLE_ARI
    ari_pass = int(np.flatnonzero(off)[-1] + 1) if off.any() else 0
    return elbo_pass, (ari_pass if ari_pass < len(aris) else None)


# ---------------------------------------------------------------------------------------------
# 1. Small houses: memoized VI against full-batch CAVI
# ---------------------------------------------------------------------------------------------


WARMUP_PASSES = 2
"""Passes of each small-house variant run untimed before the timed runs."""


def bench_small(passes: int, anneal: int) -> list[dict[str, Any]]:
    from spcopyro.guides.memoized import StochasticOptions, run_stochastic
    from spcopyro.guides.options import VariationalOptions
    from spcopyro.guides.run import initial_q, run_variational

    variants = [
        ("memoized 16x16, 1 block/step", dict(block_size=16)),
        ("memoized 16x16, 4 blocks/step", dict(block_size=16, blocks_per_step=4)),
        ("memoized 32x32, 1 block/step", dict(block_size=32)),
        ("memoized 32x32, float64", dict(block_size=32, dtype="float64")),
        ("memoized, one block (= CAVI)", dict(block_size=100_000, dtype="float64")),
    ]
    results = []
    # Untimed: every variant's kernels compiled or loaded from numba's cache (float32 and
    # float64), which the first row of each kind paid in its seconds (0.78 s against 0.03).
    _, data, config, _ = _problem(None, False)
    q = initial_q(data, config, torch.Generator().manual_seed(SEED))
    run_variational(data, config, WARMUP_PASSES, q=q, progress=False,
                    options=VariationalOptions(anneal_iterations=1))  # fmt: skip
    for _, changes in variants:
        options = StochasticOptions(anneal_passes=1, **changes)  # type: ignore[arg-type]
        q = initial_q(data, config, torch.Generator().manual_seed(SEED))
        q = q.to(torch.float32 if options.dtype == "float32" else torch.float64)
        run_stochastic(data, config, WARMUP_PASSES, q=q, options=options, progress=False,
                       generator=torch.Generator().manual_seed(SEED))  # fmt: skip
    for house_name, easy in (("default", False), ("easy", True)):
        _, data, config, truth = _problem(None, easy)
        progress(f"[small] {house_name} house: {data.num_free} cells, {passes} passes each")
        q = initial_q(data, config, torch.Generator().manual_seed(SEED))
        run = run_variational(data, config, passes, q=q, progress=False,
                              options=VariationalOptions(anneal_iterations=anneal))  # fmt: skip
        rows = [("full-batch CAVI (float64)", run, None)]
        for name, changes in variants:
            options = StochasticOptions(anneal_passes=anneal, **changes)  # type: ignore[arg-type]
            q = initial_q(data, config, torch.Generator().manual_seed(SEED))
            q = q.to(torch.float32 if options.dtype == "float32" else torch.float64)
            memo = run_stochastic(data, config, passes, q=q, options=options, progress=False,
                                  generator=torch.Generator().manual_seed(SEED))  # fmt: skip
            rows.append((name, memo, options))
        for name, r, options in rows:
            full = r.gammas == config.gamma
            rises = np.diff(r.objective[full]) if full.sum() > 1 else np.zeros(1)
            results.append({
                "house": house_name, "free_cells": data.num_free, "method": name,
                "options": None if options is None else vars(options),
                "passes": len(r.objective), "final_elbo": float(r.objective[-1]),
                "ari": _ari(truth, r.labels.numpy()), "concepts": int(r.num_concepts[-1]),
                "seconds": float(r.seconds[-1]),
                "seconds_per_pass": float(r.seconds[-1] / len(r.objective)),
                "min_elbo_rise_at_full_gamma": float(rises.min()),
            })  # fmt: skip
    return results


# ---------------------------------------------------------------------------------------------
# 2 and 3. The large map, each in a fresh process
# ---------------------------------------------------------------------------------------------


def child_stochastic(side: int, passes: int, anneal: int, block: int, per_step: int) -> dict:
    """Memoized VI on the ``side x side`` map: times, ELBO and ARI per pass, memory."""
    from spcopyro.guides.memoized import (
        StochasticOptions,
        compact_initial_q,
        run_stochastic,
        start_state,
    )

    rss_import = _max_rss_bytes()
    t0 = time.perf_counter()
    _, data, config, truth = _problem(side)
    data_s = time.perf_counter() - t0
    rss_data = _max_rss_bytes()
    options = StochasticOptions(block_size=block, blocks_per_step=per_step, anneal_passes=anneal)
    t0 = time.perf_counter()
    q = compact_initial_q(data, config, torch.Generator().manual_seed(SEED))
    setup = start_state(data, config, q, options)  # tiles, memo (timed here, reused below)
    setup_s = time.perf_counter() - t0
    rss_setup = _max_rss_bytes()
    labels: list[np.ndarray] = []
    tensor_bytes: dict[str, int] = {}

    def keep(sweep: int, state: Any) -> None:
        labels.append(state.q.argmax(-1).to(torch.int8).numpy())  # [N] int8 (L <= 127)
        tensor_bytes.update(state.nbytes())

    t0 = time.perf_counter()
    run = run_stochastic(data, config, passes, q=q, options=options, blocks=setup.blocks,
                         generator=torch.Generator().manual_seed(SEED), progress=False,
                         callback=keep)  # fmt: skip
    run_s = time.perf_counter() - t0
    peak = _max_rss_bytes()
    aris = np.array([_ari(truth, lab.astype(np.int64)) for lab in labels])
    elbo_pass, ari_pass = _stable(run.objective, aris, run.gammas, config.gamma)
    model_bytes = sum(
        t.element_size() * t.numel()
        for t in (data.neighbours, data.pairs, data.obs_cells, *data.colours,
                  *(m.counts for m in data.modalities))
    )  # fmt: skip
    return {
        "free_cells": data.num_free,
        "observed_cells": int(data.obs_cells.shape[0]),
        "num_concepts": config.num_concepts,
        "gamma": config.gamma,
        "blocks": setup.blocks.num_blocks,
        "options": vars(options),
        "data_s": data_s,
        "setup_s": setup_s,
        "run_s": run_s,
        "passes": len(run.objective),
        "seconds": run.seconds.tolist(),
        "seconds_per_pass": float(np.median(np.diff(np.concatenate([[0.0], run.seconds])))),
        "elbo": run.objective.tolist(),
        "ari": aris.tolist(),
        "concepts": run.num_concepts.tolist(),
        "gammas": run.gammas.tolist(),
        "stable_elbo_pass": elbo_pass,
        "stable_elbo_s": None if elbo_pass is None else float(run.seconds[elbo_pass]),
        "stable_ari_pass": ari_pass,
        "stable_ari_s": None if ari_pass is None else float(run.seconds[ari_pass]),
        "min_elbo_rise_at_full_gamma": float(
            np.diff(run.objective[run.gammas == config.gamma]).min()
        )
        if (run.gammas == config.gamma).sum() > 1
        else None,  # fmt: skip
        "rss_after_import_bytes": rss_import,
        "rss_after_data_bytes": rss_data,
        "rss_after_setup_bytes": rss_setup,
        "peak_rss_bytes": peak,
        "tensor_bytes": tensor_bytes,
        "model_data_bytes": model_bytes,
    }


def child_cavi(side: int, iterations: int) -> dict:
    """Full-batch CAVI (float64 q, :func:`run_variational`'s default backend: the compiled
    sparse update where numba imports) on the same map. Seconds an iteration: the median of
    the iterations after the first, which also loads the compiled kernels (the memoized run's
    pass is a median too; the whole run over the iterations charged that load to the ratio).
    The setup is timed apart and never in it: building the model data, and
    :func:`run_variational`'s own setup before its first iteration."""
    from spcopyro.guides.run import initial_q, resolve_backend, run_variational

    rss_import = _max_rss_bytes()
    t0 = time.perf_counter()
    _, data, config, truth = _problem(side)
    data_s = time.perf_counter() - t0
    rss_data = _max_rss_bytes()
    q = initial_q(data, config, torch.Generator().manual_seed(SEED))
    t0 = time.perf_counter()
    run = run_variational(data, config, iterations, q=q, progress=False)
    run_s = time.perf_counter() - t0
    steps = np.diff(np.concatenate([[0.0], run.seconds]))  # [S] seconds of each iteration
    return {
        "free_cells": data.num_free,
        "iterations": iterations,
        "backend": resolve_backend("auto"),
        "data_s": data_s,
        "run_s": run_s,
        # run_variational's own setup before its first iteration (the driver's clock starts
        # after it): the whole call less the iterations' cumulative seconds
        "setup_s": max(run_s - float(run.seconds[-1]), 0.0),
        "first_iteration_s": float(steps[0]),
        "seconds_per_iteration": float(np.median(steps[1:] if len(steps) > 1 else steps)),
        "elbo": run.objective.tolist(),
        "ari": _ari(truth, run.labels.numpy()),
        "rss_after_import_bytes": rss_import,
        "rss_after_data_bytes": rss_data,
        "peak_rss_bytes": _max_rss_bytes(),
        "q_bytes": q.element_size() * q.numel(),
    }


def in_child(args: list[str], what: str) -> dict[str, Any]:
    """Run this script with ``args`` in a fresh interpreter; its last stdout line is JSON."""
    command = [sys.executable, str(Path(__file__).resolve()), *args,
               "--torch-threads", str(torch.get_num_threads())]  # fmt: skip
    progress(f"[{what}] in a subprocess: {' '.join(args)}")
    busy0, own0, t0 = busy_cpu_seconds(), own_cpu_seconds(), time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(
            f"{what} subprocess exited with {done.returncode}:\n{done.stderr[-3000:]}"
        )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["process_s"] = wall
    if busy0 is not None:
        other = (busy_cpu_seconds() - busy0) - (own_cpu_seconds() - own0)  # type: ignore[operator]
        result["other_processes_cores"] = other / wall
    return result


# ---------------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------------


def render(results: dict[str, Any]) -> str:
    out = []
    small = results["small"]
    out.append("Small houses: memoized VI against full-batch CAVI (same start, annealing)")
    out.append(format_table(
        ["house / method", "cells", "passes", "ELBO", "ARI", "concepts", "s", "s/pass",
         "min ELBO rise per pass at full gamma"],
        [[f"{r['house']}: {r['method']}", r["free_cells"], r["passes"], f"{r['final_elbo']:.1f}",
          f"{r['ari']:.3f}", r["concepts"], f"{r['seconds']:.2f}",
          f"{r['seconds_per_pass']:.3f}", f"{r['min_elbo_rise_at_full_gamma']:.2g}"]
         for r in small],
    ))  # fmt: skip
    large = results.get("large")
    if large:
        out.append("")
        out.append(
            f"Large map: {large['free_cells']} free cells, {large['observed_cells']} observed, "
            f"L = {large['num_concepts']}, gamma = {large['gamma']}, {large['blocks']} tiles of "
            f"{large['options']['block_size']}x{large['options']['block_size']}, "
            f"{large['options']['blocks_per_step']} per step, "
            f"{large['options']['anneal_passes']} annealing passes"
        )
        checkpoints = sorted({0, 1, 4, 9, 14, 19, 29, 39, large["passes"] - 1})
        out.append(format_table(
            ["pass", "seconds", "ELBO", "ARI", "concepts", "gamma"],
            [[p + 1, f"{large['seconds'][p]:.1f}", f"{large['elbo'][p]:.6g}",
              f"{large['ari'][p]:.3f}", large["concepts"][p], f"{large['gammas'][p]:.2f}"]
             for p in checkpoints if p < large["passes"]],
        ))  # fmt: skip
        tb = large["tensor_bytes"]
        out.append(
            f"model data {large['data_s']:.1f} s, tiles + memo {large['setup_s']:.1f} s, "
            f"{large['seconds_per_pass']:.2f} s per pass (median); stable ELBO after pass "
            f"{_plus1(large['stable_elbo_pass'])} ({_s(large['stable_elbo_s'])}), stable ARI "
            f"after pass {_plus1(large['stable_ari_pass'])} ({_s(large['stable_ari_s'])}); "
            f"other processes used {large.get('other_processes_cores', float('nan')):.1f} cores"
        )
        out.append(
            f"memory (MiB): peak RSS {_mib(large['peak_rss_bytes'])}, after imports "
            f"{_mib(large['rss_after_import_bytes'])}, after model data "
            f"{_mib(large['rss_after_data_bytes'])}, after tiles + memo "
            f"{_mib(large['rss_after_setup_bytes'])}; tensors: q {_mib(tb.get('q'))}, "
            f"tiles {_mib(tb.get('blocks'))}, memo {_mib(tb.get('memo'))}, rows "
            f"{_mib(tb.get('rows'))}, model data {_mib(large['model_data_bytes'])}"
        )
    cavi = results.get("large_cavi")
    if cavi:
        out.append(
            f"baseline full-batch CAVI ({cavi.get('backend', '?')}) on the same map: "
            f"{cavi['seconds_per_iteration']:.2f} s per iteration (median after the first, "
            f"{cavi.get('first_iteration_s', float('nan')):.2f} s with the kernels' load; "
            f"{cavi['iterations']} iterations; setup apart: model data "
            f"{cavi.get('data_s', float('nan')):.1f} s, run_variational's own before the first "
            f"iteration {cavi.get('setup_s', float('nan')):.1f} s), peak RSS "
            f"{_mib(cavi['peak_rss_bytes'])} MiB (after model data "
            f"{_mib(cavi['rss_after_data_bytes'])}), float64 q {_mib(cavi['q_bytes'])} MiB"
        )
        if large:
            out.append(
                f"ratios: time per pass / CAVI iteration "
                f"{large['seconds_per_pass'] / cavi['seconds_per_iteration']:.2f}; peak RSS "
                f"added by the run {_mib(large['peak_rss_bytes'] - large['rss_after_data_bytes'])}"
                f" MiB against CAVI's "
                f"{_mib(cavi['peak_rss_bytes'] - cavi['rss_after_data_bytes'])} MiB"
            )
    return "\n".join(out)


def _plus1(p: int | None) -> str:
    return "-" if p is None else str(p + 1)


def _s(value: float | None) -> str:
    return "never" if value is None else f"{value:.1f} s"


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[1] if __doc__ else None)
    p.add_argument("--quick", action="store_true", help="a ~1e4-cell smoke test")
    p.add_argument("--side", type=integer_at_least(MIN_SIDE),
                   help="large map side (default 1050: ~1e6 cells; --quick: 110)")  # fmt: skip
    p.add_argument("--passes", type=COUNT, help="passes on the large map (default 60; quick: 6)")
    p.add_argument("--anneal", type=INDEX, help="annealing passes, all runs (default 10; quick: 2)")
    p.add_argument("--block-size", type=COUNT, default=64)
    p.add_argument("--blocks-per-step", type=COUNT, default=4)
    p.add_argument("--small-passes", type=COUNT, help="default 40 (--quick: 6)")
    p.add_argument("--cavi-iterations", type=INDEX,
                   help="0 skips the CAVI baseline (default 3; --quick: 2)")  # fmt: skip
    p.add_argument("--torch-threads", type=COUNT, default=1)
    p.add_argument("--out", type=Path,
                   help="JSON output (default benchmarks/stochastic_vi_results.json, "
                        "stochastic_vi_quick.json with --quick)")  # fmt: skip
    p.add_argument("--child", choices=["stochastic", "cavi"], help=argparse.SUPPRESS)
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    torch.set_num_threads(args.torch_threads)
    args.side = quick_or(args.side, args.quick, 110, 1050)
    args.passes = quick_or(args.passes, args.quick, 6, 60)
    args.anneal = quick_or(args.anneal, args.quick, 2, 10)
    args.small_passes = quick_or(args.small_passes, args.quick, 6, 40)
    args.cavi_iterations = quick_or(args.cavi_iterations, args.quick, 2, 3)
    if args.child == "stochastic":
        print(json.dumps(child_stochastic(args.side, args.passes, args.anneal, args.block_size,
                                          args.blocks_per_step)))  # fmt: skip
        return 0
    if args.child == "cavi":
        print(json.dumps(child_cavi(args.side, args.cavi_iterations)))
        return 0
    os.environ.setdefault("CI", "1")  # no progress bars in the children
    out = args.out or SCRIPT_DIR / ("stochastic_vi_quick.json" if args.quick
                                    else "stochastic_vi_results.json")  # fmt: skip
    results: dict[str, Any] = {"machine": machine_info(), "memory_note": MEMORY_NOTE,
                               "settings": {"preset": PRESET, "gamma": GAMMA, "seed": SEED,
                                            **{k: v for k, v in vars(args).items()
                                               if k not in ("out", "child")}}}  # fmt: skip
    results["small"] = bench_small(args.small_passes, args.anneal)
    common = ["--side", str(args.side), "--passes", str(args.passes), "--anneal", str(args.anneal)]
    results["large"] = in_child(
        ["--child", "stochastic", *common, "--block-size", str(args.block_size),
         "--blocks-per-step", str(args.blocks_per_step)], "large"
    )  # fmt: skip
    if args.cavi_iterations > 0:
        results["large_cavi"] = in_child(
            ["--child", "cavi", *common, "--cavi-iterations", str(args.cavi_iterations)],
            "large CAVI baseline",
        )
    results["machine"]["load_average_after"] = list(os.getloadavg())
    text = render(results)
    print(text)
    results["table"] = text
    out.write_text(json.dumps(results, indent=2) + "\n")
    progress(f"wrote {out}")
    return 0


if __name__ == "__main__":
    run_main(main)
