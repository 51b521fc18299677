"""The stability study's figure (:func:`plot_stability`). The comparison's figures (ARI and
concepts per sweep, maps side by side: paper Figs. 5-7) are drawn from a study's stored results
(:mod:`spcopyro.study.experiment`, :mod:`spcopyro.study.maps`).

Drawn on :class:`matplotlib.figure.Figure` objects and written with ``savefig`` (no pyplot, no
backend chosen on import), like :mod:`spcopyro.figures.plotting`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from spcopyro._util.outputs import replace_figure
from spcopyro.figures.fonts import any_script


def plot_stability(stability: dict, path: Path, method: str = "A-dp") -> Path:
    """Write :func:`stability_figure` to ``path`` (PNG)."""
    fig = stability_figure(stability, method)
    path.parent.mkdir(parents=True, exist_ok=True)
    with any_script(fig):  # words of any script, not boxes
        replace_figure(fig, path, dpi=120, bbox_inches="tight")  # whole or not at all
    return path


def stability_figure(stability: dict, method: str = "A-dp") -> Figure:
    """The stability study (:func:`~spcopyro.study.robustness.stability_of_rows`) in two panels.

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
    # below the axes: in its lower left corner it hid the last rows' points
    left.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, frameon=False)
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
        # below the axes, as the left panel's (loc="best" moved between runs, over points)
        right.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2,
                     frameon=False)  # fmt: skip
    else:
        right.set_axis_off()
    fig.suptitle(f"Stability, {stability['sweeps']} sweeps per chain")
    return fig
