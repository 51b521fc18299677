"""The remaining silent gaps of a fit and a map tour on a large map have a bar (helper 217).

On a 2000 x 2000-cell warehouse map at 0.05 m (3.07 million free cells, 400 images,
``spcopyro fit --sweeps 50``; timestamps on stderr, a loaded 2-core machine) the terminal showed
nothing for 7.5 s in the point estimate's first step (renaming the samples and stacking them,
before the first sorted one) and 2.5 s over the agreement map; ``spcopyro simulate --map``
segments the map's rooms (5-15 s) with no bar. Each has a bar from SETUP_PROGRESS_CELLS free
cells (monkeypatched to 0 here, so small maps count as large).
"""

from __future__ import annotations

import numpy as np
import pytest

import spcopyro.results.point_estimate as pe
from spcopyro._util import progress
from spcopyro.config import preset
from spcopyro.fit.house import fit_house
from spcopyro.synthetic import HouseSpec, make_house


@pytest.fixture
def large(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every map counts as large, and bars are on (they are off under $CI)."""
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setattr(progress, "SETUP_PROGRESS_CELLS", 0)


def test_the_point_estimate_bar_counts_each_sample_as_it_is_renamed(monkeypatch):
    """Renaming every sample 0..J-1 ran before the bar's first step (all S renamings, then the
    stack of the [S, N] codes): the bar stood at 0 for 7.5 s on the warehouse map."""
    from tqdm.auto import tqdm

    compact, seen = pe.compact, []

    def watched(labels):
        seen.append([bar.n for bar in tqdm._instances])
        return compact(labels)

    monkeypatch.setattr(pe, "compact", watched)
    samples = np.random.default_rng(3).integers(0, 4, (6, 300))
    expected = pe.point_estimate(samples, "vi", max_clusters=10, progress=False)
    seen.clear()
    found = pe.point_estimate(samples, "vi", max_clusters=10, progress=True)
    assert [bars[0] for bars in seen[:6]] == list(range(6))  # one step per sample renamed
    np.testing.assert_array_equal(found.labels, expected.labels)
    assert found.expected_loss == expected.expected_loss


def test_the_agreement_map_has_a_bar_on_a_large_map(large, capsys):
    house = make_house(seed=1, spec=HouseSpec(height=30, width=40, num_rooms=2, num_trials=2))
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    result = fit_house(house, settings, sweeps=20, progress=True, marginal_samples=5,
                       point_estimate="vi")  # fmt: skip
    assert result.agreement is not None
    err = capsys.readouterr().err
    assert "agreement map" in err
    assert "5/5" in err.split("agreement map")[-1]  # one step per kept sample


def test_simulate_on_a_map_shows_a_bar_while_it_segments_the_rooms(large, capsys):
    from spcopyro.robot.map_simulation import MapTour, simulate_on_map

    grid = make_house(seed=0, spec=HouseSpec(height=30, width=36, num_rooms=2)).grid
    simulate_on_map(grid, tour=MapTour(door_width=1.0))
    err = capsys.readouterr().err
    assert "room segments at 1 m doors" in err
    assert "/" in err.split("room segments at 1 m doors")[-1]


def test_room_segments_show_a_bar_by_default_on_a_large_map(large, capsys):
    """room_segments' default (None) is a bar on a large map, as auto_door_width's room counts
    have: the fit's rooms start and baseline (F) call it without progress."""
    from spcopyro.baselines.geometry import geometry_semantic_map, room_segments

    house = make_house(seed=0, spec=HouseSpec(height=30, width=36, num_rooms=2))
    room_segments(house.grid, door_width=1.0)
    assert "room segments at 1 m doors" in capsys.readouterr().err
    geometry_semantic_map(house.grid, house.observations, door_width=1.0)
    assert "room segments at 1 m doors" in capsys.readouterr().err


def test_room_count_stays_quiet_where_it_segments_the_rooms(large, capsys, monkeypatch):
    """room_count's fallback (a min_room_area a hair above whole cells) segments the map once
    per candidate width of auto_door_width, whose own bar counts the widths: no bar of its own,
    as its level-set counts have none."""
    from spcopyro.maps import rooms as geometry  # the segmentation, re-exported by (F)'s

    monkeypatch.setattr(geometry, "_counts_are_created", lambda res, area: False)
    grid = make_house(seed=0, spec=HouseSpec(height=30, width=36, num_rooms=2)).grid
    assert geometry.room_count(grid, 1.0, 1.0) >= 1
    assert "room segments" not in capsys.readouterr().err


def test_a_small_map_stays_quiet(monkeypatch, capsys):
    """Below SETUP_PROGRESS_CELLS free cells none of these bars shows, bars on (CI unset): the
    agreement map's (a fit with progress and marginal samples) and the room segments' (a map
    tour, room_segments' default, baseline (F))."""
    from spcopyro.baselines.geometry import geometry_semantic_map, room_segments
    from spcopyro.robot.map_simulation import MapTour, simulate_on_map

    monkeypatch.delenv("CI", raising=False)
    house = make_house(seed=1, spec=HouseSpec(height=30, width=40, num_rooms=2, num_trials=2))
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    result = fit_house(house, settings, sweeps=20, progress=True, marginal_samples=5,
                       point_estimate="vi")  # fmt: skip
    assert result.agreement is not None  # the agreement map was made, without a bar
    simulate_on_map(house.grid, tour=MapTour(door_width=1.0))
    room_segments(house.grid, door_width=1.0)
    geometry_semantic_map(house.grid, house.observations, door_width=1.0)
    err = capsys.readouterr().err
    assert "point estimate" in err  # bars are on: the point estimate's is not a setup bar
    assert "agreement map" not in err and "room segments" not in err
