"""The figures' speed-ups of issue 25 item 1 (docs/speed.md) draw the same PNG, byte for byte: the
map's image handed to matplotlib as opaque RGBA (:func:`spcopyro.figures.map_axes.opaque`) and the
text sizes shared by the renderers of one save (:class:`spcopyro.figures.png.MeasuredCanvas`),
against a plain RGB image on a plain Agg canvas. A matplotlib whose resampling or text measuring
came to depend on either would fail here, not change the figures silently."""

from __future__ import annotations

import numpy as np
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
