"""Figures that say what they show: colours a reader can tell apart (every concept its own,
touching concepts far apart), a label on every sizeable region, and the answer to "where is X?"
drawn over the map -- checked on the helpers that compute them, and that the files are written."""

from __future__ import annotations

import numpy as np
import pytest
from hand_results import two_rooms

from spcopyro.figures.plotting import (
    ANSWER_RGB,
    FREE_RGB,
    RUNNER_UP_RGB,
    plot_semantic_map,
    plot_where,
    region_label_spots,
    semantic_colours,
    semantic_map_image,
    where_figure,
    where_image,
)
from spcopyro.maps import (
    RGB_OCCUPIED,
    concept_colours,
    distinct_colours,
    label_colours,
    region_adjacency,
    render_labels,
)
from spcopyro.maps.palette import delta_e, delta_e94, srgb_to_lab


def smallest_difference(colours: np.ndarray) -> float:
    """Smallest Delta E (CIE94, the palette's measure) between two of ``[K, 3]`` colours."""
    d = delta_e94(colours[:, None, :], colours[None, :, :])  # [K, K]
    np.fill_diagonal(d, np.inf)
    return float(d.min())


def test_srgb_to_lab_known_values():
    np.testing.assert_allclose(srgb_to_lab([255, 255, 255]), [100.0, 0.0, 0.0], atol=1e-3)
    np.testing.assert_allclose(srgb_to_lab([0, 0, 0]), [0.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(srgb_to_lab([255, 0, 0]), [53.24, 80.09, 67.20], atol=0.01)


@pytest.mark.parametrize(("n", "at_least"), [(10, 28.0), (40, 14.0), (120, 9.0)])
def test_distinct_colours_look_different(n, at_least):
    colours = distinct_colours(n)
    assert colours.shape == (n, 3) and colours.dtype == np.uint8
    assert len({tuple(c) for c in colours.tolist()}) == n
    assert smallest_difference(colours) >= at_least
    lightness = srgb_to_lab(colours)[:, 0]
    assert lightness.min() >= 40 and lightness.max() <= 90  # neither wall-black nor free-white
    np.testing.assert_array_equal(distinct_colours(n)[: n // 2], distinct_colours(n // 2))
    # the plain label colours come far closer: why the semantic map no longer uses them
    assert smallest_difference(label_colours(n)) < smallest_difference(colours)


def test_delta_e94_is_symmetric_and_weighs_chroma_less_in_saturated_colours():
    grey, darker = [128, 128, 128], [64, 64, 64]
    lightness = srgb_to_lab(grey)[0] - srgb_to_lab(darker)[0]
    assert delta_e94(grey, darker) == pytest.approx(lightness)  # no chroma: CIE76's value
    assert delta_e94(grey, darker) == pytest.approx(delta_e(grey, darker))
    green, yellow_green = [0, 255, 0], [180, 240, 105]
    assert delta_e94(green, yellow_green) == pytest.approx(delta_e94(yellow_green, green))
    # CIE76 put these two greens 52.6 apart, as far as red from orange looks: they look alike
    assert delta_e(green, yellow_green) > 50 and delta_e94(green, yellow_green) < 13


def test_the_palette_keeps_look_alikes_apart():
    """Chosen by CIE76, 12 colours held pure green and a light yellow-green (12.3 apart in
    CIE94): two concepts of room1ldk4's map looked alike."""
    colours = distinct_colours(12)
    assert smallest_difference(colours) > 25  # 12.3 under the CIE76 palette
    assert not {(0, 255, 0), (180, 240, 105)} <= {tuple(c) for c in colours.tolist()}


def test_region_adjacency_by_hand():
    labels = np.array([[0, 0, 1], [2, -1, 1], [2, 3, -1]])
    assert region_adjacency(labels) == {(0, 1), (0, 2), (2, 3)}


def test_touching_concepts_get_the_most_different_colours():
    # a 10 x 10 chessboard of concepts (tiles of 3 x 3 cells): each touches up to four others
    tiles = np.arange(100).reshape(10, 10)
    labels = np.kron(tiles, np.ones((3, 3), dtype=np.int64))  # [30, 30]
    order = np.arange(100)
    colours = concept_colours(labels, order)  # [100, 3]
    assert len({tuple(c) for c in colours.tolist()}) == 100  # every concept its own colour
    touching = np.array(sorted(region_adjacency(labels)))  # [E, 2]
    spread = delta_e94(colours[touching[:, 0]], colours[touching[:, 1]]).min()
    palette = distinct_colours(100)  # the same colours in palette order
    in_order = delta_e94(palette[touching[:, 0]], palette[touching[:, 1]]).min()
    assert spread > in_order + 20 and spread >= 40, (spread, in_order)  # measured: 47 against 12


def test_every_sizeable_region_gets_one_label_inside_it():
    image = np.full((12, 12), -1)
    image[:, :5] = 0  # concept 0, left ...
    image[:, 7:] = 0  # ... and right: one concept in two regions
    image[:, 5:7] = 1  # concept 1 between them
    image[0, 5] = 2  # a one-cell speck
    image[4:8, 8:] = 3  # concept 3 cuts a notch into the right region: a U of concept 0
    points = region_label_spots(image, min_cells=5)
    assert [(c, cells, largest) for c, _, _, cells, largest, _ in points] == [
        (0, 60, True), (0, 44, False), (1, 23, True), (3, 16, True),
    ]  # fmt: skip
    for concept, row, col, _, _, _ in points:
        assert image[row, col] == concept  # inside its region (the U's centroid is not)
    assert region_label_spots(image, min_cells=61) == []


def test_a_label_that_collides_takes_another_spot_of_its_region():
    """room1ldk5's CAVI fit (22 concepts) left the label of its kitchen concept, the fourth
    largest, out of semantic_map.png: at its region's most interior cell it overlapped the
    label of a region one cell larger, though the region had room elsewhere. A label that
    collides is tried at further spots of its region, spread over it, before it is left out."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from spcopyro.figures.map_pieces import place_labels

    image = np.full((12, 12), -1)
    image[:, :5] = 0
    image[:, 5:] = 1
    image[6:, 8:] = 2  # an L of concept 1 around concept 2
    points = region_label_spots(image, min_cells=5, spots=4)
    assert [p[:5] for p in points] == [p[:5] for p in region_label_spots(image, min_cells=5)]
    for concept, row, col, _, _, spots in points:
        assert spots[0] == (row, col) and len(set(spots)) == len(spots) == 4
        assert all(image[r, c] == concept for r, c in spots)  # every spot inside its region

    fig = Figure(figsize=(4, 4))
    ax = fig.subplots()
    ax.set(xlim=(0, 10), ylim=(0, 10))
    FigureCanvasAgg(fig)
    labels = [(5.0, 5.0, "first label", {}, []),
              (5.0, 5.2, "second label", {}, [(5.0, 5.1), (2.0, 8.0)]),
              (5.0, 4.8, "third label", {}, [(5.0, 4.9)])]  # fmt: skip
    assert place_labels(fig, ax, labels) == (2, [2])  # the third has no free spot
    assert [(t.get_text(), t.get_position()) for t in ax.texts] == [
        ("first label", (5.0, 5.0)), ("second label", (2.0, 8.0))]  # fmt: skip


def test_semantic_colours_and_the_where_picture():
    result = two_rooms()
    colours = semantic_colours(result)  # [L, 3]
    assert len({tuple(c) for c in colours.tolist()}) == 3
    used = result.concepts_in_use()  # largest first: the palette's choice for touching regions
    np.testing.assert_array_equal(colours[used], concept_colours(result.label_image(), used))
    image = result.label_image()
    drawn = semantic_map_image(result)  # [H, W, 3]
    for concept in used:
        assert (drawn[image == concept] == colours[concept]).all()
    answer = result.where("kitchen", prior="pi")  # the speck, runner-up the left room
    rgb = where_image(result, answer)  # [H, W, 3]
    image = result.label_image()
    assert (rgb[image == 2] == ANSWER_RGB).all()
    assert (rgb[image == 0] == RUNNER_UP_RGB).all()
    others = rgb[image == 1]
    assert not (others == ANSWER_RGB).all(axis=1).any()
    assert not (others == RUNNER_UP_RGB).all(axis=1).any()
    assert (others == FREE_RGB).all()  # the rest of the map white
    assert (rgb[:, 15] == RGB_OCCUPIED).all()


def test_figures_are_written(tmp_path):
    result = two_rooms()
    assert plot_semantic_map(result, tmp_path / "map.png").stat().st_size > 0
    answer = result.where("kitchen", prior="pi")
    assert plot_where(result, answer, tmp_path / "where.png").stat().st_size > 0


def test_the_where_legend_counts_a_one_cell_runner_up_as_one_cell():
    """The legend said "runner-up: concept 2, p = ... (1 cells)" for a speck (the answer's
    entry said "1 cell"): both entries count their cells in the singular for one."""
    import dataclasses

    result = two_rooms()
    answer = dataclasses.replace(result.where("kitchen"), runner_up=2)  # the 1-cell speck
    for marginals in (None, np.full((result.grid.num_free, 3), 1 / 3)):
        shown = dataclasses.replace(result, marginals=marginals)
        legend = where_figure(shown, answer).axes[0].get_legend()
        texts = [t.get_text() for t in legend.get_texts()]
        runner = next(t for t in texts if t.startswith("runner-up"))
        assert runner.endswith("(1 cell, 0.01 m²)"), texts
        answer_text = next(t for t in texts if t.startswith("answer"))
        assert answer_text.endswith(" m²)"), texts  # as graph.png's areas, not "m^2"


def test_a_figure_path_without_a_suffix_is_written_and_told_as_png(tmp_path, capsys):
    """``show --out fig`` and ``where --out fig`` printed "wrote fig" while matplotlib wrote
    fig.png (and inside ``png.background_writes`` the PNG went to ``fig`` itself): the path
    returned, printed and written is ``fig.png`` either way."""
    from spcopyro.cli.main import main
    from spcopyro.figures.png import background_writes

    result = two_rooms()
    assert plot_semantic_map(result, tmp_path / "plain") == tmp_path / "plain.png"
    with background_writes():
        assert plot_semantic_map(result, tmp_path / "threaded") == tmp_path / "threaded.png"
    assert (tmp_path / "plain.png").is_file() and (tmp_path / "threaded.png").is_file()
    assert not (tmp_path / "plain").exists() and not (tmp_path / "threaded").exists()
    out = result.save(tmp_path / "fit")
    assert main(["where", str(out), "kitchen", "--out", str(tmp_path / "kitchen")]) == 0
    assert f"wrote {tmp_path / 'kitchen.png'}\n" in capsys.readouterr().out
    assert (tmp_path / "kitchen.png").is_file()


def test_where_legend_and_warnings_clear_the_x_label_of_a_wide_map():
    """Below a wide, short map the legend sat at a fraction of the map's height under it, over
    the x label, and the warnings over the legend; the colour bar, sized from the axes box, rose
    above the map into the title. Each now keeps clear of the others."""
    import dataclasses

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    result = two_rooms()  # 10 x 31 cells: three times as wide as tall
    shown = dataclasses.replace(result, marginals=np.full((result.grid.num_free, 3), 1 / 3))
    answer = shown.where("kitchen", prior="pi")  # a speck: three warnings
    fig = where_figure(shown, answer)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()  # places the labels
    renderer = canvas.get_renderer()
    ax = fig.axes[0]
    bar = next(a for a in [*fig.axes, *ax.child_axes] if a is not ax)  # the colour bar
    xlabel = ax.xaxis.label.get_window_extent(renderer)
    legend = ax.get_legend().get_window_extent(renderer)
    warnings = next(t for t in ax.texts if t.get_text().startswith("warning:"))
    warned = warnings.get_window_extent(renderer)
    assert legend.y1 < xlabel.y0 and warned.y1 < legend.y0
    axes, colours = ax.get_window_extent(renderer), bar.get_window_extent(renderer)
    assert colours.y1 <= axes.y1 + 1 and colours.y0 >= axes.y0 - 1
    fig = where_figure(result, result.where("kitchen", prior="pi"))  # legend beside the map
    FigureCanvasAgg(fig).draw()
    ax = fig.axes[0]
    warnings = next(t for t in ax.texts if t.get_text().startswith("warning:"))
    assert warnings.get_window_extent().y1 < ax.xaxis.label.get_window_extent().y0


def test_render_labels_takes_colours():
    labels = np.array([[0, 1], [-1, 1]])
    colours = np.array([[10, 20, 30], [40, 50, 60]], dtype=np.uint8)
    rgb = render_labels(labels, colours=colours)
    np.testing.assert_array_equal(rgb[0, 1], [40, 50, 60])
    np.testing.assert_array_equal(rgb[1, 0], [255, 255, 255])
    with pytest.raises(ValueError, match="colours must be"):
        render_labels(labels, colours=colours[:1])


def _japanese_house():
    import dataclasses

    from spcopyro.synthetic import make_house

    house = make_house(seed=0)
    utterances = tuple(
        ("キッチン",) if k % 5 == 0 else u for k, u in enumerate(house.observations.utterances)
    )
    return dataclasses.replace(
        house, observations=dataclasses.replace(house.observations, utterances=utterances)
    )


def test_words_no_font_can_draw_are_told_once_in_words(tmp_path, caplog, monkeypatch):
    """Issue 22 item 10: Japanese words showed as boxes without a word. With no font that has
    their glyphs, the figures say so once (and matplotlib's per-glyph warnings stay quiet)."""
    import logging

    import spcopyro.figures.fonts as fonts
    import spcopyro.figures.plotting as plotting

    monkeypatch.setattr(fonts, "CJK_FONTS", ())  # as on a machine without such a font
    monkeypatch.setattr(fonts, "_warned_glyphs", set())
    house = _japanese_house()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        plotting.plot_house(house, tmp_path / "a.png")
        plotting.plot_house(house, tmp_path / "b.png")
    told = [r.getMessage() for r in caplog.records if "no glyphs" in r.getMessage()]
    assert len(told) == 1 and "キッチン" in told[0] and "fonts-noto-cjk" in told[0]


def test_an_installed_japanese_font_draws_the_words(tmp_path, caplog, monkeypatch):
    import logging

    import spcopyro.figures.fonts as fonts
    import spcopyro.figures.plotting as plotting

    if len(fonts._font_families()) < 2:
        pytest.skip("no font with Japanese glyphs installed (e.g. fonts-ipafont-gothic)")
    monkeypatch.setattr(fonts, "_warned_glyphs", set())
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        plotting.plot_house(_japanese_house(), tmp_path / "a.png")
    assert not [r for r in caplog.records if "no glyphs" in r.getMessage()]


def test_background_writes_give_the_files_savefig_gives(tmp_path):
    """Issue 25 item 1: inside ``png.background_writes`` a figure's PNG is compressed on a
    thread, byte for byte the file written without it; the block ends with every file there."""
    from spcopyro.figures.png import background_writes

    result = two_rooms()
    plot_semantic_map(result, tmp_path / "plain.png")
    with background_writes():
        plot_semantic_map(result, tmp_path / "threaded.png")
        answer = result.where("kitchen", prior="pi")
        plot_where(result, answer, tmp_path / "where.png")
    assert (tmp_path / "threaded.png").read_bytes() == (tmp_path / "plain.png").read_bytes()
    assert (tmp_path / "where.png").stat().st_size > 0


def test_a_legend_outside_the_axes_is_inside_the_png(tmp_path):
    """The crop box was measured at the figure's 100 dpi and the PNG drawn at 150, where text
    is wider: a semantic map's legend reached 0.2 inch past the box and its longest line was
    cut ("refrigerator 0.0"). The PNG now spans the figure's artists as drawn at its dpi."""
    import cv2
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from spcopyro.figures.png import DPI, PAD_INCHES, save_figure

    fig = Figure(figsize=(4, 3))
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], label="entrance 0.74, bedroom 0.19, refrigerator 0.04 " * 2)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    save_figure(fig, tmp_path / "legend.png")
    fig.set_dpi(DPI)
    legend = ax.get_legend().get_window_extent(FigureCanvasAgg(fig).get_renderer())  # pixels
    tight = fig.get_tightbbox(FigureCanvasAgg(fig).get_renderer())  # inches
    width = cv2.imread(str(tmp_path / "legend.png")).shape[1]
    assert legend.x1 / DPI <= tight.x1 and abs(width - (tight.width + 2 * PAD_INCHES) * DPI) <= 2


def _side_by_side_rooms():
    """A tall map (8 m x 1.4 m): concepts 0 and 1 share a band half-way up, side by side, their
    label centres 0.6 m apart; concept 2 fills the rest. Every word was heard in every concept
    (no two words of a row equal): each label lists three words."""
    import dataclasses

    from hand_results import one_word_per_concept

    from spcopyro.maps import FREE, OccupancyGrid
    from spcopyro.results.result import EmissionTable

    occupancy = np.full((80, 14), FREE, dtype=np.int8)
    grid = OccupancyGrid(occupancy=occupancy, resolution=0.1, origin=(0.0, 0.0, 0.0))
    image = np.full(grid.shape, 2)
    image[34:46, :7] = 0
    image[34:46, 7:] = 1
    result = one_word_per_concept(grid, image[grid.free], ("bedroom", "entrance", "living"), 3)
    w = np.array([[0.9, 0.06, 0.04], [0.04, 0.9, 0.06], [0.06, 0.04, 0.9]])  # [L, V]
    words = EmissionTable("words", result.vocabulary, w)
    return dataclasses.replace(result, emissions=(result.emissions[0], words))


def test_labels_of_neighbouring_regions_do_not_overlap():
    """room1ldk4's labels of concepts 27 and 3 ran into each other ("table 0.41 x15entrance 0.40
    x7.0"): the boxes were measured before the axes took the map's equal aspect, on a wider
    axes than drawn. Now no two labels' boxes overlap as drawn, and the title counts the one
    left out."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.figures.plotting import DPI, semantic_map_figure

    fig = semantic_map_figure(_side_by_side_rooms())
    fig.set_dpi(DPI)
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    (ax,) = fig.axes
    boxes = [t.get_window_extent(renderer) for t in ax.texts]
    assert len(boxes) == 3  # concept 2 above and below, one of the two side by side
    assert not any(a.overlaps(b) for k, a in enumerate(boxes) for b in boxes[k + 1 :])
    assert "3 labelled regions, 1 left unlabelled (legend)" in ax.get_title()


def test_the_title_says_where_unlabelled_regions_are_described():
    """room1ldk5's CAVI fit titled semantic_map.png "8 left unlabelled (legend)" while the
    legend has entries for the 12 largest concepts only: 7 of the 8 regions were of smaller
    concepts, in no legend entry. The title now says how many of each (a tall map of concept 0
    and 14 bands of 24 cells: the bands' labels crowd each other out)."""
    from hand_results import one_word_per_concept

    from spcopyro.figures.map_pieces import MAX_LEGEND_CONCEPTS, legend_concepts
    from spcopyro.figures.plotting import semantic_map_figure
    from spcopyro.maps import FREE, OccupancyGrid

    heights = [60] + [2] * 14  # rows of concepts 0..14
    grid = OccupancyGrid(np.full((sum(heights), 12), FREE, dtype=np.int8), 0.1, (0.0, 0.0, 0.0))
    image = np.repeat(np.arange(15), heights)[:, None].repeat(12, 1)  # [H, W]
    words = tuple(f"word{k}" for k in range(15))
    result = one_word_per_concept(grid, image[grid.free], words, 15)
    assert legend_concepts(result) == set(range(MAX_LEGEND_CONCEPTS))  # 12-14 only counted
    fig = semantic_map_figure(result)
    (ax,) = fig.axes
    written = {int(t.get_text().split("]")[0][1:]) for t in ax.texts}  # "[3]\nword3 ..."
    left_out = set(range(15)) - written
    inside = len(left_out & set(range(MAX_LEGEND_CONCEPTS)))
    assert 0 < inside < len(left_out)  # some of each
    assert (f", {len(left_out)} left unlabelled ({inside} in the legend, "
            f"{len(left_out) - inside} in concepts.json)") in ax.get_title()  # fmt: skip


def test_the_legend_names_the_words_p_as_fit_prints_them():
    """semantic_map.png's legend said "posterior mean p" of a CAVI or LBP fit's words, which
    fit's listing calls "words as the method estimates them" (no posterior mean given labels:
    a variational method's E_q). A fit that recorded its posterior means (Gibbs:
    inference["parameters"]) keeps "posterior mean p"."""
    import dataclasses

    from spcopyro.figures.plotting import semantic_map_figure
    from spcopyro.results.posterior_means import PARAMETERS_GIVEN_LABELS

    def title(result):
        (legend,) = [ax.get_legend() for ax in semantic_map_figure(result).axes]
        return legend.get_title().get_text()

    variational = two_rooms()
    assert "parameters" not in variational.inference
    assert title(variational) == ("concepts, largest first: words as the method estimates them "
                                  "(x lift = p(word | concept) / p(word))")  # fmt: skip
    gibbs = dataclasses.replace(variational, inference={"parameters": PARAMETERS_GIVEN_LABELS})
    assert title(gibbs) == ("concepts, largest first: words (posterior mean p; x lift = "
                            "p(word | concept) / p(word))")  # fmt: skip


def _crowded_house():
    """The synthetic house with its first 12 utterances heard at two spots, words of three
    kinds at each (room1dk5: 'bedroom' hidden under 'shelf' and 'other words')."""
    import dataclasses

    from spcopyro.synthetic import make_house

    house = make_house(seed=0)
    obs = house.observations
    xy = np.array(obs.word_xy, dtype=np.float64)
    xy[:6] = xy[0]
    xy[6:12] = xy[6]
    words = ("bedroom", "shelf", "bed") * 4 + tuple(u[-1:] for u in obs.utterances[12:])
    words = tuple((w,) if isinstance(w, str) else w for w in words)
    return dataclasses.replace(
        house, observations=dataclasses.replace(obs, word_xy=xy, utterances=words)
    )


def test_every_word_in_the_house_legend_shows_in_its_own_colour():
    """room1dk5's house.png: 'bedroom' was in the legend but all its markers lay under others,
    and tv/kitchen, chair/entrance had near-twin colours. Markers at one spot are now spread
    apart (no centre within half a marker of one drawn over it) and the colours differ."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.figures.plotting import house_figure

    fig = house_figure(_crowded_house())
    FigureCanvasAgg(fig).draw()
    (ax,) = fig.axes
    words = [c for c in ax.collections if c.get_label() not in ("", "_nolegend_")][1:]
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert {"bedroom", "shelf", "bed"} <= set(legend) and legend[-1].startswith("other words")
    assert legend[0].startswith("images")
    assert {c.get_label() for c in words} == set(legend[1:])  # but the images
    diameter = np.sqrt(28.0) * fig.dpi / 72.0
    drawn = sorted(words, key=lambda c: c.get_zorder())  # stable: later ones drawn over
    for k, mine in enumerate(drawn):
        centres = ax.transData.transform(mine.get_offsets())  # [n, 2]
        above = [ax.transData.transform(c.get_offsets()) for c in drawn[k + 1 :]]
        above += [np.empty((0, 2))]
        gaps = np.linalg.norm(centres[:, None] - np.concatenate(above)[None], axis=-1)
        visible = (gaps >= 0.5 * diameter).all(axis=1) if gaps.shape[1] else [True]
        assert np.any(visible), mine.get_label()
    named = np.array([c.get_facecolor()[0, :3] for c in words
                      if not c.get_label().startswith("other words")])  # fmt: skip
    assert smallest_difference(np.round(named * 255).astype(np.uint8)) >= 25


def test_the_trace_names_its_marked_sweep_and_the_reported_map():
    """The dashed line was labelled "point estimate" but marks the sweep of the highest log
    joint; a fit reporting the point estimate over its samples says that map is not that
    state, and the concept count is said to be the chain's per sweep."""
    import dataclasses

    from spcopyro.figures.plotting import trace_figure

    result = dataclasses.replace(two_rooms(), method="gibbs")
    top, bottom = trace_figure(result).axes
    assert [t.get_text() for t in top.get_legend().get_texts()] == [
        f"highest {result.trace.objective_name} (sweep 1)"
    ]
    assert "per sweep" in bottom.get_ylabel() and "specks included" in bottom.get_ylabel()
    assert "point estimate" not in trace_figure(result).texts[0].get_text()
    sampled = dataclasses.replace(result, agreement=np.ones(result.grid.num_free))
    title = trace_figure(sampled).texts[0].get_text()
    assert "point estimate over the kept samples,\nnot the state of sweep 1" in title


def test_a_refined_fits_trace_says_it_shows_the_refinement():
    """A refined fit's trace is its second stage's: its sweeps started at 1 again with no word
    of the coarse stage before them."""
    import dataclasses

    from spcopyro.figures.plotting import trace_figure

    result = two_rooms()
    refine = {"refine": True, "coarse": {"sweeps": 5000, "cell_size": 0.3}}
    refined = dataclasses.replace(result, inference={**result.inference, "refine": refine})
    title = trace_figure(refined).texts[0].get_text()
    assert f"the refinement on the map's {result.grid.resolution:g} m cells" in title
    assert "after 5000 sweeps on 0.3 m cells (not shown)" in title
    not_refined = {"refine": False, "reason": "..."}
    kept = dataclasses.replace(result, inference={**result.inference, "refine": not_refined})
    assert "refinement" not in trace_figure(kept).texts[0].get_text()


def test_a_variational_trace_does_not_call_q_a_chain():
    """CAVI, LBP and SVI count each cell's most probable concept under q per iteration; the
    axis said "the chain's state" for them too."""
    import dataclasses

    from spcopyro.figures.plotting import trace_figure

    result = dataclasses.replace(two_rooms(), method="cavi")
    _, bottom = trace_figure(result).axes
    assert "per iteration" in bottom.get_ylabel() and "argmax of q" in bottom.get_ylabel()
    assert "chain" not in bottom.get_ylabel()


def test_a_vi_gibbs_trace_is_of_its_gibbs_sweeps():
    """vi-gibbs traces the log joint of its Gibbs chain's sweeps (after the CAVI start): its
    axes said "per iteration (argmax of q per cell)" and its legend "iteration"."""
    import dataclasses

    from spcopyro.figures.plotting import trace_figure

    result = dataclasses.replace(two_rooms(), method="vi-gibbs")
    top, bottom = trace_figure(result).axes
    assert "per sweep" in bottom.get_ylabel() and "the chain's state" in bottom.get_ylabel()
    assert "argmax of q" not in bottom.get_ylabel() and bottom.get_xlabel() == "sweep"
    assert "(sweep " in top.get_legend().get_texts()[0].get_text()


def test_a_variational_trace_marks_its_final_iteration_as_final_not_highest():
    """A variational fit reports its final q; LBP's Bethe objective and SVI's noisy estimate can
    peak earlier, and the legend called the final iteration the highest."""
    import dataclasses

    from spcopyro.figures.plotting import trace_figure
    from spcopyro.inference.protocol import Trace

    trace = Trace(np.array([1.0, 3.0, 2.0]), np.array([3, 3, 3]), np.zeros(3), "Bethe ELBO")
    result = dataclasses.replace(two_rooms(), method="lbp", trace=trace, best_iteration=2)
    top, _ = trace_figure(result).axes
    label = top.get_legend().get_texts()[0].get_text()
    assert label == "final Bethe ELBO (iteration 3): the reported q"


@pytest.mark.parametrize(
    "method, source",
    [("gibbs", "Gibbs label frequencies\n"), ("vi-gibbs", "Gibbs label frequencies (vi-gibbs)"),
     ("cavi", "q(C) of cavi")],
)  # fmt: skip
def test_the_uncertainty_map_names_where_its_marginals_come_from(monkeypatch, method, source):
    """vi-gibbs's marginals are its Gibbs stage's label frequencies; the title said q(C)."""
    import dataclasses

    from spcopyro.figures import plotting

    marginals = np.full((two_rooms().labels.size, 3), 1 / 3)
    result = dataclasses.replace(two_rooms(), method=method, marginals=marginals)
    titles = []
    monkeypatch.setattr(plotting, "_plot_cell_values", lambda *a, title, **k: titles.append(title))
    plotting.plot_uncertainty(result, "unused.png")
    assert source in titles[0]


def test_counts_of_one_are_singular(tmp_path, monkeypatch):
    import dataclasses

    import spcopyro.figures.plotting as plotting

    titles = []
    monkeypatch.setattr(plotting, "_plot_cell_values", lambda *a, **k: titles.append(k["title"]))
    agreement = np.ones(two_rooms().grid.num_free)
    agreement[0] = 0.2
    plotting.plot_agreement(dataclasses.replace(two_rooms(), agreement=agreement), tmp_path)
    assert "1 cell below 0.5" in titles[0]


def _legend_side(fig) -> str:
    """'below' or 'beside' the map, from the drawn boxes of the axes and its legend."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    ax = fig.axes[0]
    axes, legend = ax.get_window_extent(renderer), ax.get_legend().get_window_extent(renderer)
    xlabel = ax.xaxis.label.get_window_extent(renderer)
    if legend.y1 < xlabel.y0:
        return "below"
    assert legend.x0 > axes.x1, (legend, axes)
    return "beside"


def test_a_wide_maps_legend_goes_below_it_in_columns():
    """On a map five times as wide as high the house figure's legend, beside the map, was
    taller than the map: most of the PNG blank, the map a strip. A map wider than
    WIDE_ASPECT times its height now has its legends (house, semantic map) below it, in
    columns; a squarer map keeps them beside it."""
    from spcopyro.figures.plotting import house_figure, semantic_map_figure
    from spcopyro.synthetic import HouseSpec, make_house

    wide = make_house(seed=1, spec=HouseSpec(height=30, width=200))
    fig = house_figure(wide)
    assert _legend_side(fig) == "below"
    texts = fig.axes[0].get_legend().get_texts()
    assert len({round(t.get_window_extent().x0) for t in texts}) == 4  # columns
    assert _legend_side(semantic_map_figure(two_rooms())) == "below"  # 10 x 31 cells
    assert _legend_side(house_figure(make_house(seed=0))) == "beside"  # 60 x 80 cells
    import dataclasses

    square = two_rooms()
    occupancy = np.repeat(square.grid.occupancy, 2, axis=0)  # 20 x 31 cells
    grid = type(square.grid)(occupancy=occupancy, resolution=0.1, origin=(0.0, 0.0, 0.0))
    image = np.repeat(square.label_image(), 2, axis=0)
    taller = dataclasses.replace(square, grid=grid, labels=image[grid.free])
    assert _legend_side(semantic_map_figure(taller)) == "beside"


def test_study_figures_draw_words_of_any_script_as_the_maps_do(tmp_path, caplog, monkeypatch):
    """A study's figures (quality against time, the experiment's maps, ablation and comparison
    plots) were saved without the fallback fonts the maps use: a Japanese source or variant
    name was boxes, with one matplotlib warning per glyph and no word (a helper's QA)."""
    import logging
    import warnings

    import spcopyro.figures.fonts as fonts
    from spcopyro.study.figures import write_quality_time

    monkeypatch.setattr(fonts, "CJK_FONTS", ())  # as on a machine without such a font
    monkeypatch.setattr(fonts, "_warned_glyphs", set())
    rows = [{"status": "ok", "data": "台所の家", "variant": "既定", "method": "gibbs",
             "seconds": 1.5, "ari": 0.8}]  # fmt: skip
    with (
        caplog.at_level(logging.WARNING, logger="spcopyro"),
        warnings.catch_warnings(record=True) as caught,
    ):
        warnings.simplefilter("always")
        write_quality_time(rows, tmp_path / "q.png")
    assert not [w for w in caught if "missing from font" in str(w.message)]
    told = [r.getMessage() for r in caplog.records if "no glyphs" in r.getMessage()]
    assert len(told) == 1 and "fonts-noto-cjk" in told[0]


def test_the_vi_point_estimate_is_not_read_as_variational_inference(tmp_path):
    """trace.png and agreement.png of a default fit said "the vi point estimate" and "the vi
    estimate": beside compare-inference's VI methods it read as variational inference's. They
    name the loss (variation of information); a result that does not say which, "point
    estimate"."""
    import dataclasses

    from matplotlib.image import imread

    from spcopyro.figures.plotting import _estimate_name, plot_agreement, trace_figure

    result = dataclasses.replace(two_rooms(), method="gibbs")
    inference = {**result.inference, "point_estimate": "vi"}
    sampled = dataclasses.replace(result, agreement=np.ones(result.grid.num_free),
                                  inference=inference)  # fmt: skip
    title = trace_figure(sampled).texts[0].get_text()
    assert "the variation-of-information point estimate over the kept samples" in title
    assert " vi " not in title
    assert _estimate_name(sampled) == "variation-of-information point estimate"
    assert imread(plot_agreement(sampled, tmp_path / "a.png")).size
    bare = dataclasses.replace(sampled, inference={})
    assert _estimate_name(bare) == "point estimate"


def test_an_svi_trace_says_it_is_an_estimate_and_where_gamma_was_annealed():
    """SVI's trace is one draw's ELBO estimate a step, at the step's coupling while gamma rises
    from 0 (its first 100 steps by default); trace.png labelled it "ELBO" as CAVI's exact ELBO
    at the model's gamma. vi-gibbs's trace, the sweeps after its CAVI start, said nothing of it."""
    import dataclasses

    from spcopyro.figures.plotting import trace_figure
    from spcopyro.inference.protocol import Trace

    result = two_rooms()
    trace = Trace(np.linspace(-50.0, -10.0, 20), np.full(20, 2), np.arange(1.0, 21.0), "ELBO")
    svi = dataclasses.replace(result, method="svi", trace=trace, best_iteration=19,
                              inference={"num_particles": 1, "anneal_iterations": 8})  # fmt: skip
    top = trace_figure(svi).axes[0]
    assert top.get_ylabel() == "ELBO estimate (nats)\na lower bound on log p(data)\n(1 draw a step)"
    texts = [t.get_text() for t in top.get_legend().get_texts()]
    assert "steps 1-8: gamma annealed from 0, the estimate at that gamma" in texts, texts
    cavi = dataclasses.replace(svi, method="cavi", inference={"anneal_iterations": 8})
    exact = trace_figure(cavi).axes[0].get_ylabel()  # exact, at the model's gamma
    assert exact == "ELBO (nats)\na lower bound on log p(data)"
    vi_gibbs = dataclasses.replace(result, method="vi-gibbs", inference={"vi_iterations_run": 43})
    title = trace_figure(vi_gibbs).texts[0].get_text()
    assert "Gibbs sweeps from a CAVI start of 43 iterations (not shown)" in title


def test_the_trace_names_its_objective_s_unit_and_what_it_is():
    """trace.png's axis said "log joint" on a Gibbs fit (room1dk5: about +118,000) and "ELBO"
    on a CAVI fit (about -1,400), with no unit and nothing saying that the two are different
    quantities: the log joint holds the drawn parameters' densities, the ELBO bounds log
    p(data). Each axis now names its unit and its quantity."""
    import dataclasses

    from spcopyro.figures.plotting import trace_figure
    from spcopyro.inference.protocol import Trace

    result = dataclasses.replace(two_rooms(), method="gibbs")
    gibbs = trace_figure(result).axes[0].get_ylabel()
    assert gibbs == "log joint (nats)\nlog p(data, labels, parameters)", gibbs
    for method, name, meaning in [
        ("cavi", "ELBO", "a lower bound on log p(data)"),
        ("lbp", "Bethe ELBO", "Bethe's approximation of log p(data)"),
    ]:
        trace = Trace(np.linspace(-50.0, -10.0, 5), np.full(5, 2), np.arange(1.0, 6.0), name)
        fit = dataclasses.replace(result, method=method, trace=trace, best_iteration=4)
        assert trace_figure(fit).axes[0].get_ylabel() == f"{name} (nats)\n{meaning}"


def test_the_house_legend_names_the_other_words():
    """house.png colours the 12 most heard words and draws the rest as grey circles; their
    legend entry read "other words" alone, so room1ldk5's 'bedroom', 'bath' and 'chair' were
    circles no figure named. It names them, the most heard first, six at most."""
    import dataclasses
    from collections import Counter

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.figures.house import other_words_label
    from spcopyro.figures.plotting import house_figure
    from spcopyro.synthetic import make_house

    house = make_house(seed=0)
    obs = house.observations
    colour = [f"word{k:02d}" for k in range(12) for _ in range(3)]  # 36 utterances, 3 each
    rest = ["bedroom", "chair", "bedroom", "bath", "e", "d", "c", "b", "a"]
    words = (colour + rest + ["word00"] * len(obs.utterances))[: len(obs.utterances)]
    assert len(words) >= len(colour) + len(rest)
    house = dataclasses.replace(house, observations=dataclasses.replace(
        obs, utterances=tuple((w,) for w in words)))  # fmt: skip
    fig = house_figure(house)
    FigureCanvasAgg(fig).draw()
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    wanted = "other words: bedroom, a, b, bath, c, chair and 2 more"
    assert legend[-1] == wanted  # most heard first, ties alphabetically
    assert wanted in [c.get_label() for c in fig.axes[0].collections]
    assert other_words_label(Counter(["x", "y", "y", ""]), ["x"]) == "other words: y"
    assert other_words_label(Counter(["x", ""]), ["x"]) == "other words"  # an empty one only


def test_the_house_legend_names_one_other_word_over_the_limit():
    """messages.shown_count's rule: "and 1 more" takes as much of the line as the word it
    hides, so seven other words (one over OTHER_WORDS_NAMED) are all named; eight still end
    "and 2 more"."""
    from collections import Counter

    from spcopyro.figures.house import OTHER_WORDS_NAMED, other_words_label

    words = [f"w{k}" for k in range(OTHER_WORDS_NAMED + 2)]
    one_over = Counter(words[: OTHER_WORDS_NAMED + 1])
    assert other_words_label(one_over, []) == "other words: " + ", ".join(words[:-1])
    two_over = other_words_label(Counter(words), [])
    assert two_over == "other words: " + ", ".join(words[:OTHER_WORDS_NAMED]) + " and 2 more"
