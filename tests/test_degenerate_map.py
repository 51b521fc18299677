"""The warning of a degenerate map (issue 21, item 5): one concept over most of the free cells
while words said at different places lie inside it, or lie outside it in small concepts
(:mod:`spcopyro.results.map_checks`)."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pytest

from spcopyro.config import DEFAULT_PRESET, preset
from spcopyro.fit.house import fit_house, preset_fit_kwargs
from spcopyro.results.map_checks import (
    DEGENERATE_PATCHES,
    DEGENERATE_SEPARATION,
    DEGENERATE_SHARE,
    NAMED_WORDS,
    PATCHES_HEARD,
    PATCHES_SHARE,
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


def test_one_word_over_the_limit_is_named_not_counted():
    """shown_count's rule: "and 1 more" takes as much of the line as the word it hides."""
    labels = np.zeros(20, dtype=np.int64)
    words = [f"w{k}" for k in range(NAMED_WORDS + 1)]
    cells = np.arange(len(words))
    xy = np.array([[float(k), 0.0] for k in range(len(words))])
    warning = degenerate_map_warning(labels, cells, xy, [(w,) for w in words])
    assert f"{words[-1]} (1)" in warning and "more" not in warning


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
    assert ("(try a lower gamma (fit's --gamma), GibbsOptions(merge_moves=0.2) (fit's "
            "--merge-moves 0.2) so that regions can split") in sampled  # fmt: skip
    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=1))
    settings = preset("original-code", num_concepts=1, gamma=3.0)
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        fit_house(house, settings, method="cavi", sweeps=2, progress=False)
    [warning] = [r.getMessage() for r in caplog.records if "one concept" in r.getMessage()]
    assert (
        "(try a lower gamma (fit's --gamma), method='gibbs' with GibbsOptions("
        "merge_moves=0.2) (fit's --method gibbs --merge-moves 0.2) so that regions"
    ) in warning
    # a library caller is named the Python settings, spcopyro fit's user the flags (both)
    assert "or the default preset 'coarse' (fit's --preset coarse) if the fit" in warning


def _one_concept_and_patches(patch: int) -> tuple[np.ndarray, tuple]:
    """1000 free cells: concept 7 over all but two patches of ``patch`` cells, concept 1 on
    cells 0.. around the kitchen (x = 0) and concept 2 on cells 500.. around the bedroom
    (x = 4); one "toilet" heard inside concept 7 (cell 900, x = 8)."""
    labels = np.full(1000, 7)
    labels[:patch], labels[500 : 500 + patch] = 1, 2
    said = _utterances(
        ("kitchen", 0, 0.0), ("kitchen", 1, 0.2), ("bedroom", 500, 4.0),
        ("bedroom", 501, 4.1), ("bedroom", 502, 3.9), ("toilet", 900, 8.0),
    )  # fmt: skip
    return labels, said


def test_one_concept_beside_words_in_small_patches_warns_naming_them_and_the_sizes():
    """CAVI on room1dk5 (original-code, gamma 3, 100 iterations) put 94% of the free cells in
    one concept, the place words in concepts of 12-124 cells around where they were said
    (together 5% of the map), and gave no warning: the words were not inside the big one."""
    labels, said = _one_concept_and_patches(30)  # the patches: 6% of the free cells
    warning = degenerate_map_warning(labels, *said, sampled=False)
    assert warning is not None
    assert warning.startswith(
        "one concept (7) holds 94% of the free cells and 1 of the 6 placed utterances: "
        "toilet (1), while words said at different places (up to 3.9 m apart) lie outside it "
        "in small concepts, together 6.0% of the free cells: bedroom (3 in 1 concept of 30 "
        "cells), kitchen (2 in 1 concept of 30 cells); the map gives these words patches"
    )
    assert "--method gibbs --merge-moves 0.2" in warning
    # a word in several patches: their count and the range of their sizes
    labels[1] = 3
    warning = degenerate_map_warning(labels, *said)
    assert "kitchen (2 in 2 concepts of 1-29 cells)" in warning
    assert "together 6.0% of the free cells" in warning


def test_words_outside_in_concepts_the_size_of_rooms_do_not_warn():
    """The rooms beside one large one: the words' concepts hold DEGENERATE_PATCHES or more."""
    assert DEGENERATE_PATCHES == 0.2
    labels, said = _one_concept_and_patches(100)  # 20%: rooms, not patches
    assert degenerate_map_warning(labels, *said) is None
    labels, said = _one_concept_and_patches(99)  # 19.8%
    assert "together 19.8% of the free cells" in degenerate_map_warning(labels, *said)


def test_the_patches_warning_needs_a_concept_over_half_the_map_holding_few_words():
    assert PATCHES_SHARE == 0.5 and PATCHES_HEARD == 0.25
    labels, said = _one_concept_and_patches(30)
    labels[550:] = 5  # concept 7 on 490 cells (49%), concept 5 on 450 cells
    said[0][5] = 540  # the toilet said on concept 7
    assert degenerate_map_warning(labels, *said) is None
    labels[550] = 7  # 49.1%
    assert degenerate_map_warning(labels, *said) is None
    labels[551:560] = 7  # 50%: "more than" half
    assert degenerate_map_warning(labels, *said) is None
    labels[560] = 7  # 50.1%
    assert "holds 50% of the free cells and 1 of the 6 placed utterances: toilet (1), while" in (
        degenerate_map_warning(labels, *said)
    )
    # the largest concept holds 2 of 7 utterances (over a quarter): a room where words are said
    labels, (cells, xy, words) = _one_concept_and_patches(30)
    cells, xy, words = (
        np.append(cells, 901),
        np.concatenate([xy, [[8.0, 0.0]]]),
        [*words, ("toilet",)],
    )
    assert degenerate_map_warning(labels, cells, xy, words) is None
    # a further bedroom outside: 2 of 8, a quarter ("at most")
    cells, xy, words = (
        np.append(cells, 503),
        np.concatenate([xy, [[4.0, 0.0]]]),
        [*words, ("bedroom",)],
    )
    warning = degenerate_map_warning(labels, cells, xy, words)
    assert "holds 94% of the free cells and 2 of the 8 placed utterances: toilet (2)," in warning


def test_words_outside_said_at_one_place_do_not_warn():
    labels, said = _one_concept_and_patches(30)
    cells, xy, words = said
    xy[2:5, 0] = 1.0  # the bedroom said 1 m from the kitchen: one place
    assert degenerate_map_warning(labels, cells, xy, words) is None
    assert DEGENERATE_SEPARATION > 1.0


def test_a_default_preset_fits_advice_names_the_inference_fit_house_was_not_given(caplog):
    """A library fit from ``preset("coarse")``'s settings (a variant: one concept) was told to
    try "the default preset 'coarse' ... if the fit used another": it used coarse, but not the
    inference ``spcopyro fit`` runs for it (``preset_fit_kwargs``). The advice says so; given
    those options it names no preset; settings of another preset keep the old advice."""
    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=1))
    settings = preset(DEFAULT_PRESET, num_concepts=1)

    def warning(**kwargs: object) -> str:
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="spcopyro"):
            fit_house(house, settings, sweeps=2, progress=False, **kwargs)
        [message] = [r.getMessage() for r in caplog.records if "one concept" in r.getMessage()]
        return message

    skipped = warning()
    assert "if the fit used another" not in skipped
    assert skipped.endswith(
        "so that regions can split, or the inference spcopyro fit runs for preset 'coarse': the "
        "settings came from preset 'coarse' but fit_house was not given "
        "preset_fit_kwargs('coarse')'s options)"
    )
    given = warning(**preset_fit_kwargs(DEFAULT_PRESET, marginal_samples=2))
    assert given.endswith("(fit's --merge-moves 0.2) so that regions can split)")
    other = degenerate_map_warning(np.full(10, 3), *_kitchen_and_bedroom(3.0))
    assert other.endswith("or the default preset 'coarse' (fit's --preset coarse) if the fit "
                          "used another)")  # fmt: skip


@pytest.mark.parametrize("preset_name", [DEFAULT_PRESET, "original-code"])
def test_spcopyro_fits_advice_names_the_default_preset_only_after_another(
    tmp_path, capsys, preset_name
):
    """``spcopyro fit`` with the default preset, which runs that preset's inference, told the
    user to try "the default preset 'coarse' (fit's --preset coarse) if the fit used another":
    the command knows which preset it ran, but passed nothing. After the default preset the
    advice names no preset; after another it still names the default one."""
    from spcopyro.cli.main import main
    from spcopyro.synthetic import write_synthetic

    spec = HouseSpec(height=40, width=50, num_rooms=3, num_trials=1)
    data = write_synthetic(tmp_path / "data", seed=1, spec=spec)
    argv = ["fit", str(data), "--out", str(tmp_path / "fit"), "--sweeps", "2", "--no-figures",
            "--concepts", "1", "--preset", preset_name]  # fmt: skip
    assert main(argv) == 0
    [line] = [x for x in capsys.readouterr().err.splitlines() if "one concept (0) holds" in x]
    if preset_name == DEFAULT_PRESET:
        assert "preset" not in line.split("(try a lower")[1], line
        assert line.endswith("--merge-moves 0.2) so that regions can split)"), line
    else:
        assert line.endswith(f"or the default preset {DEFAULT_PRESET!r} (fit's --preset "
                             f"{DEFAULT_PRESET}) if the fit used another)"), line  # fmt: skip
