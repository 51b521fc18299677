"""Per-house maps drawn from a study's stored label maps (issue 26 item 2): nothing is refitted.

Every finished cell stores its label map on the map's cells with the map itself and the truth
(``OUT/maps/KEY.npz``, :func:`label_map_arrays`; the table's
``label_map`` column names the file). :func:`write_house_maps` draws, per data source, one
figure of every row's map (variant or baseline, with its method) at the source's first seed,
beside the truth when it is known -- from ``results.csv`` and those files alone, so
``--report-only`` redraws them.

Drawn on :class:`matplotlib.figure.Figure` objects and written with ``savefig`` (no pyplot),
like :mod:`spcopyro.figures.plotting`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spcopyro._util.outputs import replace_figure
from spcopyro.experiments.ablation_variants import OVERRIDE_PREFIXES
from spcopyro.figures.fonts import any_script
from spcopyro.maps import OccupancyGrid
from spcopyro.maps.coarse import labels_on_grid
from spcopyro.study.cells import BASELINE_METHOD
from spcopyro.study.spec import MAPS_PREFIX, maps_file_name

__all__ = [
    "Arrays", "StoredMap", "label_map_arrays", "labels_on_map", "load_label_map",
    "REGION_TRUTH_PANEL", "TRUTH_PANEL", "plot_label_maps", "remove_stale", "row_name",
    "row_names", "write_house_maps",
]  # fmt: skip

Arrays = dict[str, np.ndarray]
"""Named arrays saved as one ``.npz`` (a trace, a label map)."""
TRUTH_PANEL, REGION_TRUTH_PANEL = "truth", "region truth (this project's)"
"""The first panel's name (:func:`source_panels`) where the source's truth is known: a
synthetic house's or simulated map's, a public house's (this project's region truth)."""


def labels_on_map(result, house, settings) -> np.ndarray:
    """``[H, W]`` a fit's labels on the map's cells of ``house`` (refined from a coarser model
    grid of ``settings.data.cell_size``, :func:`spcopyro.maps.coarse.labels_on_grid`)."""
    return labels_on_grid(result.label_image(), house.grid, settings.data.cell_size)


def label_map_arrays(labels: np.ndarray, house, truth: np.ndarray | None) -> Arrays:
    """A cell's ``[H, W]`` label map on the map's cells as stored (``maps/KEY.npz``): ``labels``
    int16 (-1: not a free cell), the map's ``occupancy`` int8, ``resolution`` and ``origin``,
    and ``truth`` int16 when the source has one -- all a figure needs to draw the map."""
    grid = house.grid
    arrays: Arrays = {
        "labels": np.asarray(labels, dtype=np.int16),
        "occupancy": np.asarray(grid.occupancy, dtype=np.int8),
        "resolution": np.float64(grid.resolution),
        "origin": np.asarray(grid.origin, dtype=np.float64),
    }
    if truth is not None:
        arrays["truth"] = np.asarray(truth, dtype=np.int16)
    return arrays


@dataclass(frozen=True)
class StoredMap:
    """A cell's stored label map: ``labels`` ``[H, W]`` (-1: not a free cell), the map's
    ``grid`` and the source's ``truth`` ``[H, W]`` (None when unknown)."""

    labels: np.ndarray
    grid: OccupancyGrid
    truth: np.ndarray | None


def load_label_map(folder: str | os.PathLike[str], row: dict[str, object]) -> StoredMap | None:
    """The stored label map of a table row (its ``label_map`` file under ``folder``); None when
    the row has none (a failed cell, or one stored before its kind of cell kept label maps)."""
    name = row.get("label_map")
    if not name or row.get("status") != "ok":
        return None
    path = Path(folder) / str(name)
    if not path.is_file():
        return None
    with np.load(path) as stored:
        grid = OccupancyGrid(
            stored["occupancy"], float(stored["resolution"]), tuple(stored["origin"].tolist())
        )
        truth = stored["truth"] if "truth" in stored.files else None
        return StoredMap(stored["labels"].astype(np.int64), grid, truth)


def _ranked(labels: np.ndarray) -> np.ndarray:
    """[H, W] labels renumbered by region size (0 = largest), -1 kept: the same colours for
    the same-sized regions of two maps."""
    inside = labels >= 0
    if not inside.any():
        return labels
    values, sizes = np.unique(labels[inside], return_counts=True)
    order = values[np.argsort(-sizes, kind="stable")]
    rank = np.full(int(labels.max()) + 1, -1)
    rank[order] = np.arange(order.size)
    return np.where(inside, rank[np.maximum(labels, 0)], -1)


def _matched_to(truth: np.ndarray, ranked: np.ndarray) -> np.ndarray:
    """[H, W] ``ranked`` (labels ranked by size, :func:`_ranked`) renumbered so that each
    concept matched with a category of ``truth`` ``[H, W]`` (ranked too; the one-to-one matching
    of most shared cells, :func:`spcopyro.results.renumber.matching_permutation`) takes its
    number, and so its colour; the concepts matched with none follow the truth's numbers,
    largest first. -1 kept."""
    from spcopyro.results.renumber import matching_permutation

    both = (ranked >= 0) & (truth >= 0)  # [H, W] the cells both label
    if not both.any():
        return ranked
    first_free = int(truth.max()) + 1  # the truth's categories are 0 .. first_free - 1
    count = max(int(ranked.max()) + 1, first_free)
    perm = matching_permutation(truth[both], ranked[both], count)  # [count]
    shared = np.zeros((count, count), dtype=bool)  # [concept, category]: any cell in common
    shared[ranked[both], truth[both]] = True
    matched = shared[np.arange(count), perm]  # [count]: perm a category it shares cells with
    perm[~matched] = first_free + np.arange(int((~matched).sum()))  # the rest, by size
    return np.where(ranked >= 0, perm[np.maximum(ranked, 0)], -1)


def plot_label_maps(
    grid: OccupancyGrid, panels: Sequence[tuple[str, np.ndarray]], path: Path, title: str
) -> Path:
    """Label maps ``[H, W]`` of one map side by side, at most four a row (paper Fig. 7), each
    coloured by region size; written to ``path``. Where the first panel is the truth
    (:func:`source_panels`' :data:`TRUTH_PANEL` or :data:`REGION_TRUTH_PANEL`), every other
    panel's concepts take the colours of the truth's categories they are matched with
    (:func:`_matched_to`), from one colour table: coloured each by its own sizes, the same place
    had different colours in neighbouring panels."""
    from matplotlib.figure import Figure

    from spcopyro.figures.map_axes import draw_map_image, known_bounds
    from spcopyro.maps import render_labels
    from spcopyro.maps.render import label_colours

    shown = [_ranked(np.asarray(labels)) for _, labels in panels]  # [H, W] each
    colours = None  # each panel its own table, by its number of concepts
    if _truth_first(panels):
        shown[1:] = [_matched_to(shown[0], labels) for labels in shown[1:]]
        colours = label_colours(max(int(labels.max()) for labels in shown) + 1)  # [K, 3]
    columns = max(1, min(4, len(panels)))
    rows_n = max(1, -(-len(panels) // columns))
    fig = Figure(figsize=(4 * columns, 3.6 * rows_n))
    axes = fig.subplots(rows_n, columns, squeeze=False)
    rows, cols = known_bounds(grid)
    for ax, (name, _), labels in zip(axes.ravel(), panels, shown, strict=False):
        draw_map_image(ax, grid, render_labels(labels, grid, colours), rows, cols)  # [H, W, 3]
        ax.set_title(name, fontsize=7)
        ax.set_xticks([])
        ax.set_yticks([])
    for ax in axes.ravel()[len(panels) :]:
        ax.axis("off")
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    with any_script(fig):  # words of any script, not boxes
        replace_figure(fig, path, dpi=120, bbox_inches="tight")  # whole or not at all
    return path


def row_name(variant: object, method: object) -> str:
    """A study row's name in a figure (a maps panel's title, quality_time.png's legend): a
    baseline's name (its method column is :data:`BASELINE_METHOD`); the method alone where the
    variant is none, ``default`` or named as the method (compare-inference's "cavi / cavi" read
    as two things); else ``variant / method``. The one rule of both figures: they differed."""
    variant, method = str(variant), str(method)
    if method == BASELINE_METHOD:
        return variant or method
    return method if variant in ("", "default", method) else f"{variant} / {method}"


def _options_text(row: dict[str, object]) -> str:
    """What a variant row sets, short: its ``overrides`` column (``settings.gamma=3.0,...``)
    without the method (named beside it) and the prefixes
    (:data:`~spcopyro.experiments.ablation_variants.OVERRIDE_PREFIXES`), as
    ``gamma=3.0, merge_moves=0.2``; its preset first where it sets one."""
    items = [item for item in str(row.get("overrides") or "").split(",") if item]
    items = [item.partition(".")[2] if item.split(".")[0] in OVERRIDE_PREFIXES
             else item for item in items if not item.startswith("method=")]  # fmt: skip
    return ", ".join(items)


def row_names(rows: Sequence[dict[str, object]]) -> dict[tuple[str, str], str]:
    """Every (variant, method) of ``rows`` named for a figure, each name its own:
    :func:`row_name`, and where that is shared by rows that differ (variants ``default`` and
    ``gibbs`` of method gibbs, differing in an option, were both "gibbs" in the maps' titles and
    the legend of quality_time.png), each of them with what its variant sets (``gibbs
    (gamma=3.0)``, the one that sets nothing left bare), or, where even that is shared,
    ``variant / method``. Both figures name their rows with it, over the whole table."""
    groups = {(str(r["variant"]), str(r["method"])): r for r in rows}  # a row of each (the last)
    names = {group: row_name(*group) for group in groups}
    for name in set(names.values()):
        twins = [group for group in groups if names[group] == name]
        if len(twins) < 2:
            continue
        texts = {group: _options_text(groups[group]) for group in twins}
        if len(set(texts.values())) == len(twins):  # the options tell them apart
            names.update({g: f"{name} ({texts[g]})" if texts[g] else name for g in twins})
        else:
            names.update({g: f"{g[0] or 'default'} / {g[1]}" for g in twins})
    return names


def row_label(rows: Sequence[dict[str, object]]) -> Callable[[dict[str, object]], str]:
    """A row of ``rows`` -> its name among them (:func:`row_names`, made once for them all)."""
    names = row_names(rows)
    return lambda row: names[str(row["variant"]), str(row["method"])]


def source_panels(
    rows: Sequence[dict[str, object]], folder: str | os.PathLike[str], data: str,
    seed: int | None = None, label=None,
) -> tuple[OccupancyGrid, list[tuple[str, np.ndarray]], int] | None:  # fmt: skip
    """The panels of source ``data`` at ``seed`` (None: its first seed with a stored map):
    the truth when known (a public house's named "region truth (this project's)"), then each
    row's map in the table's order, named by ``label(row)`` (default :func:`row_label` of
    ``rows``); None when no map is stored. Reads the drawn seed's files only, each once (a
    lower seed's rows, tried first, store none)."""
    mine = [(int(r["seed"]), r) for r in rows if r["data"] == data]  # type: ignore[call-overload]
    tried = sorted({s for s, _ in mine}) if seed is None else [seed]
    for seed in tried:  # the first with a stored map
        loaded = [(r, load_label_map(folder, r)) for s, r in mine if s == seed]
        maps = [(r, stored) for r, stored in loaded if stored is not None]
        if maps:
            break
    else:
        return None
    grid, truth = maps[0][1].grid, maps[0][1].truth
    # a public house's truth is this project's (public_truth: from where place words were
    # said), not the paper's drawn one: a panel titled "truth" read as the paper's
    public = any(r.get("data_kind") == "public" for _, r in mine)  # the source's kind
    truth_name = REGION_TRUTH_PANEL if public else TRUTH_PANEL
    panels = [] if truth is None else [(truth_name, truth)]
    if label is None:  # the whole table's names: the legend of quality_time.png's
        label = row_label(rows)
    panels += [(label(row), stored.labels) for row, stored in maps]
    return grid, panels, seed


def _truth_first(panels: Sequence[tuple[str, np.ndarray]]) -> bool:
    """Whether the first of :func:`source_panels`' ``panels`` is the source's truth."""
    return bool(panels) and panels[0][0] in (TRUTH_PANEL, REGION_TRUTH_PANEL)


def remove_stale(folder: Path, patterns: Sequence[str], kept: Sequence[Path]) -> list[Path]:
    """Delete the files of ``folder`` matching one of ``patterns`` (a run's own figure names)
    that are not ``kept``: an earlier run's figures of sources the table no longer has, which
    were left beside the new ones. Returns what was deleted."""
    keep = {Path(p).resolve() for p in kept}
    removed = []
    for pattern in patterns:
        for path in sorted(folder.glob(pattern)):
            if path.is_file() and path.resolve() not in keep:
                path.unlink()
                removed.append(path)
    return removed


def write_house_maps(
    rows: Sequence[dict[str, object]], folder: str | os.PathLike[str]
) -> list[Path]:
    """One figure per data source (``folder/maps_<data>.png``): every row's stored map at the
    source's first seed, beside the truth when known (module docstring). Returns the paths; an
    earlier ``maps_*.png`` of a source without one now is deleted (:func:`remove_stale`)."""
    folder = Path(folder)
    paths = []
    label = row_label(rows)  # once for the table, not once per source
    for data in dict.fromkeys(str(r["data"]) for r in rows):
        found = source_panels(rows, folder, data, label=label)
        if found is None:
            continue
        grid, panels, seed = found
        title = f"{data}, seed {seed}: every row's map"
        paths.append(plot_label_maps(grid, panels, folder / maps_file_name(data), title))
    remove_stale(folder, [f"{MAPS_PREFIX}*.png"], paths)
    return paths
