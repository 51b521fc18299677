"""The figures' speed-ups of issue 25 item 1 (docs/speed.md) draw the same PNG, byte for byte: the
map's image handed to matplotlib as opaque RGBA (:func:`spcopyro.figures.map_axes.opaque`) and the
text sizes shared by the renderers of one save (:class:`spcopyro.figures.png.MeasuredCanvas`),
against a plain RGB image on a plain Agg canvas. A matplotlib whose resampling or text measuring
came to depend on either would fail here, not change the figures silently."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg

from spcopyro.figures import map_axes, png
from spcopyro.figures.house import plot_house
from spcopyro.synthetic import make_house
from spcopyro.synthetic.spec import HouseSpec


def test_opaque_is_the_rgb_image_with_a_full_alpha():
    rgb = np.random.default_rng(0).integers(0, 256, (5, 7, 3)).astype(np.uint8)  # [h, w, 3]
    rgba = map_axes.opaque(rgb)
    assert rgba.shape == (5, 7, 4) and rgba.dtype == np.uint8
    np.testing.assert_array_equal(rgba[..., :3], rgb)
    assert (rgba[..., 3] == 255).all()
    scalar = np.zeros((5, 7))  # not a uint8 RGB image: as it is
    assert map_axes.opaque(scalar) is scalar


def test_the_house_figure_is_the_same_png_as_drawn_plainly(tmp_path, monkeypatch):
    """house.png (the map's image in colours, texts, a legend, word markers) drawn as the package
    draws it, then with an RGB image on a plain Agg canvas: the same bytes."""
    spec = HouseSpec(height=30, width=40, num_rooms=3, num_open_plan=0, min_room_size=8)
    house = make_house(seed=0, spec=spec)
    fast = plot_house(house, tmp_path / "fast.png").read_bytes()
    monkeypatch.setattr(map_axes, "opaque", lambda rgb: rgb)
    monkeypatch.setattr(png, "MeasuredCanvas", FigureCanvasAgg)
    plain = plot_house(house, tmp_path / "plain.png").read_bytes()
    assert fast == plain


def test_a_study_s_maps_are_drawn_as_opaque_rgba_the_same_png(tmp_path, monkeypatch):
    """A study's maps_HOUSE.png hands each panel's image to imshow as opaque RGBA (it handed RGB,
    resampled as float64), the same bytes as drawn from RGB."""
    from spcopyro.study.maps import plot_label_maps

    spec = HouseSpec(height=30, width=40, num_rooms=3, num_open_plan=0, min_room_size=8)
    house = make_house(seed=0, spec=spec)
    panels = [("truth", house.truth), ("gibbs", house.truth)]
    drawn = []
    imshow = Axes.imshow

    def recorded(ax, image, *args, **kwargs):
        drawn.append(np.asarray(image).shape[-1])
        return imshow(ax, image, *args, **kwargs)

    monkeypatch.setattr(Axes, "imshow", recorded)
    fast = plot_label_maps(house.grid, panels, tmp_path / "fast.png", "h").read_bytes()
    assert drawn == [4, 4]
    monkeypatch.setattr(map_axes, "opaque", lambda rgb: rgb)
    plain = plot_label_maps(house.grid, panels, tmp_path / "plain.png", "h").read_bytes()
    assert drawn[2:] == [3, 3] and fast == plain


def test_a_map_in_strips_converts_its_image_once(monkeypatch):
    """strip_axes makes the opaque RGBA copy of the map once, not once a strip."""
    spec = HouseSpec(height=24, width=400, num_rooms=6, num_open_plan=0, min_room_size=10)
    grid = make_house(seed=0, spec=spec).grid
    rgb = np.zeros((*grid.shape, 3), dtype=np.uint8)  # [H, W, 3]
    real, converted = map_axes.opaque, []

    def counted(image):
        converted.append(image.shape[-1] == 3)
        return real(image)

    monkeypatch.setattr(map_axes, "opaque", counted)
    _, axes, _, _ = map_axes.map_axes(grid, rgb, (8, 6))
    assert len(axes) == 3 and sum(converted) == 1, converted


def test_a_map_s_image_is_drawn_one_way_in_house_figures_and_a_study_s_maps(tmp_path, monkeypatch):
    """show_map (house.png, the semantic map) and a study's maps_HOUSE.png draw a map's image
    through one map_axes.draw_map_image (plot_label_maps cropped, converted and placed it by
    hand, as show_map did): each panel and each map once."""
    from spcopyro.study.maps import plot_label_maps

    spec = HouseSpec(height=30, width=40, num_rooms=3, num_open_plan=0, min_room_size=8)
    house = make_house(seed=0, spec=spec)
    real, drawn = map_axes.draw_map_image, []

    def counted(ax, grid, rgb, rows, cols):
        drawn.append(rgb.shape)
        return real(ax, grid, rgb, rows, cols)

    monkeypatch.setattr(map_axes, "draw_map_image", counted)
    plot_label_maps(house.grid, [("truth", house.truth), ("gibbs", house.truth)],
                    tmp_path / "maps.png", "h")  # fmt: skip
    assert drawn == [(*house.grid.shape, 3)] * 2
    plot_house(house, tmp_path / "house.png")
    assert len(drawn) == 3


def _placed_one_text_per_spot(fig, ax, labels):
    """place_labels as it was before it measured a label once: a text made at every spot tried,
    measured there and removed where it overlaps (the reference of the test below)."""
    import warnings

    from spcopyro.figures.map_pieces import OUTLINE

    renderer = fig.canvas.get_renderer()
    ax.apply_aspect()
    boxes, skipped = [], []
    for index, (x, y, text, style, spots) in enumerate(labels):
        for at in [(x, y), *spots]:
            artist = ax.text(*at, text, ha="center", va="center", path_effects=OUTLINE,
                             zorder=4, **style)  # fmt: skip
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message="Glyph .* missing from font")
                box = artist.get_window_extent(renderer=renderer).expanded(1.15, 1.25)
            if not any(box.overlaps(other) for other in boxes):
                boxes.append(box)
                break
            artist.remove()
        else:
            skipped.append(index)
    return len(boxes), skipped


def test_a_label_measured_once_is_placed_as_a_text_made_at_every_spot():
    """place_labels measures each label once and moves its box to the spots it tries: the box of
    a text written there to the bit (matplotlib moves a text's layout to its position), so 200
    crowded labels of the semantic map's styles, some of two lines or other scripts, take the
    same spots and the same are left out as with a text made and measured at every spot."""
    from matplotlib.figure import Figure

    from spcopyro.figures.map_pieces import _label_box, place_labels

    rng = np.random.default_rng(0)
    styles = [{"fontsize": 7, "style": "normal", "color": "black"},
              {"fontsize": 6, "style": "italic", "color": "0.25"}]  # fmt: skip
    words = ["[12] kitchen 0.41 x15", "[3] bed", "no words heard here", "[7] 台所 0.20\nsofa",
             "[101] entrance 0.40 x7.0, corridor 0.23"]  # fmt: skip
    labels = []
    for k in range(200):
        (x, y), *spots = rng.uniform([0.3, -1.7], [11.9, 6.4], (6, 2)).tolist()  # [6, 2]
        labels.append((x, y, words[k % len(words)], styles[k % 2], [tuple(s) for s in spots]))
    placed = []
    for place in (place_labels, _placed_one_text_per_spot):
        fig = Figure(figsize=(9, 5))
        ax = fig.subplots()
        ax.set(xlim=(0, 12.3), ylim=(-2, 6.7), aspect="equal")
        FigureCanvasAgg(fig)
        placed.append(
            (place(fig, ax, labels), [(t.get_text(), t.get_position()) for t in ax.texts])
        )
        renderer = fig.canvas.get_renderer()
        for text in ax.texts:  # the box moved to a text's spot is the text's own
            style = {"fontsize": text.get_fontsize(), "style": text.get_style()}
            moved = _label_box(fig, renderer, text.get_text(), style).translated(
                *ax.transData.transform(text.get_position())
            )
            assert np.array_equal(moved.get_points(), text.get_window_extent(renderer).get_points())
    assert placed[0] == placed[1]
    (written, left_out), texts = placed[0]
    assert written == len(texts) and 0 < len(left_out) < 200 - 20  # crowded, not all left out
