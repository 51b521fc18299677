"""The inference comparison's figure: quality against wall-clock time (log axis), one per house
type (``comparison_<house type>.png`` beside ``comparison.md``,
:mod:`spcopyro.experiments.comparison_report`), drawn on a :class:`matplotlib.figure.Figure`
(no pyplot), as in :mod:`spcopyro.experiments.figures`.

Each fit is one thin line through its curve (:func:`~.inference_comparison.fit_and_score`): the
label maps the method kept along its run (or its re-runs at shorter budgets), then, last, the
map the method reports. That last point is a different kind of map for a sampler (Gibbs, Gibbs +
Swendsen-Wang, VI then Gibbs: the highest-log-joint state visited, not its last state) and the
same kind for the variational methods and loopy BP (argmax of the final q, or beliefs), so it
has its own marker (:data:`FINAL_MARKER`, hollow) and one grey legend entry
(:data:`FINAL_LABEL`): a step into it is a change of kind of map, not of time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from spcopyro._util.outputs import replace_figure
from spcopyro.experiments.inference_comparison import LOWER_IS_BETTER, SCORES, SYNTHETIC, VARIANTS
from spcopyro.figures.fonts import any_script

SCORE_NAMES = {
    "ari": "ARI",
    "matching_rate": "matching rate",
    "top1": "held-out top-1",
    "top3": "held-out top-3",
    "mean_rank": "held-out mean rank",
    "distance_m": "localisation distance (m)",
}

FINAL_MARKER = "D"
"""The marker of each curve's last point (hollow, in the method's colour): the method's
reported map, not one of the maps it kept along its run."""

FINAL_LABEL = "last point: the reported map (samplers: best visited; VI, BP: argmax q)"
"""The legend's one entry (grey) for :data:`FINAL_MARKER`."""

FINAL_NOTE = (
    "Each line is one fit: the label maps its method kept along the run, each scored with the "
    "means given it; its last point (hollow diamond) is the map the method reports, at the "
    "run's end. For a sampler that is a different kind of map, the highest-log-joint state it "
    "visited (not its last state), so its line may step there; for the variational methods and "
    "loopy BP it is argmax of the final q, the kind of map its line already plots."
)
"""Said under the figure in ``comparison.md``: what the last point of each line is."""


def plot_curves(summary: dict[str, object], house_type: str, path: Path) -> Path:
    """Write :func:`curves_figure` to ``path``."""
    fig = curves_figure(summary, house_type)
    path.parent.mkdir(parents=True, exist_ok=True)
    with any_script(fig):  # words of any script, not boxes
        replace_figure(fig, path, dpi=110, bbox_inches="tight")  # whole or not at all
    return path


def curves_figure(summary: dict[str, object], house_type: str) -> Figure:
    """Quality against wall-clock time (log axis) of every fit of one house type: one panel
    per score of :data:`~.inference_comparison.SCORES`, one colour per method, each fit one
    thin line whose last point (the method's reported map) is a hollow :data:`FINAL_MARKER`;
    the legend of the methods and of that marker below the panels."""
    records: dict = summary["records"][house_type]  # type: ignore[index]
    methods: dict = summary["methods"]  # type: ignore[assignment]
    scores = SCORES[house_type]
    fig = Figure(figsize=(5.2 * len(scores), 4.2))
    axes = fig.subplots(1, len(scores))
    colours = {key: f"C{i}" for i, key in enumerate(VARIANTS)}
    for ax, score in zip(np.atleast_1d(axes), scores, strict=True):
        for key, recs in records.items():
            for i, record in enumerate(recs):
                t = [p["seconds"] for p in record["curve"]]  # [points]
                v = [p[score] for p in record["curve"]]  # [points]
                ax.plot(t, v, color=colours[key], lw=1.0, alpha=0.6, marker=".", ms=3,
                        label=methods[key] if i == 0 else None)  # fmt: skip
                # the reported map, not a kept one (module docstring): its own marker
                ax.plot(t[-1:], v[-1:], ls="none", marker=FINAL_MARKER, ms=5, mfc="none",
                        mec=colours[key], mew=1.0, alpha=0.8)  # fmt: skip
        ax.set_xscale("log")
        ax.set_xlabel("wall-clock seconds")
        # ARI reads the labels alone; the other scores read pi and phi too, here their
        # posterior means given the labels (the table's "means | labels" column, not its own)
        given = "" if score == "ari" else " (means | labels)"
        lower = " (lower is better)" if score in LOWER_IS_BETTER else ""
        # the qualifiers on a line of their own: on one line the distance's label ran longer
        # than its panel, over the figure's title
        qualifiers = (given + lower).strip()
        ax.set_ylabel(SCORE_NAMES[score] + ("\n" + qualifiers if qualifiers else ""))
        ax.grid(alpha=0.3, which="both")
    handles, labels = np.atleast_1d(axes)[0].get_legend_handles_labels()
    handles.append(Line2D([], [], ls="none", marker=FINAL_MARKER, ms=5, mfc="none", mec="grey"))
    labels.append(FINAL_LABEL)
    # below the panels, never over a line (loc="best" inside the axes covered the top-1 lines)
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), fontsize=8,
               ncol=min(3, max(len(labels), 1)), frameon=False)  # fmt: skip
    title = "synthetic houses (one line per seed)" if house_type == SYNTHETIC else (
        "public houses (one line per house and held-out trial)")  # fmt: skip
    fig.suptitle(f"Quality against time, {title}")
    return fig
