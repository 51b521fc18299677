"""A study's report (issue 26) drawn from its table alone: the markdown tables (failed
cells, counts' decimals), quality_time.png (its groups, log axis labels, legend, titles,
held-out word panels, one line a source) and the maps figures (row names, each stored map
read once).
"""

from __future__ import annotations

import pytest
from study_setup import small_house

from spcopyro.study.cells import cells_of
from spcopyro.study.spec import study_from_dict


def test_quality_time_figure_shows_every_group_and_skips_what_it_cannot_place():
    from matplotlib.collections import PathCollection

    from spcopyro.study.figures import quality_time_figure

    def row(data, variant, method, seconds, ari, status="ok"):
        return dict(data=data, variant=variant, method=method, seconds=seconds, ari=ari,
                    status=status)  # fmt: skip

    rows = [
        row("dense", "default", "gibbs", 10.0, 0.9), row("dense", "default", "gibbs", 12.0, 0.8),
        row("dense", "default", "cavi", 1.0, 0.6), row("public", "default", "gibbs", 30.0, 0.5),
        row("public", "default", "cavi", None, 0.4),  # no time: left out
        row("public", "default", "cavi", 0.0, 0.4),  # no place on a log axis
        row("public", "g3", "gibbs", 5.0, 0.3, status="failed"),  # failed: left out
    ]  # fmt: skip
    fig = quality_time_figure(rows)
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in panels] == ["dense", "public"]
    assert all(ax.get_xscale() == "log" for ax in panels)
    seeds = [len(c.get_offsets()) for c in panels[0].collections if isinstance(c, PathCollection)]
    assert sorted(seeds) == [1, 2]  # gibbs' two seeds, cavi's one
    dense_means = sorted(
        line.get_ydata()[0] for line in panels[0].lines if line.get_marker() == "o"
    )
    assert dense_means == pytest.approx([0.6, 0.85])
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["gibbs", "cavi"]
    assert quality_time_figure([row("dense", "default", "gibbs", 1.0, None)]) is None


def test_a_report_table_of_failed_cells_only_has_as_many_cells_as_columns():
    """A source whose cells all failed has no score column: its header had a fourth, empty
    column the separator line lacked (``| variant | method | seeds |  |`` over ``|---|---|---|``),
    which markdown does not draw as a table."""
    from spcopyro.study.report import report_markdown

    def row(data, status, ari):
        return dict(variant="a", data=data, method="gibbs", seed=0, status=status, ari=ari,
                    error_type="ValueError" if status != "ok" else "", error="no")  # fmt: skip

    text = report_markdown([row("bad", "error", None), row("good", "ok", 0.5)])
    tables = [line for line in text.splitlines() if line.startswith("|")]
    assert tables[:3] == [
        "| variant | method | seeds |",
        "|---|---|---|",
        "| a | gibbs | 0 (1 failed) |",
    ]
    assert tables[3:] == [
        "| variant | method | seeds | ari |",
        "|---|---|---|---|",
        "| a | gibbs | 1 | 0.500 |",
    ]
    assert "2 cells in the table" in text
    assert "1 cell in the table;" in report_markdown([row("good", "ok", 0.5)])  # not "1 cells"
    assert "| a | gibbs | 1 | 0.000 |" in report_markdown([row("good", "ok", -1e-4)])  # not -0.000


def test_a_report_gives_counts_one_decimal_in_every_row():
    """ablation_small's report: concepts "90.000 +- 1.414" above "117.5 +- 2.1" (decimals chosen
    per value). Counts now have one decimal in every row; other scores keep three below 100."""
    from spcopyro.study.report import report_markdown

    def row(variant, seed, concepts, seconds):
        return dict(variant=variant, data="dense", method="gibbs", seed=seed, status="ok",
                    ari=0.5, concepts=concepts, seconds=seconds)  # fmt: skip

    rows = [row("a", 0, 89, 0.1), row("a", 1, 91, 0.11), row("b", 0, 116, 99.0),
            row("b", 1, 119, 150.0)]  # fmt: skip
    lines = [line for line in report_markdown(rows).splitlines() if line.startswith("| a")]
    lines += [line for line in report_markdown(rows).splitlines() if line.startswith("| b")]
    assert lines == [
        "| a | gibbs | 2 | 0.500 +- 0.000 | 90.0 +- 1.4 | 0.105 +- 0.007 |",
        "| b | gibbs | 2 | 0.500 +- 0.000 | 117.5 +- 2.1 | 124.5 +- 36.1 |",
    ]


@pytest.mark.parametrize(
    "times", [(0.053, 0.475, 0.133), (2.0, 9.0), (100.0, 300.0), (0.4,), (1e-3, 1e3), (0.5, 40.0)]
)
def test_quality_time_axis_labels_do_not_overlap(times):
    """A panel spanning under a decade had every minor tick labelled (``4x10^-2 6x10^-2 10^-1
    2x10^-1 ...``), printed over each other."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.study.figures import quality_time_figure

    rows = [dict(data="room1dk5", variant=f"v{i}", method="gibbs", seconds=t, ari=0.5,
                 status="ok") for i, t in enumerate(times)]  # fmt: skip
    fig = quality_time_figure(rows)
    FigureCanvasAgg(fig).draw()
    (ax,) = fig.axes
    low, high = ax.get_xlim()
    labels = [label for label in ax.get_xticklabels() + ax.get_xticklabels(minor=True)
              if label.get_text() and low <= label.get_position()[0] <= high]  # fmt: skip
    assert len(labels) >= 2, [label.get_text() for label in labels]
    boxes = sorted((label.get_window_extent() for label in labels), key=lambda box: box.x0)
    for left, right in zip(boxes, boxes[1:], strict=False):
        assert left.x1 <= right.x0, [label.get_text() for label in labels]


def test_quality_time_legend_fits_in_the_figure():
    """compare-inference's report on one public house drew its 7 groups' legend in four columns
    of "stochastic-vi / stochastic-vi" under one 4.3 in panel: it ran past both edges of the
    image, "gibbs" and "vi-gibbs / vi-gibbs" cut to "gibbs" and "vi-gi"."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.experiments.inference_comparison import VARIANTS
    from spcopyro.study.figures import quality_time_figure

    rows = [dict(data="room1dk5", variant=key, method=v.method, seconds=1.0 + i, ari=0.1,
                 status="ok") for i, (key, v) in enumerate(VARIANTS.items())]  # fmt: skip
    fig = quality_time_figure(rows)
    renderer = FigureCanvasAgg(fig).get_renderer()
    (legend,) = fig.legends
    box, page = legend.get_window_extent(renderer), fig.bbox
    assert page.x0 <= box.x0 and box.x1 <= page.x1, (box, page)


def test_quality_time_figure_says_its_axes_in_words():
    """quality_time.png's title read "ari against seconds" (two results.csv columns): it says
    what the ARI is against (a public house's region truth, a synthetic house's ground truth)
    and that the time is wall-clock seconds per fit."""
    from spcopyro.study.figures import quality_time_figure

    def row(data, kind):
        return dict(data=data, data_kind=kind, variant="cavi", method="cavi", seconds=2.0,
                    ari=0.5, status="ok")  # fmt: skip

    titles = {}
    for kinds in (("public",), ("synthetic",), ("synthetic", "public")):
        fig = quality_time_figure([row(f"d{i}", kind) for i, kind in enumerate(kinds)])
        titles[kinds] = " ".join(fig._suptitle.get_text().split())  # noqa: SLF001
        assert [ax.get_ylabel() for ax in fig.axes] == ["ARI"] * len(kinds)
        assert {ax.get_xlabel() for ax in fig.axes} == {"wall-clock seconds per fit (log scale)"}
    tail = ", against wall-clock seconds per fit: seeds (faint), mean ± sd (marked)"
    assert titles == {
        ("public",): "ARI against the region truth" + tail,
        ("synthetic",): "ARI against the ground truth" + tail,
        ("synthetic", "public"): "ARI against the truth (a public house's: the region truth)"
        + tail,
    }


def test_two_variants_of_one_method_get_names_of_their_own_in_both_figures(tmp_path):
    """A study of variants ``default`` and ``gibbs`` (gamma 3), both of method gibbs, named both
    rows "gibbs" in quality_time.png's legend and the maps' panel titles (``row_name``), so the
    two could not be told apart; the one that sets something now says what (its overrides)."""
    import numpy as np

    from spcopyro.maps import OccupancyGrid
    from spcopyro.study.figures import quality_time_figure
    from spcopyro.study.maps import label_map_arrays, row_label, row_names, source_panels

    study = study_from_dict({
        "study": {"name": "twin", "sweeps": 5},
        "variants": {"default": {}, "gibbs": {"gamma": 3.0}, "lbp": {"method": "lbp"}},
        "data": {"small": small_house()},
    })  # fmt: skip
    rows = [c.inputs() for c in cells_of(study)]  # the table's rows, before any fit
    occupancy = np.zeros((3, 4), dtype=np.int8)
    grid = OccupancyGrid(occupancy, 0.05, (0.0, 0.0, 0.0))
    (tmp_path / "maps").mkdir()
    labels = np.zeros((3, 4), dtype=np.int64)
    np.savez(
        tmp_path / "maps" / "a.npz", **label_map_arrays(labels, type("H", (), {"grid": grid}), None)
    )
    for k, row in enumerate(rows):
        row.update(status="ok", seconds=1.0 + k, ari=0.5, label_map="maps/a.npz")
    names = ["gibbs", "gibbs (gamma=3.0)", "lbp"]
    assert list(row_names(rows).values()) == names
    label = row_label(rows)  # the one naming of the maps' panels, given or not
    assert [label(row) for row in rows] == names
    (legend,) = quality_time_figure(rows).legends
    assert [t.get_text() for t in legend.get_texts()] == names
    _, panels, _ = source_panels(rows, tmp_path, "small")
    assert [name for name, _ in panels] == names
    same = [{**row, "overrides": ""} for row in rows]  # nothing tells them apart: their names
    assert list(row_names(same).values()) == ["default / gibbs", "gibbs / gibbs", "lbp"]


def test_quality_time_shows_a_held_out_source_s_word_score_beside_its_map_score():
    """Rows of a held-out source carry ``top1`` (held-out word prediction); quality_time.png drew
    only the ARI against time, so a method that bought its map with its words looked best. A
    source with word scores gets a second panel of them; one without keeps its one panel."""
    from spcopyro.study.figures import quality_time_figure

    def row(data, method, seconds, ari, top1=None):
        kind = "public" if top1 is not None else "synthetic"
        return dict(data=data, variant="default", method=method, seconds=seconds, ari=ari,
                    top1=top1, status="ok", data_kind=kind)  # fmt: skip

    rows = [row("room", "gibbs", 100.0, 0.6, 0.34), row("room", "cavi", 2.0, 0.5, 0.21),
            row("room", "cavi", 3.0, 0.5, 0.25), row("small", "gibbs", 10.0, 0.9)]  # fmt: skip
    fig = quality_time_figure(rows)
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in panels] == ["room", "room: held-out words", "small"]
    assert panels[1].get_ylabel() == "held-out top-1 word accuracy"
    means = sorted(line.get_ydata()[0] for line in panels[1].lines if line.get_marker() == "o")
    assert means == pytest.approx([0.23, 0.34])
    assert "held-out top-1 word accuracy" in fig._suptitle.get_text().replace("\n", " ")
    plain = quality_time_figure([r for r in rows if r["data"] == "small"])
    assert [ax.get_title() for ax in plain.axes if ax.get_title()] == ["small"]


def test_quality_time_puts_each_source_s_panels_on_one_line():
    """With word scores the panels ran two a line in one stream: a synthetic house (no ``top1``,
    one panel) before a held-out public one split the public one's ARI panel (end of line 1)
    from its word panel (start of line 2). Each source now has a line of its own."""
    from spcopyro.study.figures import quality_time_figure

    def row(data, seconds, top1=None):
        kind = "synthetic" if top1 is None else "public"
        return dict(data=data, variant="default", method="gibbs", seconds=seconds, ari=0.5,
                    top1=top1, status="ok", data_kind=kind)  # fmt: skip

    fig = quality_time_figure([row("small", 10.0), row("room", 2.0, 0.3), row("other", 3.0)])
    at = {ax.get_title(): ax.get_position() for ax in fig.axes}
    assert list(at) == ["small", "room", "room: held-out words", "other"]
    room, words = at["room"], at["room: held-out words"]
    assert room.y0 == pytest.approx(words.y0) and room.x0 < words.x0
    assert at["small"].y0 > room.y0 > at["other"].y0  # a line each, in the table's order
    assert at["small"].x0 == pytest.approx(room.x0) == pytest.approx(at["other"].x0)


def test_the_maps_name_the_table_s_rows_once(tmp_path, monkeypatch):
    """write_house_maps named the whole table's rows (row_names) once per source, and
    source_panels did so even when given ``label`` (every call of experiment.write_figures)."""
    import numpy as np

    from spcopyro.maps import OccupancyGrid
    from spcopyro.study import maps

    grid = OccupancyGrid(np.zeros((3, 4), dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    (tmp_path / "maps").mkdir()
    arrays = maps.label_map_arrays(
        np.zeros((3, 4), dtype=np.int64), type("H", (), {"grid": grid}), None
    )
    np.savez(tmp_path / "maps" / "a.npz", **arrays)
    rows = [dict(data=data, variant="default", method="gibbs", seed=0, status="ok",
                 data_kind="synthetic", label_map="maps/a.npz")
            for data in ("h1", "h2", "h3")]  # fmt: skip
    calls = []
    named = maps.row_names
    monkeypatch.setattr(maps, "row_names", lambda rows: calls.append(1) or named(rows))
    monkeypatch.setattr(maps, "plot_label_maps", lambda *args: args[2])
    assert len(maps.write_house_maps(rows, tmp_path)) == 3
    assert len(calls) == 1
    _, panels, _ = maps.source_panels(rows, tmp_path, "h1", label=lambda row: "mine")
    assert len(calls) == 1 and [name for name, _ in panels] == ["mine"]


def test_the_maps_read_the_drawn_seed_s_stored_maps_once(tmp_path, monkeypatch):
    """source_panels read every stored map of a source at every seed (each once since
    6704dcd) though it draws one seed's: it reads the drawn seed's files only now, each once,
    passing over a lower seed whose cells stored no map."""
    import numpy as np

    from spcopyro.maps import OccupancyGrid
    from spcopyro.study import maps

    grid = OccupancyGrid(np.zeros((3, 4), dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    (tmp_path / "maps").mkdir()
    rows = []
    for data in ("h1", "h2"):
        for seed in (1, 0):
            for variant in ("default", "other"):
                key = f"{data}_{seed}_{variant}"
                labels = np.full((3, 4), seed, dtype=np.int64)  # which seed's map was drawn
                arrays = maps.label_map_arrays(labels, type("H", (), {"grid": grid}), None)
                np.savez(tmp_path / "maps" / f"{key}.npz", **arrays)
                rows.append(dict(data=data, variant=variant, method="gibbs", seed=seed,
                                 status="ok", data_kind="synthetic",
                                 label_map=f"maps/{key}.npz"))  # fmt: skip
    read, drawn = [], []
    load = maps.load_label_map
    monkeypatch.setattr(maps, "load_label_map",
                        lambda f, row: read.append(row["label_map"]) or load(f, row))  # fmt: skip
    monkeypatch.setattr(maps, "plot_label_maps", lambda *args: drawn.append(args[1]) or args[2])
    assert len(maps.write_house_maps(rows, tmp_path)) == 2
    drawn_files = sorted(row["label_map"] for row in rows if row["seed"] == 0)
    assert sorted(read) == drawn_files  # seed 0's, each once (was every seed's, 8 reads)
    names = [[name for name, _ in panels] for panels in drawn]
    assert names == [["gibbs", "other / gibbs"]] * 2
    assert all((labels == 0).all() for panels in drawn for _, labels in panels)  # the first seed
    failed = [dict(r, status="failed") if r["seed"] == 0 else r for r in rows]
    read.clear()
    _, panels, seed = maps.source_panels(failed, tmp_path, "h1")
    assert seed == 1 and all((labels == 1).all() for _, labels in panels)
    assert sorted(read) == sorted(r["label_map"] for r in rows if r["data"] == "h1")  # 0: none
    read.clear()
    _, panels, seed = maps.source_panels(rows, tmp_path, "h2", seed=1)
    assert seed == 1 and sorted(read) == ["maps/h2_1_default.npz", "maps/h2_1_other.npz"]
    assert maps.source_panels(failed, tmp_path, "h1", seed=0) is None
