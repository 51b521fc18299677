"""A word or instruction that starts with '-' (`spcopyro where OUT -tv`): argparse reads it as
an option; the usage error says how to give it."""

from __future__ import annotations

import inspect
import re

import pytest
from hand_results import two_rooms

from spcopyro.cli import common
from spcopyro.cli.main import build_parser, main


@pytest.fixture
def fit(tmp_path):
    return str(two_rooms().save(tmp_path / "fit"))


@pytest.mark.parametrize(
    ("argv", "how"),
    [
        (["where", "{fit}", "-kitchen"], "a word that starts with '-' is given as: spcopyro "
         "where OUT [options] -- -kitchen"),
        (["where", "--prior", "pi", "{fit}", "-kitchen"], "spcopyro where OUT [options] -- "),
        (["navigate", "{fit}", "-kitchen", "--start", "-0.5,1"], "an instruction that starts "
         "with '-' is given as: spcopyro navigate OUT --start X,Y [options] -- -kitchen"),
        (["navigate", "{fit}", "--start=0.5,0.5", "-kitchen"], "-- -kitchen"),
        (["export", "{fit}", "--nav2", "{out}", "--word", "-kitchen"], "--word=-kitchen"),
        (["export", "{fit}", "--nav2", "{out}", "--word", "bed", "-kitchen"], "--word=-kitchen"),
    ],
)  # fmt: skip
def test_a_word_that_starts_with_a_dash_is_told_how_to_give_it(fit, tmp_path, capsys, argv, how):
    """QA: `spcopyro where OUT -tv` answered "the following arguments are required: word"."""
    argv = [a.format(fit=fit, out=tmp_path / "nav2") for a in argv]
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "'-kitchen' is read as an option" in err and how in err, err


def test_given_as_the_error_says_the_word_is_read(fit, tmp_path, capsys):
    assert main(["where", fit, "--prior", "area", "--", "-kitchen"]) == 0
    assert "'kitchen' is concept" in capsys.readouterr().out  # "-kitchen": its punctuation goes
    assert main(["export", fit, "--nav2", str(tmp_path / "nav2"), "--word", "bed",
                 "--word=-kitchen"]) == 0  # fmt: skip
    assert "keepout mask for 'kitchen'" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["where", "{fit}", "kitchen", "-x"], "unrecognized arguments: -x"),  # not the word
        (["where", "{fit}", "kitchen", "--out", "-x.png"], "--out: expected one argument"),
        (["export", "{fit}", "--nav2", "{out}", "-x"], "unrecognized arguments: -x"),
    ],
)
def test_other_dashes_keep_argparses_own_error(fit, tmp_path, capsys, argv, message):
    argv = [a.format(fit=fit, out=tmp_path / "nav2") for a in argv]
    with pytest.raises(SystemExit):
        main(argv)
    err = capsys.readouterr().err
    assert message in err and "is read as an option" not in err, err


def test_the_parser_itself_says_how_to_give_a_dash_word(fit, capsys):
    """The check is the parser's own usage error (CommandParser.error, no argparse internals):
    `build_parser().parse_args` says it too, not only `main` (which ran a check of its own, on
    argparse's private ``_actions``, before parsing)."""
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["where", fit, "-kitchen"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "'-kitchen' is read as an option" in err and "-- -kitchen" in err, err


def test_the_dash_word_check_reads_no_private_argparse_names():
    """refuse_dash_words read argparse's private ``_actions``, ``_option_string_actions`` and
    ``_SubParsersAction``; the parser records what it needs through the public API."""
    source = inspect.getsource(common)
    used = sorted(set(re.findall(r"\._(?:actions|option_string_actions|SubParsersAction|"
                                 r"subparsers|group_actions)\b", source)))  # fmt: skip
    assert used == [], used


@pytest.mark.parametrize("word", ["-kitchen", "kitchen?", "«Kitchen»"])
def test_a_word_answered_for_another_says_which(fit, tmp_path, capsys, word):
    """QA: `where OUT -- -tv` answered for 'tv' and said nothing of it: the word looked up is
    not the word given (the vocabulary holds none with punctuation at its ends); it says so, in
    where and in export, and answers as before."""
    assert main(["where", fit, "--", word]) == 0
    captured = capsys.readouterr()
    assert "'kitchen' is concept" in captured.out
    assert f"warning: {word!r} is not a word of the vocabulary: read as 'kitchen'" in (
        captured.err
    ), captured.err
    assert main(["export", fit, "--nav2", str(tmp_path / "nav2"), f"--word={word}"]) == 0
    captured = capsys.readouterr()
    assert "keepout mask for 'kitchen'" in captured.out
    assert f"warning: {word!r} is not a word of the vocabulary: read as 'kitchen'" in (
        captured.err
    ), captured.err


def test_a_place_of_an_instruction_read_as_another_word_says_which(tmp_path, capsys):
    """navigate shows a place as the instruction spells it ('-corridor'), and plans the fit's
    word it is read as ('corridor'): it says so, as where and export do."""
    from test_navigate import START_A, house_result

    fit = str(house_result().save(tmp_path / "fit"))
    start = f"--start={START_A[0]},{START_A[1]}"
    assert main(["navigate", fit, start, "--", "go to the -corridor"]) == 0
    captured = capsys.readouterr()
    assert "instruction 'go to the -corridor': -corridor" in captured.out
    assert "warning: '-corridor' is not a word of the vocabulary: read as 'corridor'" in (
        captured.err
    ), captured.err
    assert main(["navigate", fit, start, "go to the Corridor"]) == 0
    assert "is not a word of the vocabulary" not in capsys.readouterr().err


@pytest.mark.parametrize("word", ["kitchen", "Kitchen", " KITCHEN ", "ｋｉｔｃｈｅｎ"])
def test_the_same_word_in_another_case_or_form_is_answered_without_a_note(fit, capsys, word):
    assert main(["where", fit, word]) == 0
    assert "is not a word of the vocabulary" not in capsys.readouterr().err
