"""Words holding invisible format characters (Unicode category Cf: a zero-width space, a
byte-order mark) asked of ``where`` and ``navigate`` or given to :class:`Observations`:
``'kit\\u200bchen'`` prints as ``'kitchen'`` but is another word, and is said to be."""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import pytest
from test_navigate import START_A, house_result

from spcopyro.cli.main import main
from spcopyro.data import Observations
from spcopyro.data.observations import hidden_words_told
from spcopyro.data.text import hidden_words_warning
from spcopyro.results.semantic_map import UnknownWordError, word_index
from spcopyro.robot.navigation.goals import parse_instruction

HIDDEN = "'kit\\u200bchen' holds invisible format characters (Unicode category Cf): U+200B ZERO "
FOUND = "without them it is 'kitchen', a word of the vocabulary"


def test_where_says_a_word_holds_invisible_characters(tmp_path, capsys):
    """QA: `where OUT kit\\u200bchen` (pasted) was 'not in the vocabulary; did you mean kitchen?'
    of a word printed 'kitchen'; it names the character and the word without it."""
    fit = str(house_result().save(tmp_path / "fit"))
    assert main(["where", fit, "kit\u200bchen"]) == 2
    err = capsys.readouterr().err
    assert HIDDEN + "WIDTH SPACE; " + FOUND in err, err
    assert "did you mean" not in err
    assert main(["where", fit, "\u200bkitchen"]) == 0  # at its ends: stripped, and named
    assert "(it holds U+200B ZERO WIDTH SPACE)" in capsys.readouterr().err


def test_navigate_says_a_place_holds_invisible_characters(tmp_path, capsys):
    """QA: navigate split 'kit\\u200bchen' at its zero-width space and asked 'did you mean
    kitchen?' of 'kit'."""
    fit = str(house_result().save(tmp_path / "fit"))
    argv = ["navigate", fit, "--start", f"{START_A[0]},{START_A[1]}", "--out",
            str(tmp_path / "plan"), "--no-figure", "--", "go to the kit\u200bchen"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "word 'kit\\u200bchen' of the instruction is not in" in err, err
    assert HIDDEN + "WIDTH SPACE; " + FOUND in err
    vocabulary = ("kitchen", "bedroom")
    assert parse_instruction("go to the kitchen\u200b, bedroom", vocabulary).places == vocabulary


def test_a_vocabulary_word_holding_invisible_characters_is_named():
    """The data's 'kit\\u200bchen' asked as 'kitchen': 'did you mean kitchen?' said nothing."""
    message = re.escape("the vocabulary's 'kit\\u200bchen' is 'kitchen' with invisible format")
    with pytest.raises(UnknownWordError, match=message):
        word_index(("kit\u200bchen", "bed"), "kitchen")
    with pytest.raises(ValueError, match=message):
        parse_instruction("go to the kitchen", ("kit\u200bchen", "bed"))
    with pytest.raises(UnknownWordError, match=r"U\+200B ZERO WIDTH SPACE; known words: bed, "):
        word_index(("kitchen", "bed"), "ba\u200bth")  # nothing without it: the usual hint
    assert parse_instruction("go to the kit\u200bchen", ("kit\u200bchen",)).places == (
        "kit\u200bchen",
    )  # fmt: skip


def _observations(utterances):
    n = len(utterances)
    return Observations(
        image_features=np.ones((1, 2)), image_xy=np.zeros((1, 2)), image_trial=[0],
        utterances=utterances, word_xy=np.zeros((n, 2)), word_trial=[0] * (n - 1) + [1],
    )  # fmt: skip


def test_observations_given_tokens_warn_of_invisible_characters_once(caplog):
    """The Python API given tokens directly said nothing of 'kit\\u200bchen' (St.csv's reader
    did); one warning per construction, none again for a subset of them."""
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        obs = _observations((("kit\u200bchen",), ("b\ufeffed", "kit\u200bchen"), ("kitchen",)))
    said = [r.getMessage() for r in caplog.records if "format characters" in r.getMessage()]
    assert said == [
        "Observations: 2 word(s) of the utterances hold invisible format characters (Unicode "
        "category Cf), each a word apart from its letters without them: 'kit\\u200bchen' "
        "(utterance 0: U+200B ZERO WIDTH SPACE), 'b\\ufeffed' (utterance 1: U+FEFF ZERO WIDTH "
        "NO-BREAK SPACE) (kept: remove them where the language does not need them)"
    ]
    assert obs.utterances[0] == ("kit\u200bchen",)  # kept
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        assert obs.select_trials([0]).num_utterances == 2
        _observations((("kitchen",), ("bed",)))
    assert "format characters" not in caplog.text


def test_one_function_words_both_hidden_word_warnings(caplog):
    """The St.csv reader's and Observations' warnings were worded in two places (and drifted:
    only the reader's names Persian): :func:`hidden_words_warning` owns both texts, pinned
    here (5 words: 3 named, then the count) and by the tests of each."""
    said = [("kit\u200bchen",), ("a\u200b", "b\u200b"), ("c\u200b", "d\u200b"), ("bed",)]
    assert hidden_words_warning([("kitchen",), ("bed",)]) is None
    assert hidden_words_warning(said, Path("room") / "St.csv") == (
        f"{Path('room') / 'St.csv'}, line 1: 5 word(s) hold invisible format characters "
        "(Unicode category Cf), each read as a word apart from its letters without them: "
        "'kit\\u200bchen' (utterance 1: U+200B ZERO WIDTH SPACE), 'a\\u200b' (utterance 2: "
        "U+200B ZERO WIDTH SPACE), 'b\\u200b' (utterance 2: U+200B ZERO WIDTH SPACE), ... (2 "
        "more) (kept: remove them where the language does not need them, as Persian needs its "
        "zero-width non-joiner)"
    )
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        _observations(said)
    assert [r.getMessage() for r in caplog.records] == [hidden_words_warning(said)]
    assert hidden_words_warning(said).startswith(
        "Observations: 5 word(s) of the utterances hold invisible format characters "
    )
    assert "(utterance 0: U+200B" in hidden_words_warning(said)  # its indices, from 0
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="spcopyro"), hidden_words_told():
        _observations(said)  # its caller warned
    assert caplog.records == []
