"""What ``spcopyro fit`` scores against a house's ground truth, and on which cells."""

from __future__ import annotations

import json

import numpy as np

from spcopyro.cli.main import main
from spcopyro.maps.coarse import refine_labels
from spcopyro.metrics import adjusted_rand_index
from spcopyro.synthetic import HouseSpec, make_house


def test_a_fit_left_on_the_model_grid_gives_its_ari_on_the_maps_cells_too(tmp_path, capsys):
    """The default preset fits on 0.3 m cells; Gibbs refines onto the map's 0.1 m cells and was
    scored there (3620 cells), CAVI stays on the model grid and was scored against the truth by
    block (328 cells): two methods' "adjusted Rand index against the ground truth" lines were of
    different truths, the line naming neither. It names the cells and gives both."""
    out = tmp_path / "cavi"
    assert main(["fit", "--out", str(out), "--method", "cavi", "--sweeps", "30",
                 "--no-figures"]) == 0  # fmt: skip
    line = next(s for s in capsys.readouterr().out.splitlines() if "Rand index" in s)
    scores = json.loads((out / "scores.json").read_text())
    house = make_house(seed=0, spec=HouseSpec.embedded())  # fit's default data
    labels = np.load(out / "labels.npy")  # [h, w] on the model's cells
    assert labels.shape != house.grid.shape
    fine = refine_labels(labels, house.grid, 3)  # 0.3 m cells of the 0.1 m map
    assert abs(scores["ari_map_cells"] - adjusted_rand_index(fine, house.truth)) < 1e-12
    expected = (f"adjusted Rand index against the ground truth: {scores['ari']:.3f} on the "
                f"model's {(labels >= 0).sum()} free cells of 0.3 m (the truth by block), "
                f"{scores['ari_map_cells']:.3f} on the map's {house.grid.num_free} of 0.1 m, "
                "as a refined fit is scored")  # fmt: skip
    assert line == expected, line
