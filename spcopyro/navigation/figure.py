"""``navigate.png``: the map, the destination word's probability map, the path, start and stops."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from spcopyro.maps.render import render_labels
from spcopyro.navigation.planning import NavigationPlan
from spcopyro.plotting import _extent, _save, _show_image

__all__ = ["plot_plan"]


def plot_plan(plan: NavigationPlan, path: str | os.PathLike[str]) -> Path:
    """Draw ``plan`` (module docstring) into the PNG ``path``."""
    grid = plan.planning.grid
    fig = Figure(figsize=(9, 8))
    ax = fig.subplots()
    rgb = render_labels(np.full(grid.shape, -1), grid, np.zeros((1, 3), dtype=np.uint8))
    rows, cols = _show_image(ax, grid, rgb)
    goal = plan.goal
    image = np.full(grid.shape, np.nan)  # [H, W]
    image[grid.free] = goal.probability
    shown = ax.imshow(image[rows, cols], extent=_extent(grid, rows, cols), origin="upper",
                      cmap="Blues", vmin=0.0, vmax=1.0, interpolation="nearest")  # fmt: skip
    fig.colorbar(shown, ax=ax, label=f"p(cell in the place of '{goal.word}')", shrink=0.8)
    ax.plot(plan.path_xy[:, 0], plan.path_xy[:, 1], color="C3", lw=2, label="path")
    ax.plot(*plan.start, marker="o", color="C2", ms=9, ls="", label="start")
    for stop in plan.stops[:-1]:
        ax.plot(*stop.xy, marker="s", color="C1", ms=8, ls="")
        ax.annotate(stop.word, stop.xy, xytext=(5, 5), textcoords="offset points", fontsize=9)
    ax.plot(*goal.xy, marker="*", color="C3", ms=16, ls="", label=f"goal: {goal.word}")
    length = 0.3 * max(1.0, plan.radius * 4)
    ax.arrow(goal.xy[0], goal.xy[1], length * np.cos(goal.yaw), length * np.sin(goal.yaw),
             width=0.02, color="C3")  # fmt: skip
    for stop in plan.stops:
        for c in stop.choice.candidates:
            if (c.xy != stop.xy) or not c.reachable:
                ax.plot(*c.xy, marker="x", color="C4", ms=8, ls="")
    ax.legend(fontsize=8, loc="best")
    ax.set_title(f"navigate: {plan.instruction.text!r}\n{plan.length:.2f} m, "
                 f"radius {plan.radius:g} m")  # fmt: skip
    return _save(fig, path)
