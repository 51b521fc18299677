"""The footprint's reach share (DataPreparation.footprint_reach_share, spcopyro.data.footprint,
"Reaching the Voronoi border"): a share e of each observation spread uniformly over its geodesic
Voronoi cell among its modality's observed cells, 1 - e over its footprint.

Checked: every placed observation's weights still sum to one (kernels, radius 0, field of view);
on an open map with two sources the Voronoi part lands exactly on each side of the bisector,
a tied column split equally; it never crosses a wall; observations sharing a cell share it;
e = 0 is today's footprint byte for byte (weights, counts, saved preparation); the factored
counts equal the dense ones; the refinement replaces it; bad values are refused naming the
field; ``spcopyro fit --footprint-reach-share`` reaches config.json.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from gibbs_problems import tiny_grid
from test_footprint import ROWS, observations

from spcopyro.cli.main import main
from spcopyro.config import DataPreparation, footprint_spreads, preset
from spcopyro.data import cell_counts, footprint, place_observations
from spcopyro.data.counts import prepared_cell_counts
from spcopyro.data.footprint import (
    disc_weights,
    footprint_weights,
    free_cell_graph,
    voronoi_weights,
)
from spcopyro.fit.refine import refined_settings, replaced_preparation


@pytest.fixture
def problem(rng):
    grid = tiny_grid(ROWS)
    return grid, observations(grid, rng)


@pytest.mark.parametrize("share", [0.1, 0.5, 0.9])
@pytest.mark.parametrize(("radius", "kernel", "fov"), [
    (0.0, "uniform", None), (0.25, "uniform", None), (0.3, "gaussian", 120.0),
])  # fmt: skip
def test_every_placed_observations_weights_still_sum_to_one(problem, share, radius, kernel, fov):
    grid, obs = problem
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    cells = np.append(cells, -1)  # [T + 1] an unplaced observation: an empty row
    yaw = np.append(obs.image_yaw, 0.0) if fov else None
    weights = footprint_weights(grid, cells, radius, kernel, yaw=yaw, fov=fov,
                                reach_share=share).toarray()  # fmt: skip  # [T + 1, N]
    np.testing.assert_allclose(weights[:-1].sum(axis=1), 1.0, rtol=1e-12)
    assert not weights[-1].any()
    assert (weights >= 0).all()
    disc = disc_weights(grid, cells, radius, kernel, yaw=yaw, fov=fov).toarray()
    voronoi = voronoi_weights(grid, cells).toarray()
    np.testing.assert_allclose(weights, (1 - share) * disc + share * voronoi, atol=1e-15)


def test_the_voronoi_part_lands_exactly_on_each_side_of_the_bisector():
    """An open 3 x 7 map, sources in column 1 and column 5: columns 0-2 are the left source's,
    4-6 the right one's, column 3 (equidistant) is split equally. A 3 x 8 map with sources in
    columns 1 and 6 has no tied cell: columns 0-3 and 4-7."""
    grid = tiny_grid([".......", ".......", "......."])  # 0.1 m cells, 21 free
    left, right = int(grid.free_index[1, 1]), int(grid.free_index[1, 5])
    cells = np.array([left, right, -1])
    voronoi = voronoi_weights(grid, cells).toarray()  # [3, 21]
    zone = np.zeros((3, 7))
    zone[:, :3], zone[:, 3] = 1.0, 0.5  # the left source's cells, the bisector half
    np.testing.assert_allclose(voronoi[0].reshape(3, 7), zone / zone.sum(), rtol=1e-12)
    np.testing.assert_allclose(voronoi[1].reshape(3, 7), zone[:, ::-1] / zone.sum(), rtol=1e-12)
    assert not voronoi[2].any()
    share = 0.25
    mixed = footprint_weights(grid, cells, 0.15, reach_share=share).toarray()
    disc = footprint_weights(grid, cells, 0.15).toarray()
    np.testing.assert_allclose(mixed - (1 - share) * disc, share * voronoi, atol=1e-15)

    even = tiny_grid(["........"] * 3)
    cells = np.array([int(even.free_index[1, 1]), int(even.free_index[1, 6])])
    voronoi = voronoi_weights(even, cells).toarray().reshape(2, 3, 8)
    np.testing.assert_allclose(voronoi[0][:, :4], 1 / 12, rtol=1e-12)
    assert not voronoi[0][:, 4:].any()
    np.testing.assert_allclose(voronoi[1][:, 4:], 1 / 12, rtol=1e-12)


def test_the_voronoi_cell_is_geodesic_and_shared_by_observations_at_one_cell():
    """ROWS: a wall down column 5, its doorway in the bottom row. A source at (0, 4), left of
    the wall, and one at (0, 7), right of it: the cells right of the wall are the right one's
    (the left one's path goes round through the doorway), though (0, 6) is as near to either
    in a straight line. Two observations at one cell get the same row."""
    grid = tiny_grid(ROWS)
    a, b = int(grid.free_index[0, 4]), int(grid.free_index[0, 7])
    voronoi = voronoi_weights(grid, np.array([a, b, b])).toarray()  # [3, N]
    right = grid.free_index[:4, 6:].ravel()  # free cells right of the wall, above the door
    assert not voronoi[0][right].any() and (voronoi[1][right] > 0).all()
    np.testing.assert_array_equal(voronoi[1], voronoi[2])
    np.testing.assert_allclose(voronoi.sum(axis=1), 1.0, rtol=1e-12)


def test_a_pocket_no_source_reaches_gets_nothing_and_warns_nothing():
    """Column 4 is walled off from the sources' part of the map: its cells get no weight (the
    rows still sum to 1 over the cells reached), and the unreached cells' infinite distances
    raise no floating-point warning."""
    grid = tiny_grid(["...#.", "...#.", "...#."])
    cells = np.array([int(grid.free_index[0, 0]), int(grid.free_index[2, 2])])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        voronoi = voronoi_weights(grid, cells).toarray()  # [2, N]
    pocket = grid.free_index[:, 4]
    assert not voronoi[:, pocket].any()
    np.testing.assert_allclose(voronoi.sum(axis=1), 1.0, rtol=1e-12)


def test_share_zero_is_todays_footprint_byte_for_byte(problem):
    grid, obs = problem
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    today = footprint_weights(grid, cells, 0.25, "gaussian")
    zero = footprint_weights(grid, cells, 0.25, "gaussian", reach_share=0.0)
    for part in ("data", "indices", "indptr"):
        assert getattr(zero, part).tobytes() == getattr(today, part).tobytes()
    plain = DataPreparation(footprint_radius=0.25, word_footprint_radius=0.0)
    off = plain.replace(footprint_reach_share=0.0)
    assert plain.to_json() == off.to_json() and "footprint_reach_share" not in off.to_json()
    a = prepared_cell_counts(grid, obs, plain)
    b = prepared_cell_counts(grid, obs, off)
    for part in ("cells", "image_counts", "word_counts"):
        assert getattr(a, part).tobytes() == getattr(b, part).tobytes()
    assert a.modalities[0].counts.tobytes() == b.modalities[0].counts.tobytes()
    none = DataPreparation()  # no footprint at all: the paper's counts, the reach share unread
    assert prepared_cell_counts(grid, obs, none).spread == {}


@pytest.mark.parametrize("radius", [0.0, 0.3])
def test_counts_with_the_reach_share_are_the_weighted_sums_factored_too(problem, radius):
    grid, obs = problem
    counts = cell_counts(grid, obs, snap_distance=0.0, footprint_radius=radius,
                         footprint_reach_share=0.4)  # fmt: skip
    image_cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    word_cells, _, _ = place_observations(grid, obs.word_xy, 0.0)
    image_w = footprint_weights(grid, image_cells, radius, reach_share=0.4).toarray()  # [T, N]
    word_w = footprint_weights(grid, word_cells, radius, reach_share=0.4).toarray()  # [U, N]
    reached = np.flatnonzero((image_w.sum(axis=0) > 0) | (word_w.sum(axis=0) > 0))
    np.testing.assert_array_equal(counts.cells, reached)
    np.testing.assert_allclose(counts.image_counts, image_w[:, reached].T @ obs.image_features)
    words = counts.word_counts.sum(axis=1)  # [M] each utterance's tokens, weighted
    lengths = np.array([len(u) for u in obs.utterances], dtype=float)  # [U]
    np.testing.assert_allclose(words, word_w[:, reached].T @ lengths)
    for name, dense in (("images", counts.image_counts), ("words", counts.word_counts)):
        np.testing.assert_allclose(counts.spread[name].dense(), dense, atol=1e-12)


def test_the_free_cell_graph_is_built_once_where_none_is_given(problem, monkeypatch):
    """footprint_weights without a graph built it in disc_weights and again for the Voronoi
    part: once now, passed to both, the weights as with a graph given."""
    grid, obs = problem
    cells, _, _ = place_observations(grid, obs.image_xy, 0.0)
    given = footprint_weights(grid, cells, 0.25, reach_share=0.5, graph=free_cell_graph(grid))
    built = []

    def counted(of):
        built.append(of)
        return free_cell_graph(of)

    monkeypatch.setattr(footprint, "free_cell_graph", counted)
    weights = footprint_weights(grid, cells, 0.25, reach_share=0.5)
    assert len(built) == 1
    for part in ("data", "indices", "indptr"):
        assert getattr(weights, part).tobytes() == getattr(given, part).tobytes()


def test_a_reach_share_alone_spreads_the_counts_and_the_observed_cells_line_says_so():
    """At radius 0 no footprint is on (has_footprint: the kernel and fov unread) but the reach
    share spreads the counts (DataPreparation.spreads, config.footprint_spreads: the one test
    of cell_counts and of the summary's observed cells line)."""
    from spcopyro.cli.common import _summary
    from spcopyro.data.model_grid import model_house
    from spcopyro.synthetic import HouseSpec, make_house

    data = preset("coarse", footprint_radius=0.0, footprint_reach_share=0.25).data
    assert not data.has_footprint and data.spreads
    # coarse's door width (since 2026-12-06) goes with its share: DataPreparation.replace sets
    # only what it is given, and a door width without a share is refused
    assert not data.replace(footprint_reach_share=0.0, footprint_reach_door_width=None).spreads
    assert footprint_spreads(0.0, 0.0, 0.25) and not footprint_spreads(0.0, 0.0, 0.0)
    assert footprint_spreads(0.5, 0.0, 0.0) and footprint_spreads(0.0, 0.5, 0.0)
    house = model_house(make_house(seed=0, spec=HouseSpec.embedded()), data.cell_size)
    lines = _summary(house, warn=False, preparation=data).splitlines()
    observed = next(x for x in lines if x.startswith("observed cells"))
    assert observed.endswith(
        " within their 0 m footprints and Voronoi cells within rooms at 1 m doors"
    )
    placed, spread = (int(x.split()[0]) for x in observed.split(maxsplit=2)[2].split("; "))
    assert spread > placed


def test_the_refinement_replaces_the_reach_share():
    settings = preset("coarse", footprint_reach_share=0.25)
    refined = refined_settings(settings, 100, 2500)
    assert refined.data.footprint_reach_share == 0.0
    assert replaced_preparation(settings, refined.data)["footprint_reach_share"] == {
        "given": 0.25, "refinement": 0.0}  # fmt: skip
    assert "footprint_reach_share" not in replaced_preparation(preset("coarse"), refined.data)


@pytest.mark.parametrize("bad", [1.0, -0.1, float("nan"), float("inf"), True, "0.5"])
def test_a_bad_reach_share_is_refused_naming_the_field_and_value(bad):
    with pytest.raises(ValueError) as caught:
        DataPreparation(footprint_reach_share=bad)
    assert f"DataPreparation.footprint_reach_share={bad!r}: must be a number in [0, 1)" in str(
        caught.value
    )
    grid = tiny_grid(["..."])
    with pytest.raises(ValueError, match=r"footprint_reach_share=.*must be a number in \[0, 1\)"):
        footprint_weights(grid, np.array([0]), 0.0, reach_share=bad)


def test_fit_reach_share_option_reaches_config_json(tmp_path):
    out = tmp_path / "fit"
    code = main(["fit", "--sweeps", "3", "--backend", "torch", "--footprint-reach-share", "0.25",
                 "--out", str(out)])  # fmt: skip
    assert code == 0
    settings = json.loads((out / "config.json").read_text())
    assert settings["data"]["footprint_reach_share"] == 0.25
    assert settings["data"]["footprint_radius"] == 0.75  # the preset's footprint, kept
