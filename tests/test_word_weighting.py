"""The word weighting ``auto`` (the default): tf-idf when the utterances are sentences (at
least 30% of them of more than one token), counts otherwise; resolved once the data are known,
recorded as resolved (config.json, the data line), kept by an update
(:mod:`spcopyro.data.word_weighting`). It was tf-idf when any utterance was a sentence: one
"living room" in a house of single words switched it to tf-idf, which weighs down the place
words said most often."""

from __future__ import annotations

import dataclasses
import json
import math
import re

import numpy as np
import pytest

from spcopyro.baselines.spcoa import spcoa_data
from spcopyro.cli.main import main
from spcopyro.config import DataPreparation, preset
from spcopyro.data import cell_counts
from spcopyro.data.word_weighting import (
    TFIDF_SENTENCE_SHARE,
    AutoWeighting,
    auto_word_weighting,
    keeping_word_weighting,
    resolve_word_weighting,
    resolved_settings,
    sentence_count,
)
from spcopyro.fit.house import fit_house
from spcopyro.results.result import SpCoResult
from spcopyro.robot.online import check_compatible, fit_update
from spcopyro.synthetic import HouseSpec, make_house, write_synthetic
from spcopyro.synthetic.lexicon import FILLER_WORDS

SMALL = dict(height=40, width=50, num_rooms=3)


def _house(sentences: float):
    return make_house(seed=1, spec=HouseSpec(**SMALL, sentence_fraction=sentences))


def test_sentences_are_weighted_by_tfidf_single_words_are_counted():
    words, sentences = _house(0.0), _house(0.5)
    assert sentence_count(words.observations) == 0
    assert auto_word_weighting(words.observations).weighting == "count"
    said = sentence_count(sentences.observations)
    assert 0 < said < sentences.observations.num_utterances
    assert auto_word_weighting(sentences.observations).weighting == "tfidf"
    total = sentences.observations.num_utterances
    assert auto_word_weighting(sentences.observations).note == (
        f"auto: {said} of {total} utterances are sentences ({100 * said // total}%; tf-idf "
        "from 30%)"
    )
    # an explicit weighting is kept whatever the utterances are
    assert resolve_word_weighting("count", sentences.observations) == "count"
    assert resolve_word_weighting("tfidf", words.observations) == "tfidf"
    with pytest.raises(ValueError) as refused:
        resolve_word_weighting("bm25", words.observations)
    # spelt as DataPreparation's refusal (_util.messages.one_of), not "must be one of ..."
    assert str(refused.value) == "word_weighting='bm25': must be 'count', 'tfidf' or 'auto'"


def _named(observations, names: int, utterances: int | None = None):
    """``observations`` (its first ``utterances``, default all) with its first ``names``
    utterances the two-word place name "living room"."""
    keep = slice(0, utterances)
    said = tuple(
        ("living", "room") if i < names else tokens
        for i, tokens in enumerate(observations.utterances[keep])
    )
    return dataclasses.replace(
        observations,
        utterances=said,
        word_xy=observations.word_xy[keep],
        word_trial=observations.word_trial[keep],
    )


def test_a_few_two_word_names_in_a_house_of_single_words_are_still_counted():
    house = _house(0.0)
    total = house.observations.num_utterances
    for names in (1, 2):
        observations = _named(house.observations, names)
        assert sentence_count(observations) == names
        assert auto_word_weighting(observations).weighting == "count"  # was tf-idf: any sentence
        np.testing.assert_array_equal(
            cell_counts(house.grid, observations, word_weighting="auto").word_counts,
            cell_counts(house.grid, observations, word_weighting="count").word_counts,
        )
    one = _named(house.observations, 1)
    assert auto_word_weighting(one).note == (
        f"auto: 1 of {total} utterances is a sentence ({100 // total}%; tf-idf from 30%)"
    )


def test_tfidf_from_the_threshold_share_of_sentences_on():
    assert TFIDF_SENTENCE_SHARE == 0.3
    words = _house(0.0).observations
    total = words.num_utterances
    needed = math.ceil(TFIDF_SENTENCE_SHARE * total)  # 11 of 36: 30.6%; 10 are 27.8%
    assert auto_word_weighting(_named(words, needed - 1)).weighting == "count"
    assert auto_word_weighting(_named(words, needed)).weighting == "tfidf"
    # exactly the share: 3 of 10 (a float 0.3 * 10 would read 3.0000000000000004)
    assert auto_word_weighting(_named(words, 3, utterances=10)).weighting == "tfidf"
    assert auto_word_weighting(_named(words, 2, utterances=10)).weighting == "count"
    assert auto_word_weighting(_named(words, 3, utterances=10)).note == (
        "auto: 3 of 10 utterances are sentences (30%; tf-idf from 30%)"
    )
    nothing = _named(words, 0, utterances=0)
    assert auto_word_weighting(nothing).weighting == "count"
    assert auto_word_weighting(nothing) == AutoWeighting("count", 0, 0)
    assert auto_word_weighting(nothing).note is None  # nothing to explain: counted, as ever


def test_auto_is_the_default_and_the_counts_follow_the_rule():
    assert DataPreparation().word_weighting == "auto"
    assert preset().data.word_weighting == "auto"
    with pytest.raises(ValueError, match="must be 'count', 'tfidf' or 'auto'"):
        DataPreparation(word_weighting="bm25")
    for house, expected in ((_house(0.0), "count"), (_house(0.5), "tfidf")):
        grid, obs = house.grid, house.observations
        auto = cell_counts(grid, obs, word_weighting="auto")
        same = cell_counts(grid, obs, word_weighting=expected)
        np.testing.assert_array_equal(auto.word_counts, same.word_counts)
        np.testing.assert_array_equal(
            spcoa_data(obs, word_weighting="auto").words,
            spcoa_data(obs, word_weighting=expected).words,
        )
    settings = preset("original-code", gamma=3.0)
    resolved = resolved_settings(settings, _house(0.5).observations)
    assert resolved.data.word_weighting == "tfidf" and resolved.preset == "original-code"
    assert resolved.chosen == settings.chosen


def test_a_library_fit_records_the_resolved_weighting():
    settings = preset("original-code", gamma=3.0, num_concepts=10)
    for sentences, expected in ((0.0, "count"), (0.5, "tfidf")):
        result = fit_house(_house(sentences), settings, sweeps=3)
        assert result.preparation.word_weighting == expected
        assert result.settings_json()["data"]["word_weighting"] == expected


def test_a_library_update_keeps_the_weighting_of_the_fit_it_updates():
    house = _house(0.5)  # auto: tf-idf
    settings = preset("original-code", gamma=3.0, num_concepts=10)
    saved = fit_house(house, settings.replace(word_weighting="count"), sweeps=3)
    assert keeping_word_weighting("count", settings).data.word_weighting == "count"
    check_compatible(saved, house, settings)  # "auto" is the saved fit's weighting
    (updated,) = fit_update(saved, house, settings, sweeps=2)
    assert updated.preparation.word_weighting == "count"
    with pytest.raises(ValueError, match="word_weighting: saved fit 'count', this run 'tfidf'"):
        fit_update(saved, house, settings.replace(word_weighting="tfidf"), sweeps=2)


def test_the_decision_carries_the_counts_its_note_gives():
    """The data line's note is made from the counts the rule decided by, which the decision
    carries (an earlier note function took the observations and counted the sentences again,
    by a rule of its own); it holds no observations to count again."""
    sentences = _house(0.5).observations
    decision = auto_word_weighting(sentences)
    assert decision == AutoWeighting("tfidf", sentence_count(sentences), sentences.num_utterances)
    counted = AutoWeighting("count", 6, 36)
    assert counted.note == "auto: 6 of 36 utterances are sentences (16%; tf-idf from 30%)"
    assert AutoWeighting("count", 0, 36).note is None  # single words: counted, as ever
    assert AutoWeighting("count", 0, 36).reason == "none of 36 utterances is a sentence"


def test_an_update_says_the_kept_weighting_only_where_it_tells_something():
    assert AutoWeighting("count", 0, 36).kept_note("count", "OUT") is None  # the public houses
    assert AutoWeighting("count", 2, 36).kept_note("count", "OUT") is None
    assert AutoWeighting("tfidf", 18, 36).kept_note("tfidf", "OUT") == "auto: as the fit in OUT"
    assert AutoWeighting("tfidf", 18, 36).kept_note("count", "OUT") == (
        "auto: as the fit in OUT; this data alone would be tfidf: 18 of 36 utterances are "
        "sentences (50%; tf-idf from 30%)"
    )
    assert AutoWeighting("count", 0, 36).kept_note("tfidf", "OUT") == (
        "auto: as the fit in OUT; this data alone would be count: none of 36 utterances is a "
        "sentence"
    )


def test_a_result_built_without_a_preparation_records_its_words_counted():
    """SpCoResult's own default preparation recorded "auto" (DataPreparation's default), which
    an update then resolved for its own data: tf-idf on a house of sentences."""
    house = _house(0.5)  # auto: tf-idf
    model = preset("original-code", gamma=3.0, num_concepts=10)
    settings = dataclasses.replace(model, data=DataPreparation())  # auto
    fitted = fit_house(house, settings.replace(word_weighting="count"), sweeps=3)
    bare = SpCoResult(
        **{f.name: getattr(fitted, f.name) for f in dataclasses.fields(SpCoResult)
           if f.name != "preparation"}
    )  # fmt: skip
    assert bare.preparation == DataPreparation(word_weighting="count")
    for asked in (settings, None):
        (updated,) = fit_update(bare, house, asked, sweeps=2)
        assert updated.preparation.word_weighting == "count"
    # a result that records "auto" (saved so before): refused, not resolved for this data
    unresolved = dataclasses.replace(fitted, preparation=DataPreparation())
    for asked in (settings, None):
        with pytest.raises(ValueError, match="the saved fit records word_weighting 'auto', not"):
            fit_update(unresolved, house, asked, sweeps=2)
    # asking for the weighting it was fitted with does not get around the record
    with pytest.raises(ValueError, match="word_weighting: saved fit 'auto', this run 'count'"):
        fit_update(unresolved, house, settings.replace(word_weighting="count"), sweeps=2)


def test_a_recorded_auto_is_refused_saying_to_edit_the_record_most_likely_to_count():
    """The refusal sent a library caller with a result in memory to "config.json's
    data.word_weighting", did not say which weighting it most likely was, nor that asking the
    update for one does not get around it."""
    settings = preset("original-code")
    with pytest.raises(ValueError) as refused:
        keeping_word_weighting("auto", settings)
    assert str(refused.value) == (
        "the saved fit records word_weighting 'auto', not the weighting its words were counted "
        "with ('count' or 'tfidf'), so an update cannot keep it: record the one it was fitted "
        "with in its preparation.word_weighting (config.json's data.word_weighting for a saved "
        "fit), most likely 'count' (a result built without a preparation counted its words); "
        "asking the update for a weighting (--word-weighting, the settings' word_weighting) does "
        "not get around it, as the update's preparation must be the one recorded"
    )


def test_fit_update_keeps_the_weighting_config_json_records(tmp_path):
    """fit --update reads OUT's weighting before the data line, by keeping_word_weighting, as a
    library update does; a config.json recording "auto" is refused, naming the fit."""
    from argparse import Namespace

    from spcopyro.cli.fit_update import update_settings

    settings, out = preset("original-code"), tmp_path / "out"
    out.mkdir()
    for saved in ("count", "tfidf"):
        (out / "config.json").write_text(json.dumps({"data": {"word_weighting": saved}}))
        kept = update_settings(Namespace(update=str(out)), settings, 100)
        assert kept.data.word_weighting == saved
        asked = update_settings(
            Namespace(update=str(out)), settings.replace(word_weighting="tfidf"), 100
        )
        assert asked.data.word_weighting == "tfidf"  # as asked: check_compatible compares
    (out / "config.json").write_text(json.dumps({"data": {"word_weighting": "auto"}}))
    with pytest.raises(ValueError, match=f"the fit in {re.escape(str(out))} records word_"):
        update_settings(Namespace(update=str(out)), settings, 100)


@pytest.fixture
def sentence_house(tmp_path):
    spec = HouseSpec(**SMALL, sentence_fraction=0.5)
    return write_synthetic(tmp_path / "data", seed=1, spec=spec)


def _fit(house, out, *extra):
    argv = ["fit", str(house), "--out", str(out), "--sweeps", "3", "--no-figures", "--preset",
            "original-code", "--gamma", "3", "--concepts", "10", *extra]  # fmt: skip
    assert main(argv) == 0, argv


def _recorded(out) -> str:
    return json.loads((out / "config.json").read_text())["data"]["word_weighting"]


def test_fit_records_the_resolved_weighting_and_says_why(sentence_house, tmp_path, capsys):
    _fit(sentence_house, tmp_path / "auto")
    text = capsys.readouterr().out
    assert _recorded(tmp_path / "auto") == "tfidf"
    assert ", word weighting tfidf (auto: " in text
    assert " utterances are sentences (50%; tf-idf from 30%))" in text  # 18 of 36
    _fit(sentence_house, tmp_path / "count", "--word-weighting", "count")
    assert _recorded(tmp_path / "count") == "count"
    assert "word weighting" not in capsys.readouterr().out  # counts: said as before


def test_a_house_with_too_few_sentences_is_counted_and_says_why(tmp_path, capsys):
    spec = HouseSpec(**SMALL, sentence_fraction=0.1)  # 6 of 36 utterances are sentences
    house = write_synthetic(tmp_path / "data", seed=1, spec=spec)
    _fit(house, tmp_path / "auto")
    assert _recorded(tmp_path / "auto") == "count"
    data = [line for line in capsys.readouterr().out.splitlines() if line.startswith("data ")]
    assert re.search(
        r", word weighting count \(auto: 6 of 36 utterances are sentences \(16%; tf-idf from "
        r"30%\)\)",
        data[0],
    ), data
    # single words only (the public houses): counted, and the data line says nothing, as ever
    words = write_synthetic(tmp_path / "words", seed=1, spec=HouseSpec(**SMALL))
    _fit(words, tmp_path / "words_fit")
    assert _recorded(tmp_path / "words_fit") == "count"
    data = [line for line in capsys.readouterr().out.splitlines() if line.startswith("data ")]
    assert "word weighting" not in data[0], data


def test_tfidf_is_an_alias_of_word_weighting_tfidf(sentence_house, tmp_path, capsys):
    _fit(sentence_house, tmp_path / "alias", "--tfidf")
    assert _recorded(tmp_path / "alias") == "tfidf"
    data = [line for line in capsys.readouterr().out.splitlines() if line.startswith("data ")]
    assert data[0].endswith(", word weighting tfidf"), data  # chosen, not auto's
    with pytest.raises(SystemExit):
        main(["fit", str(sentence_house), "--out", str(tmp_path / "x"), "--tfidf",
              "--word-weighting", "count"])  # fmt: skip
    assert "not allowed with argument" in capsys.readouterr().err


def test_an_update_keeps_the_weighting_of_the_fit_it_updates(sentence_house, tmp_path, capsys):
    first = tmp_path / "first"
    _fit(sentence_house, first, "--word-weighting", "count")  # auto would be tfidf here
    second = tmp_path / "second"
    argv = ["fit", str(sentence_house), "--out", str(second), "--update", str(first),
            "--sweeps", "2", "--preset", "original-code", "--gamma", "3", "--concepts", "10",
            "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    assert _recorded(second) == "count"
    data = [line for line in capsys.readouterr().out.splitlines() if line.startswith("data ")]
    assert data[-1].endswith(
        f", word weighting count (auto: as the fit in {first}; this data alone would be tfidf: "
        "18 of 36 utterances are sentences (50%; tf-idf from 30%))"
    ), data
    # a fit by tf-idf, kept: said why; single words, counted before and now: nothing said
    _fit(sentence_house, tmp_path / "tfidf")
    words = write_synthetic(tmp_path / "words", seed=1, spec=HouseSpec(**SMALL))
    _fit(words, tmp_path / "words_fit")
    capsys.readouterr()
    for house, fitted, said in (
        (sentence_house, tmp_path / "tfidf", f", word weighting tfidf (auto: as the fit in "
                                              f"{tmp_path / 'tfidf'})"),
        (words, tmp_path / "words_fit", None),
    ):  # fmt: skip
        again = tmp_path / f"{fitted.name}_again"
        argv = ["fit", str(house), "--out", str(again), "--update", str(fitted), "--sweeps",
                "2", "--preset", "original-code", "--gamma", "3", "--concepts", "10",
                "--no-figures"]  # fmt: skip
        assert main(argv) == 0
        data = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("data ")]
        if said is None:  # was 'word weighting count (auto: as the fit in ...)'
            assert "word weighting" not in data[-1], data
        else:
            assert data[-1].endswith(said), data


def test_a_simulated_house_of_sentences_names_no_region_after_a_filler(tmp_path, capsys):
    # seed 1: with words counted, 200 sweeps name a region "is" (seeds 1-6 of 0-7 name one
    # filler or two); auto's tf-idf names none on any of the eight
    assert main(["simulate", "--out", str(tmp_path / "d"), "--seed", "1",
                 "--sentences", "0.5"]) == 0  # fmt: skip
    out = tmp_path / "fit"
    assert main(["fit", str(tmp_path / "d" / "synthetic"), "--out", str(out), "--sweeps",
                 "200", "--no-figures"]) == 0  # fmt: skip
    capsys.readouterr()
    names = [c["name"] for c in json.loads((out / "concepts.json").read_text()) if not c["speck"]]
    assert names and not FILLER_WORDS & set(names), names
    assert _recorded(out) == "tfidf"
