"""Why the posterior prefers one concept: the log joint of the collapsed map against the truth's,
term by term (issue 21, item 2).

    python benchmarks/collapse_terms.py [--out benchmarks/collapse_terms.json]

For a public house (room1dk5, against the project's region truth,
:mod:`spcopyro.experiments.public_truth`) and a synthetic open-plan house (seed 0, its own
truth), two label maps are compared: **collapsed** (every free cell in one concept) and **truth**
(one concept per truth category; cells the truth leaves out join the largest category). With pi,
theta and w integrated out (all conjugate), the log joint is, up to terms that do not depend on
the labels (the multinomial coefficients of each observed cell's counts):

* ``labels``: log DM(N_1..N_L | c), c = alpha / L (weak-limit DP): the label-count prior, in
  which every free cell votes;
* ``potts``: gamma E(C), the Potts agreements (eq. 3; the normaliser is left out, as in the
  model);
* ``images``, ``words``: sum over concepts of log DM(the concept's summed counts | chi or beta).

Each term is printed as *collapsed minus truth* (positive: the term prefers the collapse), for
the model's cell size (the map's own 0.05 m cells, or 0.25 m model cells), the image scaling
(``floor100``: a histogram as 100 draws, or ``probability``: one observation) and the words'
weight (1 or 10, over a 1 m footprint or none), all else as preset ``auto``. The model's
settings that do not appear (gamma 3, alpha 1e7, L 120, beta 0.1, chi 1) are ``auto``'s. The
last variant, named "(coarse)", is the default preset's data settings with the 1 m footprint,
the default before 2026-12-06 (0.75 m since); it keeps its 1 m and its name, which
docs/real_houses.md's tables quote.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
from pathlib import Path

import numpy as np
import torch
from bench_cli import dataset_root, results_path, run_main
from scipy.special import gammaln

from spcopyro.config import preset
from spcopyro.data import load_house
from spcopyro.data.model_grid import model_house
from spcopyro.experiments.public_truth import public_truth
from spcopyro.fit.house import prepare_model_data
from spcopyro.synthetic import HouseSpec, make_house

VARIANTS = {
    "0.05 m, floor100, words x1": dict(),
    "0.05 m, probability, words x1": dict(feature_scaling="probability"),
    "0.25 m, floor100, words x1": dict(cell_size=0.25),
    "0.25 m, probability, words x1": dict(cell_size=0.25, feature_scaling="probability"),
    # coarse's data settings before 2026-12-06 (its footprint is 0.75 m since): see above
    "0.25 m, probability, words x10 over 1 m (coarse)": dict(
        cell_size=0.25, feature_scaling="probability", word_scaling=10.0, footprint_radius=1.0
    ),
}


def dirichlet_multinomial(counts: np.ndarray, concentration: float) -> float:
    """sum over rows of log DM(row | symmetric concentration), without the multinomial
    coefficient: lgamma(K a) - lgamma(K a + n) + sum_k [lgamma(a + n_k) - lgamma(a)]."""
    counts = np.atleast_2d(counts)
    k = counts.shape[1]
    n = counts.sum(1)
    return float(
        np.sum(gammaln(k * concentration) - gammaln(k * concentration + n))
        + np.sum(gammaln(concentration + counts) - gammaln(concentration))
    )


def terms(labels: np.ndarray, data, config) -> dict[str, float]:
    """The label-dependent log-joint terms of ``labels`` ([N], values < L)."""
    num_concepts = config.num_concepts
    sizes = np.bincount(labels, minlength=num_concepts)  # [L]
    c = config.pi_concentration
    label_term = float(
        gammaln(num_concepts * c) - gammaln(num_concepts * c + sizes.sum())
        + np.sum(gammaln(c + sizes) - gammaln(c))
    )  # fmt: skip
    pairs = data.pairs.numpy()
    potts = config.gamma * float(np.sum(labels[pairs[:, 0]] == labels[pairs[:, 1]]))
    out = {"labels": label_term, "potts": potts}
    observed = labels[data.obs_cells.numpy()]  # [M]
    for modality in data.modalities:
        counts = modality.counts.numpy()  # [M, K]
        per_concept = np.zeros((num_concepts, counts.shape[1]))
        np.add.at(per_concept, observed, counts)
        used = per_concept.sum(1) > 0
        out[modality.name] = dirichlet_multinomial(
            per_concept[used], config.concentration(modality.name)
        )
    return out


def compare(house, truth: np.ndarray) -> dict[str, dict[str, float]]:
    """Collapsed minus truth, term by term, under each variant."""
    truth = np.asarray(truth).copy()
    largest = np.bincount(truth[truth >= 0]).argmax()
    truth[house.grid.free & (truth < 0)] = largest
    names = tuple(f"c{k}" for k in range(int(truth.max()) + 1))
    with_truth = dataclasses.replace(house, truth=truth, category_names=names)
    out = {}
    for name, overrides in VARIANTS.items():
        settings = preset("auto", **overrides)
        model = model_house(with_truth, settings.data.cell_size)
        _, data = prepare_model_data(model, settings)
        split = model.truth[model.grid.free]  # [N]
        split = np.where(split >= 0, split, largest)
        collapsed = terms(np.zeros_like(split), data, settings.model)
        along = terms(split, data, settings.model)
        diff = {k: collapsed[k] - along[k] for k in collapsed}
        diff["total"] = sum(diff.values())
        diff["free_cells"] = int(model.grid.num_free)
        out[name] = diff
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out",
        default=None,
        help="JSON output (default benchmarks/collapse_terms.json, "
        "collapse_terms_quick.json with --quick)",
    )
    parser.add_argument("--quick", action="store_true", help="accepted for the smoke tests")
    args = parser.parse_args(argv)
    args.out = results_path(args.out, "collapse_terms", args.quick)
    logging.getLogger("spcopyro").setLevel(logging.ERROR)
    torch.set_num_threads(1)
    houses = {}
    root = dataset_root(without="the public house room1dk5 is skipped")
    if root is not None:
        house = load_house(Path(root) / "room1dk5")
        houses["room1dk5 (public)"] = (house, public_truth(house).labels)
    synthetic = make_house(seed=0, spec=HouseSpec.open_plan())
    houses["open-plan seed 0 (synthetic)"] = (synthetic, synthetic.truth)
    report = {}
    for title, (house, truth) in houses.items():
        rows = compare(house, truth)
        report[title] = rows
        print(f"### {title}: log joint of the collapsed map minus the truth's (nats)\n")
        print("| variant | free cells | labels | potts | images | words | total |")
        print("|---|---|---|---|---|---|---|")
        for name, d in rows.items():
            print(f"| {name} | {d['free_cells']} | {d['labels']:+.0f} | {d['potts']:+.0f} | "
                  f"{d['images']:+.0f} | {d['words']:+.0f} | **{d['total']:+.0f}** |")  # fmt: skip
        print()
    Path(args.out).write_text(json.dumps(report, indent=1))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    run_main(main)
