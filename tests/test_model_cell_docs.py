"""The README's first command fits the default house on 0.3 m cells and prints so ("map 20 x 27
cells at 0.3 m"), next to ``cell_size=0.25``; the README said only "a model grid of 0.25 m
cells". The model cell is the nearest whole number of map cells, as the docs now say."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from spcopyro.config import preset
from spcopyro.data.model_grid import model_house
from spcopyro.maps.coarse import coarsening_factor
from spcopyro.synthetic import make_house

ROOT = Path(__file__).resolve().parents[1]


def _flat(path: str) -> str:
    return re.sub(r"\s+", " ", (ROOT / path).read_text(encoding="utf-8"))


def test_the_default_house_is_fitted_on_the_cells_the_readme_names():
    cell = preset("coarse").data.cell_size
    house = model_house(make_house(seed=0), cell)
    assert house.grid.resolution == pytest.approx(0.3)
    assert coarsening_factor(0.05, cell) == 5  # the public houses' maps: 0.25 m
    assert coarsening_factor(0.1, 0.25) == 3  # a half rounds up, not to even (round: 2)
    readme = _flat("README.md")
    assert "0.25 m on the public houses' 0.05 m maps, 0.3 m on the default house's 0.1 m" in readme
    assert "so 0.3 m on a 0.1 m map such as the default house's" in _flat("docs/commands.md")
