"""The "did you mean" of `where`, `export` and `navigate`: one rule
(:func:`spcopyro.results.semantic_map.close_words`) that offers a typo's word, not a different
room (QA: `where FIT bathroom` on room2ldk4 answered "did you mean bedroom?", and `navigate
"go to the bathroom"` refused with the same suggestion: difflib's default cutoff 0.6, ratio
bathroom/bedroom 0.667)."""

from __future__ import annotations

import re

import pytest
from test_navigate import house_result

from spcopyro.cli.main import main
from spcopyro.results.semantic_map import UnknownWordError, close_words, word_index
from spcopyro.robot.navigation import parse_instruction

ROOM2LDK4 = ("bedroom", "entrance", "bed", "sofa", "kitchen", "living", "door", "table",
             "refrigerator", "toilet", "parlor", "shower", "shelf", "tv", "closet")  # fmt: skip
"""The words of the public house room2ldk4 (St.csv), most heard first."""
ROOM1DK5 = ("living", "kitchen", "entrance", "shower", "washroom", "toilet", "bedroom", "wall",
            "shelf", "refrigerator", "chair", "tv", "table", "bed")  # fmt: skip
ROOM1LDK5 = ("kitchen", "living", "sofa", "shower", "door", "washroom", "wall", "toilet",
             "table", "entrance", "dining", "tv", "bath", "chair", "bedroom")  # fmt: skip

DIFFERENT_ROOMS = [
    ("bathroom", ROOM2LDK4),  # bedroom 0.667
    ("bathroom", ROOM1DK5),  # washroom 0.75, bedroom 0.667
    ("restroom", ROOM1DK5),  # bedroom 0.667, washroom 0.625
    ("hall", ROOM1DK5),  # wall 0.75
    ("floor", ROOM2LDK4),  # door 0.667
    ("dining", ROOM1DK5),  # living 0.667
    ("terrace", ROOM2LDK4),  # entrance 0.667
]
TYPOS = [
    ("kitchn", ROOM2LDK4, "kitchen"),
    ("bedrom", ROOM2LDK4, "bedroom"),
    ("toliet", ROOM2LDK4, "toilet"),
    ("refridgerator", ROOM2LDK4, "refrigerator"),
    ("entrence", ROOM2LDK4, "entrance"),
    ("tabel", ROOM2LDK4, "table"),
    ("washrom", ROOM1DK5, "washroom"),
    ("livingroom", ROOM2LDK4, "living"),  # glued to "room": 0.75 by ratio
    ("dining-room", ROOM1LDK5, "dining"),
    ("bathroom", ROOM1LDK5, "bath"),  # the house whose bathroom is "bath"
]


@pytest.mark.parametrize(("word", "vocabulary"), DIFFERENT_ROOMS)
def test_where_offers_no_different_room(word, vocabulary):
    with pytest.raises(UnknownWordError) as caught:
        word_index(vocabulary, word)
    message = str(caught.value)
    assert "did you mean" not in message, message
    assert f"known words: {', '.join(sorted(vocabulary))}" in message


@pytest.mark.parametrize(("word", "vocabulary", "meant"), TYPOS)
def test_where_still_offers_a_typos_word(word, vocabulary, meant):
    with pytest.raises(UnknownWordError, match=rf"; did you mean {meant}\b"):
        word_index(vocabulary, word)


@pytest.mark.parametrize(("word", "vocabulary"), DIFFERENT_ROOMS)
def test_navigate_ignores_a_different_room_and_reports_it(word, vocabulary):
    """A word with no close word is ignored and reported (goals.py), not a did-you-mean error:
    "go to the kitchen, bathroom" drives to the kitchen and says 'bathroom' was ignored; with
    no known place left the instruction names none."""
    instruction = parse_instruction(f"go to the kitchen, {word}", vocabulary)
    assert instruction.places == ("kitchen",)
    assert instruction.ignored == (word,)
    with pytest.raises(ValueError, match=rf"names no place the fit knows \(ignored: {word}\)"):
        parse_instruction(f"go to the {word}", vocabulary)


@pytest.mark.parametrize(("word", "vocabulary", "meant"), TYPOS)
def test_navigate_refuses_a_typo_naming_the_same_words_as_where(word, vocabulary, meant):
    with pytest.raises(UnknownWordError) as caught:
        word_index(vocabulary, word)
    offered = re.search(r"did you mean (.*)\?", str(caught.value)).group(1)
    with pytest.raises(ValueError, match=rf"did you mean {re.escape(offered)}\?$"):
        parse_instruction(f"go to the {word}", vocabulary)
    assert offered.split(", ")[0] == meant


def test_an_accent_left_out_is_close():
    """'cafe' is 0.75 from 'café' compared composed, 0.889 decomposed (NFKD)."""
    assert close_words("cafe", ("bedroom", "café")) == ["café"]
    assert close_words("CAFE", ("bedroom", "café")) == ["café"]


def test_glued_room_comes_first_and_words_are_not_repeated():
    assert close_words("bedroom", ("bed", "bedrooms")) == ["bed", "bedrooms"]
    assert close_words("living_room", ("living", "kitchen")) == ["living"]
    assert close_words("refrigeratorroom", ("refrigerator",)) == ["refrigerator"]  # also 0.857
    assert close_words("room", ROOM2LDK4) == []  # no word before "room"


@pytest.mark.parametrize("word", ["room", "-room", "_room", " room", "rooom", "x"])
def test_a_blank_vocabulary_word_is_never_offered(word):
    """The word "room" (its stem, before "room", empty) was offered the vocabulary's "": the data's
    readers make no blank word (a blank line or entry is an error naming its file and line,
    double spaces part words), but a vocabulary built by hand or read from a result may hold
    one."""
    assert close_words(word, ("", " ", "kitchen")) == []
    assert close_words("kitchn", ("", "kitchen", " ")) == ["kitchen"]
    with pytest.raises(UnknownWordError) as raised:
        word_index(("", "kitchen"), word)
    assert "did you mean" not in str(raised.value)


def test_the_commands_offer_no_different_room(tmp_path, capsys):
    """On a saved fit whose words are bedroom, corridor, kitchen, closet and the."""
    fit = str(house_result().save(tmp_path / "fit"))
    assert main(["where", fit, "bathroom"]) == 2
    err = capsys.readouterr().err
    assert "did you mean" not in err
    assert "known words: bedroom, closet, corridor, kitchen, the" in err
    assert main(["navigate", fit, "go to the bathroom", "--start=0.35,1.45"]) == 2
    err = capsys.readouterr().err
    assert "did you mean" not in err
    assert "names no place the fit knows (ignored: bathroom)" in err
    assert main(["where", fit, "bedrom"]) == 2
    assert "did you mean bedroom?" in capsys.readouterr().err
