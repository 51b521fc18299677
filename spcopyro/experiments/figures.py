"""The experiment's figures: ARI and concepts per sweep (paper Figs. 5-6), maps side by side
(Fig. 7), SpCoMapping's map with each concept's best words (Fig. 10F).

Drawn on :class:`matplotlib.figure.Figure` objects and written with ``savefig`` (no pyplot, no
backend chosen on import), like :mod:`spcopyro.figures.plotting`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from spcopyro.data import House
from spcopyro.experiments.methods import METHOD_LABELS, ExperimentResult, Fitted
from spcopyro.figures.plotting import _extent, known_bounds, plot_semantic_map
from spcopyro.maps import render_labels


def _ranked(labels: np.ndarray) -> np.ndarray:
    """[H, W] labels renumbered by region size (0 = largest), -1 kept."""
    inside = labels >= 0
    if not inside.any():
        return labels
    values, sizes = np.unique(labels[inside], return_counts=True)
    order = values[np.argsort(-sizes, kind="stable")]
    rank = np.full(int(labels.max()) + 1, -1)
    rank[order] = np.arange(order.size)
    return np.where(inside, rank[np.maximum(labels, 0)], -1)


def plot_traces(fits: dict[str, Fitted], path: Path, title: str) -> Path:
    """ARI against the truth (sampled every few sweeps) and concepts in use per sweep."""
    fig = Figure(figsize=(7, 6))
    top, bottom = fig.subplots(2, 1, sharex=True)
    for method, fitted in fits.items():
        if fitted.result is None:
            continue
        label = METHOD_LABELS[method]
        if fitted.ari_trace is not None:
            top.plot(*fitted.ari_trace, lw=1.0, label=label)
        sweeps = np.arange(1, len(fitted.result.trace.num_concepts) + 1)
        bottom.plot(sweeps, fitted.result.trace.num_concepts, lw=1.0, label=label)
    top.set_ylabel("ARI vs truth (Fig. 5)")
    bottom.set_ylabel("concepts in use (Fig. 6)")
    bottom.set_xlabel("sweep")
    for ax in (top, bottom):
        ax.set_xscale("log")
    top.legend(fontsize=7)
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    return path


def plot_maps(house: House, fits: dict[str, Fitted], path: Path, title: str) -> Path:
    """The truth (when known) and every method's label map side by side (Fig. 7)."""
    grid = house.grid
    panels = [("ground truth", house.truth)] if house.truth is not None else []
    panels += [(METHOD_LABELS[m], f.model.label_image()) for m, f in fits.items()]
    columns = min(4, len(panels))
    rows_n = -(-len(panels) // columns)
    fig = Figure(figsize=(4 * columns, 3.6 * rows_n))
    axes = fig.subplots(rows_n, columns, squeeze=False)
    rows, cols = known_bounds(grid)
    for ax, (name, labels) in zip(axes.ravel(), panels, strict=False):
        rgb = render_labels(_ranked(np.asarray(labels)), grid)  # [H, W, 3]
        ax.imshow(rgb[rows, cols], extent=_extent(grid, rows, cols), interpolation="nearest")
        ax.set_title(name, fontsize=7)
        ax.set_xticks([])
        ax.set_yticks([])
    for ax in axes.ravel()[len(panels) :]:
        ax.axis("off")
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    return path


def write_figures(out: Path, result: ExperimentResult) -> list[Path]:
    """All figures of a run into ``out/figures``; returns their paths."""
    folder = out / "figures"
    house = result.synthetic_house
    paths = [
        plot_traces(
            result.synthetic_fits,
            folder / "synthetic_traces.png",
            f"{house.name} seed 0: ARI and concepts per sweep",
        ),
        plot_maps(
            house,
            result.synthetic_fits,
            folder / "synthetic_maps.png",
            f"{house.name} seed 0: every method's map",
        ),
    ]
    for method, fitted in result.synthetic_fits.items():
        if fitted.result is not None:
            paths.append(plot_semantic_map(fitted.result, folder / f"synthetic_{method}_words.png"))
    for name, fits in result.public_fits.items():
        title = f"{name}: every method's map (fitted on all but the first trial)"
        paths.append(
            plot_maps(result.public_houses[name], fits, folder / f"{name}_maps.png", title)
        )
        if "A-dp" in fits and fits["A-dp"].result is not None:
            paths.append(plot_semantic_map(fits["A-dp"].result, folder / f"{name}_A-dp_words.png"))
    return paths


def plot_stability(stability: dict, path: Path, method: str = "A-dp") -> Path:
    """The stability study (:func:`~spcopyro.experiments.robustness.stability_study`) in two panels.

    Left: every chain's ARI against the truth per setting (grey), chain 0 (circle) and the best
    of K chains by log joint (cross), one marker per house seed. Right: for the settings of
    ``method`` (one configuration, so their log joints compare within a house), each chain's ARI
    against its best log joint minus the highest one reached on that house: whether a higher log
    joint means a better map.
    """
    settings: dict[str, dict] = stability["settings"]
    names = list(settings)
    fig = Figure(figsize=(12, 0.45 * len(names) + 2.0))
    left, right = fig.subplots(1, 2)
    for y, name in enumerate(names):
        row = settings[name]
        chains = [c["ari"] for seed in row["chains"] for c in seed]
        left.scatter(chains, np.full(len(chains), y), s=12, color="0.75", zorder=1)
        left.scatter(row["single"], np.full(len(row["single"]), y - 0.15), s=28,
                     facecolors="none", edgecolors="C0", zorder=2)  # fmt: skip
        left.scatter(row["best_of_chains"], np.full(len(row["best_of_chains"]), y + 0.15),
                     s=28, marker="x", color="C3", zorder=2)  # fmt: skip
    left.set_yticks(range(len(names)), names, fontsize=8)
    left.invert_yaxis()
    left.set_xlabel("ARI against the truth")
    left.scatter([], [], s=12, color="0.75", label="every chain")
    left.scatter([], [], s=28, facecolors="none", edgecolors="C0", label="one chain (chain 0)")
    left.scatter([], [], s=28, marker="x", color="C3", label="best of K by log joint")
    left.legend(fontsize=7, loc="lower left")
    left.set_title(f"{stability['chains']} chains x seeds {stability['seeds']}", fontsize=9)

    family = [name for name in names if settings[name]["method"] == method]
    if family:
        seeds = range(len(stability["seeds"]))
        top = [max(c["best_log_joint"] for name in family for c in settings[name]["chains"][s])
               for s in seeds]  # fmt: skip
        for colour, name in enumerate(family):
            points = [(c["best_log_joint"] - top[s], c["ari"])
                      for s in seeds for c in settings[name]["chains"][s]]  # fmt: skip
            x, y = np.array(points).T
            right.scatter(x, y, s=18, color=f"C{colour}", label=name)
        right.set_xlabel("best log joint - the house's highest (nats)")
        right.set_ylabel("ARI against the truth")
        right.set_title(f"{method}: does a higher log joint mean a better map?", fontsize=9)
        right.legend(fontsize=7)
    else:
        right.set_axis_off()
    fig.suptitle(f"Stability, {stability['sweeps']} sweeps per chain")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    return path
