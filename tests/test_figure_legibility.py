"""What a reader of the figures sees: no concept in a colour that passes for the unknown grey or a
wall, legends and titles that say what is drawn, as the CLI prints it (properties of the artists
and colours, not pixels). Where the pieces stand (legends off the panels, long maps in strips):
test_figure_layout.py."""

from __future__ import annotations

import json

import numpy as np

from spcopyro.maps.palette import concept_colours, delta_e94, distinct_colours, srgb_to_lab


def _chroma(colours: np.ndarray) -> np.ndarray:
    lab = srgb_to_lab(colours)  # [K, 3]
    return np.hypot(lab[:, 1], lab[:, 2])


def test_no_concept_is_drawn_in_grey():
    # palettes of 40 colours and more held (120, 120, 120) and (165, 165, 165): a concept in
    # them read as unexplored space (the unknown grey is (205, 205, 205)) or a wall
    for n in (40, 120, 240):
        colours = distinct_colours(n)  # [n, 3]
        assert _chroma(colours).min() >= 15.0, n
        assert delta_e94(colours, [205, 205, 205]).min() > 15.0, n
    labels = np.arange(144).reshape(12, 12)  # 144 touching concepts (original-code fits: 120)
    colours = concept_colours(labels, np.arange(144))  # [144, 3]
    assert _chroma(colours).min() >= 15.0
    assert not (colours.max(axis=1) - colours.min(axis=1) < 8).any()  # no r = g = b grey


def _legend_texts(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]


def test_a_house_of_sentences_is_marked_by_the_places_named():
    from spcopyro.figures.map_pieces import utterance_marks
    from spcopyro.figures.plotting import house_figure
    from spcopyro.synthetic import HouseSpec, make_house

    marks = utterance_marks(
        [["here", "is", "the", "kitchen"], ["the", "stove", "is", "here"], ["kitchen"],
         ["we", "are", "in", "the", "living", "room"], ["this", "is", "the", "room"], []]
    )  # fmt: skip
    assert marks == ["kitchen", "stove", "kitchen", "living", "room", ""]
    # every utterance a sentence: their last words were "here", "room", "kitchen", ...
    house = make_house(1, HouseSpec.embedded(sentence_fraction=1.0))
    words = make_house(1, HouseSpec.embedded())  # the same house, one word each
    texts = _legend_texts(house_figure(house))
    assert "here" not in texts and "the" not in texts
    assert {"bedroom", "living", "kitchen"} <= set(texts), texts
    named = {t for t in texts[1:] if not t.startswith("other words")}
    assert named <= {w for u in words.observations.utterances for w in u}


def test_a_house_of_words_only_draws_no_images_entry(tmp_path):
    # its house.png listed "images (0)" beside the words
    from spcopyro.data import load_house
    from spcopyro.figures.plotting import house_figure
    from spcopyro.synthetic import HouseSpec, write_synthetic

    data = write_synthetic(tmp_path, seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3))
    texts = _legend_texts(house_figure(load_house(data)))
    assert texts[0].startswith("images (") and texts[0] != "images (0)"
    for path in [*data.glob("pose_*.csv"), data / "Ft.csv", data / "Xtx.csv", data / "Xty.csv"]:
        path.unlink()
    texts = _legend_texts(house_figure(load_house(data)))
    assert not any(t.startswith("images") for t in texts), texts
    assert len(texts) > 1  # the words still show


def test_the_trace_of_one_of_several_chains_says_which(tmp_path, monkeypatch):
    """`fit --chains K` drew the kept chain's trace with no word that the K - 1 others exist."""
    import contextlib
    import dataclasses

    from hand_results import two_rooms

    from spcopyro.figures.plotting import trace_figure

    result = dataclasses.replace(two_rooms(), method="gibbs")
    title = trace_figure(result, (2, 3)).texts[0].get_text()
    assert "chain 2 of 3 (the one kept; chains.json), the others not shown" in title
    for alone in (None, (0, 1)):
        assert " of " not in trace_figure(result, alone).texts[0].get_text()

    import spcopyro.cli.fit_write as fit_cli  # the CLI hands the kept chain to the figures
    from spcopyro.cli.main import main
    from spcopyro.synthetic import HouseSpec, write_synthetic

    seen = {}

    @contextlib.contextmanager
    def recorded(*args, **kwargs):  # the figures drawn while the rest is written: none here
        seen.update(kwargs)
        yield

    monkeypatch.setattr(fit_cli, "figures_drawn", recorded)
    data = write_synthetic(tmp_path, seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3))
    argv = ["fit", str(data), "--out", str(tmp_path / "f"), "--sweeps", "5", "--chains", "2",
            "--refine", "never"]  # fmt: skip
    assert main(argv) == 0
    kept = json.loads((tmp_path / "f" / "chains.json").read_text())["best_chain"]
    assert seen["kept"] == (kept, 2)


def test_words_left_out_of_the_fit_are_said_to_be_grey():
    """A word heard off the free space ('unplaced' in fit's summary) was drawn grey on the
    semantic map while its legend said only "fill: the concept there"."""
    import dataclasses

    from hand_results import two_rooms

    from spcopyro.figures.plotting import semantic_map_figure
    from spcopyro.synthetic import make_house

    obs = make_house(seed=0).observations
    xy = np.tile([[0.55, 0.45]], (len(obs.utterances), 1))  # [U, 2] in the left room
    on_map = dataclasses.replace(obs, word_xy=xy)
    xy = xy.copy()
    xy[:2] = [[9.0, 9.0], [-5.0, 0.5]]  # far off the 3.1 x 1 m map
    off_map = dataclasses.replace(obs, word_xy=xy)

    def word_entry(observations) -> str:
        fig = semantic_map_figure(two_rooms(), observations=observations)
        (text,) = [t for t in _legend_texts(fig) if t.startswith("where a word was heard")]
        return text

    assert "left out" not in word_entry(on_map)
    assert "mid grey: 2 left out, off the free space" in word_entry(off_map)


def test_the_legend_leaves_out_words_at_p_0_00_as_fit_prints():
    """A CAVI fit's legend read "[6] ...: bathroom 0.63, bathtub 0.35, shoes 0.00" where fit
    printed "bathroom 0.63, bathtub 0.35"."""
    import dataclasses

    from hand_results import two_rooms

    from spcopyro.figures.plotting import semantic_map_figure
    from spcopyro.results.result import EmissionTable

    result = two_rooms()
    images, words = result.emissions
    w = np.array(words.probabilities, dtype=np.float64)
    w[0] = [0.6, 0.398, 0.002]  # kitchen, bed, sofa
    result = dataclasses.replace(
        result, emissions=(images, EmissionTable(words.name, words.items, w))
    )
    (entry,) = [t for t in _legend_texts(semantic_map_figure(result)) if t.startswith("[0]")]
    assert "kitchen 0.60, bed 0.40" in entry and "sofa" not in entry


def test_the_where_title_leaves_out_words_at_p_0_00():
    import dataclasses

    from hand_results import two_rooms

    from spcopyro.figures.plotting import where_figure
    from spcopyro.results.result import EmissionTable

    result = two_rooms()
    images, words = result.emissions
    w = np.array([[0.6, 0.398, 0.002], [0.398, 0.6, 0.002], [0.7, 0.298, 0.002]])  # [L, V]
    result = dataclasses.replace(
        result, emissions=(images, EmissionTable(words.name, words.items, w))
    )
    (ax,) = [a for a in where_figure(result, result.where("kitchen")).axes if a.get_title()]
    assert "its words: kitchen" in ax.get_title() and "sofa" not in ax.get_title()


def test_the_where_figure_names_the_answers_p_apart_from_the_cells():
    """``where --out`` labelled the answer's probability "p = 0.748" beside a colour bar of each
    cell's probability: two p's, one name. It now names them as ``where`` prints them."""
    import dataclasses

    from hand_results import two_rooms

    from spcopyro.figures.plotting import where_figure

    result = two_rooms()
    shown = dataclasses.replace(result, marginals=np.full((result.grid.num_free, 3), 1 / 3))
    answer = shown.where("bed")
    fig = where_figure(shown, answer)
    ax = fig.axes[0]
    bar = next(a for a in [*fig.axes, *ax.child_axes] if a is not ax)  # the colour bar
    assert bar.get_ylabel().startswith("p(cell is the place) for 'bed'")
    answer_line, runner_line = _legend_texts(fig)[:2]
    assert answer_line.startswith(
        f"answer: concept 1, p(concept | word) = {answer.probability:.3f}"
    )
    assert runner_line.startswith(f"runner-up: concept {answer.runner_up}, p(concept | word) = ")
    assert f"concept 1, p(concept | word) = {answer.probability:.3f}" in ax.get_title()
    assert "p = " not in ax.get_title() + answer_line + runner_line


def test_the_where_legend_gives_the_runner_ups_area_as_the_answers():
    """where's legend read "answer: ... (518 cells, 5.18 m²)" but "runner-up: ... (692 cells)"."""
    import dataclasses

    from hand_results import two_rooms

    from spcopyro.figures.plotting import where_figure

    result = two_rooms()
    shown = dataclasses.replace(result, marginals=np.full((result.grid.num_free, 3), 1 / 3))
    for fit in (result, shown):  # filled regions, and outlines over the probabilities
        answer_line, runner_line = _legend_texts(where_figure(fit, fit.where("bed")))[:2]
        assert answer_line.endswith(" (149 cells, 1.49 m²)"), answer_line
        assert runner_line.startswith("runner-up: concept 0, "), runner_line
        assert runner_line.endswith(" (150 cells, 1.50 m²)"), runner_line


def test_legend_counts_of_words_heard_read_as_english(monkeypatch):
    """'[63] 199 cells, 1 words heard: ...' and '[11] 204 cells, 0 words heard: no words heard
    here' (an original-code fit's legend)."""
    from hand_results import two_rooms

    from spcopyro.figures.map_pieces import concept_handles
    from spcopyro.figures.plotting import semantic_colours
    from spcopyro.results.result import SpCoResult

    result = two_rooms()
    colours = semantic_colours(result)
    labels = {}
    for heard in (0.0, 1.0, 1.04, 2.5):
        monkeypatch.setattr(SpCoResult, "heard", lambda self, concept, heard=heard: heard)
        labels[heard] = concept_handles(result, colours)[0].get_label()
    assert labels[0.0] == "[0] 150 cells: no words heard here"
    assert labels[1.0].startswith("[0] 150 cells, 1 word heard: kitchen 0.60")
    assert labels[1.04].startswith("[0] 150 cells, 1 word heard: ")
    assert labels[2.5].startswith("[0] 150 cells, 2.5 words heard: ")


def test_a_word_heard_on_a_wall_has_a_white_rim():
    """room1dk5's coarse walls cover two words heard by a door: with a black rim on the black
    wall they read as specks of paint."""
    import dataclasses

    from hand_results import two_rooms
    from matplotlib.collections import PathCollection

    from spcopyro.figures.plotting import semantic_map_figure
    from spcopyro.synthetic import make_house

    obs = make_house(seed=0).observations
    xy = np.tile([[0.55, 0.45]], (len(obs.utterances), 1))  # [U, 2] in the left room
    xy[0] = [1.55, 0.45]  # on the wall (column 15: x 1.5..1.6)
    fig = semantic_map_figure(two_rooms(), observations=dataclasses.replace(obs, word_xy=xy))
    (markers,) = [c for c in fig.axes[0].collections if isinstance(c, PathCollection)]
    edges = markers.get_edgecolors()[:, :3]  # [U, 3]
    np.testing.assert_array_equal(edges[0], [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(edges[1:], np.zeros((len(xy) - 1, 3)))


def test_the_house_figure_of_a_coarse_fit_names_both_grids():
    """fit's house.png of room1dk5 said "700 free cells" (the model's 0.25 m cells) where show
    said "18622 free cells" (the map's 0.05 m ones), with no word of the cell sizes."""
    import dataclasses

    from spcopyro.figures.plotting import house_figure
    from spcopyro.maps.coarse import coarsen_grid
    from spcopyro.synthetic import make_house

    house = make_house(seed=0)  # 0.1 m cells
    coarse = dataclasses.replace(house, grid=coarsen_grid(house.grid, 3), truth=None)
    title = house_figure(house).axes[0].get_title()
    assert title == f"synthetic: {house.grid.num_free} free cells of 0.1 m"
    title = house_figure(coarse).axes[0].get_title()
    assert title.startswith(f"synthetic: {coarse.grid.num_free} free cells of 0.3 m\n")
    assert f"(the model's cells; the map's: {house.grid.num_free} free of 0.1 m)" in title


def test_the_summary_lines_of_concepts_go_larger_first(capsys):
    """An original-code fit listed "... 103 smaller concepts" (of 1-12 cells) before "7 specks
    of 14-18 cells": the lines said nothing of the smaller concepts' sizes, out of order."""
    from spcopyro.cli.concept_listing import print_concepts
    from spcopyro.config import SpCoConfig
    from spcopyro.figures.map_pieces import concept_handles
    from spcopyro.maps import FREE, OccupancyGrid
    from spcopyro.results.result import EmissionTable, SpCoResult, Trace

    sizes = [300] * 12 + [5] * 103 + [14, 15, 16, 18]  # 4 specks of 14-18 < 0.5 % of 3729
    n, num = sum(sizes), len(sizes)
    totals = np.zeros((num, 3))  # [L, 1 + M]: cells observed, images, words heard
    totals[:115, 2] = 1.0  # a word heard in each but the last 4 (the specks)
    result = SpCoResult(
        grid=OccupancyGrid(np.full((1, n), FREE, dtype=np.int8), 0.1, (0.0, 0.0, 0.0)),
        config=SpCoConfig(num_concepts=num, prior="dirichlet"),
        labels=np.repeat(np.arange(num), sizes),  # [N]
        pi=np.full(num, 1 / num),
        emissions=(
            EmissionTable("images", ("0", "1"), np.full((num, 2), 0.5)),
            EmissionTable("words", ("a", "b"), np.full((num, 2), 0.5)),
        ),  # fmt: skip
        trace=Trace(objective=np.zeros(1), num_concepts=np.array([num]), seconds=np.zeros(1)),
        best_iteration=0,
        concept_totals=totals,
    )
    labels = [h.get_label() for h in concept_handles(result, np.zeros((num, 3)))]
    # largest first; listed in concepts.json too, as fit's listing says (the legend did not)
    assert labels[-2] == (
        "4 specks of 14-18 cells where under 0.1 words were heard (concepts 118, 117, 116, "
        "115; concepts.json lists them)"
    ), labels[-2:]
    # where their words are, as fit's listing says (the legend's line did not)
    assert labels[-1] == "... 103 smaller concepts of 5 cells in concepts.json", labels[-2:]
    print_concepts(result, limit=12)
    lines = capsys.readouterr().out.splitlines()
    speck_line = "  + 4 specks of 14-18 cells where under 0.1 words were heard"
    assert lines[-3].startswith(speck_line), lines
    assert lines[-2] == "  ... 103 smaller concepts of 5 cells in concepts.json", lines


def test_the_where_figure_tells_free_space_from_unknown():
    """where.png drew free space in grey 225 beside the unknown grey 205: 7 delta-E apart,
    the two read as one. Free space is white there as in house.png and navigate.png."""
    from hand_results import two_rooms
    from matplotlib.patches import Patch

    from spcopyro.figures.plotting import where_figure, where_image
    from spcopyro.maps import RGB_UNKNOWN

    result = two_rooms()
    answer = result.where("kitchen")
    free = where_image(result, answer)[result.label_image() == 1][0]  # [3] a free cell's colour
    assert delta_e94(free, RGB_UNKNOWN) > 15.0, free  # the palette keeps concepts 15 away
    legend = where_figure(result, answer).axes[0].get_legend()
    patches = {t.get_text(): h for t, h in zip(legend.get_texts(), legend.legend_handles,
                                               strict=True) if isinstance(h, Patch)}  # fmt: skip
    assert delta_e94(np.array(patches["free space"].get_facecolor()[:3]) * 255,
                     np.array(patches["unknown"].get_facecolor()[:3]) * 255) > 15.0  # fmt: skip


def test_a_word_heard_on_a_wall_has_a_white_rim_in_house_png_too():
    """house.png kept black rims on walls (a coarse grid's walls cover words heard by a door:
    room1ldk4's 0.25 m grid covers 7 of 45), as the semantic map did before; its legend keeps
    black rims."""
    import dataclasses

    from matplotlib.collections import PathCollection

    from spcopyro.figures.plotting import house_figure
    from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
    from spcopyro.synthetic import make_house

    occupancy = np.full((10, 31), FREE, dtype=np.int8)
    occupancy[:, 15] = OCCUPIED  # x 1.5..1.6
    grid = OccupancyGrid(occupancy, 0.1, (0.0, 0.0, 0.0))
    obs = make_house(seed=0).observations
    xy = np.tile([[0.55, 0.45]], (2, 1))
    xy[0] = [1.55, 0.45]  # on the wall
    obs = dataclasses.replace(obs, utterances=(("kitchen",), ("bed",)), word_xy=xy,
                              word_trial=np.zeros(2, dtype=np.int64))  # fmt: skip
    house = dataclasses.replace(make_house(seed=0), grid=grid, observations=obs, truth=None)
    fig = house_figure(house)
    markers = [
        c for c in fig.axes[0].collections if isinstance(c, PathCollection) and c.get_clip_on()
    ]  # not those off the map
    rims = {c.get_label(): c.get_edgecolors()[:, :3].tolist() for c in markers}
    del rims[f"images ({obs.num_images})"]
    assert rims == {"kitchen": [[1.0, 1.0, 1.0]], "bed": [[0.0, 0.0, 0.0]]}, rims
    legend = fig.axes[0].get_legend()
    assert [h.get_markeredgecolor() for h in legend.legend_handles[1:3]] == ["k", "k"]
    # [3]: the images off this 3.1 m map, triangles at its edge (test_off_map_figures.py)


def test_a_per_cell_map_at_its_top_is_not_as_dark_as_a_wall():
    """agreement.png drew a default fit's free cells (agreement near 1) in Greens' darkest
    green, L* 24, beside black walls: the map one dark mass. uncertainty.png's and where's
    probability maps shared the colour maps' dark ends. Their top colour is as light as
    navigate.png's (L* >= 40)."""
    from hand_results import two_rooms

    from spcopyro.figures.plotting import _cell_values_figure

    result = two_rooms()
    values = np.ones(result.grid.num_free)
    for cmap in ("Greens", "Blues", "YlOrRd"):
        fig = _cell_values_figure(result, values, title="t", label="p", vmax=1.0, cmap=cmap)
        (image,) = fig.axes[0].images[1:]  # over the map's own image
        top = np.round(np.array(image.cmap(1.0)[:3]) * 255).astype(np.uint8)
        assert srgb_to_lab(top[None])[0, 0] >= 40, (cmap, top)


def test_every_figure_names_a_cells_probability_as_where_prints_it(monkeypatch, tmp_path):
    """`where` prints p(cell is the place), and its answer's figure labels its colour bar so;
    its second figure (X_probability.png) was titled "p(cell in its place)" over a colour bar
    "probability", and navigate.png's bar read "p(cell in the place of 'bath')": three names
    of one value (room1ldk5). They all say p(cell is the place) now."""
    import dataclasses

    from hand_results import two_rooms
    from test_navigate import START_A, house_result

    import spcopyro.figures.plotting as plotting
    from spcopyro.robot.navigation import navigate
    from spcopyro.robot.navigation.figure import plan_figure

    result = two_rooms()
    shown = dataclasses.replace(result, marginals=np.full((result.grid.num_free, 3), 1 / 3))
    drawn = []
    monkeypatch.setattr(plotting, "save_figure", lambda fig, path: drawn.append(fig) or path)
    plotting.plot_where_probability(shown, "bed", tmp_path / "bed_probability.png")
    (fig,) = drawn
    title = fig.axes[0].get_title()  # two_rooms is a Gibbs fit: its marginals, frequencies
    assert "? p(cell is the place), Gibbs label frequencies, area prior" in title, title
    labels = [a.get_ylabel() for a in fig.axes[0].child_axes] + [a.get_ylabel() for a in fig.axes]
    assert "p(cell is the place) for 'bed'" in labels, labels

    plan = navigate(house_result(), "go to the bedroom", START_A)
    fig = plan_figure(plan)
    labels = [a.get_ylabel() for ax in fig.axes for a in [ax, *ax.child_axes]]
    assert f"p(cell is the place) for '{plan.goal.shown}'" in labels, labels
