"""`spcopyro navigate`: how the instruction's words are read and shown (the house of
tests/test_navigate.py: A bedroom, B corridor, C kitchen, E bedroom, D closet)."""

from __future__ import annotations

import ast
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hand_results import one_word_per_concept
from test_navigate import START_A, house_grid, house_result

from spcopyro.cli.main import main
from spcopyro.robot.navigation import NavigationError, navigate, parse_instruction, planning_grid
from spcopyro.robot.navigation.goals import choose_goal
from spcopyro.robot.navigation.graph import shortest_paths

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
        ("shinshitsu no saki no oshiire", ("shinshitsu", "oshiire")),
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


@pytest.mark.parametrize("vocabulary", [ROMAJI, ROMAJI[:4], ("kitchen", "bedroom", "mae")])
@pytest.mark.parametrize(
    "text", ["kitchen no bedroom", "go to the kitchen no bedroom", "shinshitsu no oshiire"]
)
def test_no_between_two_places_is_refused_as_either_reading(vocabulary, text):
    """QA: "kitchen no bedroom" visited the kitchen, then the bedroom ("no" read as the
    particle): as English it keeps the robot out of the bedroom. "no" between two known places
    is refused, naming both readings; "shinshitsu no oshiire" (the bedroom's closet) too."""
    words = text.split()
    if not {words[-3], words[-1]} <= set(vocabulary):
        vocabulary = (*vocabulary, words[-3], words[-1])
    with pytest.raises(NavigationError, match="says 'no' between two places") as refused:
        parse_instruction(text, vocabulary)
    assert f"name only the places to visit, in order ('{words[-3]} {words[-1]}'" in str(
        refused.value
    ), refused.value


def test_no_between_two_places_is_refused_by_the_command(tmp_path, capsys):
    fit = romaji_result().save(tmp_path / "fit")
    argv = ["navigate", str(fit), "daidokoro no rouka", f"--start={START_A[0]},{START_A[1]}"]
    assert main(argv) == 2
    assert "says 'no' between two places, 'daidokoro' and 'rouka'" in capsys.readouterr().err


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


def test_a_goal_in_a_patch_smaller_than_a_place_is_warned_of():
    """QA: with no high-probability patch of 0.5 m^2 (a short fit: a 0.25 m^2 patch at the
    kitchen's edge) navigate took the largest patch and said nothing; it warns that the place
    is small or uncertain, and a patch of a place's size gives no such note."""
    grid = house_grid()
    planning = planning_grid(grid, 0.0)
    p_image = np.full(grid.shape, 0.3)
    p_image[5:8, 23:26] = 0.9  # 9 cells of 0.01 m^2 in room C: 0.09 m^2
    probability = p_image[grid.free]  # [N]
    start = planning.allowed.free_index[4, 3]
    distance, _ = shortest_paths(planning, start)
    choice = choose_goal(planning, "Kitchen", probability, distance)
    assert math.isclose(choice.candidate.area, 0.09)
    assert any("'Kitchen': no patch" in n and "the goal is in the largest, 0.09 m^2" in n
               and "small, or uncertain" in n for n in choice.notes)  # fmt: skip
    p_image[2:17, 21:30] = 0.9  # the whole room: 1.35 m^2
    choice = choose_goal(planning, "Kitchen", p_image[grid.free], distance)
    assert choice.candidate.area > 1 and not choice.notes


def _bare_p(text: str) -> list[str]:
    """The lines of ``text`` that print a probability as a bare 'p = ' or 'p >= '."""
    import re

    return [line for line in text.splitlines() if re.search(r"(^|[ (])p (=|>=) ", line)]


def test_navigate_names_its_probabilities_as_where_does(tmp_path, capsys):
    """QA: since bcf81ba `where` prints 'p(concept | word)' for the answer and 'p(cell is the
    place)' for a cell; navigate's stop line, its ambiguous candidates, its unreachable and
    --strict messages and where's close-odds warning (which navigate repeats) still printed a
    bare 'p = ...', one name for two quantities."""
    import dataclasses

    from test_navigate import START_B, WORDS

    from spcopyro.results.result import EmissionTable
    from spcopyro.robot.navigation import AmbiguousGoalError, UnreachableGoalError

    result = house_result()
    fit = str(result.save(tmp_path / "fit"))
    start = f"--start={START_B[0]},{START_B[1]}"
    assert main(["navigate", fit, "go to the bedroom", start]) == 0  # two regions
    out = capsys.readouterr().out
    assert "(goal cell: p(cell is the place) = " in out, out
    assert out.count(" p(cell is the place) = ") == 3, out  # the goal, each candidate
    assert not _bare_p(out), out
    assert main(["navigate", fit, "go to the bedroom", start, "--strict"]) == 2
    err = capsys.readouterr().err
    assert err.count("(p(cell is the place) = ") == 2 and not _bare_p(err), err
    with pytest.raises(UnreachableGoalError) as unreachable:  # the walled-off closet
        navigate(result, "closet", START_A)
    message = str(unreachable.value)
    assert "(p(cell is the place) = " in message and not _bare_p(message), message
    # 'kitchen' nearly as probable under the corridor's concept: where's close-odds warning
    w = result.emission("words").probabilities.copy()  # [L, V]
    w[1, WORDS.index("kitchen")] = w[2, WORDS.index("kitchen")] * 0.7
    guessed = dataclasses.replace(result, emissions=tuple(
        EmissionTable("words", WORDS, w / w.sum(1, keepdims=True)) if e.name == "words" else e
        for e in result.emissions))  # fmt: skip
    (odds,) = [x for x in guessed.where("kitchen").warnings if "not clearly more" in x]
    assert "(p(concept | word) = " in odds and not _bare_p(odds), odds
    notes = navigate(guessed, "kitchen", START_A).goal.choice.notes
    assert any("(p(concept | word) = " in n for n in notes) and not _bare_p("\n".join(notes))
    with pytest.raises(AmbiguousGoalError) as strict:
        navigate(guessed, "kitchen", START_A, strict=True)
    message = str(strict.value)
    assert "(p(concept | word) = " in message and not _bare_p(message), message


def test_a_small_patch_s_note_names_its_probability():
    """The note of a goal in a patch under a place's size names its p as a cell's."""
    grid = house_grid()
    planning = planning_grid(grid, 0.0)
    p_image = np.full(grid.shape, 0.3)
    p_image[5:8, 23:26] = 0.9
    distance, _ = shortest_paths(planning, planning.allowed.free_index[4, 3])
    (note,) = choose_goal(planning, "kitchen", p_image[grid.free], distance).notes
    assert "with p(cell is the place) >= 0.8 x the best (0.900)" in note, note


def test_an_unknown_place_lists_every_word_of_a_home_s_vocabulary():
    """QA (room1dk5, 300 sweeps): "go to the bathroom" listed 12 of the 14 known words and
    '... (2 more)', hiding 'washroom', the one the user wanted; where lists a home's whole
    vocabulary (KNOWN_WORDS_SHOWN), and navigate now does too, in both of its lists."""
    from spcopyro.results.semantic_map import KNOWN_WORDS_SHOWN

    vocabulary = ("bed", "bedroom", "chair", "entrance", "kitchen", "living", "refrigerator",
                  "shelf", "shower", "table", "toilet", "tv", "wall", "washroom")  # fmt: skip
    with pytest.raises(ValueError, match="names no place") as none:
        parse_instruction("go to the bathroom", vocabulary)
    assert str(none.value).endswith("known words: " + ", ".join(vocabulary)), none.value
    with pytest.raises(ValueError, match="names a stop") as stop:
        parse_instruction("go to the kitchen via the bathroom", vocabulary)
    assert "(its words: " + ", ".join(vocabulary) + ")" in str(stop.value), stop.value
    many = tuple(f"room{k:02d}x" for k in range(KNOWN_WORDS_SHOWN + 2))
    with pytest.raises(ValueError, match=r"\.\.\. \(2 more\)$"):
        parse_instruction("go to the garage", many)


def test_navigate_and_where_list_the_known_words_with_one_helper():
    """messages.listed writes the "up to KNOWN_WORDS_SHOWN, then ', ... (N more)'" list
    that where's unknown word and navigate's instruction errors each spelt on their own."""
    from spcopyro._util.messages import listed
    from spcopyro.results.semantic_map import KNOWN_WORDS_SHOWN, UnknownWordError, word_index

    assert listed(["a", "b", "c", "d"], 2) == "a, b, ... (2 more)"
    assert listed(["a", "b"], 2) == "a, b" and listed([], 2) == ""
    many = tuple(f"room{k:02d}x" for k in range(KNOWN_WORDS_SHOWN + 2))
    shown = listed(many)
    assert shown.endswith(f"room{KNOWN_WORDS_SHOWN - 1:02d}x, ... (2 more)")
    with pytest.raises(UnknownWordError) as where:
        word_index(many, "garage")
    assert str(where.value).endswith("; known words: " + shown), where.value
    with pytest.raises(ValueError, match="names no place") as navigate_error:
        parse_instruction("go to the garage", many)
    assert str(navigate_error.value).endswith("known words: " + shown), navigate_error.value


def test_listed_names_one_entry_over_the_limit_instead_of_counting_it():
    """A list read "a, b, ... (1 more)", which took as much of the line as the "c" it hid
    (where's note on room1dk6's 'bedroom' hid 'table' so, fbd0d38): one over the limit is now
    named, two are counted, and where's shared-answer note cuts by the same rule
    (``shown_count``)."""
    from spcopyro._util.messages import KNOWN_WORDS_SHOWN, listed, shown_count

    assert listed(["a", "b", "c"], 2) == "a, b, c"
    assert listed(["a", "b", "c", "d"], 2) == "a, b, ... (2 more)"
    many = tuple(f"room{k:02d}x" for k in range(KNOWN_WORDS_SHOWN + 1))
    assert listed(many) == ", ".join(many)
    assert [shown_count(n, 3) for n in range(7)] == [0, 1, 2, 3, 4, 3, 3]


def test_every_layer_lists_words_with_the_one_helper_of_messages():
    """``listed`` lives beside ``echo`` in ``_util.messages`` (which the data layer may import):
    the St.csv warnings (invisible characters, sentences without spaces) and ``fit --update``'s
    unheard words spelt the same list on their own; every module imports it from there, not
    through ``semantic_map`` (which uses it but no longer lists it in its ``__all__``)."""
    import spcopyro.cli.fit_update as fit_update
    import spcopyro.data.dataset_files as dataset_files
    import spcopyro.data.text as text
    import spcopyro.results.semantic_map as semantic_map
    from spcopyro._util import messages

    for module in (semantic_map, text, dataset_files, fit_update):
        assert module.listed is messages.listed, module.__name__
    assert "listed" not in semantic_map.__all__
    package = Path(messages.__file__).parents[1]
    through = sorted(
        str(path.relative_to(package.parent))
        for path in package.rglob("*.py")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.ImportFrom)
        and node.module != "spcopyro._util.messages"
        and any(alias.name == "listed" for alias in node.names)
    )
    assert through == [], through
    assert semantic_map.KNOWN_WORDS_SHOWN == messages.KNOWN_WORDS_SHOWN == 30
    hidden = [[f"w{k}\u200b"] for k in range(5)]  # [5 utterances of 1 word]
    warning = text.hidden_words_warning(hidden)
    assert (
        warning is not None and "(utterance 2: U+200B ZERO WIDTH SPACE), ... (2 more) (" in warning
    )


@pytest.mark.parametrize(
    ("text", "vocabulary", "message"),
    [
        ("", (), "the instruction '' is empty: name the places to visit, in order, e.g. 'go to "
         "the kitchen'; known words: none"),
        (" ?! ", ("bed", "sofa"), "the instruction ' ?! ' has no words: name the places to "
         "visit, in order, e.g. 'go to the bed'; known words: bed, sofa"),
        ("go to the attic", ("the",), "the instruction 'go to the attic' names no place the fit "
         "knows (ignored: attic); known words: none: the fit has no word that can name a place "
         "(fitted without words, or only connecting words such as 'the' heard)"),
        ("go to the attic", ("bed",), "the instruction 'go to the attic' names no place the fit "
         "knows (ignored: attic); known words: bed"),
    ],
)  # fmt: skip
def test_an_instruction_naming_no_place_says_which_words_are_known(text, vocabulary, message):
    """The four messages of an instruction with no place, whole: no words or some, and a fit
    with place words or none ("known words: " ended with nothing after)."""
    with pytest.raises(ValueError) as raised:
        parse_instruction(text, vocabulary)
    assert str(raised.value) == message
