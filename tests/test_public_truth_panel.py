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
