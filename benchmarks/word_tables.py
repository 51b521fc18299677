#!/usr/bin/env python
r"""What a Gibbs result's word tables are worth: one draw of w against posterior means.

For each synthetic house (seeds 0..n-1, the default spec) and each setting, one Gibbs run
(``thin`` keeping about 50 label maps over the second half of the sweeps) is scored three ways,
the labels being the same (the MAP-visited state):

* ``draw``: pi, theta and w as drawn at that state (what results held before issue 14);
* ``mean given labels``: their posterior means given those labels
  (:func:`spcopyro.results.posterior_means.posterior_means`);
* ``mean over samples``: those means averaged over the kept label maps (what ``spcopyro fit``
  reports with ``--marginal-samples``, its default).

Scores: the matching rate (eq. 18, places by eq. 19) with the pi prior and with the area prior
(:class:`spcopyro.results.semantic_map.SpCoSemanticMap`), and the share of the concepts in use
where a word was heard whose top word (the most probable) names the category that holds most of the
concept's cells.

Usage::

    python benchmarks/word_tables.py               # 3 seeds, 1000 sweeps (~2 min)
    python benchmarks/word_tables.py --quick       # smoke test
    python benchmarks/word_tables.py --seeds 5 --sweeps 2000 --out /tmp/words.json

It prints a table (mean over seeds) and writes every number to a JSON file
(``benchmarks/word_tables_results.json`` unless ``--out``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import torch
from bench_cli import COUNT, quick_or, results_path, run_main

from spcopyro.config import preset
from spcopyro.fit.gibbs_chains import with_sample_marginals
from spcopyro.fit.house import prepare_model_data, result_of
from spcopyro.gibbs.method import GibbsInference
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.metrics import matching_rate
from spcopyro.results.concept_words import listed_top_words
from spcopyro.results.result import SpCoResult
from spcopyro.results.semantic_map import SpCoSemanticMap
from spcopyro.synthetic import HouseSpec, make_house

SETTINGS = {
    "original-code, gamma 3": lambda: preset("original-code", gamma=3.0),
    "paper-dp": lambda: preset("paper-dp"),
}
KINDS = ("draw", "mean given labels", "mean over samples")


def top_word_agreement(result: SpCoResult, truth: np.ndarray, names: tuple[str, ...]) -> float:
    """Share of the concepts in use that list a word as ``fit`` lists them (a word was heard
    there and the fit modelled its words) whose most probable word is a token of the name of the
    category holding most of their cells; nan (not measured) where no concept lists a word, as
    for a fit that did not model its words (0.0 would read as measured and every top word wrong)."""
    image = result.label_image()  # [H, W]
    hits = []
    for concept in result.concepts_in_use():
        listed = listed_top_words(result, int(concept), 1)  # as fit lists them
        if not listed:
            continue  # no word heard here, or words not modelled: its top word means nothing
        cells = truth[(image == concept) & (truth >= 0)]
        if cells.size == 0:
            continue
        category = names[int(np.bincount(cells).argmax())]
        hits.append(listed[0][0] in category.split())
    return float(np.mean(hits)) if hits else float("nan")


def score(result: SpCoResult, house) -> dict[str, float]:
    names = house.category_names
    return {
        "matching_rate_pi": matching_rate(
            SpCoSemanticMap(result, prior="pi"), house.truth, names
        ).value,
        "matching_rate_area": matching_rate(
            SpCoSemanticMap(result, prior="area"), house.truth, names
        ).value,
        "top_word_names_category": top_word_agreement(result, house.truth, names),
    }


def run(seeds: int, sweeps: int, spec: HouseSpec | None, report) -> dict[str, object]:
    records: dict[str, dict[str, list[dict[str, float]]]] = {}
    for label, settings_of in SETTINGS.items():
        records[label] = {kind: [] for kind in KINDS}
        for seed in range(seeds):
            house = make_house(seed=seed) if spec is None else make_house(seed=seed, spec=spec)
            settings = settings_of()
            counts, data = prepare_model_data(house, settings)
            output = GibbsInference().run(
                data, settings.model, iterations=sweeps,
                generator=torch.Generator().manual_seed(seed),
                options=GibbsOptions(), progress=False, thin=max(1, sweeps // 100),
            )  # fmt: skip
            drawn = dataclasses.replace(output, parameters_drawn=False)
            sampled = with_sample_marginals(output, sweeps, data, settings)
            for kind, out in zip(KINDS, (drawn, output, sampled), strict=True):
                result = result_of(out, house, counts, data, settings, "gibbs")
                records[label][kind].append({"seed": seed, **score(result, house)})
            report(f"{label}, seed {seed}: done")
    return records


def _cell(values: list[float]) -> str:
    """``mean ± sd`` of a score's measured values (nan: not measured, left out), the number
    measured where some seed was not, and "not measured" where none was."""
    measured = [v for v in values if not np.isnan(v)]
    if not measured:
        return "not measured"
    text = f"{np.mean(measured):.3f} ± {np.std(measured):.3f}"
    return text if len(measured) == len(values) else f"{text} ({len(measured)}/{len(values)} seeds)"


def table(records) -> str:
    lines = [
        "| setting | word tables | matching rate (pi) | matching rate (area) | "
        "top word names the category |",
        "|---|---|---|---|---|",
    ]
    for label, kinds in records.items():
        for kind, rows in kinds.items():
            cells = []
            for key in ("matching_rate_pi", "matching_rate_area", "top_word_names_category"):
                cells.append(_cell([r[key] for r in rows]))
            lines.append(f"| {label} | {kind} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=COUNT, help="seeds 0..n-1 (default 3; --quick: 1)")
    parser.add_argument("--sweeps", type=COUNT, help="default 1000 (--quick: 60)")
    parser.add_argument("--quick", action="store_true", help="1 seed, 60 sweeps, a small house")
    parser.add_argument(
        "--out",
        default=None,
        help="JSON output (default benchmarks/word_tables_results.json, "
        "word_tables_results_quick.json with --quick)",
    )
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "word_tables_results", args.quick)
    torch.set_num_threads(1)
    spec = None
    args.seeds = quick_or(args.seeds, args.quick, 1, 3)
    args.sweeps = quick_or(args.sweeps, args.quick, 60, 1000)
    if args.quick:
        spec = HouseSpec(height=40, width=50, num_rooms=3, num_trials=2)
    records = run(args.seeds, args.sweeps, spec, lambda m: print(m, file=sys.stderr))
    text = table(records)
    print(f"{args.seeds} synthetic seeds, {args.sweeps} sweeps, mean ± sd over seeds\n{text}")
    payload = {"seeds": args.seeds, "sweeps": args.sweeps, "quick": args.quick,
               "records": records, "table": text}  # fmt: skip
    Path(args.out).write_text(json.dumps(payload, indent=1) + "\n")
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    run_main(main)
