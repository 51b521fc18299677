"""`spcopyro navigate`: how the instruction's words are read and shown (the house of
tests/test_navigate.py: A bedroom, B corridor, C kitchen, E bedroom, D closet)."""

from __future__ import annotations

import json

import pytest
from hand_results import one_word_per_concept
from test_navigate import START_A, house_grid, house_result

from spcopyro.cli.main import main
from spcopyro.robot.navigation import NavigationError, navigate, parse_instruction

ROMAJI = ("daidokoro", "rouka", "shinshitsu", "oshiire", "no")
"""A romanised Japanese vocabulary (kitchen, corridor, bedroom, closet), "no" heard in its
sentences as a particle."""


def romaji_result():
    return one_word_per_concept(house_grid(), house_result().labels, ROMAJI[:4])


@pytest.mark.parametrize("vocabulary", [ROMAJI, ROMAJI[:4]])
@pytest.mark.parametrize(
    ("text", "places"),
    [
        ("daidokoro no mae", ("daidokoro",)),
        ("rouka no saki no daidokoro", ("rouka", "daidokoro")),
        ("shinshitsu no oshiire", ("shinshitsu", "oshiire")),
    ],
)
def test_the_japanese_particle_no_is_not_a_negation(vocabulary, text, places):
    """QA: "no" is the genitive particle of a romanised Japanese instruction ("daidokoro no
    mae", in front of the kitchen); it was read as the English "no" and every such instruction
    was refused, and in a fit whose sentences hold "no" it would have been a place."""
    assert parse_instruction(text, vocabulary).places == places


@pytest.mark.parametrize(
    "text", ["no daidokoro", "go to the daidokoro, no, the rouka", "daidokoro no", "to no rouka"]
)
def test_no_as_a_negation_is_still_refused(text):
    with pytest.raises(NavigationError, match="says 'no'"):
        parse_instruction(text, ROMAJI)


def test_a_romanised_instruction_with_no_is_driven(capsys):
    plan = navigate(romaji_result(), "daidokoro no mae", START_A)
    assert [s.word for s in plan.stops] == ["daidokoro"]
    assert plan.instruction.ignored == ("mae",)


def test_the_words_are_shown_as_the_instruction_spells_them(tmp_path, capsys):
    """QA: navigate printed and drew the stops lower-cased ("kitchen" for "Kitchen", "tv" for
    "TV"); it shows them as said, and still finds the fit's words."""
    fit = house_result().save(tmp_path / "fit")
    parsed = parse_instruction("go to the KITCHEN via the Corridor", house_result().vocabulary)
    assert parsed.places == ("corridor", "kitchen") and parsed.said == ("Corridor", "KITCHEN")
    argv = ["navigate", str(fit), "go to the KITCHEN via the Corridor", "--start",
            f"{START_A[0]},{START_A[1]}", "--out", str(tmp_path / "plan")]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "instruction 'go to the KITCHEN via the Corridor': Corridor (via) -> KITCHEN" in out
    assert "\nCorridor: goal" in out and "\nKITCHEN: goal" in out
    assert "route: bedroom -> Corridor -> KITCHEN" in out
    record = json.loads((tmp_path / "plan" / "navigate.json").read_text())
    assert [(s["word"], s["said"]) for s in record["stops"]] == [
        ("corridor", "Corridor"),
        ("kitchen", "KITCHEN"),
    ]
    # a place said twice keeps its first spelling, one stop
    assert parse_instruction("Kitchen kitchen", house_result().vocabulary).said == ("Kitchen",)
