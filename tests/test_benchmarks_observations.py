"""The benchmarks of the observations and their uses: features.py (image features),
word_tables.py (the word tables; whether a concept's top word names its category),
footprint.py (the cells the observations reach) and navigation.py (going to a place named by a
word).

--quick runs are smoke tests: their numbers are never asserted here. The other tests import
a script from benchmarks/ (the ``script`` fixture, tests/conftest.py: their folder on
sys.path, as when they run) and call its functions on small inputs.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math

import pytest
from benchmark_setup import _Measuring, run_benchmark


@pytest.mark.slow
def test_features_benchmark_quick(tmp_path):
    out = tmp_path / "features.json"
    done = run_benchmark("features.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert out.is_file() and json.loads(out.read_text())


@pytest.mark.slow
def test_word_tables_benchmark_quick(tmp_path):
    out = tmp_path / "words.json"
    done = run_benchmark("word_tables.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "| original-code, gamma 3 | mean given labels |" in done.stdout
    records = json.loads(out.read_text())["records"]
    assert set(records["paper-dp"]) == {"draw", "mean given labels", "mean over samples"}


def test_word_tables_a_fit_that_did_not_model_its_words_is_not_measured(script):
    """word_tables' top-word score is nan (not measured) where no concept lists a word."""
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house
    from spcopyro.synthetic import HouseSpec, make_house

    word_tables = script("word_tables")
    house = make_house(seed=0, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=2))
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    result = fit_house(house, settings, sweeps=3, progress=False)
    names = house.category_names
    modelled = word_tables.top_word_agreement(result, house.truth, names)
    assert 0.0 <= modelled <= 1.0
    unmodelled = dataclasses.replace(result, config=result.config.replace(use_words=False))
    assert math.isnan(word_tables.top_word_agreement(unmodelled, house.truth, names))


def test_word_tables_table_leaves_unmeasured_seeds_out_and_says_so(script):
    """... and its table says "not measured" rather than 0.000 as if every top word were wrong."""

    def row(share: float) -> dict[str, float]:
        return {"matching_rate_pi": 0.5, "matching_rate_area": 0.5,
                "top_word_names_category": share}  # fmt: skip

    nan = float("nan")
    records = {"s": {"none": [row(nan), row(nan)], "some": [row(nan), row(0.5)],
                     "all": [row(0.25), row(0.75)]}}  # fmt: skip
    lines = script("word_tables").table(records).splitlines()
    assert lines[2].endswith("| 0.500 ± 0.000 | not measured |")
    assert lines[3].endswith("| 0.500 ± 0.000 (1/2 seeds) |")
    assert lines[4].endswith("| 0.500 ± 0.250 |")


@pytest.mark.slow
def test_navigation_benchmark_quick(tmp_path):
    out = tmp_path / "navigation.json"
    done = run_benchmark("navigation.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert results["presets"] == ["coarse", "paper-dp"]
    for row in results["synthetic"].values():
        assert row["utterances"] > 0
        for method in ("coarse", "paper-dp", "baseline"):
            assert 0.0 <= row[method]["success"] <= 1.0
        assert 0.0 <= row["coarse"]["hierarchical"] <= 1.0
    assert "paper-dp success" in done.stdout and "baseline path/shortest" in done.stdout


@pytest.mark.slow
def test_footprint_quick_leaves_no_partial_file(tmp_path):
    out = tmp_path / "footprint.json"
    done = run_benchmark("footprint.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(out.read_text())["rows"]
    assert not (tmp_path / "footprint.partial.json").exists()


def test_footprint_warms_up_before_the_first_timed_fit(script, monkeypatch):
    """footprint.py's first fit (the first house's 'no observations') paid numba's load in its
    seconds: a --quick run printed 1.5 s a fit against 0.1 s for the fits with observations.
    Untimed short fits, without and with observations, come first."""
    footprint = script("footprint")
    calls = []

    def fit(house, settings, sweeps, seed):
        calls.append((settings.model.use_images, sweeps))
        if sweeps == 7:  # the first timed fit
            raise _Measuring

    monkeypatch.setattr(footprint, "fit_spco", fit)
    args = argparse.Namespace(presets=["paper-dp"], houses=["synthetic"], seeds=[0], sweeps=7,
                              radii=[0.0])  # fmt: skip
    with pytest.raises(_Measuring):
        footprint.run(args)
    warm = getattr(footprint, "WARMUP_SWEEPS", 2)
    assert calls == [(False, warm), (True, warm), (False, 7)], calls
