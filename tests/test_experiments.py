"""``spcopyro experiment``: the comparison table and figures, end to end on a smoke run."""

from __future__ import annotations

import json

import numpy as np
import pytest

from spcopyro.cli.main import main
from spcopyro.experiments.methods import (
    METHOD_LABELS,
    METHODS,
    REGISTRY,
    SPCO_METHODS,
    register,
    spco_settings,
)
from spcopyro.experiments.table import (
    PUBLIC_SCORES,
    QUICK_SPEC,
    ExperimentSettings,
    run_experiment,
    table_markdown,
)


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


def test_quick_experiment_writes_table_and_figures(tmp_path):
    settings = ExperimentSettings.quick(command="spcopyro experiment --quick")
    summary = run_experiment(tmp_path, settings)
    md = (tmp_path / "table.md").read_text()
    data = json.loads((tmp_path / "table.json").read_text())
    assert data["command"] == "spcopyro experiment --quick"
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
    assert data["public"] == {} and "Public houses skipped" in md  # no dataset_root given
    figures = data["figures"]
    assert figures == summary["figures"]
    for name in ("figures/synthetic_traces.png", "figures/synthetic_maps.png"):
        assert name in figures
    for name in figures:
        assert (tmp_path / name).stat().st_size > 1000


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
    synthetic_row, public_row = [line for line in md.splitlines() if line.startswith("| (E)")]
    assert synthetic_row.endswith("| 0.100 ± 0.000 | 0.100 ± 0.000 | — | — | 0.1 |")
    assert public_row.endswith(
        "| 0.25 / 0.50 / 0.5 / 0.50 m | 0.50 / 0.50 / 0.5 / 0.50 m | 0.375 |"
    )
    assert "## The paper's own numbers" in md and "0.0001 on room2ldk4" in md


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


def test_studies_run_and_report_every_setting():
    from spcopyro.config import SpCoConfig, SpCoSettings
    from spcopyro.experiments.studies import ABLATIONS, modality_ablation, sentence_study
    from spcopyro.synthetic import FILLER_WORDS

    config = SpCoSettings(SpCoConfig(num_concepts=6, prior="dirichlet", alpha=10.0, gamma=2.0))
    scores = modality_ablation(config, sweeps=5, seeds=(0,), spec=QUICK_SPEC)
    assert list(scores) == list(ABLATIONS) == ["MRF only", "+ words", "+ images", "words + images"]
    assert all(len(v) == 1 and -1.0 <= v[0] <= 1.0 for v in scores.values())
    sentences = sentence_study(config, sweeps=5, min_cells=1)
    assert set(sentences.filler_top_share) == {"count", "tfidf"}
    for weighting, tops in sentences.top_words.items():
        share = np.mean([t[0] in FILLER_WORDS for t in tops])
        assert sentences.filler_top_share[weighting] == pytest.approx(share)


def test_write_studies_writes_both_tables(tmp_path):
    import json

    from spcopyro.experiments.studies import ABLATIONS, write_studies

    markdown = write_studies(tmp_path, sweeps=3, seeds=(0,))
    assert (tmp_path / "studies.md").read_text() == markdown
    for name in ABLATIONS:
        assert f"| {name} |" in markdown
    assert "| count |" in markdown and "| tfidf |" in markdown
    payload = json.loads((tmp_path / "studies.json").read_text())
    assert set(payload["ablation"]) == set(ABLATIONS) and payload["sweeps"] == 3
