"""A public house's truth panel names whose truth it is.

The experiment's ``HOUSE_maps.png`` (and a study's ``maps_HOUSE.png``) titled the public house's
first panel "truth": read beside the paper's Table 4 as the paper's participant-drawn maps,
though it is this project's region truth (:mod:`spcopyro.experiments.public_truth`).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from spcopyro.maps import OccupancyGrid
from spcopyro.study.maps import label_map_arrays, source_panels


def _rows(tmp_path, kind: str) -> list[dict[str, object]]:
    occupancy = np.zeros((3, 4), dtype=np.int8)
    house = SimpleNamespace(grid=OccupancyGrid(occupancy, 0.05, (0.0, 0.0, 0.0)))
    labels = np.zeros((3, 4), dtype=np.int64)
    (tmp_path / "maps").mkdir()
    np.savez(tmp_path / "maps" / "a.npz", **label_map_arrays(labels, house, labels))
    row = {"data": "h", "data_kind": kind, "seed": 0, "status": "ok", "variant": "A-dp",
           "method": "gibbs", "label_map": "maps/a.npz"}  # fmt: skip
    return [row]


def test_a_public_house_s_truth_panel_is_named_the_project_s(tmp_path):
    _, panels, _ = source_panels(_rows(tmp_path, "public"), tmp_path, "h")
    assert [name for name, _ in panels] == ["region truth (this project's)", "A-dp / gibbs"]


def test_a_synthetic_house_s_truth_panel_stays_truth(tmp_path):
    _, panels, _ = source_panels(_rows(tmp_path, "synthetic"), tmp_path, "h")
    assert [name for name, _ in panels] == ["truth", "A-dp / gibbs"]


def test_a_variant_named_as_its_method_is_named_once(tmp_path):
    """compare-inference's maps_HOUSE.png titled its panels "cavi / cavi", "lbp / lbp" (its
    variants are named as their methods), and quality_time.png's legend the same: one name."""
    from spcopyro.study.figures import quality_time_figure

    rows = _rows(tmp_path, "synthetic")
    rows.append({**rows[0], "variant": "cavi", "method": "cavi"})
    rows.append({**rows[0], "variant": "gibbs-sw", "method": "gibbs"})
    _, panels, _ = source_panels(rows, tmp_path, "h")
    assert [name for name, _ in panels] == ["truth", "A-dp / gibbs", "cavi", "gibbs-sw / gibbs"]
    timed = [{**row, "seconds": 1.0 + k, "ari": 0.5} for k, row in enumerate(rows)]
    (legend,) = quality_time_figure(timed).legends
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts == ["A-dp / gibbs", "cavi", "gibbs-sw / gibbs"]


def test_every_map_panel_takes_the_colours_of_the_truth_s_categories(tmp_path, monkeypatch):
    """maps_HOUSE.png coloured each panel by its own concepts' sizes: a fit whose largest
    concept was the truth's second category drew that room in the truth's first colour, and two
    fits the same room in two colours (compare-inference --houses synthetic: the kitchen blue
    beside orange). Each concept now takes the colour of the truth's category it is matched
    with (results.renumber.matching_permutation), one colour table for every panel; one matched
    with none a colour of no category's."""
    import spcopyro.maps
    from spcopyro.study.maps import write_house_maps

    truth = np.zeros((4, 10), dtype=np.int64)  # [H, W] category 0: 7 columns, 1: 3 columns
    truth[:, 7:] = 1
    fit = np.full((4, 10), 7, dtype=np.int64)  # the right room: concept 7
    fit[:, :4], fit[:, 4:7] = 2, 4  # the left room split in two concepts, of 4 and 3 columns
    house = SimpleNamespace(grid=OccupancyGrid(np.zeros((4, 10), dtype=np.int8), 0.05, (0, 0, 0)))
    (tmp_path / "maps").mkdir()
    rows = []
    for name, labels in (("a", fit), ("b", truth + 3)):  # b: the truth, numbered otherwise
        np.savez(tmp_path / "maps" / f"{name}.npz", **label_map_arrays(labels, house, truth))
        rows.append({"data": "h", "data_kind": "synthetic", "seed": 0, "status": "ok",
                     "variant": name, "method": "gibbs",
                     "label_map": f"maps/{name}.npz"})  # fmt: skip
    drawn = []
    render = spcopyro.maps.render_labels

    def capture(labels, grid=None, colours=None):
        rgb = render(labels, grid, colours)  # [H, W, 3]
        drawn.append(rgb)
        return rgb

    monkeypatch.setattr(spcopyro.maps, "render_labels", capture)
    write_house_maps(rows, tmp_path)
    truth_rgb, fit_rgb, same_rgb = drawn
    assert (same_rgb == truth_rgb).all()  # the truth renumbered: the same colours
    assert (fit_rgb[:, 7:] == truth_rgb[:, 7:]).all()  # the right room: its category's colour
    assert (fit_rgb[:, :4] == truth_rgb[:, :4]).all()  # the left room's larger part: matched
    left_b = fit_rgb[0, 5]  # matched with no category: a colour of none of them
    assert not any((left_b == truth_rgb[0, c]).all() for c in (0, 9))


def test_both_figures_name_a_baseline_and_a_default_variant_alike(tmp_path):
    """maps_HOUSE.png and quality_time.png name a row by one rule (study.maps.row_name): the
    maps wrote "default / gibbs" where the legend wrote "gibbs", the legend "kmeans / baseline"
    where the maps wrote "kmeans"."""
    from spcopyro.study.figures import quality_time_figure

    rows = _rows(tmp_path, "synthetic")
    rows.append({**rows[0], "variant": "default", "method": "gibbs"})
    rows.append({**rows[0], "variant": "", "method": "cavi"})
    rows.append({**rows[0], "variant": "kmeans", "method": "baseline"})
    names = ["A-dp / gibbs", "gibbs", "cavi", "kmeans"]
    _, panels, _ = source_panels(rows, tmp_path, "h")
    assert [name for name, _ in panels] == ["truth", *names]
    timed = [{**row, "seconds": 1.0 + k, "ari": 0.5} for k, row in enumerate(rows)]
    (legend,) = quality_time_figure(timed).legends
    assert [t.get_text() for t in legend.get_texts()] == names


def test_a_baseline_row_is_named_by_the_cells_own_method_constant(monkeypatch):
    """row_name tells a baseline row by the one BASELINE_METHOD the cells are made with (it wrote
    the literal "baseline" beside cells' constant): renamed, the rule follows it. The constant
    is the cells' (the module that makes the rows), which maps reads, not a figure module's."""
    from spcopyro.study import cells, maps

    assert cells.BASELINE_METHOD is maps.BASELINE_METHOD
    assert "BASELINE_METHOD" in cells.__all__ and "BASELINE_METHOD" not in maps.__all__
    assert maps.row_name("kmeans", cells.BASELINE_METHOD) == "kmeans"
    monkeypatch.setattr(maps, "BASELINE_METHOD", "a baseline")
    assert maps.row_name("kmeans", "a baseline") == "kmeans"
    assert maps.row_name("kmeans", "baseline") == "kmeans / baseline"
