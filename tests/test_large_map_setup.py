"""A fit's setup: its summary counts the observations as its model data do (the same snap
distance, the footprint counts spread once per fit), and on a large map a progress bar while
they are spread (docs/variational.md, "From spcopyro fit on a large map")."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import spcopyro._util.progress as progress_module
import spcopyro.data.counts as counts_module
from spcopyro.cli.main import main
from spcopyro.config import preset
from spcopyro.data import DEFAULT_SNAP_DISTANCE, prepared_cell_counts
from spcopyro.data.footprint import shared_footprints
from spcopyro.data.model_grid import model_house
from spcopyro.synthetic import HouseSpec, make_house


@pytest.fixture
def spreads(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The free cells of every map whose observations are spread over their footprints."""
    calls: list[int] = []
    spread = counts_module._with_footprint

    def counted(plain, grid, *args, **kwargs):
        calls.append(int(grid.num_free))
        return spread(plain, grid, *args, **kwargs)

    monkeypatch.setattr(counts_module, "_with_footprint", counted)
    return calls


def test_fit_spreads_the_footprints_once(
    tmp_path, spreads: list[int], capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``spcopyro fit``'s summary line "observed cells ... within their 0.75 m footprints" and its
    model data read the same spread counts: computed once (twice before, 24 s each at 10^6
    cells), and the summary's number is still the fit's observed cells. Once fitted, the spread
    counts are not kept while the outputs are written."""
    import spcopyro.cli.fit as fit_module
    import spcopyro.data.footprint as footprint_module

    kept_while_writing: list[int] = []
    write = fit_module.write_outputs

    def writing(*args, **kwargs):
        kept_while_writing.append(len(footprint_module._SHARED.get()))
        return write(*args, **kwargs)

    monkeypatch.setattr(fit_module, "write_outputs", writing)
    out = tmp_path / "out"
    argv = ["fit", "--out", str(out), "--sweeps", "2", "--refine", "never", "--no-figures"]
    assert main(argv) == 0
    assert len(spreads) == 1, f"footprints spread {len(spreads)} times"
    assert kept_while_writing == [0]
    spreads.clear()
    printed = capsys.readouterr().out
    line = next(x for x in printed.splitlines() if x.startswith("observed cells"))
    data = preset().data
    model = model_house(make_house(seed=0, spec=HouseSpec.embedded()), data.cell_size)
    fresh = prepared_cell_counts(model.grid, model.observations, data, warn=False)
    assert f"; {len(fresh.cells)} within their 0.75 m footprints" in line


@pytest.mark.parametrize("snap", [0.0, DEFAULT_SNAP_DISTANCE])
def test_the_summary_places_the_observations_with_the_fit_s_snap_distance(snap: float) -> None:
    """The summary's placement and observed-cells lines are the fit's own counts' under its
    snap distance: an image moved onto a wall cell beside free space is left out with snap
    distance 0 (as the fit leaves it out, and warns) and snapped with the default. The summary
    placed the observations with the default 0.25 m whatever the fit's ``--snap-distance``
    (room1dk5, ``--snap-distance 0.05``: "15 snapped, 0 unplaced (snap distance 0.25 m)" beside
    the fit's warning that 10 images were left out)."""
    from spcopyro.cli.common import _summary
    from spcopyro.maps.grid import OCCUPIED

    house = make_house(seed=0, spec=HouseSpec.embedded())
    grid, obs = house.grid, house.observations
    walls = grid.occupancy == OCCUPIED  # [H, W]
    beside = np.zeros_like(walls)  # [H, W] a wall cell with a free 4-neighbour
    beside[1:] |= grid.free[:-1]
    beside[:-1] |= grid.free[1:]
    beside[:, 1:] |= grid.free[:, :-1]
    beside[:, :-1] |= grid.free[:, 1:]
    wall = np.argwhere(walls & beside)[0]  # [2] row, col
    image_xy = obs.image_xy.copy()  # [T, 2]
    image_xy[0] = grid.cell_to_world(wall[None])[0]
    house = dataclasses.replace(house, observations=dataclasses.replace(obs, image_xy=image_xy))
    data = dataclasses.replace(preset("paper-dp").data, snap_distance=snap)
    counts = prepared_cell_counts(house.grid, house.observations, data, warn=False)
    p = counts.placement
    assert (p.images_snapped, p.images_unplaced) == ((0, 1) if snap == 0 else (1, 0))
    lines = _summary(house, warn=False, preparation=data)
    placement = next(x for x in lines.splitlines() if x.startswith("placement"))
    assert placement.startswith(
        f"placement        images: {p.images_on_free} on free cells, {p.images_snapped} "
        f"snapped, {p.images_unplaced} unplaced;"
    )
    assert f"(snap distance {snap} m)" in placement
    observed = next(x for x in lines.splitlines() if x.startswith("observed cells"))
    assert observed == f"observed cells   {len(counts.cells)} (where observations were placed)"


def test_shared_footprints_reuses_only_the_same_inputs(spreads: list[int]) -> None:
    """Within :func:`shared_footprints` the same grid, observations and preparation spread once
    and give the same counts as outside it; another preparation, or outside it, spreads again."""
    house = make_house(seed=0)
    data = preset("original-code").data
    data = dataclasses.replace(data, footprint_radius=0.5)
    plain = prepared_cell_counts(house.grid, house.observations, data)
    assert len(spreads) == 1
    with shared_footprints():
        first = prepared_cell_counts(house.grid, house.observations, data, warn=False)
        again = prepared_cell_counts(house.grid, house.observations, data)
        assert again is first
        assert len(spreads) == 2
        wider = dataclasses.replace(data, footprint_radius=1.0)
        other = prepared_cell_counts(house.grid, house.observations, wider)
        assert len(spreads) == 3
        assert len(other.cells) > len(first.cells)
    np.testing.assert_array_equal(first.cells, plain.cells)
    np.testing.assert_allclose(first.image_counts, plain.image_counts, rtol=0, atol=0)
    np.testing.assert_allclose(first.word_counts, plain.word_counts, rtol=0, atol=0)
    prepared_cell_counts(house.grid, house.observations, data)
    assert len(spreads) == 4


def test_large_map_shows_a_footprint_bar(monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    """From SETUP_PROGRESS_CELLS free cells the spreading shows a bar on stderr, with the
    footprint, the map's size and the observed cells done; below it nothing."""
    monkeypatch.delenv("CI", raising=False)
    house = make_house(seed=0)
    data = preset().data
    prepared_cell_counts(house.grid, house.observations, data, warn=False)
    assert "footprints" not in capsys.readouterr().err
    monkeypatch.setattr(progress_module, "SETUP_PROGRESS_CELLS", house.grid.num_free)
    counts = prepared_cell_counts(house.grid, house.observations, data, warn=False)
    err = capsys.readouterr().err
    obs = house.observations
    sources = sum(len(np.unique(c)) for c in (
        _cells(house, obs.image_xy, data), _cells(house, obs.word_xy, data)))  # fmt: skip
    assert f"0.75 m footprints on {house.grid.num_free:,} free cells" in err
    assert f"{sources}/{sources}" in err
    assert f"summing the counts on the {len(counts.cells):,} cells they reach" in err


def _cells(house, xy: np.ndarray, data) -> np.ndarray:
    """The free indices the observations at ``xy`` [T, 2] are placed on (placed ones only)."""
    from spcopyro.data.placement import place_observations

    cell, _, _ = place_observations(house.grid, xy, data.snap_distance)
    return cell[cell >= 0]


def test_large_map_shows_the_memoized_vi_setup(monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    """memoized VI's memo and coefficients (tens of seconds at 10^6 cells, before its passes'
    bar) count their steps on a bar from SETUP_PROGRESS_CELLS free cells; not below, nor with
    progress=False."""
    import torch

    from spcopyro.fit.house import prepare_model_data
    from spcopyro.guides.memoized import StochasticOptions, compact_initial_q, start_state

    monkeypatch.delenv("CI", raising=False)
    house = make_house(seed=0)
    settings = preset("original-code")
    _, data = prepare_model_data(house, settings)
    config = settings.model
    options = StochasticOptions(block_size=16)
    q = compact_initial_q(data, config, torch.Generator().manual_seed(0))
    start_state(data, config, q, options)
    assert "memoized VI setup" not in capsys.readouterr().err
    monkeypatch.setattr(progress_module, "SETUP_PROGRESS_CELLS", data.num_free)
    start_state(data, config, q, options, progress=False)
    assert "memoized VI setup" not in capsys.readouterr().err
    state = start_state(data, config, q, options)
    err = capsys.readouterr().err
    chunks = sum(-(-len(data.obs_cells) // max(1, 65536 // m.counts.shape[-1]))
                 for m in data.modalities if config.uses(m.name))  # fmt: skip
    steps = state.blocks.num_blocks + chunks
    assert f"memoized VI setup on {data.num_free:,} cells" in err
    assert f"{steps}/{steps}" in err
