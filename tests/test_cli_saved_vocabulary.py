"""Questions on a fit saved by an older spcopyro, whose vocabulary holds words the tokenizer now
folds or strips (``Kitchen.``, ``TV``): ``where OUT kitchen`` said the word was not in the
vocabulary. ``where``, ``export --word``, ``navigate`` and ``show --graph`` read the saved words
as ``fit --update`` does (:func:`~spcopyro.results.saved_vocabulary.renormalised_result`) and say
once which were read as which; ``navigate.json`` keeps how the instruction's and the fit's words
were read."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from hand_results import two_rooms

from spcopyro.cli.main import main
from spcopyro.results.saved_vocabulary import renormalised_result

NOTE = "word(s) of its vocabulary are not words the tokenizer makes now"


def older(result, names: dict[str, str], split: str | None = None):
    """``result`` as an older spcopyro saved it: its words renamed by ``names``, and the column
    of ``split`` (a word) split in two halves, the second one named ``split.upper() + '.'``."""
    tables = []
    for table in result.emissions:
        if table.name == "words":
            items = [names.get(w, w) for w in table.items]
            w = np.array(table.probabilities, dtype=np.float64)  # [L, V]
            if split is not None:
                v = table.items.index(split)
                w = np.concatenate([w, w[:, v : v + 1] / 2], axis=1)  # [L, V + 1]
                w[:, v] /= 2
                items.append(split.upper() + ".")
            table = dataclasses.replace(table, items=tuple(items), probabilities=w)
        tables.append(table)
    totals = result.word_totals
    if totals is not None and split is not None:
        v = result.vocabulary.index(split)
        totals = np.append(np.asarray(totals, dtype=np.float64), totals[v] / 2)
        totals[v] /= 2
    counts = result.word_counts  # [L, V]
    if counts is not None and split is not None:
        v = result.vocabulary.index(split)
        counts = np.concatenate([counts, counts[:, v : v + 1] / 2], axis=1)  # [L, V + 1]
        counts[:, v] /= 2
    return dataclasses.replace(
        result, emissions=tuple(tables), word_totals=totals, word_counts=counts
    )


def test_a_saved_vocabulary_is_folded_to_todays_words():
    counts = np.array([[3.0, 0.0, 2.0], [1.0, 2.0, 4.0], [0.0, 0.0, 0.0]])  # [L, V]
    today = dataclasses.replace(two_rooms(), word_totals=counts.sum(0), word_counts=counts)
    old = older(today, {"kitchen": "Kitchen."}, split="sofa")
    assert old.vocabulary == ("Kitchen.", "bed", "sofa", "SOFA.")
    read, saved = renormalised_result(old)
    assert read.vocabulary == today.vocabulary
    np.testing.assert_allclose(read.w, today.w)
    np.testing.assert_allclose(read.word_totals, today.word_totals)
    np.testing.assert_allclose(read.word_counts, today.word_counts)
    assert saved.renamed == (("Kitchen.", "kitchen"), ("SOFA.", "sofa"))
    same, nothing = renormalised_result(today)  # today's words: the result itself
    assert same is today and not nothing.renamed


def test_where_and_export_find_an_older_fits_words(tmp_path, capsys):
    """QA: `where OUT stove` on a fit whose vocabulary held 'stove.' answered 'not in the
    vocabulary ... did you mean stove.?'."""
    today = str(two_rooms().save(tmp_path / "today"))
    fit = str(older(two_rooms(), {"kitchen": "Kitchen."}, split="sofa").save(tmp_path / "old"))
    for word in ("kitchen", "sofa"):
        assert main(["where", today, word]) == 0
        expected = capsys.readouterr().out
        assert main(["where", fit, word]) == 0
        captured = capsys.readouterr()
        assert captured.out == expected  # the same answer as the fit with today's words
        assert captured.err.count(NOTE) == 1, captured.err
        assert "'Kitchen.' -> 'kitchen', 'SOFA.' -> 'sofa'" in captured.err
        assert "is not a word of the vocabulary" not in captured.err
    assert main(["export", fit, "--nav2", str(tmp_path / "nav2"), "--word", "kitchen"]) == 0
    captured = capsys.readouterr()
    assert "keepout mask for 'kitchen'" in captured.out
    assert captured.err.count(NOTE) == 1, captured.err
    assert main(["where", today, "kitchen"]) == 0  # a fit of today's words: nothing said
    assert NOTE not in capsys.readouterr().err


def test_navigate_reads_an_older_fits_words_and_keeps_the_readings(tmp_path, capsys):
    """navigate plans an older fit's 'Corridor.' for 'corridor'; navigate.json records both
    readings: the fit's saved word, and the instruction's '-kitchen' read as 'kitchen'."""
    from test_navigate import START_A, house_result

    fit = str(older(house_result(), {"corridor": "Corridor."}).save(tmp_path / "old"))
    argv = ["navigate", fit, "--start", f"{START_A[0]},{START_A[1]}", "--out",
            str(tmp_path / "plan"), "--no-figure", "--", "-kitchen via the corridor"]  # fmt: skip
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "instruction '-kitchen via the corridor': corridor (via) -> -kitchen" in captured.out
    assert captured.err.count(NOTE) == 1 and "'Corridor.' -> 'corridor'" in captured.err
    record = json.loads((tmp_path / "plan" / "navigate.json").read_text())
    assert record["saved_words_read_as"] == [{"saved": "Corridor.", "word": "corridor"}]
    stops = [(s["word"], s["said"], s["word_note"]) for s in record["stops"]]
    assert stops[0] == ("corridor", "corridor", None)
    word, said, note = stops[1]
    assert (word, said) == ("kitchen", "-kitchen")
    assert (
        note is not None and "'-kitchen' is not a word of the vocabulary: read as 'kitchen'" in note
    )
    assert main(["show", fit, "--graph", "--out", str(tmp_path / "graph.png")]) == 0
    places = json.loads((tmp_path / "graph.json").read_text())["places"]
    words = {word for place in places for word in place["words"]}
    assert "corridor" in words and "Corridor." not in words, words


@pytest.mark.parametrize("instruction", ["go to the kitchen", "go to the Kitchen"])
def test_navigate_json_has_no_note_for_a_word_said_as_the_vocabulary_has_it(
    tmp_path, capsys, instruction
):
    from test_navigate import START_A, house_result

    fit = str(house_result().save(tmp_path / "fit"))
    argv = ["navigate", fit, instruction, "--start", f"{START_A[0]},{START_A[1]}", "--out",
            str(tmp_path / "plan"), "--no-figure"]  # fmt: skip
    assert main(argv) == 0
    record = json.loads((tmp_path / "plan" / "navigate.json").read_text())
    assert record["saved_words_read_as"] == []
    assert [s["word_note"] for s in record["stops"]] == [None]
    assert NOTE not in capsys.readouterr().err


def test_a_saved_word_asked_for_as_saved_is_told_once(tmp_path, capsys):
    """QA: `where OUT stove.` on a fit that saved 'stove.' warned twice, oddly together: that
    the saved 'stove.' was read as 'stove', then that the typed 'stove.' is not a vocabulary
    word and was read as 'stove'. Now one warning names the saved words read as others and says
    that the word asked for is answered for as 'stove'; `export --word` alike."""
    fit = str(older(two_rooms(), {"kitchen": "Kitchen."}, split="sofa").save(tmp_path / "old"))
    for word in ("Kitchen.", "kitchen."):
        assert main(["where", fit, word]) == 0
        captured = capsys.readouterr()
        assert captured.out.startswith("'kitchen' is concept")
        said = [line for line in captured.err.splitlines() if line.startswith("warning:")]
        assert len(said) == 1, captured.err
        assert NOTE in said[0] and f"{word!r} is answered for as 'kitchen'" in said[0]
        assert "is not a word of the vocabulary" not in captured.err
    assert main(["where", fit, "sofa."]) == 0  # its pair is named first
    note = capsys.readouterr().err
    assert "read as it reads them: 'SOFA.' -> 'sofa', 'Kitchen.' -> 'kitchen';" in note
    assert main(["where", fit, "--", "-kitchen"]) == 0  # no saved word: the note on the typed
    captured = capsys.readouterr()
    assert "'-kitchen' is not a word of the vocabulary: read as 'kitchen'" in captured.err
    assert "is answered for as" not in captured.err
    argv = ["export", fit, "--nav2", str(tmp_path / "nav2"), "--word", "Kitchen."]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "keepout mask for 'kitchen'" in captured.out
    assert captured.err.count("warning:") == 1, captured.err
    assert "'Kitchen.' is answered for as 'kitchen'" in captured.err
