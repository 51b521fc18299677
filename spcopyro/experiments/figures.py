"""The experiment's figures: ARI and concepts per sweep (paper Figs. 5-6), maps side by side
(Fig. 7), SpCoMapping's map with each concept's best words (Fig. 10F)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from spcopyro.data import House  # noqa: E402
from spcopyro.experiments.methods import METHOD_LABELS, Fitted  # noqa: E402
from spcopyro.maps import render_labels  # noqa: E402
from spcopyro.plotting import _extent, known_bounds, plot_semantic_map  # noqa: E402

if TYPE_CHECKING:
    from spcopyro.experiments.table import ExperimentResult


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
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for method, fitted in fits.items():
        if fitted.result is None:
            continue
        label = METHOD_LABELS[method]
        if fitted.ari_trace is not None:
            top.plot(*fitted.ari_trace, lw=1.0, label=label)
        sweeps = np.arange(1, len(fitted.result.num_concepts) + 1)
        bottom.plot(sweeps, fitted.result.num_concepts, lw=1.0, label=label)
    top.set_ylabel("ARI vs truth (Fig. 5)")
    bottom.set_ylabel("concepts in use (Fig. 6)")
    bottom.set_xlabel("sweep")
    for ax in (top, bottom):
        ax.set_xscale("log")
    top.legend(fontsize=7)
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def plot_maps(house: House, fits: dict[str, Fitted], path: Path, title: str) -> Path:
    """The truth (when known) and every method's label map side by side (Fig. 7)."""
    grid = house.grid
    panels = [("ground truth", house.truth)] if house.truth is not None else []
    panels += [(METHOD_LABELS[m], f.model.label_image()) for m, f in fits.items()]
    columns = min(4, len(panels))
    rows_n = -(-len(panels) // columns)
    fig, axes = plt.subplots(rows_n, columns, figsize=(4 * columns, 3.6 * rows_n), squeeze=False)
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
    plt.close(fig)
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
