"""``spcopyro experiment``: the comparison table and figures, end to end on a smoke run of its
shipped study (issue 26), and the numbers of the loop it replaced."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fake_dataset import fake_dataset
from stale_cells import STALE_DIGEST, mark_stale

from spcopyro.cli.main import main
from spcopyro.experiments.methods import (
    METHOD_LABELS,
    METHODS,
    REGISTRY,
    SPCO_METHODS,
    fit_spco,
    register,
    spco_settings,
)
from spcopyro.experiments.table import PUBLIC_CATEGORIES, PUBLIC_SCORES, table_markdown
from spcopyro.fit.house import fit_house
from spcopyro.study.experiment import EXPERIMENT, EXPERIMENT_QUICK, experiment_study, run_experiment
from spcopyro.study.maps import load_label_map
from spcopyro.study.spec import load_study
from spcopyro.study.table import read_table
from spcopyro.synthetic import HouseSpec, make_house

OLD_SIDE_RECORDS = Path(__file__).with_name("experiment_side_old_records.json")
"""What the side studies' and robustness' own loops wrote before issue 26."""
OLD_RECORDS = Path(__file__).with_name("experiment_old_records.json")
"""The per-seed and per-fold records (times left out) of the experiment's own loop before it
became a study (issue 26), for the shipped quick study with room1dk5."""


def test_methods_and_their_configs():
    assert METHODS == (
        "A-dp",
        "A-orig-g3",
        "B-dirichlet",
        "C-spcoa",
        "D-cnn",
        "E-nearest",
        "F-geometry",
    )
    assert set(METHOD_LABELS) == set(METHODS) and tuple(REGISTRY) == METHODS
    assert SPCO_METHODS == ("A-dp", "A-orig-g3", "B-dirichlet")
    assert all(REGISTRY[key].spcomapping == (key in SPCO_METHODS) for key in METHODS)
    with pytest.raises(ValueError, match="registered already"):
        register(REGISTRY["A-dp"])
    dp = spco_settings("A-dp", None).model
    assert (dp.prior, dp.gamma, dp.num_concepts, dp.alpha, dp.beta, dp.chi) == (
        "dp",
        4.0,
        120,
        1e8,
        500.0,
        1e4,
    )
    orig = spco_settings("A-orig-g3", None)
    model = orig.model
    assert (model.prior, model.gamma, model.beta, model.chi, orig.data.feature_scaling) == (
        "dp",
        3.0,
        0.1,
        1.0,
        "floor100",
    )
    dirichlet = spco_settings("B-dirichlet", 6).model
    assert (dirichlet.prior, dirichlet.num_concepts, dirichlet.gamma) == ("dirichlet", 6, 3.0)
    with pytest.raises(ValueError, match="number of categories"):
        spco_settings("B-dirichlet", None)
    with pytest.raises(ValueError, match="not an SpCoMapping method"):
        spco_settings("D-cnn", None)


def test_every_row_fits_under_the_fit_s_thread_policy(monkeypatch):
    """A baseline row (SpCoA) ran with torch's default of one thread a core, SpCoMapping's with
    the fit's policy (one on a house this size): SpCoA took 9.2 s beside another process on
    room1dk5 against 1.1 s with one thread."""
    import torch

    from spcopyro.experiments.methods import Method, RunSettings, fit_method

    seen = []

    def fit(house, context):
        seen.append(torch.get_num_threads())
        return REGISTRY["F-geometry"].fit(house, context)

    monkeypatch.setitem(REGISTRY, "X-probe", Method("X-probe", "probe", fit))
    house = make_house(seed=0, spec=HouseSpec.embedded())
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        fit_method("X-probe", house, RunSettings(sweeps=1))
        assert seen == [1] and torch.get_num_threads() == 2  # and restored after
    finally:
        torch.set_num_threads(before)


def _quick(**changes):
    return experiment_study(load_study(EXPERIMENT_QUICK), **changes)


def test_quick_experiment_writes_table_and_figures(tmp_path):
    """The shipped quick study without the public houses: table.json / table.md as the old
    command wrote them, figures from the stored maps and traces; a rerun fits nothing."""
    study = _quick(public=False, command="spcopyro experiment --quick")
    lines: list[str] = []
    summary = run_experiment(tmp_path, study, report=lines.append)
    md = (tmp_path / "table.md").read_text()
    data = json.loads((tmp_path / "table.json").read_text())
    assert data["command"] == "spcopyro experiment --quick" and data["failed"] == 0
    assert data["settings"]["sweeps"] == 20 and data["settings"]["seeds"] == 2
    assert list(data["synthetic"]) == list(METHODS)
    for method in METHODS:
        per_seed = data["synthetic_per_seed"][method]
        assert [r["seed"] for r in per_seed] == [0, 1]
        aris = [r["ari"] for r in per_seed]
        assert data["synthetic"][method]["ari"]["mean"] == pytest.approx(np.mean(aris))
        assert data["synthetic"][method]["ari"]["sd"] == pytest.approx(np.std(aris, ddof=1))
        assert all(-1.0 <= a <= 1.0 for a in aris)
        assert 0.0 <= data["synthetic"][method]["matching_rate"]["mean"] <= 1.0
        assert METHOD_LABELS[method] in md  # one row per method
        has_area = "matching_rate_area" in data["synthetic"][method]
        assert has_area == (method in ("A-dp", "A-orig-g3", "B-dirichlet"))
    assert (
        "| method | ARI | matching rate | matching rate (area prior) | concepts | s per fit |" in md
    )
    assert data["public"] == {} and "Public houses skipped" in md
    assert summary["figures"] == data["figures"] == [
        "figures/synthetic_maps.png", "figures/synthetic_traces.png",
    ]  # fmt: skip
    for name in data["figures"]:
        assert (tmp_path / name).stat().st_size > 1000
    rows = read_table(tmp_path / "results.csv")
    assert len(rows) == 14 and all(r["label_map"] for r in rows)
    stored = load_label_map(tmp_path, rows[0])
    assert stored is not None and stored.truth is not None
    assert stored.labels.shape == stored.grid.shape == stored.truth.shape
    with np.load(tmp_path / str(rows[0]["trace"])) as trace:  # A-dp, seed 0: the ARI per 5 sweeps
        assert list(trace["ari_iterations"]) == [5, 10, 15, 20]
        assert np.all(np.abs(trace["ari"]) <= 1.0)  # the samples' (the map: the best visited)
    lines.clear()
    again = run_experiment(tmp_path, study, report=lines.append)
    assert lines[0].startswith("nothing to run: all 14 cells")
    assert again["synthetic_per_seed"] == summary["synthetic_per_seed"]


def test_experiment_options_change_the_shipped_study():
    study = _quick(houses=["room1dk6"], methods=["E-nearest", "A-dp"], seeds=3, sweeps=300,
                   spcoa_iterations=7)  # fmt: skip
    assert [v.name for v in study.variants] == ["A-dp"] and study.baselines == ("E-nearest",)
    synthetic, public = study.data
    assert synthetic.seeds == (0, 1, 2) and (public.target, public.seeds) == ("room1dk6", (0, 1, 2))
    assert study.sweeps_for("gibbs") == 300 and study.ari_every == 3
    assert study.spcoa_iterations == 7
    with pytest.raises(ValueError, match="unknown --methods"):
        _quick(methods=["Z-none"])
    full = load_study(EXPERIMENT)
    assert [v.name for v in full.variants] == list(SPCO_METHODS)
    assert SPCO_METHODS + full.baselines == METHODS
    assert full.sweeps_for("gibbs") == 5000 and full.spcoa_iterations == 200
    assert full.ari_every == 50 and full.seeds == tuple(range(5))
    assert [d.name for d in full.data if d.kind == "public"] == list(PUBLIC_CATEGORIES)
    for method in SPCO_METHODS:  # the variants are the registry's rows
        variant = next(v for v in full.variants if v.name == method)
        assert variant.spco_settings(6) == spco_settings(method, 6)


def test_experiment_names_an_unknown_house_as_the_users(tmp_path, capsys):
    """--houses room9: the error named the shipped study file and a [data.room9] table it
    does not hold; it names the option and the dataset's houses, before anything is run."""
    root = fake_dataset(tmp_path / "data")
    out = tmp_path / "out"
    code = main(["experiment", "--out", str(out), "--quick", "--data", str(root),
                 "--houses", "room1", "room9"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert "--houses room9: not a house of" in err and "its houses: room1" in err
    assert ".toml" not in err
    assert not out.exists()


def test_fit_spco_gives_fit_houses_labels():
    """A study with ari_every fits its variants with fit_spco (to keep label maps along the
    run); the labels are fit_house's."""
    house = make_house(seed=1, spec=HouseSpec.scaled(45, 60))
    for method in SPCO_METHODS:
        settings = spco_settings(method, 3)
        kept, (iterations, aris) = fit_spco(house, settings, sweeps=12, seed=1, thin=4)
        plain = fit_house(house, settings, sweeps=12, seed=1, progress=False, threads=1)
        assert np.array_equal(kept.labels, plain.labels), method
        assert list(iterations) == [4, 8, 12] and len(aris) == 3


def test_an_experiment_row_gets_the_degenerate_map_check(monkeypatch, caplog):
    """An SpCoMapping row of the experiment fits by fit_spco, which never ran fit_house's
    degenerate-map check (only the study's ari_every cells did, in evaluate._fit): its
    one-concept map went without the warning. fit_spco now checks every map it returns."""
    import spcopyro.fit.map_warnings as map_warnings
    from spcopyro.experiments.methods import RunSettings, fit_method

    checked = []

    def warning(labels, house, snap, sampled=True, **_):
        checked.append(labels.shape)
        return "degenerate map (test)"

    monkeypatch.setattr(map_warnings, "house_map_warning", warning)
    house = make_house(seed=1, spec=HouseSpec.scaled(45, 60))
    with caplog.at_level("WARNING", logger="spcopyro"):
        fit_method("A-dp", house, RunSettings(sweeps=2, trace_every=1))
    assert checked == [(house.grid.num_free,)]
    assert "degenerate map (test)" in caplog.text


def test_experiment_reproduces_the_old_loop(dataset_root, tmp_path):
    """The shipped quick study gives the numbers the experiment's own loop gave before issue 26
    for the same seeds and budgets (recorded in experiment_old_records.json)."""
    old = json.loads(OLD_RECORDS.read_text())
    summary = run_experiment(tmp_path, _quick(), root=dataset_root)
    assert summary["failed"] == 0

    def same(was: list[dict], now: list[dict], where: object) -> None:
        assert len(was) == len(now), where
        for a, b in zip(was, now, strict=True):
            b = {k: v for k, v in b.items() if k != "seconds"}
            assert set(a) == set(b), (where, set(a) ^ set(b))
            for key, value in a.items():
                assert b[key] == pytest.approx(value, rel=1e-9, nan_ok=True), (where, key)

    for method, records in old["synthetic_per_seed"].items():
        same(records, summary["synthetic_per_seed"][method], method)
    for house, by_method in old["public_per_fold"].items():
        for method, records in by_method.items():
            same(records, summary["public_per_fold"][house][method], (house, method))
    assert (tmp_path / "figures" / "room1dk5_maps.png").is_file()


def test_public_table_layout():
    # table_markdown on a hand-made summary: one column per house, four scores per cell
    public = {
        house: {m: {s: 0.5 for s in (*PUBLIC_SCORES, "inside_rate", "seconds")} for m in METHODS}
        for house in ("room1dk5", "room2ldk4")
    }
    public["room1dk5"]["E-nearest"]["top1"] = 0.25
    synthetic = {
        m: {s: {"mean": 0.1, "sd": 0.0} for s in ("ari", "matching_rate", "seconds")}
        for m in METHODS
    }
    summary = {
        "command": "",
        "methods": METHOD_LABELS,
        "synthetic": synthetic,
        "public": public,
        "settings": {"sweeps": 5, "spcoa_iterations": 2, "seeds": 1},
        "notes": ["n"],
    }
    md = table_markdown(summary)
    assert "| method | room1dk5 | room2ldk4 | mean top-1 |" in md
    ours = "| (E) nearest utterance's word"  # not the quoted paper's "| (E) Nearest neighbor"
    synthetic_row, public_row = [line for line in md.splitlines() if line.startswith(ours)]
    assert synthetic_row.endswith("| 0.100 | 0.100 | — | — | 0.1 |")  # one seed: no sd
    assert public_row.endswith(
        "| 0.25 / 0.50 / 0.5 / 0.50 m | 0.50 / 0.50 / 0.5 / 0.50 m | 0.375 |"
    )
    assert "## The paper's own numbers" in md and "0.0001 on room2ldk4" in md
    # the paper's Table 4 has two parts, (a) ARI and (b) matching rate; the note said only (b)
    assert "by ARI (4a) and matching rate (eq. 18, 4b)" in md


def test_synthetic_table_shows_a_sd_only_over_two_seeds_or_more():
    """One seed showed ``0.100 ± 0.000``: a spread of 0 where there is no sample sd."""
    synthetic = {m: {"ari": {"mean": 0.1, "sd": 0.0}} for m in ("A-dp", "F-geometry")}
    summary = {
        "command": "", "methods": {"A-dp": "A", "F-geometry": "F"}, "synthetic": synthetic,
        "public": {}, "settings": {"sweeps": 5, "spcoa_iterations": 2, "seeds": 2},
        "synthetic_per_seed": {"A-dp": [{"seed": 0}, {"seed": 1}], "F-geometry": [{"seed": 0}]},
        "notes": [],
    }  # fmt: skip
    rows = [
        line for line in table_markdown(summary).splitlines() if line.startswith(("| A", "| F"))
    ]
    assert rows == ["| A | 0.100 ± 0.000 | — | — | — | — |", "| F | 0.100 | — | — | — | — |"]
    # the settings line names what ran: no SpCoA iterations without a C-spcoa row
    assert "SpCoMapping: 5 Gibbs sweeps" in table_markdown(summary)
    assert "SpCoA" not in table_markdown(summary)
    summary["methods"] = {"F-geometry": "F", "C-spcoa": "C"}
    md = table_markdown(summary)
    assert "SpCoA: 2 iterations." in md and "SpCoMapping: 5" not in md


def test_quick_experiment_cli_on_the_public_dataset(dataset_root, tmp_path, capsys):
    code = main(
        [
            "experiment",
            "--out",
            str(tmp_path),
            "--quick",
            "--data",
            str(dataset_root),
            "--seeds",
            "1",
            "--methods",
            "A-dp",
            "E-nearest",
        ]
    )
    assert code == 0
    data = json.loads((tmp_path / "table.json").read_text())
    assert list(data["synthetic"]) == ["A-dp", "E-nearest"]
    (house,) = data["public"]  # --quick: the first house only
    folds = data["public_per_fold"][house]["A-dp"]
    assert [f["held_out_trial"] for f in folds] == sorted({f["held_out_trial"] for f in folds})
    assert len(folds) == 3
    assert data["public"][house]["A-dp"]["top1"] == pytest.approx(
        np.mean([f["top1"] for f in folds])
    )
    assert (tmp_path / "figures" / f"{house}_maps.png").is_file()
    assert "wrote" in capsys.readouterr().out


def test_side_studies_give_the_old_loops_numbers(tmp_path):
    """``--studies`` as the shipped studies modality and sentences: the same studies.json and
    studies.md as the former loops for the same sweeps and seeds; a rerun fits nothing."""
    from spcopyro.experiments.studies import ABLATIONS
    from spcopyro.study.side_studies import side_studies, write_studies

    old = json.loads(OLD_SIDE_RECORDS.read_text())["studies"]
    markdown = write_studies(tmp_path, sweeps=20, seeds=(0, 1))
    assert json.loads((tmp_path / "studies.json").read_text()) == old
    assert (tmp_path / "studies.md").read_text() == markdown
    for name in ABLATIONS:
        assert f"| {name} |" in markdown
    assert "| count |" in markdown and "| tfidf |" in markdown
    modality, sentences = side_studies(sweeps=1000, seeds=(0, 1, 2))
    assert [v.name for v in modality.variants] == list(ABLATIONS)
    for variant in modality.variants:  # the (A') row with the modalities switched
        expected = spco_settings("A-orig-g3", None).replace(**ABLATIONS[variant.name])
        assert variant.spco_settings(None) == expected
    assert sentences.seeds == (0,) and [v.name for v in sentences.variants] == ["count", "tfidf"]
    lines: list[str] = []
    assert write_studies(tmp_path, sweeps=20, seeds=(0, 1), report=lines.append) == markdown
    assert len(lines) == 2 and all(line.startswith("nothing to run") for line in lines)


def test_studies_markdown_says_the_sentence_study_is_one_house():
    """The header named seeds [0, 1, 2] for both side studies; the sentence study runs on the
    first seed's house alone (side_studies)."""
    from spcopyro.experiments.studies import SentenceScores, studies_markdown

    scores = SentenceScores({"count": 0.5}, {"count": [["the", "kitchen"]]})
    markdown = studies_markdown({"MRF only": [0.1, 0.2]}, scores, sweeps=10, seeds=(3, 4))
    assert "| setting | seed 3 | seed 4 | mean |" in markdown
    assert "the house of seed 3 alone" in markdown
    # the paper's Table 5 is 20 fixed sentences in a real room: not what this study fits
    assert "Not the paper's Table 5 setting: that is 20 fixed sentences" in markdown


def test_experiment_reruns_stale_cells_when_asked(tmp_path, capsys):
    """Cells stored by another spcopyro source are kept with "--rerun-stale runs them again",
    an option experiment did not have (compare-inference and ablation got it)."""
    out = tmp_path / "exp"
    command = ["experiment", "--out", str(out), "--no-public", "--seeds", "1",
               "--methods", "F-geometry"]  # fmt: skip
    assert main(command) == 0
    stored = mark_stale(out)
    capsys.readouterr()
    assert main(command) == 0
    assert "--rerun-stale runs them again" in capsys.readouterr().out
    assert json.loads(stored.read_text())["source_digest"] == STALE_DIGEST
    assert main([*command, "--rerun-stale"]) == 0
    assert json.loads(stored.read_text())["source_digest"] != STALE_DIGEST


def test_a_smoke_runs_verdicts_come_with_a_caveat():
    """A --quick table (20 sweeps) said 'the best SpCoMapping row ... does NOT beat the best
    baseline' with nothing to say its maps were still specks: below SMOKE_SWEEPS a fit, a line
    before the verdicts says so; a run at the paper's budget has none."""
    summary = {
        "command": "", "methods": {"A-dp": "A"}, "public": {},
        "synthetic": {"A-dp": {"ari": {"mean": 0.1, "sd": 0.0}}},
        "settings": {"sweeps": 20, "spcoa_iterations": 2, "seeds": 1},
        "notes": ["synthetic ari: the best SpCoMapping row (A-dp) does NOT beat ..."],
    }  # fmt: skip
    notes = table_markdown(summary).split("## Notes", 1)[1].strip().splitlines()
    assert notes[0].startswith("- **20 sweeps a fit** (the paper ran 5000): a smoke run"), notes
    assert notes[1].startswith("- synthetic ari: the best SpCoMapping row"), notes
    summary["settings"]["sweeps"] = 5000
    notes = table_markdown(summary).split("## Notes", 1)[1].strip().splitlines()
    assert notes == ["- synthetic ari: the best SpCoMapping row (A-dp) does NOT beat ..."], notes
