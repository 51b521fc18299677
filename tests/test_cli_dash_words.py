"""A word or instruction that starts with '-' (`spcopyro where OUT -tv`): argparse reads it as
an option; the usage error says how to give it."""

from __future__ import annotations

import pytest
from hand_results import two_rooms

from spcopyro.cli.main import main


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
