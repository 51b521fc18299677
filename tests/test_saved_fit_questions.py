"""Questions on a saved fit (``where``, ``navigate``): the notes they print read the saved fit
the same way, and what they share is computed once."""

from __future__ import annotations

import json

from test_cli_saved_vocabulary import NOTE, older
from test_navigate import START_A, house_result

from spcopyro.cli.main import main

OTHER_WORD = "is not a word of the vocabulary"


def test_navigate_reads_a_place_said_as_a_saved_word_as_where_does(tmp_path, capsys):
    """QA: on a fit that saved '-Kitchen', `where OUT -- -kitchen` said that '-kitchen' is
    answered for as 'kitchen'; `navigate OUT "go to the -kitchen"` did not, and called
    '-kitchen' no word of the vocabulary (stderr and navigate.json's word_note): it gave
    other_word_note no saved vocabulary."""
    fit = str(older(house_result(), {"kitchen": "-Kitchen"}).save(tmp_path / "old"))
    assert main(["where", fit, "--", "-kitchen"]) == 0
    where_err = capsys.readouterr().err
    assert "'-kitchen' is answered for as 'kitchen'" in where_err
    assert OTHER_WORD not in where_err
    argv = ["navigate", fit, "--start", f"{START_A[0]},{START_A[1]}", "--out",
            str(tmp_path / "plan"), "--no-figure", "--", "go to the -kitchen"]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert err.count(NOTE) == 1
    assert "'-kitchen' is answered for as 'kitchen'" in err
    assert OTHER_WORD not in err
    record = json.loads((tmp_path / "plan" / "navigate.json").read_text())
    assert [(s["word"], s["said"], s["word_note"]) for s in record["stops"]] == [
        ("kitchen", "-kitchen", None)
    ]
    assert record["saved_words_read_as"] == [{"saved": "-Kitchen", "word": "kitchen"}]


def test_where_out_computes_the_unmapped_mass_once(tmp_path, monkeypatch, capsys):
    """`where --out` printed the unmapped-mass note and drew it into both figures, computing
    the cells' mass on absent concepts three times ([N, L] each)."""
    from test_where_shared import unmapped_result

    from spcopyro.results import uncertainty

    calls = []
    original = uncertainty.unmapped_mass

    def counted(result):
        calls.append(result)
        return original(result)

    monkeypatch.setattr(uncertainty, "unmapped_mass", counted)
    result, _ = unmapped_result()
    fit = str(result.save(tmp_path / "fit"))
    assert main(["where", fit, "bed", "--out", str(tmp_path / "bed.png")]) == 0
    assert "lies on concepts absent from the map)" in capsys.readouterr().out
    assert (tmp_path / "bed_probability.png").is_file()
    assert len(calls) == 1
    note = uncertainty.unmapped_note(result)  # another result: computed for it
    assert note is not None and len(calls) == 2
    assert uncertainty.unmapped_note(result) == note and len(calls) == 2
    mass = uncertainty.unmapped_mass(result)
    assert mass is not None and not mass.flags.writeable  # no caller changes the next one's


def test_the_word_posteriors_are_computed_once_per_prior(monkeypatch):
    """where's other-words note normalised eq. 19 over every word at each answer (navigate asks
    once per place); now once per prior and result, with the same answers."""
    import dataclasses

    import numpy as np
    import pytest
    from hand_results import two_rooms

    from spcopyro.results import result as result_module
    from spcopyro.results import where as where_module

    calls = []
    original = where_module.concept_given_words

    def counted(w, prior):
        calls.append(prior)
        return original(w, prior)

    monkeypatch.setattr(result_module, "concept_given_words", counted)
    monkeypatch.setattr(where_module, "concept_given_words", counted)
    result = two_rooms()
    answers = [result.where(word) for word in ("bed", "sofa", "kitchen", "bed")]
    assert len(calls) == 1
    for answer in answers:  # as shared_answers computes them afresh
        fresh = original(result.w, result.concept_prior())
        expected = where_module.shared_answers(
            result.w, result.concept_prior(), answer.concept, result.vocabulary, answer.word,
            posterior=fresh,
        )  # fmt: skip
        assert answer.shared_with == expected
    assert [w for w, _ in answers[0].shared_with] == ["sofa"]
    result.where("bed", prior="pi")
    result.where("sofa", prior="pi")
    assert len(calls) == 2
    table = result.word_posteriors()
    with pytest.raises(ValueError):
        table[0, 0] = 1.0
    flat = dataclasses.replace(result, emissions=tuple(
        dataclasses.replace(t, probabilities=np.ones_like(t.probabilities) / 3)
        if t.name == "words" else t for t in result.emissions
    ))  # fmt: skip
    assert flat.where("bed").shared_with != answers[0].shared_with  # a new result: computed anew
    assert len(calls) == 3


def sink_result():
    """test_navigate's house with a sixth word, 'sink', that the kitchen's concept (2) emits as
    often as 'kitchen': where answers both with concept 2."""
    import dataclasses

    import numpy as np
    from hand_results import one_word_per_concept
    from test_navigate import WORDS, house_grid

    base = house_result()
    words = (*WORDS, "sink")
    result = one_word_per_concept(house_grid(), base.labels, words)
    w = np.array(result.w)  # [L, V]
    w[2, words.index("sink")] = w[2, words.index("kitchen")]
    w /= w.sum(1, keepdims=True)
    tables = tuple(
        dataclasses.replace(t, probabilities=w) if t.name == "words" else t
        for t in result.emissions
    )
    return dataclasses.replace(result, emissions=tables)


def test_navigate_says_when_a_stops_concept_answers_other_words_too(tmp_path, capsys):
    """QA (room2ldk4, 200 sweeps): `navigate OUT "go to the toilet"` sent the robot to the
    living room's concept (p 0.989) and said nothing; `where OUT toilet` notes that the concept
    is the answer for 'living', 'table' and 'shower' too."""
    fit = str(sink_result().save(tmp_path / "fit"))
    assert main(["where", fit, "sink"]) == 0
    where_note = capsys.readouterr().out.split("note: ", 1)[1].splitlines()[0]
    assert where_note.startswith(
        "concept 2 is also the answer, at p(concept | word) > 0.5, for 'kitchen'"
    )
    start = f"--start={START_A[0]},{START_A[1]}"
    plan = str(tmp_path / "plan")
    argv = ["navigate", fit, "go to the sink via the corridor", start, "--out", plan, "--no-figure"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert f"  note: {where_note}" in out.splitlines()  # the same note as where's
    assert out.count("note: ") == 1  # the corridor's concept answers no other word
    stops = json.loads((tmp_path / "plan" / "navigate.json").read_text())["stops"]
    assert [s["word"] for s in stops] == ["corridor", "sink"]
    assert stops[0]["shared_with"] == []
    assert [w for w, _ in stops[1]["shared_with"]] == ["kitchen"]
    assert stops[1]["shared_with"][0][1] > 0.5
    # the stop's p is its goal cell's, which the line says (where's p is the concept's)
    p = stops[1]["probability"]
    assert "sink: goal x=" in out and f"(goal cell: p(cell is the place) = {p:.3f}; " in out


def test_show_graph_prints_the_words_where_answers_with_each_place(tmp_path, capsys):
    """A place is named by its concept's top word; show --graph printed only that, so two
    places named 'bedroom' (room2ldk4) did not say which one `where bedroom` is."""
    fit = str(sink_result().save(tmp_path / "fit"))
    assert main(["show", fit, "--graph", "--out", str(tmp_path / "graph.png")]) == 0
    lines = capsys.readouterr().out.splitlines()
    kitchen = [k for k, line in enumerate(lines) if ": kitchen (" in line or ": sink (" in line]
    assert len(kitchen) == 1
    detail = lines[kitchen[0] + 1]
    assert detail.strip().startswith("concept 2, top words ")
    answered = detail.split("where answers it for: ")[1].split(", ")
    assert sorted(answered) == ["kitchen", "sink"]
    bedrooms = [k for k, line in enumerate(lines) if ": bedroom (" in line]
    assert len(bedrooms) == 2  # rooms A and E, one concept
    for k in bedrooms:
        assert "where answers it for: bedroom" in lines[k + 1]
