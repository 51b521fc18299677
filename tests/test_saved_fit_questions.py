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
