"""The reach share with the door cut in the default preset ``coarse`` (issue 21, 2026-12-06):
``footprint_reach_share=0.2`` with ``footprint_reach_door_width=1.0``, the rooms start's
``spcopyro.maps.rooms.DEFAULT_DOOR_WIDTH`` (docs/real_houses.md, "Reaching the Voronoi border").

Checked: the preset holds both and a default ``fit_house`` records them in its preparation and
config; a share of 0 given over the preset's drops the preset's door width with it
(``preset`` and ``SpCoSettings.replace``, ``spcopyro fit --footprint-reach-share 0``), while a
door width the caller gives with a share of 0 is still refused, naming both; the default fit's
summary says the cut on its data and observed-cells lines.
"""

from __future__ import annotations

import dataclasses
import json

import pytest

from spcopyro.cli.main import main
from spcopyro.config import DEFAULT_PRESET, PRESETS, DataPreparation, SpCoSettings, preset
from spcopyro.maps.rooms import DEFAULT_DOOR_WIDTH
from spcopyro.synthetic import HouseSpec, make_house

CUT = "reach share 0.2 (Voronoi cells within rooms at 1 m doors)"


def test_the_default_preset_spreads_a_fifth_within_rooms_at_the_rooms_starts_doors():
    assert DEFAULT_PRESET == "coarse"
    values = PRESETS["coarse"]
    assert values["footprint_reach_share"] == 0.2
    assert values["footprint_reach_door_width"] == DEFAULT_DOOR_WIDTH == 1.0
    data = preset().data
    assert (data.footprint_reach_share, data.footprint_reach_door_width) == (0.2, 1.0)
    assert data.footprint_reach_radius is None
    for other in ("auto", "paper-dp", "original-code"):  # the other presets: off, as before
        assert not preset(other).data.footprint_reach_share
        assert preset(other).data.footprint_reach_door_width is None


def test_a_default_fit_house_records_the_share_and_door_width():
    from spcopyro.fit.house import fit_house

    house = make_house(seed=3, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=2))
    result = fit_house(house, preset(), sweeps=3, seed=0, progress=False, init="rooms")
    assert result.preparation.footprint_reach_share == 0.2
    assert result.preparation.footprint_reach_door_width == 1.0
    saved = result.preparation.to_json()  # as config.json saves it (0 and None left out)
    assert saved["footprint_reach_share"] == 0.2
    assert saved["footprint_reach_door_width"] == 1.0


def test_a_share_of_0_over_the_presets_drops_its_door_width():
    off = preset(footprint_reach_share=0)
    assert off.data.footprint_reach_share == 0
    assert off.data.footprint_reach_door_width is None
    assert "footprint_reach_door_width" not in off.chosen
    assert "footprint_reach_door_width" not in off.data.to_json()
    replaced = preset().replace(footprint_reach_share=0.0)
    assert replaced.data.footprint_reach_door_width is None
    assert replaced.data == off.data
    # a share other than 0 keeps the preset's door width
    assert preset(footprint_reach_share=0.25).data.footprint_reach_door_width == 1.0


def test_a_door_width_given_with_a_share_of_0_is_still_refused():
    message = r"footprint_reach_door_width=1\.5: cuts the Voronoi cells of footprint_reach_share"
    with pytest.raises(ValueError, match=message):
        preset(footprint_reach_share=0, footprint_reach_door_width=1.5)
    with pytest.raises(ValueError, match=message):
        preset().replace(footprint_reach_share=0.0, footprint_reach_door_width=1.5)
    chosen = preset(footprint_reach_door_width=1.5)  # the caller's, over the preset's share
    with pytest.raises(ValueError, match=message):
        chosen.replace(footprint_reach_share=0.0)
    with pytest.raises(ValueError, match=r"footprint_reach_radius=2\.0: cuts the Voronoi"):
        preset(footprint_reach_share=0, footprint_reach_radius=2.0)


def test_a_door_width_not_the_presets_is_the_callers_though_not_in_chosen():
    """Chosen is SpCoSettings.chose's rule (refine's warning's too): set by the caller, or
    differing from the preset's value, or settings made without a preset. Such a door width
    with a share of 0 is refused, not dropped (it was dropped wherever not in ``chosen``)."""
    message = r"footprint_reach_door_width=1\.5: cuts the Voronoi cells of footprint_reach_share"
    made = SpCoSettings(
        data=DataPreparation(footprint_reach_share=0.2, footprint_reach_door_width=1.5)
    )
    with pytest.raises(ValueError, match=message):
        made.replace(footprint_reach_share=0)
    data = preset().data.replace(footprint_reach_door_width=1.5)
    other = dataclasses.replace(preset(), data=data)  # coarse's, chosen empty, 1.5 not 1 m
    assert other.preset == "coarse" and not other.chosen
    with pytest.raises(ValueError, match=message):
        other.replace(footprint_reach_share=0)
    assert not other.chose("footprint_reach_share") and other.chose("footprint_reach_door_width")


def test_the_default_fits_summary_says_the_cut_and_a_share_of_0_turns_it_off(tmp_path, capsys):
    out = tmp_path / "default"
    assert main(["fit", "--sweeps", "3", "--backend", "torch", "--refine", "never",
                 "--no-figures", "--out", str(out)]) == 0  # fmt: skip
    lines = capsys.readouterr().out.splitlines()
    (data,) = [line for line in lines if line.startswith("data ")]
    (observed,) = [line for line in lines if line.startswith("observed cells")]
    assert data.endswith(CUT), data
    assert observed.endswith("footprints and Voronoi cells within rooms at 1 m doors"), observed
    saved = json.loads((out / "config.json").read_text())["data"]
    assert (saved["footprint_reach_share"], saved["footprint_reach_door_width"]) == (0.2, 1.0)

    off = tmp_path / "off"
    assert main(["fit", "--sweeps", "3", "--backend", "torch", "--footprint-reach-share", "0",
                 "--no-figures", "--out", str(off)]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    assert "reach share" not in printed and "Voronoi" not in printed
    saved = json.loads((off / "config.json").read_text())["data"]
    assert "footprint_reach_share" not in saved and "footprint_reach_door_width" not in saved
