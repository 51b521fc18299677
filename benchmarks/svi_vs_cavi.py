#!/usr/bin/env python
"""SVI with the Pyro guide (``--method svi``) against CAVI (``--method cavi``) from the same starts.

On the 3-room synthetic house of the tests (``make_house(seed=1, HouseSpec(40, 50, 3 rooms, 3
trials))``, 1299 free cells, preset ``original-code`` with gamma 3, L = 8), for each start seed:
SVI (:func:`spcopyro.guides.svi_method.fit_svi`, its default options) for ``--steps`` steps and CAVI
(dense torch reference, gamma annealed over 30 of 60 iterations) from the same random q; both
scored by the exact ELBO (:func:`spcopyro.guides.elbo.elbo`) at their final parameters and by
the ARI of argmax q against the ground truth. Also SVI's traced estimate (mean of its last 20
steps) beside the exact ELBO.

Usage::

    python benchmarks/svi_vs_cavi.py                 # 300 steps, 4 starts (a few minutes)
    python benchmarks/svi_vs_cavi.py --quick --out /tmp/svi.json   # smoke run: 10 steps, 1 start

Prints a table and writes the numbers with machine information to a JSON file (default
``benchmarks/svi_vs_cavi_results.json``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch
from bench_cli import COUNT, quick_or, results_path, run_main
from machine import format_table, machine_info, progress

from spcopyro.config import preset
from spcopyro.fit.house import prepare_model_data
from spcopyro.guides.elbo import elbo
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.run import initial_q, run_variational
from spcopyro.guides.svi_method import SVIOptions, fit_svi
from spcopyro.metrics import adjusted_rand_index
from spcopyro.synthetic import HouseSpec, make_house

SCRIPT_DIR = Path(__file__).resolve().parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=COUNT, help="SVI steps (default 300; --quick: 10)")
    parser.add_argument("--starts", type=COUNT, help="start seeds (default 4; --quick: 1)")
    parser.add_argument("--quick", action="store_true", help="smoke run: 10 steps, one start")
    parser.add_argument(
        "--out",
        default=None,
        help="JSON output (default benchmarks/svi_vs_cavi_results.json, "
        "svi_vs_cavi_results_quick.json with --quick)",
    )
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "svi_vs_cavi_results", args.quick)
    args.steps = quick_or(args.steps, args.quick, 10, 300)
    args.starts = quick_or(args.starts, args.quick, 1, 4)
    torch.set_num_threads(1)
    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=3))
    settings = preset("original-code", gamma=3.0, num_concepts=8)
    _, data = prepare_model_data(house, settings)
    config = settings.model

    def ari(q: torch.Tensor) -> float:
        image = np.full(house.grid.shape, -1)
        image[house.grid.free] = q.argmax(-1).numpy()
        return float(adjusted_rand_index(image, house.truth))

    rows = []
    cavi_options = VariationalOptions(anneal_iterations=30, backend="torch")
    for seed in range(args.starts):
        progress(f"start {seed}: SVI {args.steps} steps, CAVI 60 iterations")
        q = initial_q(data, config, torch.Generator().manual_seed(seed))
        generator = torch.Generator().manual_seed(seed)
        svi = fit_svi(data, config, args.steps, q=q.clone(), progress=False,
                      generator=generator, options=SVIOptions())  # fmt: skip
        cavi = run_variational(data, config, 60, options=cavi_options, q=q.clone(), progress=False)
        svi_elbo = float(elbo(svi.q, svi.factors, data, config))
        cavi_elbo = float(elbo(cavi.q, cavi.factors, data, config))
        rows.append({
            "seed": seed, "svi_elbo": svi_elbo, "svi_estimate": float(svi.objective[-20:].mean()),
            "svi_ari": ari(svi.q), "svi_seconds": float(svi.seconds[-1]),
            "cavi_elbo": cavi_elbo, "cavi_ari": ari(cavi.q),
            "cavi_seconds": float(cavi.seconds[-1]),
            "svi_below_cavi_percent": 100 * (cavi_elbo - svi_elbo) / abs(cavi_elbo),
        })  # fmt: skip
    headers = ["start", "SVI ELBO", "SVI estimate", "SVI ARI", "SVI s", "CAVI ELBO", "CAVI ARI",
               "CAVI s", "SVI below CAVI"]  # fmt: skip
    table = [[str(r["seed"]), f"{r['svi_elbo']:.1f}", f"{r['svi_estimate']:.1f}",
              f"{r['svi_ari']:.3f}", f"{r['svi_seconds']:.1f}", f"{r['cavi_elbo']:.1f}",
              f"{r['cavi_ari']:.3f}", f"{r['cavi_seconds']:.1f}",
              f"{r['svi_below_cavi_percent']:.1f} %"] for r in rows]  # fmt: skip
    print(format_table(headers, table))
    record = {"machine": machine_info(), "steps": args.steps, "rows": rows}
    Path(args.out).write_text(json.dumps(record, indent=1) + "\n")
    progress(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    run_main(main)
