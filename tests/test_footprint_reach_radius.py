"""The reach share's radius (DataPreparation.footprint_reach_radius, spcopyro.data.footprint,
"Bounding the reach"): each observation's Voronoi cell cut at that geodesic distance from its
observed cell.

Checked: on a corridor the cut cell is exactly the cells within the radius, the cells beyond
every source's radius get no Voronoi weight, and every placed row still sums to one; a radius
beyond every distance gives the uncut cells; None is today's reach share byte for byte (weights,
counts, saved preparation); the refinement replaces it; bad values are refused naming the field
and value; ``spcopyro fit --footprint-reach-radius`` reaches config.json.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from gibbs_problems import tiny_grid
from test_footprint import ROWS, observations

from spcopyro.cli.main import main
from spcopyro.config import DataPreparation, preset
from spcopyro.data import place_observations
from spcopyro.data.counts import prepared_cell_counts
from spcopyro.data.footprint import footprint_weights, voronoi_weights
from spcopyro.fit.refine import refined_settings, replaced_preparation


def test_a_cut_cell_holds_the_cells_within_the_radius_and_none_beyond():
    """A 1 x 12 corridor of 0.1 m cells, sources in columns 1 and 10: uncut, columns 0-5 are the
    left source's and 6-11 the right one's; cut at 0.25 m, columns 0-3 and 8-11 (within 0.2 m),
    columns 4-7 (0.3 m and more from both) nobody's."""
    grid = tiny_grid(["............"])
    left, right = int(grid.free_index[0, 1]), int(grid.free_index[0, 10])
    cells = np.array([left, right, -1])
    uncut = voronoi_weights(grid, cells).toarray()  # [3, 12]
    np.testing.assert_allclose(uncut[0], np.r_[np.full(6, 1 / 6), np.zeros(6)], rtol=1e-12)
    cut = voronoi_weights(grid, cells, radius=0.25).toarray()  # [3, 12]
    np.testing.assert_allclose(cut[0], np.r_[np.full(4, 0.25), np.zeros(8)], rtol=1e-12)
    np.testing.assert_allclose(cut[1], np.r_[np.zeros(8), np.full(4, 0.25)], rtol=1e-12)
    assert not cut[:, 4:8].any() and not cut[2].any()
    share = 0.25
    mixed = footprint_weights(grid, cells, 0.1, reach_share=share, reach_radius=0.25).toarray()
    disc = footprint_weights(grid, cells, 0.1).toarray()
    np.testing.assert_allclose(mixed - (1 - share) * disc, share * cut, atol=1e-15)
    np.testing.assert_allclose(mixed[:2].sum(axis=1), 1.0, rtol=1e-12)
    far = voronoi_weights(grid, cells, radius=100.0)
    assert (far != voronoi_weights(grid, cells)).nnz == 0  # beyond every distance: uncut


@pytest.mark.parametrize("radius", [0.15, 0.3])
def test_cut_weights_still_sum_to_one_on_a_map_with_walls(rng, radius):
    grid = tiny_grid(ROWS)
    obs = observations(grid, rng)
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    weights = footprint_weights(grid, cells, 0.2, reach_share=0.5, reach_radius=radius)
    dense = weights.toarray()  # [T, N]
    placed = cells >= 0
    np.testing.assert_allclose(dense[placed].sum(axis=1), 1.0, rtol=1e-12)
    uncut = footprint_weights(grid, cells, 0.2, reach_share=0.5).toarray()
    assert (dense > 0).sum() <= (uncut > 0).sum()


def test_no_radius_is_todays_reach_share_byte_for_byte(rng):
    grid = tiny_grid(ROWS)
    obs = observations(grid, rng)
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    plain = footprint_weights(grid, cells, 0.2, reach_share=0.25)
    none = footprint_weights(grid, cells, 0.2, reach_share=0.25, reach_radius=None)
    for a, b in ((plain.indptr, none.indptr), (plain.indices, none.indices),
                 (plain.data, none.data)):  # fmt: skip
        assert a.tobytes() == b.tobytes()
    prep = DataPreparation(footprint_radius=0.2, footprint_reach_share=0.25)
    assert "footprint_reach_radius" not in prep.to_json()
    explicit = prep.replace(footprint_reach_radius=None)
    assert explicit.to_json() == prep.to_json()
    a = prepared_cell_counts(grid, obs, prep, warn=False)
    b = prepared_cell_counts(grid, obs, explicit, warn=False)
    assert a.cells.tobytes() == b.cells.tobytes()
    assert a.image_counts.tobytes() == b.image_counts.tobytes()
    assert a.word_counts.tobytes() == b.word_counts.tobytes()
    cut = prepared_cell_counts(grid, obs, prep.replace(footprint_reach_radius=0.15), warn=False)
    assert prep.replace(footprint_reach_radius=0.15).to_json()["footprint_reach_radius"] == 0.15
    assert cut.cells.size < a.cells.size  # the cut reaches fewer cells


def test_the_refinement_replaces_the_reach_radius():
    settings = preset("coarse", footprint_reach_share=0.25, footprint_reach_radius=2.0)
    refined = refined_settings(settings, 100, 2500)
    assert refined.data.footprint_reach_radius is None
    assert replaced_preparation(settings, refined.data)["footprint_reach_radius"] == {
        "given": 2.0, "refinement": None}  # fmt: skip


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), True, "2"])
def test_a_bad_reach_radius_is_refused_naming_the_field_and_value(bad):
    with pytest.raises(ValueError) as caught:
        DataPreparation(footprint_reach_radius=bad)
    assert f"DataPreparation.footprint_reach_radius={bad!r}: must be None (no limit) or a " in str(
        caught.value
    )
    grid = tiny_grid(["..."])
    with pytest.raises(ValueError, match=r"footprint_reach_radius=.*must be None \(no limit\)"):
        footprint_weights(grid, np.array([0]), 0.0, reach_share=0.5, reach_radius=bad)


def test_fit_reach_radius_option_reaches_config_json(tmp_path):
    out = tmp_path / "fit"
    code = main(["fit", "--sweeps", "3", "--backend", "torch", "--footprint-reach-share", "0.25",
                 "--footprint-reach-radius", "2", "--out", str(out)])  # fmt: skip
    assert code == 0
    settings = json.loads((out / "config.json").read_text())
    assert settings["data"]["footprint_reach_radius"] == 2.0
    assert settings["data"]["footprint_reach_share"] == 0.25


def test_a_reach_radius_without_a_share_is_refused(tmp_path, capsys):
    """A radius cuts the share's Voronoi cells: without a share it would change no count but
    still count as preparing the data, skipping the recommended refinement unsaid."""
    with pytest.raises(ValueError, match=r"footprint_reach_radius=2\.0: cuts the Voronoi cells"):
        DataPreparation(footprint_reach_radius=2.0)
    DataPreparation(footprint_reach_share=0.25, footprint_reach_radius=2.0)  # with a share: fine
    # the default preset's share is 0.2 since 2026-12-06: the share of 0 given explicitly
    code = main(["fit", "--sweeps", "3", "--backend", "torch", "--footprint-reach-radius", "2",
                 "--footprint-reach-share", "0", "--out", str(tmp_path / "fit")])  # fmt: skip
    assert code != 0
    assert "footprint_reach_share, which is 0" in capsys.readouterr().err
    assert not (tmp_path / "fit" / "config.json").exists()


def test_the_cut_is_worded_in_one_place_for_both_summary_lines():
    """The fit summary's data line (fit_summary.data_line) and its observed-cells line
    (cli.common) each built "Voronoi cells within R m"; both now say reach_cut_text's words."""
    from spcopyro.cli.common import _summary
    from spcopyro.cli.fit_summary import data_line, reach_cut_text
    from spcopyro.data.model_grid import model_house
    from spcopyro.synthetic import HouseSpec, make_house

    assert reach_cut_text(None) == "Voronoi cells"
    assert reach_cut_text(2.0) == "Voronoi cells within 2 m"
    data = preset("coarse", footprint_reach_share=0.25, footprint_reach_radius=2.0).data
    # with coarse's door width (its default since 2026-12-06) after the radius
    assert "reach share 0.25 (Voronoi cells within 2 m, within rooms at 1 m doors)" in data_line(
        data
    )
    house = model_house(make_house(seed=0, spec=HouseSpec.embedded()), data.cell_size)
    lines = _summary(house, warn=False, preparation=data).splitlines()
    observed = next(x for x in lines if x.startswith("observed cells"))
    assert observed.endswith(" footprints and Voronoi cells within 2 m, within rooms at 1 m doors")
