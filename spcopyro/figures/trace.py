"""trace.png: a fit's objective and labels in use per sweep or iteration (paper Figs. 5-6,
:func:`trace_figure`), and the names of its methods and point estimates that the other figures'
titles share. Re-exported by :mod:`spcopyro.figures.plotting`."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, MaxNLocator

from spcopyro._util.messages import plural
from spcopyro.figures.png import save_figure
from spcopyro.inference.names import SAMPLERS, objective_draws
from spcopyro.results.point_estimate import KEEPS_SPECKS, LOSS_LABELS
from spcopyro.results.refined import coarse_stage
from spcopyro.results.result import SpCoResult
from spcopyro.results.specks import in_use_text

ESTIMATE_NAMES = {loss: label.replace(" ", "-") for loss, label in LOSS_LABELS.items()}
"""The point estimates' names in the figures' titles, their losses' labels
(:data:`~spcopyro.results.point_estimate.LOSS_LABELS`) as adjectives: "the vi estimate" read as
variational inference's (compare-inference's VI methods), not the variation-of-information
loss's."""


OBJECTIVE_MEANINGS = {
    "log joint": "log p(data, labels, parameters)",
    "ELBO": "a lower bound on log p(data)",
    "Bethe ELBO": "Bethe's approximation of log p(data)",
}
"""What each method's objective is, under its name on trace.png's axis: a sampler's log joint
(with the Dirichlet densities of its drawn parameters, room1dk5's about +118,000 nats) and a
variational ELBO (the parameters integrated out, about -1,400 nats there) are not on one scale,
which two bare names and numbers did not say."""


def objective_axis_label(name: str, estimate: str = "") -> str:
    """trace.png's axis label of the objective ``name`` (``Trace.objective_name``): the name, its
    unit and what it is (:data:`OBJECTIVE_MEANINGS`); ``estimate`` ("1 draw a step") for SVI's
    stochastic estimate. An objective of another name keeps its name and unit."""
    head = f"{name} estimate" if estimate else name
    lines = [f"{head} (nats)"]
    if name in OBJECTIVE_MEANINGS:
        lines.append(OBJECTIVE_MEANINGS[name])
    if estimate:
        lines.append(f"({estimate})")
    return "\n".join(lines)


def _estimate_name(result: SpCoResult) -> str:
    """ "variation-of-information point estimate" (:data:`ESTIMATE_NAMES`; ``vi-specks``'s
    "... point estimate, specks kept"), or "point estimate" for a result that does not say
    which."""
    kind = str(result.inference.get("point_estimate") or "")
    loss = kind.removesuffix(KEEPS_SPECKS)
    kept = ", specks kept" if loss != kind and loss in ESTIMATE_NAMES else ""
    kind = loss if kept else kind
    return f"{ESTIMATE_NAMES.get(kind, kind)} point estimate{kept}".lstrip()


def plot_trace(
    result: SpCoResult, path: str | os.PathLike[str], kept: tuple[int, int] | None = None
) -> Path:
    """Write :func:`trace_figure` to ``path``."""
    return save_figure(trace_figure(result, kept), path)


def trace_figure(result: SpCoResult, kept: tuple[int, int] | None = None) -> Figure:
    """The objective (log joint or ELBO) and the number of concepts per iteration (paper
    Figs. 5-6), the sweep of the highest log joint marked (a variational method's final
    iteration, whose q is reported: LBP's and SVI's objectives need not peak there). When the
    reported map is a point estimate over the kept samples (``result.agreement``), the figure
    says so: that map is not the marked sweep's state. The concept count is of the chain's
    state at each sweep (every label it uses, specks included; vi-gibbs's are its Gibbs sweeps
    after the CAVI start) or, for variational methods, of each cell's most probable concept
    under q at each iteration; not the fit's "concepts in use". ``kept`` = (k, K): the result is
    chain k of the K run (``fit --chains K``), the one kept; the title says so."""
    trace = result.trace
    sweeps = np.arange(1, len(trace.objective) + 1)
    chain = result.method in SAMPLERS  # a Gibbs chain's trace (vi-gibbs: its Gibbs sweeps)
    step = "sweep" if chain else "iteration"
    fig = Figure(figsize=(7, 5))
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(sweeps, trace.objective, lw=0.8)
    best = result.best_iteration + 1
    top.axvline(best, color="C3", lw=0.6, ls="--",
                label=f"highest {trace.objective_name} ({step} {best})" if chain else
                f"final {trace.objective_name} ({step} {best}): the reported q")  # fmt: skip
    draws = objective_draws(result.method, result.inference)  # 0: the objective itself
    estimate = f"{plural(draws, 'draw')} a step" if draws else ""
    top.set_ylabel(objective_axis_label(trace.objective_name, estimate), fontsize=8)
    if result.method == "svi":  # at the step's (annealed) gamma
        asked = int(result.inference.get("anneal_iterations") or 0)  # type: ignore[call-overload]
        anneal = min(asked, len(sweeps))
        if anneal > 1:  # not the model's ELBO there: a weaker coupling's
            label = f"steps 1-{anneal}: gamma annealed from 0, the estimate at that gamma"
            top.axvspan(1, anneal, color="0.9", zorder=0, label=label)
    top.legend(fontsize=8)
    bottom.plot(sweeps, trace.num_concepts, lw=0.8, color="C1")
    if chain:
        counted = "(the chain's state, specks included)"
    else:  # a q(C), not a state: a concept counts where it is some cell's most probable one
        counted = "(argmax of q per cell, specks included)"
    bottom.set_ylabel(f"labels in use per {step}\n{counted}", fontsize=8)
    # the reported map's count beside the states': the default demo's refinement held 15-60
    # labels a sweep (one-cell labels that form and dissolve, results/specks.py) while its map
    # has 10 concepts, the figure saying nothing of the gap
    reported = f"the reported map: {in_use_text(result)}"
    if result.agreement is not None:  # a point estimate over the kept samples, no one state
        reported += f"\n(over the kept samples; a {step}'s state adds labels that come and go)"
    count = len(result.concepts_in_use())
    bottom.axhline(count, color="k", lw=1.0, ls="--", label=reported)
    highest = max([count, *np.asarray(trace.num_concepts).tolist()])
    bottom.set_ylim(0, 1.5 * highest + 1)  # the legend above the counts, the line below them
    bottom.legend(fontsize=8, loc="upper left")
    bottom.yaxis.set_major_locator(MaxNLocator(integer=True))  # a count: no 12.5 concepts
    bottom.set_xlabel(step)
    for ax in (top, bottom):
        ax.set_xscale("log")
        ax.minorticks_off()  # a Tick is some 20 artists: 60 of them were most of the figure
    bottom.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))  # 10, not mathtext
    title = f"{result.name or 'trace'} ({result.method})"
    if kept is not None and kept[1] > 1:  # the other chains' traces are not drawn
        run = "chain" if chain else "fit"
        title += f"\n{run} {kept[0]} of {kept[1]} (the one kept; chains.json), the others not shown"
    if "vi_iterations_run" in result.inference:  # vi-gibbs: the sweeps began at CAVI's labels
        title += (f"\nGibbs sweeps from a CAVI start of {result.inference['vi_iterations_run']} "
                  "iterations (not shown)")  # fmt: skip
    coarse = coarse_stage(result.inference)
    if coarse is not None:
        title += (
            f"\nthe refinement on the map's {result.grid.resolution:g} m cells, after "
            f"{coarse['sweeps']} sweeps on {coarse['cell_size']:g} m cells (not shown)"
        )
    if result.agreement is not None:
        title += (f"\nthe reported map: the {_estimate_name(result)} over the kept samples,\n"
                  f"not the state of {step} {best}")  # fmt: skip
    fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(top=0.95 - 0.035 * (title.count("\n") + 1))  # room for every line
    return fig
