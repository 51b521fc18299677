"""Tests of the stability and sensitivity studies (tiny sweeps on a small synthetic house), run
as the shipped studies ``stability`` and ``sensitivity`` (issue 26), and the numbers of the
loops they replaced (experiment_side_old_records.json).

The stability study runs every setting with 2 chains on 2 houses: the tests that read it are in
the slow lane.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from fake_dataset import fake_dataset

from spcopyro.experiments.robustness import (
    ANNEAL_FRACTION,
    REFERENCE_SETTING,
    SENSITIVITY_GRID,
    STABILITY_SETTINGS,
    robustness_markdown,
    spread,
    stability_summary,
)
from spcopyro.fit.house import best_chain
from spcopyro.study.robustness import robustness_studies, write_robustness
from spcopyro.synthetic import HouseSpec

SMALL = HouseSpec(height=30, width=40, num_rooms=2, num_open_plan=0, min_room_size=10)
SEEDS = (0, 1)
OLD_RECORDS = Path(__file__).with_name("experiment_side_old_records.json")
"""What the stability, sensitivity and side studies' own loops wrote before issue 26."""


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> tuple[Path, str]:
    """The robustness studies on the small house, 10 sweeps, 2 chains: (out, markdown)."""
    out = tmp_path_factory.mktemp("robustness")
    return out, write_robustness(out, sweeps=10, seeds=SEEDS, chains=2, spec=SMALL)


@pytest.fixture(scope="module")
def stability(written) -> dict:
    return json.loads((written[0] / "robustness.json").read_text())["stability"]


@pytest.fixture(scope="module")
def sensitivity(written) -> dict:
    return json.loads((written[0] / "robustness.json").read_text())["sensitivity"]


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
            assert len(row["ari"]) == len(SEEDS) and -1.0 <= row["ari"][0] <= 1.0
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
def test_write_robustness_files(written) -> None:
    out, markdown = written
    assert (out / "robustness.md").read_text() == markdown
    assert (out / "figures" / "stability.png").stat().st_size > 10_000
    assert "figures/stability.png" in markdown
    payload = json.loads((out / "robustness.json").read_text())
    assert set(payload) == {"stability", "sensitivity"}  # no dataset: no held-out sensitivity
    assert payload["stability"]["chains"] == 2
    for name in ("stability", "sensitivity"):  # each a study, cached in out/robustness/
        assert (out / "robustness" / name / "results.csv").is_file()
    lines: list[str] = []
    again = write_robustness(out, sweeps=10, seeds=SEEDS, chains=2, spec=SMALL,
                             report=lines.append)  # fmt: skip
    assert again == markdown and all(line.startswith("nothing to run") for line in lines)


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="chains"):
        robustness_studies(sweeps=2, seeds=(0,), chains=1)
    with pytest.raises(ValueError, match="seeds"):
        robustness_studies(sweeps=2, seeds=(), chains=2)
    with pytest.raises(ValueError, match="sweeps"):
        robustness_studies(sweeps=0, seeds=(0,))


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (dict(sweeps=True, seeds=(0,)), "sweeps must be a positive integer, got True"),
        (dict(sweeps=2, seeds=(0,), chains=True), "chains must be an integer >= 2"),
    ],
)
def test_a_bool_is_no_count_of_sweeps_or_chains(arguments, message) -> None:
    """True is an int: ``sweeps=True`` ran one sweep per setting (chains=True was refused, being
    < 2, by the same check)."""
    with pytest.raises(ValueError, match=message):
        robustness_studies(**arguments)


def test_shipped_studies_are_the_former_grids() -> None:
    stability, sensitivity = robustness_studies(sweeps=1000, seeds=(0, 1, 2), chains=3)
    assert [v.name for v in stability.variants] == list(STABILITY_SETTINGS)
    for variant in stability.variants:
        setting = STABILITY_SETTINGS[variant.name]
        options = dict(variant.options)
        assert options.get("anneal_sweeps", 0) == (200 if setting.anneal else 0)
        assert options.get("cluster_moves", 0.0) == setting.cluster_moves
        assert dict(variant.fit).get("init", "random") == setting.init
    assert [(d.house_seed, d.seeds) for d in stability.data] == [
        (s, (s, s + 1000, s + 2000)) for s in (0, 1, 2)
    ]
    names = [v.name for v in sensitivity.variants]
    assert names == [f"{p} {v:g}" for p, values in SENSITIVITY_GRID.items() for v in values]
    assert len(sensitivity.data) == 6 and sensitivity.seeds == (0, 1, 2)


def test_sensitivity_scores_the_public_houses_asked_for() -> None:
    """``public_houses`` replaces the file's five, each with its three held-out folds (the
    sensitivity ran all five under ``spcopyro experiment --houses room1dk5 --robustness``)."""
    _, five = robustness_studies(sweeps=1000)
    assert [d.name for d in five.data if d.kind == "public"] == [
        "room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4"
    ]  # fmt: skip
    _, same = robustness_studies(sweeps=1000, public_houses=[d.name for d in five.data[1:]])
    assert same.data == five.data  # the same cells: a cached run is not run again
    _, one = robustness_studies(sweeps=1000, public_houses=["room1dk5"])
    assert [(d.name, d.kind, d.heldout, d.seeds) for d in one.data] == [
        ("dense", "synthetic", False, None), ("room1dk5", "public", True, (0, 1, 2))
    ]  # fmt: skip
    _, none = robustness_studies(sweeps=1000, public=False, public_houses=["room1dk5"])
    assert [d.kind for d in none.data] == ["synthetic"]


def test_experiment_robustness_gets_the_tables_public_houses(tmp_path, monkeypatch) -> None:
    """``spcopyro experiment --houses H --robustness`` runs the sensitivity on H (the table's
    public houses), not on all five."""
    import spcopyro.study.experiment as experiment
    import spcopyro.study.robustness as robustness
    from spcopyro.cli.main import main

    asked = {}

    def run_experiment(out, study, **kwargs):  # the table, not run: its houses are asked
        Path(out).mkdir(parents=True)
        (Path(out) / "table.md").write_text("table\n")
        return {"figures": [], "settings": {"seeds": 2}, "failed": 0}

    def write(out, **kwargs):
        asked.update(kwargs)
        return "robustness"

    monkeypatch.setattr(experiment, "run_experiment", run_experiment)
    monkeypatch.setattr(robustness, "write_robustness", write)
    root = fake_dataset(tmp_path / "data", "room1dk5", "room2ldk4")  # --houses' houses
    code = main(["experiment", "--out", str(tmp_path / "out"), "--data", str(root), "--houses",
                 "room1dk5", "room2ldk4", "--robustness"])  # fmt: skip
    assert code == 0
    assert asked["public_houses"] == ["room1dk5", "room2ldk4"]
    assert asked["dataset_root"] is not None and asked["seeds"] == (0, 1)


def _same(old: object, new: object, where: str = "") -> None:
    """Equal JSON values, NaN equal to NaN, floats to a relative 1e-9: the compiled log joint
    sums with fastmath, so its last bits follow the CPU (test_pinned_outputs' fourth change;
    recorded on another machine, best_log_joint here differed by 1e-11 relative)."""
    if isinstance(old, dict):
        assert isinstance(new, dict) and set(old) == set(new), where
        for key in old:
            _same(old[key], new[key], f"{where}/{key}")
    elif isinstance(old, list):
        assert isinstance(new, list) and len(old) == len(new), where
        for k, (a, b) in enumerate(zip(old, new, strict=True)):
            _same(a, b, f"{where}[{k}]")
    elif isinstance(old, float) and math.isnan(old):
        assert isinstance(new, float) and math.isnan(new), where
    elif isinstance(old, float):
        assert new == pytest.approx(old, rel=1e-9), where
    else:
        assert old == new, where


def test_the_studies_give_the_old_loops_numbers(tmp_path) -> None:
    """Stability and sensitivity on the default house, as studies: every number the former
    loops wrote for the same seeds, chains and sweeps (the public houses: the slow test)."""
    old = json.loads(OLD_RECORDS.read_text())["robustness"]
    write_robustness(tmp_path, sweeps=20, seeds=(0, 1), chains=2)
    new = json.loads((tmp_path / "robustness.json").read_text())
    _same(old["stability"], new["stability"])
    _same(old["sensitivity"], new["sensitivity"])


@pytest.mark.slow
def test_heldout_sensitivity_gives_the_old_loops_numbers(tmp_path, dataset_root) -> None:
    old = json.loads(OLD_RECORDS.read_text())["robustness"]
    markdown = write_robustness(tmp_path, sweeps=20, seeds=(0, 1), chains=2,
                                dataset_root=dataset_root)  # fmt: skip
    new = json.loads((tmp_path / "robustness.json").read_text())
    _same(old, new)
    assert "| gamma | 3 |" in markdown and "## Sensitivity on the public houses" in markdown


@pytest.mark.slow
def test_stability_figure_without_the_log_joint_panel(stability: dict, tmp_path) -> None:
    """The right panel needs the named method's settings; without them it is left empty."""
    from spcopyro.experiments.figures import plot_stability

    only = dict(stability, settings={REFERENCE_SETTING: stability["settings"][REFERENCE_SETTING]})
    assert plot_stability(only, tmp_path / "s.png").stat().st_size > 5_000


def test_one_seed_is_not_judged_stable_or_not() -> None:
    """With one house the sds are nan: the report said "sd ... <= nan ...: none" (no setting at
    least as stable), a verdict no data supports, and printed "nan" in the sd columns."""
    rows = {
        name: {"method": method, "single": [0.5], "best_of_chains": [0.6], "chain_ari": [0.9]}
        for name, method in ((REFERENCE_SETTING, "B-dirichlet"), ("A-dp random", "A-dp"))
    }
    stability = stability_summary(rows, sweeps=10, seeds=[0], chains=3)
    sensitivity = {"base": {"preset": "original-code", "gamma": 3.0}, "critical_gamma": 2.48,
                   "seeds": [0], "parameters": {}}  # fmt: skip
    markdown = robustness_markdown(stability, sensitivity)
    assert "| A-dp random | 0.500 | — | 0.500 | 0.600 | — | 0.600 | 0.900 | 0.900 |" in markdown
    assert "<= —, that of B-dirichlet random / single): not judged: one house" in markdown
    assert "nan" not in markdown and "): none." not in markdown


def test_the_stability_legend_hides_no_point() -> None:
    """The left panel's legend sat in its lower left corner, over the last settings' chains at
    a low ARI (a map of one concept, or 10 sweeps from random labels)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.experiments.figures import stability_figure

    def row(ari: float) -> dict:  # three chains around ``ari``
        chains = [[{"ari": ari + d, "best_log_joint": d} for d in (0.0, 0.02, 0.04)]]
        return {"method": "B-dirichlet", "single": [ari], "best_of_chains": [ari + 0.02],
                "chains": chains}  # fmt: skip

    # as the stability study at a smoke budget: two settings near 0.9, the others near 0.05
    aris = [0.05, 0.05, 0.05, 0.9, 0.9, 0.05, 0.05, 0.05, 0.05]
    settings = {f"setting {k}": row(ari) for k, ari in enumerate(aris)}
    fig = stability_figure({"settings": settings, "chains": 3, "seeds": [0], "sweeps": 10})
    FigureCanvasAgg(fig).draw()
    left = fig.axes[0]
    legend = left.get_legend().get_window_extent()
    points = np.concatenate([left.transData.transform(c.get_offsets()) for c in left.collections
                             if len(c.get_offsets())])  # fmt: skip
    assert len(points) == 9 * 5
    inside = [p for p in points if legend.contains(*p)]
    assert not inside, inside
