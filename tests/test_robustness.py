"""Tests of the stability and sensitivity studies (tiny sweeps on a small synthetic house).

The stability study runs every setting with 2 chains on 2 houses (about 15 s): the tests that read
it are in the slow lane.
"""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import pytest

from spcopyro.experiments import robustness
from spcopyro.experiments.robustness import (
    ANNEAL_FRACTION,
    REFERENCE_SETTING,
    SENSITIVITY_GRID,
    STABILITY_SETTINGS,
    best_chain,
    robustness_markdown,
    sensitivity_study,
    spread,
    stability_study,
    write_robustness,
)
from spcopyro.synthetic import HouseSpec

SMALL = HouseSpec(height=30, width=40, num_rooms=2, num_open_plan=0, min_room_size=10)
SEEDS = (0, 1)


@pytest.fixture(scope="module")
def stability() -> dict:
    return stability_study(sweeps=10, seeds=SEEDS, chains=2, spec=SMALL)


@pytest.fixture(scope="module")
def sensitivity() -> dict:
    return sensitivity_study(sweeps=3, seeds=(0,), spec=SMALL)


def test_spread_by_hand() -> None:
    assert spread([1.0, 2.0, 3.0]) == {"mean": 2.0, "sd": 1.0, "min": 1.0}
    single = spread([0.25])
    assert single["mean"] == 0.25 and single["min"] == 0.25 and math.isnan(single["sd"])
    with pytest.raises(ValueError, match="no values"):
        spread([])


def test_best_chain_picks_the_highest_best_objective() -> None:
    chains = [SimpleNamespace(best_objective=v) for v in (5.0, 4.0, 6.0)]
    assert best_chain(chains) == 2
    ties = [SimpleNamespace(best_objective=7.0), SimpleNamespace(best_objective=7.0)]
    assert best_chain(ties) == 0
    with pytest.raises(ValueError, match="at least one chain"):
        best_chain([])


@pytest.mark.slow
def test_stability_rows_and_ranges(stability: dict) -> None:
    assert list(stability["settings"]) == list(STABILITY_SETTINGS)
    assert stability["seeds"] == list(SEEDS) and stability["chains"] == 2
    for row in stability["settings"].values():
        for mode in ("single", "best_of_chains", "chain_ari"):
            assert len(row[mode]) == len(SEEDS)
            assert all(-1.0 <= v <= 1.0 for v in row[mode])
            summary = row["summary"][mode]
            assert summary["min"] == min(row[mode])
            assert summary["mean"] == pytest.approx(sum(row[mode]) / 2)
            assert summary["sd"] == pytest.approx(abs(row[mode][0] - row[mode][1]) / math.sqrt(2))
        assert [len(c) for c in row["chains"]] == [2, 2]
    for name, setting in STABILITY_SETTINGS.items():
        row = stability["settings"][name]
        assert row["anneal_sweeps"] == (
            int(ANNEAL_FRACTION * stability["sweeps"]) if setting.anneal else 0
        )
        assert row["cluster_moves"] == setting.cluster_moves
    assert any(s.anneal for s in STABILITY_SETTINGS.values())
    assert any(s.cluster_moves > 0 for s in STABILITY_SETTINGS.values())


@pytest.mark.slow
def test_stability_best_of_chains_is_the_highest_log_joint(stability: dict) -> None:
    for row in stability["settings"].values():
        for seed_index, chains in enumerate(row["chains"]):
            joints = [c["best_log_joint"] for c in chains]
            expected = chains[joints.index(max(joints))]["ari"]
            assert row["best_of_chains"][seed_index] == expected
            assert row["single"][seed_index] == chains[0]["ari"]


@pytest.mark.slow
def test_stability_verdict_matches_the_sds(stability: dict) -> None:
    reference = stability["settings"][REFERENCE_SETTING]["summary"]["single"]["sd"]
    assert stability["reference_sd"] == reference
    expected = [
        f"{name} / {mode}"
        for name, setting in STABILITY_SETTINGS.items()
        if setting.method != "B-dirichlet"
        for mode in ("single", "best_of_chains")
        if stability["settings"][name]["summary"][mode]["sd"] <= reference
    ]
    assert stability["at_least_as_stable"] == expected


def test_sensitivity_every_value_present(sensitivity: dict) -> None:
    parameters = sensitivity["parameters"]
    assert list(parameters) == list(SENSITIVITY_GRID)
    for name, values in SENSITIVITY_GRID.items():
        assert [row["value"] for row in parameters[name]] == list(values)
        for row in parameters[name]:
            assert len(row["ari"]) == 1 and -1.0 <= row["ari"][0] <= 1.0
            assert 1 <= row["concepts"][0] <= 120
    assert sensitivity["critical_gamma"] == pytest.approx(math.log(1 + math.sqrt(120)))
    # gamma 3, beta 0.1, chi 1 and alpha 1e7 are all the base configuration: one fit, shared.
    base_rows = [
        parameters["gamma"][2],
        parameters["beta"][0],
        parameters["chi"][0],
        parameters["alpha"][2],
    ]
    assert all(r["ari"] == base_rows[0]["ari"] for r in base_rows)
    assert all(r["concepts"] == base_rows[0]["concepts"] for r in base_rows)


@pytest.mark.slow
def test_markdown_has_every_row(stability: dict, sensitivity: dict) -> None:
    markdown = robustness_markdown(stability, sensitivity)
    for name in STABILITY_SETTINGS:
        assert f"| {name} |" in markdown
    assert markdown.count("| gamma |") == 4 and markdown.count("| alpha |") == 3
    assert "| alpha | 1e+07 |" in markdown


@pytest.mark.slow
def test_write_robustness_files(tmp_path, monkeypatch, stability, sensitivity) -> None:
    # The studies themselves are tested above; here only what write_robustness writes.
    monkeypatch.setattr(robustness, "stability_study", lambda **_: stability)
    monkeypatch.setattr(robustness, "sensitivity_study", lambda **_: sensitivity)
    markdown = write_robustness(tmp_path, sweeps=4, seeds=SEEDS, chains=2, spec=SMALL)
    assert (tmp_path / "robustness.md").read_text() == markdown
    assert (tmp_path / "figures" / "stability.png").stat().st_size > 10_000
    assert "figures/stability.png" in markdown
    payload = json.loads((tmp_path / "robustness.json").read_text())
    assert set(payload) == {"stability", "sensitivity"}
    assert payload["stability"]["chains"] == 2


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="chains"):
        stability_study(sweeps=2, seeds=(0,), chains=1, spec=SMALL)
    with pytest.raises(ValueError, match="seeds"):
        stability_study(sweeps=2, seeds=(), chains=2, spec=SMALL)
    with pytest.raises(ValueError, match="sweeps"):
        sensitivity_study(sweeps=0, seeds=(0,), spec=SMALL)
    with pytest.raises(ValueError, match="'kappa'"):
        sensitivity_study(sweeps=2, seeds=(0,), grid={"kappa": (1.0,)}, spec=SMALL)


def test_heldout_sensitivity_on_a_public_house(dataset_root):
    from spcopyro.experiments.robustness import heldout_sensitivity, heldout_sensitivity_markdown

    grid = {"gamma": (3.0, 4.0), "beta": (0.1,)}
    result = heldout_sensitivity(dataset_root, sweeps=3, houses=["room1dk5"], grid=grid)
    assert [r["value"] for r in result["parameters"]["gamma"]] == [3.0, 4.0]
    for rows in result["parameters"].values():
        for row in rows:
            assert 0.0 <= row["top1"] <= row["top3"] <= 1.0
            assert row["distance_m"] >= 0.0
    # gamma 3 and beta 0.1 are both the base: fitted once, the same scores.
    assert result["parameters"]["gamma"][0]["top1"] == result["parameters"]["beta"][0]["top1"]
    markdown = heldout_sensitivity_markdown(result)
    assert "| gamma | 3 |" in markdown and "| beta | 0.1 |" in markdown


@pytest.mark.slow
def test_stability_figure_without_the_log_joint_panel(stability: dict, tmp_path) -> None:
    """The right panel needs the named method's settings; without them it is left empty."""
    from spcopyro.experiments.figures import plot_stability

    only = dict(stability, settings={REFERENCE_SETTING: stability["settings"][REFERENCE_SETTING]})
    assert plot_stability(only, tmp_path / "s.png").stat().st_size > 5_000
