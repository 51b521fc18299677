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
