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
