"""The warning of a weak-limit DP fit short of concept slots: its map uses at least
:data:`~spcopyro.results.map_checks.SATURATED_SLOTS` of its L concepts, so places may be merged
for want of slots (:func:`spcopyro.results.map_checks.concept_slots_warning`, logged by
``fit_house`` and ``spcopyro fit``). A default fit of a house of 960k free cells used all 120
concepts without a word."""

from __future__ import annotations

import json
import logging
from types import SimpleNamespace

import numpy as np
import pytest

from spcopyro.config import preset
from spcopyro.fit.house import fit_house, gamma_warning
from spcopyro.fit.map_warnings import log_concept_slots
from spcopyro.fit.setting_warnings import freezes
from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
from spcopyro.results import map_checks
from spcopyro.results.map_checks import REGION_AGREEMENT, SATURATED_SLOTS
from spcopyro.synthetic import make_house

START = "the map uses "


def _slots_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.getMessage().startswith(START)]


def _used(count: int, width: int = 10, rows: int = 20) -> np.ndarray:
    """``[rows, count * width]`` label image of ``count`` regions: stripes of ``width`` columns."""
    return np.repeat(np.arange(count), width)[None, :].repeat(rows, axis=0)


def concept_slots_warning(image: np.ndarray, config, *args, **kwargs) -> str | None:
    """:func:`~spcopyro.results.map_checks.concept_slots_warning` of a label image ``[H, W]``
    (-1: not a free cell) on the grid of its free cells."""
    grid = _grid_of(image)
    return map_checks.concept_slots_warning(image[grid.free], grid, config, *args, **kwargs)


def _grid_of(image: np.ndarray) -> OccupancyGrid:
    occupancy = np.where(image >= 0, FREE, OCCUPIED).astype(np.int8)  # [H, W]
    return OccupancyGrid(occupancy, 0.1, (0.0, 0.0, 0.0))


def _like_neighbours_of_image(image: np.ndarray) -> float:
    """The share of like 4-neighbour pairs counted on the image, rows then columns (the first
    version's way): the reference for the grid's pairs."""
    same = pairs = 0
    for a, b in ((image[1:, :], image[:-1, :]), (image[:, 1:], image[:, :-1])):
        both = (a >= 0) & (b >= 0)
        pairs += int(np.count_nonzero(both))
        same += int(np.count_nonzero(both & (a == b)))
    return same / pairs if pairs else 1.0


@pytest.fixture(scope="module")
def house():
    return make_house(seed=0)  # the embedded default house: 6 rooms


def test_the_embedded_house_under_a_dp_with_four_slots_warns(house, caplog):
    """Six rooms, L = 4 under the weak-limit DP: every slot in use, places merged."""
    settings = preset("coarse", num_concepts=4)
    assert settings.model.prior == "dp"
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        result = fit_house(house, settings, sweeps=300, progress=False)
    assert len(result.concepts_in_use()) == 4
    [warning] = _slots_warnings(caplog)
    assert warning.startswith("the map uses 4 of its L = 4 concept slots: the weak-limit "
                              "Dirichlet-process prior holds at most L concepts, so places may "
                              "be merged for want of slots")  # fmt: skip
    assert "num_concepts=8 (fit's --concepts 8)" in warning  # both readers' names
    assert "gamma" not in warning  # gamma 3 is above the critical 1.10 for L = 4


def test_a_finite_dirichlet_using_all_its_concepts_does_not_warn(house, caplog):
    """Under ``prior="dirichlet"`` L is the known number of concepts: all in use is no sign."""
    settings = preset("coarse", num_concepts=4, prior="dirichlet")
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        result = fit_house(house, settings, sweeps=300, progress=False)
    assert len(result.concepts_in_use()) == 4
    assert _slots_warnings(caplog) == []
    assert concept_slots_warning(_used(4), settings.model) is None


def test_the_bound_is_ninety_percent_of_l():
    config = preset("coarse").model  # L = 120, weak-limit DP
    assert SATURATED_SLOTS == 0.9 and config.num_concepts == 120
    assert concept_slots_warning(_used(6), config) is None  # the embedded house's 6 of 120
    assert concept_slots_warning(_used(107), config) is None
    warning = concept_slots_warning(_used(108), config)
    assert warning is not None and warning.startswith("the map uses 108 of its L = 120 ")
    assert "num_concepts=240 (fit's --concepts 240)" in warning
    assert ("; if that refit again fills about 90% of its 240 slots, the extra concepts are "
            "fragments rather than places (a house of 960k free cells used 218 of 240): run "
            "more sweeps (fit's --sweeps) instead") in warning  # fmt: skip
    small = preset("coarse", num_concepts=10).model
    assert concept_slots_warning(_used(8), small) is None
    assert concept_slots_warning(_used(9), small) is not None  # 9 of 10: 90%


def test_a_refined_fits_coarse_stage_using_every_slot_warns():
    """A refinement starts from the coarse map and its point estimate may join specks: 120 of
    120 on the coarse stage of a 3.9M-cell house were reported as 93."""
    config = preset("coarse").model
    assert concept_slots_warning(_used(93), config, coarse=(12, 0.25)) is None
    warning = concept_slots_warning(_used(93), config, coarse=(120, 0.25))
    assert warning is not None
    assert warning.startswith("the map uses 93 of its L = 120 concept slots (120 on its coarse "
                              "stage's 0.25 m cells)")  # fmt: skip


def test_fit_house_names_a_refined_fits_coarse_stage(house, caplog):
    """``log_concept_slots`` reads the coarse stage from ``inference["refine"]["coarse"]``."""
    settings = preset("coarse", num_concepts=4)
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        result = fit_house(house, settings, sweeps=100, progress=False, refine="always")
    coarse = result.inference["refine"]["coarse"]
    assert coarse["concepts"] == 4 and coarse["cell_size"] == pytest.approx(0.3)
    [warning] = _slots_warnings(caplog)
    used = len(result.concepts_in_use())
    assert warning.startswith(f"the map uses {used} of its L = 4 concept slots (4 on its "
                              "coarse stage's 0.3 m cells): ")  # fmt: skip


def test_labels_in_patches_fill_every_slot_whatever_l_is_and_do_not_warn():
    """A chain a few sweeps from random labels, disorder or a frozen sampler: every slot in
    use, but no regions: more slots would fill as well, so no word of L (issue: a 2-sweep fit
    at L = 10 warned)."""
    config = preset("coarse").model
    patches = np.random.default_rng(0).integers(0, 120, size=(40, 60))  # [40, 60] all in use
    assert np.unique(patches).size == 120
    assert concept_slots_warning(patches, config) is None
    assert REGION_AGREEMENT == 0.85
    assert concept_slots_warning(_used(120), config) is not None  # the same count in regions
    ragged = _used(120, width=2)  # stripes 2 cells wide: half the row pairs differ
    assert concept_slots_warning(ragged, config) is None
    holes = _used(120).copy()
    holes[:, ::2] = -1  # every other column off the free cells: only the rows' pairs count
    assert concept_slots_warning(holes, config) is not None


def test_a_short_fit_from_random_labels_does_not_warn(house, caplog):
    settings = preset("original-code", gamma=3.5, num_concepts=10)
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        result = fit_house(house, settings, sweeps=2, progress=False)
    assert len(result.concepts_in_use()) == 10
    assert _slots_warnings(caplog) == []


def _logged(image: np.ndarray, config, method: str = "gibbs") -> str | None:
    """``log_concept_slots`` of a result of ``method`` whose map is ``image``: the caller's
    reading of disorder and freezing from the fit's own warnings."""
    grid = _grid_of(image)
    result = SimpleNamespace(inference={}, config=config, method=method,
                             labels=image[grid.free], grid=grid)  # fmt: skip
    return log_concept_slots(result)


def test_below_the_critical_coupling_it_names_disorder_as_the_gamma_warning_does():
    """gamma 2.1 < ln(1 + sqrt(120)) = 2.481: where regions formed all the same (the data's
    doing), the message says the labels may be disorder's patches, as the fit's low-gamma
    warning does, and names gamma first."""
    config = preset("original-code").model
    assert gamma_warning(config) is not None  # the fit's own warning
    warning = _logged(_used(120), config)
    assert "; but with gamma = 2.1 under the critical coupling 2.481 (see its warning)" in warning
    assert "(L = 240 raises that coupling to 2.803)" in warning
    assert warning.endswith(": raise gamma (fit's --gamma) first")
    assert "is below the Potts critical coupling" not in warning  # gamma_warning's own words
    above = config.replace(gamma=3.0)
    assert gamma_warning(above) is None
    assert "gamma" not in _logged(_used(120), above)
    assert "critical" not in concept_slots_warning(_used(120), config)  # the caller's to say


def test_at_the_freezing_point_a_sampled_fit_names_the_frozen_start():
    config = preset("coarse", gamma=12.0).model
    assert freezes(config) and not freezes(config.replace(gamma=9.0))  # config_warnings' test
    warning = _logged(_used(117), config)
    assert "; but with gamma = 12, where the Gibbs sampler freezes (see its warning)" in warning
    assert warning.endswith(": lower gamma (fit's --gamma) first")
    assert "freezes" not in _logged(_used(117), config, method="cavi")  # not sampled
    assert "freezes" not in _logged(_used(117), config.replace(gamma=9.0))


def test_the_share_of_like_neighbours_is_counted_on_the_grids_pairs_as_on_the_image():
    """The Potts statistic E(C) over the grid's 4-neighbour pairs, divided by their number,
    gives the share the first version counted on the label image, holes and all."""
    rng = np.random.default_rng(1)
    images = [_used(12), _used(30, width=2), rng.integers(0, 5, size=(17, 23))]
    for image in list(images):
        holed = image.copy()
        holed[rng.random(image.shape) < 0.3] = -1  # [H, W] walls between free cells
        images.append(holed)
    for image in images:
        grid = _grid_of(image)
        share = map_checks._like_neighbours(image[grid.free], grid)
        assert share == pytest.approx(_like_neighbours_of_image(image), abs=1e-12)
    lone = np.full((3, 3), -1)
    lone[1, 1] = 0  # one free cell: no pair
    assert map_checks._like_neighbours(np.zeros(1, dtype=np.int64), _grid_of(lone)) == 1.0


def test_spcopyro_fit_prints_it_and_keeps_it_in_config_json(tmp_path, capsys):
    from spcopyro.cli.main import main

    out = tmp_path / "fit"
    argv = ["fit", "--out", str(out), "--sweeps", "300", "--no-figures", "--concepts", "4"]
    assert main(argv) == 0
    [line] = [x for x in capsys.readouterr().err.splitlines() if START in x]
    assert "of its L = 4 concept slots" in line and "(fit's --concepts 8)" in line
    said = json.loads((out / "config.json").read_text())["warnings"]
    [kept] = [x for x in said if x.startswith(START)]
    assert kept in line
