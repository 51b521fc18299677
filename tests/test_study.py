"""Studies (issue 26): the spec, the tidy table, Dask against in-process, resuming, failures.

Tiny synthetic houses and 5-10 sweeps: the numbers are checked for equality between runs, never
for their values.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from study_setup import on_a_cluster, small_house, small_house_toml

from spcopyro._util.folder_lock import LOCK_NAME
from spcopyro.cli.main import main
from spcopyro.cli.study import study_path
from spcopyro.study import STUDIES, evaluate
from spcopyro.study.cells import cells_of
from spcopyro.study.run import run_study
from spcopyro.study.spec import StudyError, load_study, study_from_dict
from spcopyro.study.table import COLUMNS, read_table

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

ROOT = Path(__file__).resolve().parents[1]

TINY = """
[study]
name = "tiny"
seeds = 2
sweeps = 8
baselines = ["F-geometry"]

[variants.og3]
preset = "original-code"
gamma = 3.0

[variants.dp]
preset = "paper-dp"

""" + small_house_toml(heldout=True)

TINY_DICT = {
    "study": {"name": "tiny", "seeds": 2, "sweeps": 8, "baselines": ["F-geometry"]},
    "variants": {"og3": {"preset": "original-code", "gamma": 3.0}, "dp": {"preset": "paper-dp"}},
    "data": {"small": small_house(heldout=True)},
}  # fmt: skip
TIMING = {"seconds", "cpu_seconds"}
WORKER_STATE = """(
    __import__("os").environ.get("MALLOC_TRIM_THRESHOLD_"),
    __import__("os").environ.get("OMP_NUM_THREADS"),
    "spcopyro.study.evaluate" in __import__("sys").modules,
    __import__("dask").config.get("distributed.worker.profile.enabled"),
)"""
"""In a worker, before any cell: its MALLOC_TRIM_THRESHOLD_ and OMP_NUM_THREADS, whether the
cells' code is imported, and whether its statistical profiler is on."""


def _write(tmp_path: Path, text: str = TINY, name: str = "tiny.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _scores(rows: list[dict]) -> list[dict]:
    """The rows without their timings (which differ between any two runs)."""
    return [{k: v for k, v in row.items() if k not in TIMING} for row in rows]


@pytest.fixture(scope="module")
def in_process(tmp_path_factory) -> tuple[Path, Path]:
    """The tiny study run in this process: (study file, output folder)."""
    root = tmp_path_factory.mktemp("study")
    path = _write(root)
    out = root / "out"
    run = run_study(load_study(path), out, workers=1, progress=False)
    assert (run.cells, run.ran, run.failed, run.cached) == (6, 6, 0, 0)
    return path, out


def test_spec_from_toml_equals_spec_from_python(tmp_path):
    from_file = load_study(_write(tmp_path))
    from_python = study_from_dict(TINY_DICT)
    assert from_file == from_python
    assert [v.name for v in from_file.variants] == ["og3", "dp"]
    assert from_file.seeds == (0, 1) and from_file.sweeps_for("gibbs") == 8
    assert len(cells_of(from_file)) == 2 * (2 + 1)  # seeds x (variants + baseline)


@pytest.mark.parametrize(
    "old, new, words",
    [
        (
            "num_rooms = 2",
            "num_roms = 2",
            ["[data.small] num_roms", "2", "HouseSpec has no", "; did you mean num_rooms?"],
        ),
        ("seeds = 2", "seeds = -1", ["[study] seeds", "-1"]),
        ("sweeps = 8", "sweeps = { gibs = 8 }", ["sweeps.gibs", "8", "unknown method"]),
        ('baselines = ["F-geometry"]', 'baselines = ["G-nothing"]', ["baselines", "G-nothing"]),
        # the known keys, and a suggestion as for an unknown study name (it had none)
        (
            "gamma = 3.0",
            "gama = 3.0",
            ["[variants.og3]", "gama", "unknown key", "'gamma', ", "; did you mean gamma?"],
        ),
        ("gamma = 3.0", 'gamma = "hot"', ["[variants.og3]", "gamma", "hot"]),
        ('synthetic = "default"', 'synthetic = "castle"', ["[data.small] synthetic", "castle"]),
        ("seeds = 2", "seedz = 2", ["[study] seedz", "unknown key", "; did you mean seeds?"]),
        # a misspelt prefix is suggested as a misspelt key is (it got no suggestion)
        ("gamma = 3.0", "setings.gamma = 3.0", ["setings.gamma", "did you mean settings.gamma?"]),
        (
            "gamma = 3.0",
            "option = { cluster_moves = 0.2 }",
            ["option.cluster_moves", "did you mean options.cluster_moves?"],
        ),
        ("seeds = 2", "seeds = [", ["not valid TOML"]),
        ("heldout = true", "heldout = true\nseeds = 0", ["[data.small] seeds", "0"]),
        ("seeds = 2", "seeds = 2\nobservations_off = 1", ["[study] observations_off", "1"]),
        # a number in quotes is TOML text: the message says how to write it (1_000 unquoted)
        (
            "sweeps = 8",
            'sweeps = "1_000"',
            ["[study] sweeps = '1_000'", "write 1_000 without the quotes"],
        ),
        ("seeds = 2", 'seeds = "2"', ["[study] seeds = '2'", "write 2 without the quotes"]),
        # a public house is loaded, not drawn: its seed changed nothing, silently
        (
            'synthetic = "default"\nheight = 24\nwidth = 30\nnum_rooms = 2\nnum_trials = 2\n'
            "min_room_size = 8",
            'public = "room1dk5"\nseed = 1',
            ["[data.small] seed = 1", "a public house is loaded, not drawn"],
        ),
        # one source's maps figure was drawn over the other's
        (
            "[data.small]",
            '[data."big house"]\nsynthetic = "default"\n[data.big_house]',
            ["[data.big_house] = 'big_house'", "maps_big_house.png is also [data.big house]'s"],
        ),
        # each of their cells failed at run time
        ("[data.small]", '[data."small/house"]', ["[data.small/house] = 'small/house'", "no '/'"]),
        (
            "num_trials = 2",
            "num_trials = 1",
            ["[data.small] heldout", "a held-out source needs num_trials >= 2, it has 1"],
        ),
        (
            "gamma = 3.0",
            'gamma = 3.0\npoint_estimate = "binder"',
            ["[variants.og3]", "point_estimate='binder'", "needs marginal_samples > 0"],
        ),
        # a trace keeps no ARI in a fit shorter than ari_every (it was ignored, silently)
        ("sweeps = 8", "sweeps = 8\nari_every = 10", ["[study] ari_every = 10", "gibbs for 8"]),
        # a prior of a hyperparameter the chain does not sample changed nothing, silently
        (
            "gamma = 3.0",
            "gamma = 3.0\nhyper = { log_gamma_sd = 2.0 }",
            ["[variants.og3]", "hyper.log_gamma_sd=2.0", "no hyperparameter the chain samples"],
        ),
        (
            "gamma = 3.0",
            'gamma = 3.0\nhyper.alpha = true\n"hyper.gamma_step" = 1.0',
            ["[variants.og3]", "hyper.gamma_step=1.0", "no hyperparameter the chain samples"],
        ),
    ],
)
def test_bad_spec_names_file_key_and_value(tmp_path, old, new, words):
    path = _write(tmp_path, TINY.replace(old, new), name="bad.toml")
    with pytest.raises(StudyError) as caught:
        load_study(path)
    message = str(caught.value)
    assert str(path) in message
    for word in words:
        assert word in message, message


def test_a_one_concept_map_of_a_study_cell_is_advised_in_the_study_files_terms():
    """The warning of a study cell's one-concept map told a study user to try
    ``GibbsOptions(merge_moves=0.2) (fit's --merge-moves 0.2)`` and ``fit's --preset coarse``,
    where the study file says ``merge_moves = 0.2`` and ``preset = "coarse"`` in a variant."""
    from spcopyro.study.cell_warnings import read_warnings

    values = json.loads(json.dumps(TINY_DICT))
    values["study"].update(seeds=1, sweeps=2, baselines=[])
    values["variants"] = {"one": {"num_concepts": 1}}  # every cell in one concept
    (cell,) = cells_of(study_from_dict(values))
    record, _, _ = evaluate.run_cell(cell)
    assert record["status"] == "ok", record["error"]
    (collapsed,) = [m for m in read_warnings(record[evaluate.WARNINGS]) if "holds 100" in m]
    assert collapsed.endswith(evaluate.advice(True)), collapsed
    assert "merge_moves = 0.2" in collapsed and 'preset = "coarse"' in collapsed, collapsed
    assert "--merge-moves" not in collapsed and "GibbsOptions" not in collapsed, collapsed


def test_fit_keywords_a_studys_method_or_scoring_cannot_take_are_refused_when_read():
    """Each cell of these failed at run time (fit_house's or the comparison's own checks)."""
    values = json.loads(json.dumps(TINY_DICT))
    values["variants"]["og3"].update(point_estimate="binder", marginal_samples=5)
    study_from_dict(values)  # Gibbs keeps the label maps binder needs ...
    values["study"]["methods"] = ["gibbs", "cavi"]  # ... CAVI does not
    with pytest.raises(StudyError, match=r"\[variants.og3\].*method 'cavi'"):
        study_from_dict(values)
    values = json.loads(json.dumps(TINY_DICT))
    values["variants"]["og3"]["init"] = "rooms"
    values["study"].update(scoring="comparison", baselines=[])
    with pytest.raises(StudyError, match="variant 'og3' sets fit_house keywords .'init': 'rooms'"):
        study_from_dict(values)


def test_hyper_options_of_a_study_reach_its_cells(tmp_path):
    """``hyper.*`` of a variant (nested or dotted) set the Gibbs chain's hyperparameter
    sampling of its cells, and are in their keys."""
    text = TINY.replace("gamma = 3.0", 'gamma = 3.0\nhyper.gamma = "exchange"\n'
                        '"hyper.log_gamma_sd" = 2.0\nhyper.alpha = true')  # fmt: skip
    study = load_study(_write(tmp_path, text, name="hyper.toml"))
    cells = {c.row: c for c in cells_of(study) if c.seed == 0}
    hyper = cells["og3"].variant.method_options().hyper
    assert (hyper.gamma, hyper.log_gamma_sd, hyper.alpha) == ("exchange", 2.0, True)
    assert not cells["dp"].variant.method_options().hyper.active
    plain = {c.row: c for c in cells_of(load_study(_write(tmp_path))) if c.seed == 0}
    assert cells["og3"].key != plain["og3"].key and cells["dp"].key == plain["dp"].key


def test_sampled_hyperparameters_are_in_the_table(tmp_path):
    """A variant's ``hyper.*`` ran, but where the chain took alpha and gamma was nowhere in
    ``results.csv``: a study of hyperparameter sampling could not read its own result."""
    text = TINY.replace("gamma = 3.0", 'gamma = 3.0\nhyper.alpha = true\nhyper.gamma = "exchange"')
    study = load_study(_write(tmp_path, text.replace("seeds = 2", "seeds = 1")))
    run_study(study, tmp_path / "out", progress=False)
    rows = {r["variant"]: r for r in read_table(tmp_path / "out" / "results.csv")}
    sampled = json.loads(rows["og3"]["hyperparameters"])
    assert sorted(sampled) == ["alpha", "gamma"]
    assert sampled["gamma"]["initial"] == 3.0 and sampled["gamma"]["posterior_mean"] > 0
    assert not rows["dp"]["hyperparameters"] and not rows["F-geometry"]["hyperparameters"]


@pytest.mark.parametrize(
    "line, words",
    [
        ('categories = "kitchen"', "categories = 'kitchen': expected a list of category names"),
        ('door_width = "wide"', "door_width = 'wide': expected 'auto' or metres > 0"),
        ("num_trials = 0", "num_trials = 0: expected an integer >= 1"),
        (
            'num_trials = "3"',
            "num_trials = '3': expected an integer >= 1 (a number in quotes is text: write 3 "
            "without the quotes)",
        ),
        ("sentence_fraction = 2.0", "sentence_fraction = 2.0: expected a share in [0, 1]"),
    ],
)
def test_a_map_tours_values_are_checked_when_read(line, words):
    """MapTour checks none of its values: each cell failed at run time, or (``categories =
    "kitchen"``) simulated a house of the categories k, i, t, c, h, e, n."""
    text = f'[variants.a]\n[data.tour]\nmap = "room1dk5"\n{line}\n'
    with pytest.raises(StudyError, match=re.escape(f"t.toml: [data.tour] {words}")):
        study_from_dict(tomllib.loads(text), source="t.toml")
    fine = study_from_dict(tomllib.loads(text.replace(line, 'categories = ["kitchen", "bath"]')))
    assert fine.data[0].map_tour().categories == ("kitchen", "bath")


@pytest.mark.parametrize(
    "line, said",
    [
        ('num_trials = "3"', "num_trials = '3': expected an integer >= 1 (a number in quotes is "
         "text: write 3 without the quotes)"),
        # no hint where the unquoted number would fail too: a count is an integer
        ('num_trials = "2.5"', "num_trials = '2.5': expected an integer >= 1"),
        ('images_per_room = "1e3"', "images_per_room = '1e3': expected an integer >= 1"),
        ('utterances_per_room = "inf"', "utterances_per_room = 'inf': expected an integer >= 0"),
        # a share or metres may be a decimal, not an infinity
        ('sentence_fraction = "0.5"', "sentence_fraction = '0.5': expected a share in [0, 1] (a "
         "number in quotes is text: write 0.5 without the quotes)"),
        ('min_room_area = "inf"', "min_room_area = 'inf': expected square metres > 0"),
        # nor where the number is of the right kind but out of the field's range
        ('num_trials = "0"', "num_trials = '0': expected an integer >= 1"),
        ('images_per_room = "-2"', "images_per_room = '-2': expected an integer >= 1"),
        ('door_width = "-1"', "door_width = '-1': expected 'auto' or metres > 0"),
        ('sentence_fraction = "2"', "sentence_fraction = '2': expected a share in [0, 1]"),
        ('door_width = "0.9"', "door_width = '0.9': expected 'auto' or metres > 0 (a number in "
         "quotes is text: write 0.9 without the quotes)"),
    ],
)  # fmt: skip
def test_a_quoted_number_is_hinted_only_where_it_would_pass_unquoted(line, said):
    """A count written "2.5" was told to write 2.5 without the quotes, which then still failed: the
    hint checked float(), not what the field wants; "0" for a count >= 1 or "2" for a share was
    told so too (the hint checked the kind of number, not the field's own check)."""
    text = f'[variants.a]\n[data.tour]\nmap = "room1dk5"\n{line}\n'
    with pytest.raises(StudyError) as error:
        study_from_dict(tomllib.loads(text), source="t.toml")
    assert str(error.value) == f"t.toml: [data.tour] {said}"


@pytest.mark.parametrize(
    "table, line, said",
    [
        ("study", 'sweeps = "0"', "[study] sweeps = '0': expected an integer >= 1"),
        ("study", 'seeds = "0"', "[study] seeds = '0': expected a count >= 1 or a list of seeds "
         ">= 0"),
        ("data.s", 'seed = "-1"', "[data.s] seed = '-1': expected an integer >= 0"),
        # where the unquoted number would pass, the hint stays (a seed may be 0)
        ("data.s", 'seed = "0"', "[data.s] seed = '0': expected an integer >= 0 (a number in "
         "quotes is text: write 0 without the quotes)"),
        ("study", 'sweeps = "8"', "[study] sweeps = '8': expected an integer >= 1 (a number in "
         "quotes is text: write 8 without the quotes)"),
    ],
)  # fmt: skip
def test_a_quoted_count_out_of_range_gets_no_hint_to_unquote_it(table, line, said):
    """``sweeps = "0"`` was told to write 0 without the quotes, which is refused too: the hint
    checked only that the text was an integer, not the field's minimum."""
    tables = {"study": "", "data.s": 'synthetic = "default"\n'}
    tables[table] += line + "\n"
    text = f"[study]\n{tables['study']}[variants.a]\n[data.s]\n{tables['data.s']}"
    with pytest.raises(StudyError) as error:
        study_from_dict(tomllib.loads(text), source="t.toml")
    assert str(error.value) == f"t.toml: {said}"


def test_python_spec_errors_and_method_grid():
    with pytest.raises(StudyError, match="<python>: \\[data\\]"):
        study_from_dict({"variants": {"a": {}}})
    values = json.loads(json.dumps(TINY_DICT))
    values["study"]["methods"] = ["gibbs", "cavi"]
    study = study_from_dict(values)
    assert [c.method for c in cells_of(study)][:4] == ["gibbs", "cavi", "gibbs", "cavi"]
    values["study"]["sweeps"] = {"og3": 7, "cavi": 3, "*": 5}  # variant, then method, then *
    study = study_from_dict(values)
    assert [(c.row, c.method, c.sweeps) for c in cells_of(study)][:4] == [
        ("og3", "gibbs", 7), ("og3", "cavi", 7), ("dp", "gibbs", 5), ("dp", "cavi", 3)
    ]  # fmt: skip
    values["study"]["sweeps"] = {"og4": 7}
    with pytest.raises(StudyError, match="sweeps.og4.*unknown method or variant"):
        study_from_dict(values)
    values["study"]["sweeps"] = 5
    values["variants"]["og3"]["method"] = "lbp"
    with pytest.raises(StudyError, match="variants.og3. method"):
        study_from_dict(values)


def test_source_seeds_and_observations_off_reach_the_cells():
    """A source's own seeds replace the study's; observations_off changes the variants' keys
    (and only theirs), so earlier cells of a study without it keep theirs."""
    values = json.loads(json.dumps(TINY_DICT))
    plain = {c.key for c in cells_of(study_from_dict(values))}
    values["data"]["small"]["seeds"] = [3]
    values["data"]["other"] = {"synthetic": "scaled", "height": 24, "width": 30, "seeds": 1}
    cells = cells_of(study_from_dict(values))
    assert [(c.data.name, c.seed) for c in cells] == [("small", 3)] * 3 + [("other", 0)] * 3
    values = json.loads(json.dumps(TINY_DICT))
    values["study"]["observations_off"] = True
    off = cells_of(study_from_dict(values))
    assert [c.observations_off for c in off] == [True, True, False] * 2
    assert {c.key for c in off} & plain == {c.key for c in off if c.variant is None}


def test_a_spcoa_cell_key_holds_the_options_its_fit_is_given(monkeypatch):
    """C-spcoa's key held its word weighting as a special case, and not its L (a constant
    _fit_spcoa passed beside it): a change of L would have reused the cached cells. Its key now
    holds the one options dict (experiments.methods.SPCOA_OPTIONS) the row's fit passes
    fit_spcoa, which this reads back from the fit itself."""
    from spcopyro.experiments import methods
    from spcopyro.study import cells as study_cells
    from spcopyro.synthetic import HouseSpec, make_house

    given: dict[str, object] = {}

    class Given(Exception):
        pass

    def fit_spcoa(house, **keywords):
        given.update(keywords)
        raise Given

    values = json.loads(json.dumps(TINY_DICT))
    values["study"]["baselines"] = ["C-spcoa", "F-geometry"]
    cells = [c for c in cells_of(study_from_dict(values)) if c.row == "C-spcoa"]
    assert [c.seed for c in cells] == [0, 1]
    inputs = study_cells._cell_inputs(cells[1], "digest")
    monkeypatch.setattr(methods, "fit_spcoa", fit_spcoa)
    house = make_house(seed=0, spec=HouseSpec(height=40, width=50, num_rooms=3))
    run = methods.RunSettings(spcoa_iterations=cells[1].spcoa_iterations)
    with pytest.raises(Given):
        methods.fit_method("C-spcoa", house, run, seed=cells[1].seed)
    assert given.pop("iterations") == inputs["spcoa_iterations"]
    assert given.pop("seed") == inputs["seed"] == 1
    assert given == inputs["spcoa_options"]
    assert {"num_concepts", "word_weighting", "alpha", "pair_distance"} <= set(given)
    # a change of an option changes the C-spcoa cells' keys and no other
    keys = {(c.row, c.seed): c.key for c in cells_of(study_from_dict(values))}
    changed = {**methods.SPCOA_OPTIONS, "num_concepts": 10}
    monkeypatch.setattr(study_cells, "SPCOA_OPTIONS", changed)
    after = {(c.row, c.seed): c.key for c in cells_of(study_from_dict(values))}
    assert {cell for cell in keys if keys[cell] != after[cell]} == {("C-spcoa", 0), ("C-spcoa", 1)}


def test_in_process_run_gives_the_tidy_table(in_process):
    _, out = in_process
    rows = read_table(out / "results.csv")
    assert len(rows) == 6 and list(rows[0]) == list(COLUMNS)
    assert {(r["variant"], r["seed"]) for r in rows} == {
        (v, s) for v in ("og3", "dp", "F-geometry") for s in (0, 1)
    }
    for row in rows:
        assert row["status"] == "ok", row["error"]
        assert row["data"] == "small" and row["data_kind"] == "synthetic"
        for score in ("ari", "matching_rate", "top1", "top3", "mean_rank", "largest_share",
                      "concepts_1pct", "free_cells", "seconds"):  # fmt: skip
            assert isinstance(row[score], int | float), (score, row)
        assert row["held_out_trial"] == row["seed"] % 2
    fits = [r for r in rows if r["method"] == "gibbs"]
    assert all(r["iterations"] == 8 and (out / r["trace"]).is_file() for r in fits)
    report = (out / "report.md").read_text()
    assert "| og3 | gibbs | 2 |" in report and "+-" in report
    assert "](quality_time.png)" in report and (out / "quality_time.png").is_file()


def test_the_table_says_which_objective_best_objective_is(in_process):
    """best_objective held a sampler's log joint and a variational fit's ELBO in one column
    with nothing saying which (compare-inference on the synthetic houses: Gibbs about +112,000,
    CAVI about -14,000): column objective names it; a baseline, with no objective, leaves it
    empty."""
    _, out = in_process
    rows = read_table(out / "results.csv")
    fits = [r for r in rows if r["method"] == "gibbs"]
    assert fits and all(r["objective"] == "log joint" for r in fits), fits
    assert all(isinstance(r["best_objective"], float) for r in fits)
    assert all(r["objective"] in ("", None) for r in rows if r["method"] == "baseline")


def test_quality_time_figure_shows_every_group_and_skips_what_it_cannot_place():
    from matplotlib.collections import PathCollection

    from spcopyro.study.figures import quality_time_figure

    def row(data, variant, method, seconds, ari, status="ok"):
        return dict(data=data, variant=variant, method=method, seconds=seconds, ari=ari,
                    status=status)  # fmt: skip

    rows = [
        row("dense", "default", "gibbs", 10.0, 0.9), row("dense", "default", "gibbs", 12.0, 0.8),
        row("dense", "default", "cavi", 1.0, 0.6), row("public", "default", "gibbs", 30.0, 0.5),
        row("public", "default", "cavi", None, 0.4),  # no time: left out
        row("public", "default", "cavi", 0.0, 0.4),  # no place on a log axis
        row("public", "g3", "gibbs", 5.0, 0.3, status="failed"),  # failed: left out
    ]  # fmt: skip
    fig = quality_time_figure(rows)
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in panels] == ["dense", "public"]
    assert all(ax.get_xscale() == "log" for ax in panels)
    seeds = [len(c.get_offsets()) for c in panels[0].collections if isinstance(c, PathCollection)]
    assert sorted(seeds) == [1, 2]  # gibbs' two seeds, cavi's one
    dense_means = sorted(
        line.get_ydata()[0] for line in panels[0].lines if line.get_marker() == "o"
    )
    assert dense_means == pytest.approx([0.6, 0.85])
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["gibbs", "cavi"]
    assert quality_time_figure([row("dense", "default", "gibbs", 1.0, None)]) is None


def test_a_report_table_of_failed_cells_only_has_as_many_cells_as_columns():
    """A source whose cells all failed has no score column: its header had a fourth, empty
    column the separator line lacked (``| variant | method | seeds |  |`` over ``|---|---|---|``),
    which markdown does not draw as a table."""
    from spcopyro.study.report import report_markdown

    def row(data, status, ari):
        return dict(variant="a", data=data, method="gibbs", seed=0, status=status, ari=ari,
                    error_type="ValueError" if status != "ok" else "", error="no")  # fmt: skip

    text = report_markdown([row("bad", "error", None), row("good", "ok", 0.5)])
    tables = [line for line in text.splitlines() if line.startswith("|")]
    assert tables[:3] == [
        "| variant | method | seeds |",
        "|---|---|---|",
        "| a | gibbs | 0 (1 failed) |",
    ]
    assert tables[3:] == [
        "| variant | method | seeds | ari |",
        "|---|---|---|---|",
        "| a | gibbs | 1 | 0.500 |",
    ]
    assert "2 cells in the table" in text
    assert "1 cell in the table;" in report_markdown([row("good", "ok", 0.5)])  # not "1 cells"
    assert "| a | gibbs | 1 | 0.000 |" in report_markdown([row("good", "ok", -1e-4)])  # not -0.000


def test_a_report_gives_counts_one_decimal_in_every_row():
    """ablation_small's report: concepts "90.000 +- 1.414" above "117.5 +- 2.1" (decimals chosen
    per value). Counts now have one decimal in every row; other scores keep three below 100."""
    from spcopyro.study.report import report_markdown

    def row(variant, seed, concepts, seconds):
        return dict(variant=variant, data="dense", method="gibbs", seed=seed, status="ok",
                    ari=0.5, concepts=concepts, seconds=seconds)  # fmt: skip

    rows = [row("a", 0, 89, 0.1), row("a", 1, 91, 0.11), row("b", 0, 116, 99.0),
            row("b", 1, 119, 150.0)]  # fmt: skip
    lines = [line for line in report_markdown(rows).splitlines() if line.startswith("| a")]
    lines += [line for line in report_markdown(rows).splitlines() if line.startswith("| b")]
    assert lines == [
        "| a | gibbs | 2 | 0.500 +- 0.000 | 90.0 +- 1.4 | 0.105 +- 0.007 |",
        "| b | gibbs | 2 | 0.500 +- 0.000 | 117.5 +- 2.1 | 124.5 +- 36.1 |",
    ]


@pytest.mark.parametrize(
    "times", [(0.053, 0.475, 0.133), (2.0, 9.0), (100.0, 300.0), (0.4,), (1e-3, 1e3), (0.5, 40.0)]
)
def test_quality_time_axis_labels_do_not_overlap(times):
    """A panel spanning under a decade had every minor tick labelled (``4x10^-2 6x10^-2 10^-1
    2x10^-1 ...``), printed over each other."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.study.figures import quality_time_figure

    rows = [dict(data="room1dk5", variant=f"v{i}", method="gibbs", seconds=t, ari=0.5,
                 status="ok") for i, t in enumerate(times)]  # fmt: skip
    fig = quality_time_figure(rows)
    FigureCanvasAgg(fig).draw()
    (ax,) = fig.axes
    low, high = ax.get_xlim()
    labels = [label for label in ax.get_xticklabels() + ax.get_xticklabels(minor=True)
              if label.get_text() and low <= label.get_position()[0] <= high]  # fmt: skip
    assert len(labels) >= 2, [label.get_text() for label in labels]
    boxes = sorted((label.get_window_extent() for label in labels), key=lambda box: box.x0)
    for left, right in zip(boxes, boxes[1:], strict=False):
        assert left.x1 <= right.x0, [label.get_text() for label in labels]


def test_quality_time_legend_fits_in_the_figure():
    """compare-inference's report on one public house drew its 7 groups' legend in four columns
    of "stochastic-vi / stochastic-vi" under one 4.3 in panel: it ran past both edges of the
    image, "gibbs" and "vi-gibbs / vi-gibbs" cut to "gibbs" and "vi-gi"."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.experiments.inference_comparison import VARIANTS
    from spcopyro.study.figures import quality_time_figure

    rows = [dict(data="room1dk5", variant=key, method=v.method, seconds=1.0 + i, ari=0.1,
                 status="ok") for i, (key, v) in enumerate(VARIANTS.items())]  # fmt: skip
    fig = quality_time_figure(rows)
    renderer = FigureCanvasAgg(fig).get_renderer()
    (legend,) = fig.legends
    box, page = legend.get_window_extent(renderer), fig.bbox
    assert page.x0 <= box.x0 and box.x1 <= page.x1, (box, page)


@pytest.mark.parametrize("start_in_process", [False, True])
def test_local_cluster_gives_the_same_numbers(in_process, tmp_path, monkeypatch, start_in_process):
    """On the workers only, or partly in this process while they start: the same numbers."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    on_a_cluster(monkeypatch)  # 6 short cells: the cluster path all the same
    path, out = in_process
    run = run_study(load_study(path), tmp_path / "dask", workers=2, progress=False,
                    start_in_process=start_in_process)  # fmt: skip
    assert run.where == "LocalCluster(2 workers)" and run.ran == 6 and run.failed == 0
    assert run.ran_here <= 6 if start_in_process else run.ran_here == 0
    local = read_table(out / "results.csv")
    dask = read_table(tmp_path / "dask" / "results.csv")
    assert _scores(dask) == _scores(local)


@pytest.mark.parametrize("method", ["spawn", "forkserver"])
def test_local_cluster_is_made_without_dasks_malloc_trim_threshold(monkeypatch, method):
    """Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in each spawned worker, which turns off glibc's
    dynamic mmap threshold: cells ran 1.5-2x slower there than in-process. The LocalCluster the
    study starts is made with it unset (None: the nanny leaves it out of the worker's
    environment), whichever way its workers start."""
    distributed = pytest.importorskip("distributed")
    import dask

    from spcopyro.study import local_cluster

    seen = {}

    class Stop(Exception):
        pass

    def fake_cluster(*args, **kwargs):
        seen.update(dask.config.get(local_cluster.PRE_SPAWN_ENVIRON))
        seen["method"] = dask.config.get(local_cluster.MULTIPROCESSING_METHOD)
        seen["loops"] = {key: dask.config.get(key) for key in local_cluster.QUIET_LOOPS}
        raise Stop

    monkeypatch.setattr(distributed, "LocalCluster", fake_cluster)
    monkeypatch.setattr(local_cluster, "start_forkserver", lambda: None)
    with pytest.raises(Stop):
        local_cluster.local_cluster(2, method)
    assert "MALLOC_TRIM_THRESHOLD_" in seen and seen["MALLOC_TRIM_THRESHOLD_"] is None
    assert seen["method"] == method
    assert seen["loops"] == local_cluster.QUIET_LOOPS  # the workers' profiler off, and so on
    assert dask.config.get(local_cluster.PRE_SPAWN_ENVIRON)["MALLOC_TRIM_THRESHOLD_"] is not None
    assert dask.config.get("distributed.worker.profile.enabled") is True  # only for the cluster


def test_forked_workers_start_with_the_cells_code_and_one_thread(monkeypatch):
    """The study's LocalCluster forks its workers from a server that imported the cells' code
    with one BLAS thread and without MALLOC_TRIM_THRESHOLD_, even when this process has it
    (Dask's nanny leaves it in the parent's environment after spawning a worker)."""
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    from distributed import Client

    from spcopyro.study import local_cluster

    if not local_cluster.forkserver_available():
        pytest.skip("no forkserver on this platform")
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    cluster = local_cluster.local_cluster(1)
    try:
        with Client(cluster) as client:
            seen = client.run(eval, WORKER_STATE)  # a builtin: the worker imports nothing
    finally:
        cluster.close()
    [(malloc_trim, threads, preloaded, profiled)] = seen.values()
    assert malloc_trim is None and threads == "1" and preloaded
    assert profiled is False  # QUIET_LOOPS reached the worker, not only this process


def test_interrupted_study_runs_only_the_missing_cells(in_process, tmp_path, monkeypatch):
    path, _ = in_process
    study = load_study(path)
    real = evaluate.run_cell
    calls: list[str] = []

    def stops_at_the_third(cell):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(cell.key)
        return real(cell)

    monkeypatch.setattr(evaluate, "run_cell", stops_at_the_third)
    with pytest.raises(KeyboardInterrupt):
        run_study(study, tmp_path / "out", progress=False)
    assert len(read_table(tmp_path / "out" / "results.csv")) == 2  # the finished cells, kept
    report = (tmp_path / "out" / "report.md").read_text()  # it read as the whole study
    assert "2 cells in the table of the study's 6: 4 not run yet" in report
    first = list(calls)

    def counts(cell):
        calls.append(cell.key)
        return real(cell)

    monkeypatch.setattr(evaluate, "run_cell", counts)
    run = run_study(study, tmp_path / "out", progress=False)
    assert (run.cached, run.ran) == (2, 4)
    assert set(calls[2:]).isdisjoint(first) and len(calls) == 6
    lines: list[str] = []
    again = run_study(study, tmp_path / "out", progress=False, report=lines.append)
    assert again.ran == 0 and again.cached == 6 and len(calls) == 6
    assert lines and lines[0].startswith("nothing to run: all 6 cells")
    assert "not run yet" not in (tmp_path / "out" / "report.md").read_text()


def test_an_interrupted_study_command_says_so_once(in_process, tmp_path, monkeypatch, capsys):
    """`spcopyro study` printed "interrupted after 2 cells: ..." and then "interrupted" again."""
    monkeypatch.setenv("CI", "1")  # no progress bar
    path, _ = in_process
    real, calls = evaluate.run_cell, []

    def stops_at_the_third(cell):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(cell.key)
        return real(cell)

    monkeypatch.setattr(evaluate, "run_cell", stops_at_the_third)
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1"]) == 130
    captured = capsys.readouterr()
    said = (captured.out + captured.err).splitlines()
    assert [line for line in said if "interrupted" in line] == [
        "interrupted after 2 cells: 4 left; run the same command again to continue"
    ]


def test_added_seed_runs_only_new_cells_and_names_do_not_count(in_process, tmp_path):
    path, out = in_process
    renamed = TINY.replace("[variants.og3]", "[variants.gamma3]").replace("seeds = 2", "seeds = 3")
    run = run_study(load_study(_write(tmp_path, renamed)), out, progress=False)
    assert (run.cached, run.ran) == (6, 3)  # seed 2 only; og3 renamed gamma3 reuses its cells
    rows = read_table(out / "results.csv")
    assert {r["variant"] for r in rows} == {"gamma3", "dp", "F-geometry"}
    longer = TINY.replace("sweeps = 8", "sweeps = 9")
    keys = {c.key for c in cells_of(load_study(_write(tmp_path, longer)))}
    before = {c.key for c in cells_of(load_study(path))}
    assert len(keys & before) == 2  # only the baseline's cells (it has no sweeps) are shared


def test_failing_cell_is_recorded_and_the_study_goes_on(tmp_path, monkeypatch):
    text = TINY + '\n[variants.broken]\npreset = "original-code"\ngamma = 2.9\n'
    fit = evaluate._fit

    def failing(cell, *args, **kwargs):  # a fit that fails at run time, as one on bad data
        if cell.row == "broken":
            raise ValueError("this fit needs marginal_samples > 0")
        return fit(cell, *args, **kwargs)

    monkeypatch.setattr(evaluate, "_fit", failing)
    lines: list[str] = []
    run = run_study(load_study(_write(tmp_path, text)), tmp_path / "out", progress=False,
                    report=lines.append)  # fmt: skip
    assert (run.ran, run.failed) == (8, 2)
    rows = read_table(tmp_path / "out" / "results.csv")
    broken = [r for r in rows if r["variant"] == "broken"]
    assert [r["status"] for r in broken] == ["error", "error"]
    assert broken[0]["error_type"] == "ValueError" and "marginal_samples" in broken[0]["error"]
    assert broken[0]["ari"] is None
    assert all(r["status"] == "ok" for r in rows if r["variant"] != "broken")
    assert any("failed: ValueError" in line for line in lines)
    assert "Failed cells" in (tmp_path / "out" / "report.md").read_text()
    lines.clear()
    again = run_study(load_study(_write(tmp_path, text)), tmp_path / "out", progress=False,
                      report=lines.append)  # fmt: skip
    assert again.ran == 0  # a failure is kept, and said to be (not "all finished" alone) ...
    assert again.failed_before == 2
    assert any("2 cell(s) failed in an earlier run" in line and "--retry-failed" in line
               for line in lines)  # fmt: skip
    path = _write(tmp_path, text)
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1"]) == 1
    retried = run_study(load_study(_write(tmp_path, text)), tmp_path / "out", progress=False,
                        retry_failed=True)  # fmt: skip
    assert (retried.ran, retried.failed) == (2, 2)  # ... until asked to retry


def test_cli_runs_resumes_and_redraws(in_process, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("CI", "1")  # no progress bar
    path, _ = in_process
    out = tmp_path / "cli"
    assert main(["study", str(path), "--out", str(out), "--workers", "1"]) == 0
    assert "| og3 | gibbs |" in capsys.readouterr().out
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--rerun-stale"]) == 0
    assert "nothing to run" in capsys.readouterr().out
    assert main(["study", str(path), "--out", str(tmp_path / "dry"), "--dry-run"]) == 0
    planned = capsys.readouterr().out
    assert "6 of 6 cells to run" in planned and "| small | og3 | gibbs | 8 | 2 |" in planned
    assert "| small | F-geometry | baseline | 0 | 2 |" in planned  # no iterations: not 8
    assert not (tmp_path / "dry").exists()
    assert main(["study", str(path), "--out", str(out), "--dry-run"]) == 0
    assert "0 of 6 cells to run (6 finished before" in capsys.readouterr().out
    report = (out / "report.md").read_text()
    (out / "report.md").unlink()
    assert main(["study", str(path), "--out", str(out), "--report-only"]) == 0
    assert (out / "report.md").read_text() == report
    assert main(["study", str(tmp_path / "none.toml"), "--out", str(out)]) == 2
    assert "ablation_small" in capsys.readouterr().err


def test_shipped_study_parses():
    path = study_path("ablation_small")
    assert path.parent == STUDIES
    study = load_study(path)
    assert len(cells_of(study)) == 16


@pytest.mark.slow
def test_dask_benchmark_quick(tmp_path):
    pytest.importorskip("distributed", reason="the study extra (dask.distributed)")
    out = tmp_path / "study_dask.json"
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "study_dask.py"), "--quick", "--pairs", "2",
         "--out", str(out)],
        capture_output=True, text=True, timeout=600, env=env,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert results["in_process"]["seconds"] > 0 and results["local_cluster"]["seconds"] > 0
    assert results["same_numbers"] is True
    assert results["cells_in_cluster"]["seconds"] > 0  # the cells' own seconds, both runs
    assert "the cells themselves" in done.stdout
    assert len(results["pair_ratios"]) == 2 and "median ratio" in done.stdout


def test_finished_study_restarted_does_nothing_and_says_so(in_process, tmp_path, monkeypatch):
    """Issue 26: a restarted finished study runs no cell, says so, and leaves its table and
    report as they were."""
    path, finished = in_process
    out = tmp_path / "out"
    shutil.copytree(finished, out)  # other tests add cells to the shared folder

    def must_not_run(cell):
        raise AssertionError(f"cell {cell.key} ran again")

    monkeypatch.setattr(evaluate, "run_cell", must_not_run)
    before: dict[str, bytes] = {}
    for _ in range(2):
        lines: list[str] = []
        run = run_study(load_study(path), out, progress=False, report=lines.append)
        assert (run.ran, run.cached, run.failed) == (0, 6, 0)
        assert lines == [f"nothing to run: all 6 cells of study 'tiny' are finished in {out} "
                         "(delete cells/ there to run them again)"]  # fmt: skip
        now = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
        now.pop(LOCK_NAME)  # the run's process and start time: not an output
        assert now == (before or now)
        before = now
    assert len(read_table(out / "results.csv")) == 6


def test_cells_other_source_computed_are_named_kept_and_rerun_when_asked(in_process, tmp_path):
    """Each record holds the digest of the source that computed it. A restarted finished study
    whose cells other source computed (or no digest names) still runs nothing, says how many
    and its report says so; --rerun-stale runs exactly those again."""
    from spcopyro.study.cells import source_digest

    path, finished = in_process
    out = tmp_path / "out"
    shutil.copytree(finished, out)
    rows = read_table(out / "results.csv")
    assert {r["source_digest"] for r in rows} == {source_digest()}
    changed = [out / "cells" / f"{row['key']}.json" for row in rows[:2]]  # of this study
    for stored, digest in zip(changed, ("0123456789abcdef", None), strict=True):
        record = json.loads(stored.read_text())
        record.pop("source_digest")
        if digest is not None:
            record["source_digest"] = digest
        stored.write_text(json.dumps(record))
    lines: list[str] = []
    run = run_study(load_study(path), out, progress=False, report=lines.append)
    assert (run.ran, run.cached) == (0, 6)
    assert lines[0].startswith("nothing to run: all 6 cells")
    assert lines[1].startswith("2 of the finished cells were computed by other spcopyro source")
    assert "--rerun-stale" in lines[1] and source_digest() in lines[1]
    assert "**Cells of 3 versions of spcopyro's source**" in (out / "report.md").read_text()
    again = run_study(load_study(path), out, progress=False, rerun_stale=True)
    assert (again.ran, again.cached) == (2, 4)
    assert {r["source_digest"] for r in read_table(out / "results.csv")} == {source_digest()}
    assert "versions of spcopyro's source" not in (out / "report.md").read_text()
    lines.clear()
    run_study(load_study(path), out, progress=False, report=lines.append, rerun_stale=True)
    assert len(lines) == 1 and lines[0].startswith("nothing to run")


def test_package_digest_covers_python_sources_only(tmp_path):
    from spcopyro.study.cells import package_digest

    (tmp_path / "sub").mkdir()
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    first = package_digest(tmp_path)
    (tmp_path / "notes.md").write_text("not code")
    (tmp_path / "sub" / "b.pyc").write_bytes(b"compiled")
    assert package_digest(tmp_path) == first
    (tmp_path / "sub" / "b.py").write_text("y = 3\n")
    assert package_digest(tmp_path) != first
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    (tmp_path / "sub" / "b.py").rename(tmp_path / "b2.py")
    assert package_digest(tmp_path) != first  # a file's path counts


def test_cells_store_their_label_maps_and_the_report_draws_them(in_process, tmp_path):
    from spcopyro.study.maps import load_label_map
    from spcopyro.study.report import write_report

    _, out = in_process
    rows = read_table(out / "results.csv")
    for row in rows:
        stored = load_label_map(out, row)
        assert stored is not None and row["label_map"] == f"maps/{row['key']}.npz"
        assert stored.labels.shape == stored.grid.shape == stored.truth.shape
        free = stored.grid.free
        assert (stored.labels[free] >= 0).all() and (stored.labels[~free] == -1).all()
    report = (out / "report.md").read_text()
    assert "![maps_small](maps_small.png)" in report
    copy = tmp_path / "copy"  # the table and the stored maps alone redraw it
    copy.mkdir()
    (copy / "results.csv").write_bytes((out / "results.csv").read_bytes())
    (copy / "maps").symlink_to(out / "maps")
    write_report(copy / "results.csv", copy / "report.md", title="tiny")
    assert (copy / "maps_small.png").stat().st_size > 1000
    assert (copy / "report.md").read_text() == report


def test_results_parquet_equals_the_csv(in_process):
    pytest.importorskip("pyarrow", reason="the parquet extra (pyarrow)")
    from spcopyro.study.table import PARQUET, read_parquet

    _, out = in_process
    csv_rows, parquet_rows = read_table(out / "results.csv"), read_parquet(out / PARQUET)
    assert parquet_rows == csv_rows and list(parquet_rows[0]) == list(COLUMNS)
    assert isinstance(parquet_rows[0]["seed"], int) and isinstance(parquet_rows[0]["ari"], float)


def test_no_parquet_without_pyarrow(tmp_path, monkeypatch):
    from spcopyro.study.table import write_parquet

    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow raises ImportError
    assert write_parquet(tmp_path / "results.parquet", [{"seed": 1}]) is None
    assert not (tmp_path / "results.parquet").exists()


@pytest.mark.parametrize(
    "extra, words",
    [
        ('scoring = "comparison"\nari_every = 2', ["ari_every", "scoring"]),
        ("ari_every = 0.5", ["ari_every", "0.5"]),
    ],
)
def test_ari_every_is_checked(tmp_path, extra, words):
    text = TINY.replace('baselines = ["F-geometry"]', extra)
    with pytest.raises(StudyError) as caught:
        load_study(_write(tmp_path, text))
    assert all(word in str(caught.value) for word in words), caught.value


def test_ari_every_needs_fits_from_random_labels(tmp_path):
    text = TINY.replace("sweeps = 8", "sweeps = 8\nari_every = 2").replace(
        'preset = "paper-dp"', 'preset = "paper-dp"\ninit = "rooms"'
    )
    with pytest.raises(StudyError, match="variant 'dp' sets fit keywords"):
        load_study(_write(tmp_path, text))
    study = load_study(_write(tmp_path, TINY.replace("sweeps = 8", "sweeps = 8\nari_every = 2")))
    keys = {c.key for c in cells_of(study)} & {c.key for c in cells_of(load_study(_write(
        tmp_path, TINY, "plain.toml")))}  # fmt: skip
    assert len(keys) == 2  # the variants' keys change with it; the baseline's do not


def test_held_out_folds_of_a_one_trial_house_name_it():
    """The message began ``None:`` for a house not read from a folder."""
    from spcopyro.experiments.table import heldout_folds
    from spcopyro.synthetic import HouseSpec, make_house

    spec = HouseSpec(height=24, width=30, num_rooms=2, min_room_size=8, num_trials=1)
    with pytest.raises(ValueError, match="^house 'one': held-out folds need >= 2 trials"):
        next(heldout_folds(make_house(seed=0, spec=spec, name="one")))


_DIGEST_AT_IMPORT = """
import json, sys
from pathlib import Path
from spcopyro.study import cells
package = Path(cells.__file__).resolve().parents[1]
with open(package / "model.py", "a") as edited:  # an edit while the study runs
    edited.write("# edited\\n")
print(json.dumps({"package": str(package), "recorded": cells.source_digest(),
                  "files_now": cells.package_digest(package)}))
"""


def test_the_source_digest_is_of_the_code_imported_not_of_later_edits(tmp_path):
    """A cell's source_digest was read from disk when first asked for (after the first cell),
    so a source file edited while a study ran changed the digest the cells recorded: it is
    read when the study's code is imported."""
    from spcopyro.study.cells import package_digest

    package = Path(__file__).resolve().parents[1] / "spcopyro"
    copy = tmp_path / "spcopyro"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = package_digest(copy)
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    done = subprocess.run([sys.executable, "-c", _DIGEST_AT_IMPORT], capture_output=True,
                          text=True, env=env, cwd=tmp_path, timeout=300, check=True)  # fmt: skip
    record = json.loads(done.stdout.strip().splitlines()[-1])
    assert record["package"] == str(copy.resolve())  # the copy ran, not the checkout
    assert record["files_now"] != before  # the edit changed the files
    assert record["recorded"] == before  # ... not the digest of the code that was imported


def test_quality_time_figure_says_its_axes_in_words():
    """quality_time.png's title read "ari against seconds" (two results.csv columns): it says
    what the ARI is against (a public house's region truth, a synthetic house's ground truth)
    and that the time is wall-clock seconds per fit."""
    from spcopyro.study.figures import quality_time_figure

    def row(data, kind):
        return dict(data=data, data_kind=kind, variant="cavi", method="cavi", seconds=2.0,
                    ari=0.5, status="ok")  # fmt: skip

    titles = {}
    for kinds in (("public",), ("synthetic",), ("synthetic", "public")):
        fig = quality_time_figure([row(f"d{i}", kind) for i, kind in enumerate(kinds)])
        titles[kinds] = " ".join(fig._suptitle.get_text().split())  # noqa: SLF001
        assert [ax.get_ylabel() for ax in fig.axes] == ["ARI"] * len(kinds)
        assert {ax.get_xlabel() for ax in fig.axes} == {"wall-clock seconds per fit (log scale)"}
    tail = ", against wall-clock seconds per fit: seeds (faint), mean ± sd (marked)"
    assert titles == {
        ("public",): "ARI against the region truth" + tail,
        ("synthetic",): "ARI against the ground truth" + tail,
        ("synthetic", "public"): "ARI against the truth (a public house's: the region truth)"
        + tail,
    }


def test_two_variants_of_one_method_get_names_of_their_own_in_both_figures(tmp_path):
    """A study of variants ``default`` and ``gibbs`` (gamma 3), both of method gibbs, named both
    rows "gibbs" in quality_time.png's legend and the maps' panel titles (``row_name``), so the
    two could not be told apart; the one that sets something now says what (its overrides)."""
    import numpy as np

    from spcopyro.maps import OccupancyGrid
    from spcopyro.study.figures import quality_time_figure
    from spcopyro.study.maps import label_map_arrays, row_label, row_names, source_panels

    study = study_from_dict({
        "study": {"name": "twin", "sweeps": 5},
        "variants": {"default": {}, "gibbs": {"gamma": 3.0}, "lbp": {"method": "lbp"}},
        "data": {"small": small_house()},
    })  # fmt: skip
    rows = [c.inputs() for c in cells_of(study)]  # the table's rows, before any fit
    occupancy = np.zeros((3, 4), dtype=np.int8)
    grid = OccupancyGrid(occupancy, 0.05, (0.0, 0.0, 0.0))
    (tmp_path / "maps").mkdir()
    labels = np.zeros((3, 4), dtype=np.int64)
    np.savez(
        tmp_path / "maps" / "a.npz", **label_map_arrays(labels, type("H", (), {"grid": grid}), None)
    )
    for k, row in enumerate(rows):
        row.update(status="ok", seconds=1.0 + k, ari=0.5, label_map="maps/a.npz")
    names = ["gibbs", "gibbs (gamma=3.0)", "lbp"]
    assert list(row_names(rows).values()) == names
    label = row_label(rows)  # the one naming of the maps' panels, given or not
    assert [label(row) for row in rows] == names
    (legend,) = quality_time_figure(rows).legends
    assert [t.get_text() for t in legend.get_texts()] == names
    _, panels, _ = source_panels(rows, tmp_path, "small")
    assert [name for name, _ in panels] == names
    same = [{**row, "overrides": ""} for row in rows]  # nothing tells them apart: their names
    assert list(row_names(same).values()) == ["default / gibbs", "gibbs / gibbs", "lbp"]


def test_quality_time_shows_a_held_out_source_s_word_score_beside_its_map_score():
    """Rows of a held-out source carry ``top1`` (held-out word prediction); quality_time.png drew
    only the ARI against time, so a method that bought its map with its words looked best. A
    source with word scores gets a second panel of them; one without keeps its one panel."""
    from spcopyro.study.figures import quality_time_figure

    def row(data, method, seconds, ari, top1=None):
        kind = "public" if top1 is not None else "synthetic"
        return dict(data=data, variant="default", method=method, seconds=seconds, ari=ari,
                    top1=top1, status="ok", data_kind=kind)  # fmt: skip

    rows = [row("room", "gibbs", 100.0, 0.6, 0.34), row("room", "cavi", 2.0, 0.5, 0.21),
            row("room", "cavi", 3.0, 0.5, 0.25), row("small", "gibbs", 10.0, 0.9)]  # fmt: skip
    fig = quality_time_figure(rows)
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in panels] == ["room", "room: held-out words", "small"]
    assert panels[1].get_ylabel() == "held-out top-1 word accuracy"
    means = sorted(line.get_ydata()[0] for line in panels[1].lines if line.get_marker() == "o")
    assert means == pytest.approx([0.23, 0.34])
    assert "held-out top-1 word accuracy" in fig._suptitle.get_text().replace("\n", " ")
    plain = quality_time_figure([r for r in rows if r["data"] == "small"])
    assert [ax.get_title() for ax in plain.axes if ax.get_title()] == ["small"]


def test_quality_time_puts_each_source_s_panels_on_one_line():
    """With word scores the panels ran two a line in one stream: a synthetic house (no ``top1``,
    one panel) before a held-out public one split the public one's ARI panel (end of line 1)
    from its word panel (start of line 2). Each source now has a line of its own."""
    from spcopyro.study.figures import quality_time_figure

    def row(data, seconds, top1=None):
        kind = "synthetic" if top1 is None else "public"
        return dict(data=data, variant="default", method="gibbs", seconds=seconds, ari=0.5,
                    top1=top1, status="ok", data_kind=kind)  # fmt: skip

    fig = quality_time_figure([row("small", 10.0), row("room", 2.0, 0.3), row("other", 3.0)])
    at = {ax.get_title(): ax.get_position() for ax in fig.axes}
    assert list(at) == ["small", "room", "room: held-out words", "other"]
    room, words = at["room"], at["room: held-out words"]
    assert room.y0 == pytest.approx(words.y0) and room.x0 < words.x0
    assert at["small"].y0 > room.y0 > at["other"].y0  # a line each, in the table's order
    assert at["small"].x0 == pytest.approx(room.x0) == pytest.approx(at["other"].x0)


def test_the_maps_name_the_table_s_rows_once(tmp_path, monkeypatch):
    """write_house_maps named the whole table's rows (row_names) once per source, and
    source_panels did so even when given ``label`` (every call of experiment.write_figures)."""
    import numpy as np

    from spcopyro.maps import OccupancyGrid
    from spcopyro.study import maps

    grid = OccupancyGrid(np.zeros((3, 4), dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    (tmp_path / "maps").mkdir()
    arrays = maps.label_map_arrays(
        np.zeros((3, 4), dtype=np.int64), type("H", (), {"grid": grid}), None
    )
    np.savez(tmp_path / "maps" / "a.npz", **arrays)
    rows = [dict(data=data, variant="default", method="gibbs", seed=0, status="ok",
                 data_kind="synthetic", label_map="maps/a.npz")
            for data in ("h1", "h2", "h3")]  # fmt: skip
    calls = []
    named = maps.row_names
    monkeypatch.setattr(maps, "row_names", lambda rows: calls.append(1) or named(rows))
    monkeypatch.setattr(maps, "plot_label_maps", lambda *args: args[2])
    assert len(maps.write_house_maps(rows, tmp_path)) == 3
    assert len(calls) == 1
    _, panels, _ = maps.source_panels(rows, tmp_path, "h1", label=lambda row: "mine")
    assert len(calls) == 1 and [name for name, _ in panels] == ["mine"]


def test_the_maps_read_the_drawn_seed_s_stored_maps_once(tmp_path, monkeypatch):
    """source_panels read every stored map of a source at every seed (each once since
    6704dcd) though it draws one seed's: it reads the drawn seed's files only now, each once,
    passing over a lower seed whose cells stored no map."""
    import numpy as np

    from spcopyro.maps import OccupancyGrid
    from spcopyro.study import maps

    grid = OccupancyGrid(np.zeros((3, 4), dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    (tmp_path / "maps").mkdir()
    rows = []
    for data in ("h1", "h2"):
        for seed in (1, 0):
            for variant in ("default", "other"):
                key = f"{data}_{seed}_{variant}"
                labels = np.full((3, 4), seed, dtype=np.int64)  # which seed's map was drawn
                arrays = maps.label_map_arrays(labels, type("H", (), {"grid": grid}), None)
                np.savez(tmp_path / "maps" / f"{key}.npz", **arrays)
                rows.append(dict(data=data, variant=variant, method="gibbs", seed=seed,
                                 status="ok", data_kind="synthetic",
                                 label_map=f"maps/{key}.npz"))  # fmt: skip
    read, drawn = [], []
    load = maps.load_label_map
    monkeypatch.setattr(maps, "load_label_map",
                        lambda f, row: read.append(row["label_map"]) or load(f, row))  # fmt: skip
    monkeypatch.setattr(maps, "plot_label_maps", lambda *args: drawn.append(args[1]) or args[2])
    assert len(maps.write_house_maps(rows, tmp_path)) == 2
    drawn_files = sorted(row["label_map"] for row in rows if row["seed"] == 0)
    assert sorted(read) == drawn_files  # seed 0's, each once (was every seed's, 8 reads)
    names = [[name for name, _ in panels] for panels in drawn]
    assert names == [["gibbs", "other / gibbs"]] * 2
    assert all((labels == 0).all() for panels in drawn for _, labels in panels)  # the first seed
    failed = [dict(r, status="failed") if r["seed"] == 0 else r for r in rows]
    read.clear()
    _, panels, seed = maps.source_panels(failed, tmp_path, "h1")
    assert seed == 1 and all((labels == 1).all() for _, labels in panels)
    assert sorted(read) == sorted(r["label_map"] for r in rows if r["data"] == "h1")  # 0: none
    read.clear()
    _, panels, seed = maps.source_panels(rows, tmp_path, "h2", seed=1)
    assert seed == 1 and sorted(read) == ["maps/h2_1_default.npz", "maps/h2_1_other.npz"]
    assert maps.source_panels(failed, tmp_path, "h1", seed=0) is None


def test_sentence_scores_list_no_words_for_a_concept_where_none_was_heard():
    """concept_words lists each large concept's words as fit does (``listed_top_words``): none
    for a concept of 50+ cells where no word was heard (its w row is the prior's, the words
    tied), which filler_top_share then leaves out; they listed its tie-order first words and
    counted it."""
    import math

    import numpy as np

    from spcopyro.config import SpCoConfig

    tied = [("the", 0.1), ("a", 0.1), ("is", 0.1)]  # tie order: fillers first

    class Fitted:
        config = SpCoConfig(num_concepts=3)
        labels = np.repeat([0, 1, 2], evaluate.SENTENCE_MIN_CELLS)  # [N]

        def concepts_in_use(self):
            return np.array([0, 1, 2])

        def heard(self, concept):
            return [4.0, 6.0, 0.0][concept]  # concept 2: no word heard

        def top_words(self, concept, n):
            return [[("the", 0.5), ("kitchen", 0.3)], [("sofa", 0.6), ("the", 0.2)], tied][concept]

    scores = evaluate._sentence_scores(Fitted())
    assert json.loads(scores["concept_words"]) == [["the", "kitchen"], ["sofa", "the"], []]
    assert scores["filler_top_share"] == 0.5  # of the two concepts listing words
    unheard = Fitted()
    unheard.heard = lambda concept: 0.0
    assert math.isnan(evaluate._sentence_scores(unheard)["filler_top_share"])
