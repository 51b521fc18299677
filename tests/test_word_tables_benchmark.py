"""benchmarks/word_tables.py's top-word score: nan (not measured) where no concept lists a
word, and its table says "not measured" rather than 0.000 as if every top word were wrong."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import pytest

from spcopyro.config import preset
from spcopyro.fit.house import fit_house
from spcopyro.synthetic import HouseSpec, make_house

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture
def word_tables(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import word_tables

    yield word_tables
    sys.modules.pop("word_tables", None)


def test_a_fit_that_did_not_model_its_words_is_not_measured(word_tables):
    house = make_house(seed=0, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=2))
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    result = fit_house(house, settings, sweeps=3, progress=False)
    names = house.category_names
    modelled = word_tables.top_word_agreement(result, house.truth, names)
    assert 0.0 <= modelled <= 1.0
    unmodelled = dataclasses.replace(result, config=result.config.replace(use_words=False))
    assert math.isnan(word_tables.top_word_agreement(unmodelled, house.truth, names))


def test_the_table_leaves_unmeasured_seeds_out_and_says_so(word_tables):
    def row(share: float) -> dict[str, float]:
        return {"matching_rate_pi": 0.5, "matching_rate_area": 0.5,
                "top_word_names_category": share}  # fmt: skip

    nan = float("nan")
    records = {"s": {"none": [row(nan), row(nan)], "some": [row(nan), row(0.5)],
                     "all": [row(0.25), row(0.75)]}}  # fmt: skip
    lines = word_tables.table(records).splitlines()
    assert lines[2].endswith("| 0.500 ± 0.000 | not measured |")
    assert lines[3].endswith("| 0.500 ± 0.000 (1/2 seeds) |")
    assert lines[4].endswith("| 0.500 ± 0.250 |")
