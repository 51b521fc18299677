"""The warning of a degenerate map (issue 21, item 5): one concept over most of the free cells
while words said at different places lie inside it (:mod:`spcopyro.results.map_checks`)."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pytest

from spcopyro.config import DEFAULT_PRESET, preset
from spcopyro.fit.house import fit_house
from spcopyro.results.map_checks import (
    DEGENERATE_SEPARATION,
    DEGENERATE_SHARE,
    NAMED_WORDS,
    degenerate_map_warning,
)
from spcopyro.synthetic import HouseSpec, make_house


def _utterances(*said: tuple[str, int, float]) -> tuple[np.ndarray, np.ndarray, list[tuple]]:
    """Utterances (word, cell, x): each on free cell ``cell`` at world (x, 0)."""
    cells = np.array([cell for _, cell, _ in said], dtype=np.int64)  # [U]
    xy = np.array([[x, 0.0] for _, _, x in said])  # [U, 2]
    return cells, xy, [(word,) for word, _, _ in said]


def _kitchen_and_bedroom(apart: float) -> tuple[np.ndarray, np.ndarray, list[tuple]]:
    """Three "kitchen"s on cell 0 at x = 0, two "bedroom"s on cell 9 at x = ``apart``."""
    return _utterances(
        ("kitchen", 0, 0.0), ("kitchen", 0, 0.0), ("kitchen", 1, 0.1),
        ("bedroom", 9, apart), ("bedroom", 9, apart),
    )  # fmt: skip


def test_one_concept_over_words_said_apart_warns_naming_them():
    labels = np.full(10, 3)
    warning = degenerate_map_warning(labels, *_kitchen_and_bedroom(3.0))
    assert warning is not None
    assert "one concept (3) holds 100% of the free cells" in warning
    assert "kitchen (3), bedroom (2)" in warning  # most heard first, with counts
    assert "--gamma" in warning and f"--preset {DEFAULT_PRESET}" in warning


def test_words_said_close_together_do_not_warn():
    labels = np.zeros(10, dtype=np.int64)
    assert degenerate_map_warning(labels, *_kitchen_and_bedroom(0.5)) is None
    assert DEGENERATE_SEPARATION > 0.5


def test_a_map_split_between_the_words_does_not_warn():
    halves = np.repeat([0, 1], 5)  # 50%: no concept holds most of the map
    assert degenerate_map_warning(halves, *_kitchen_and_bedroom(3.0)) is None
    # 70% in concept 0, but the bedroom (cell 9) is concept 1's: one word inside, no warning
    most = np.repeat([0, 1], [7, 3])
    assert degenerate_map_warning(most, *_kitchen_and_bedroom(3.0)) is None


def test_a_share_up_to_the_threshold_does_not_warn():
    assert DEGENERATE_SHARE == 0.6
    for share in (0.55, 0.6):  # "more than" 60%: exactly 60% is no warning
        labels = np.where(np.arange(100) < 100 * share, 0, 1)
        said = _utterances(("kitchen", 0, 0.0), ("bedroom", 50, 3.0))
        assert degenerate_map_warning(labels, *said) is None
    labels = np.where(np.arange(100) < 61, 0, 1)
    assert "holds 61%" in degenerate_map_warning(labels, *said)


def test_unplaced_utterances_and_word_list_length():
    labels = np.zeros(20, dtype=np.int64)
    # unplaced (-1) utterances are not inside any concept: one word left, no warning
    said = _utterances(("kitchen", 0, 0.0), ("bedroom", -1, 5.0))
    assert degenerate_map_warning(labels, *said) is None
    # a sentence: each token a word, counted once per utterance; at most NAMED_WORDS named
    words = [f"w{k}" for k in range(NAMED_WORDS + 2)]
    cells = np.arange(len(words) + 1)
    xy = np.array([[float(k), 0.0] for k in range(len(words) + 1)])
    utterances = [(w, w) for w in words] + [("w9", "here")]
    warning = degenerate_map_warning(labels, cells, xy, utterances)
    assert warning.startswith("one concept (0) holds 100%")
    assert "w9 (2), w0 (1), w1 (1)" in warning and "and 3 more" in warning  # 11 words
    with pytest.raises(ValueError, match="same utterances"):
        degenerate_map_warning(labels, cells[:2], xy, utterances)


def test_fit_house_logs_the_warning_of_a_one_concept_map(caplog):
    """A real fit with one concept (L = 1) on a small synthetic house of three named rooms."""
    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=1))
    settings = preset("original-code", num_concepts=1, gamma=3.0)
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        result = fit_house(house, settings, sweeps=2, progress=False)
    assert (result.labels == 0).all()
    [warning] = [r.getMessage() for r in caplog.records if "one concept" in r.getMessage()]
    assert warning.startswith("one concept (0) holds 100% of the free cells")
    heard = {w for u in house.observations.utterances for w in u}
    named = warning.split("lie inside it: ")[1].split(";")[0]
    assert sum(word in heard for word in named.replace(",", " ").split()) >= 2


def test_a_map_whose_resolution_is_twice_too_large_is_warned_about(caplog):
    """Issue 22 item 4: a map whose yaml resolution was off by 2x fitted without a word."""
    import logging

    from spcopyro.config import preset
    from spcopyro.fit.house import prepare_model_data
    from spcopyro.maps import OccupancyGrid
    from spcopyro.results.map_checks import coverage_warning
    from spcopyro.synthetic import HouseSpec, make_house

    house = make_house(seed=0, spec=HouseSpec())
    assert coverage_warning(house) is None
    wrong = OccupancyGrid(house.grid.occupancy, 2 * house.grid.resolution, house.grid.origin)
    wrong_house = dataclasses.replace(house, grid=wrong, truth=None, category_names=None)
    message = coverage_warning(wrong_house)
    assert message is not None and "resolution (0.2 m)" in message
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        prepare_model_data(wrong_house, preset("paper-dp"))
    assert any("may be wrong" in r.getMessage() for r in caplog.records)


def test_an_all_zero_feature_file_is_warned_about(tmp_path, caplog):
    """Issue 22 item 4: an all-zero Ft.csv fitted without a warning."""
    import logging

    from spcopyro.data import load_house
    from spcopyro.synthetic import HouseSpec, write_synthetic

    room = write_synthetic(tmp_path, seed=1, spec=HouseSpec(height=30, width=36, num_rooms=2))
    rows = (room / "Ft.csv").read_text().splitlines()
    (room / "Ft.csv").write_text("\n".join(",".join("0" for _ in r.split(",")) for r in rows))
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        load_house(room)
    messages = [r.getMessage() for r in caplog.records]
    assert any("Ft.csv: all image feature rows are all zero" in m for m in messages), messages


def test_a_variational_fits_one_concept_warning_names_a_way_its_method_takes(caplog):
    """A one-concept CAVI map was told to try "--merge-moves 0.2", which fit refuses with
    --method cavi (an option of the Gibbs sampler); it names --method gibbs with it."""
    sampled = degenerate_map_warning(np.full(10, 3), *_kitchen_and_bedroom(3.0))
    assert "(try a lower --gamma, --merge-moves 0.2 so that regions can split" in sampled
    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=1))
    settings = preset("original-code", num_concepts=1, gamma=3.0)
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        fit_house(house, settings, method="cavi", sweeps=2, progress=False)
    [warning] = [r.getMessage() for r in caplog.records if "one concept" in r.getMessage()]
    assert "(try a lower --gamma, --method gibbs --merge-moves 0.2 so that regions" in warning
