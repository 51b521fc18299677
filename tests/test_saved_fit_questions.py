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
