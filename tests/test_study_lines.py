"""A study file's errors name the line of the key they refuse (``study.toml:12: ...``), so that
a researcher's editor jumps to it: they named the table and key only."""

from __future__ import annotations

import pytest

from spcopyro.study.lines import key_line, where_path
from spcopyro.study.spec import StudyError, load_study

STUDY = """\
# a study with comments
[study]
name = "lines"
seeds = 1
sweeps = { gibbs = 5, "*" = 3 }

[variants.a]
preset = "paper-dp"

[variants."b+sw"]
preset = "paper-dp"
cluster_moves = 0.2
hyper = { alpha = true }

[data.d]
synthetic = "scaled"
height = 30
width = 40
num_rooms = 2
"""


@pytest.mark.parametrize(
    "old, new, line, words",
    [
        ("gibbs = 5", "gibs = 5", 5, "[study] sweeps.gibs = 5: unknown method"),
        ("seeds = 1", "seeds = [1, 1]", 4, "[study] seeds = [1, 1]: a seed is given twice"),
        ("cluster_moves = 0.2", "cluster_moves = 2", 12, "cluster_moves=2"),
        ('preset = "paper-dp"\ncluster', 'preset = "paperdp"\ncluster', 11, "'paperdp'"),
        ("hyper = { alpha = true }", "hyper = { alpha = 3 }", 13, "alpha=3"),
        ("hyper = { alpha = true }", "hyper.alpha = 3", 13, "alpha=3"),
        ("num_rooms = 2", "num_roms = 2", 19, "[data.d] num_roms = 2: HouseSpec has no such"),
        ("num_rooms = 2", "num_rooms = 9", 19, "HouseSpec.num_rooms 9"),
        ('synthetic = "scaled"', 'synthetic = "scaledd"', 16, "synthetic = 'scaledd'"),
    ],
)
def test_an_error_names_the_line_of_its_key(tmp_path, old, new, line, words):
    assert old in STUDY
    path = tmp_path / "study.toml"
    path.write_text(STUDY.replace(old, new, 1))
    with pytest.raises(StudyError) as caught:
        load_study(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:{line}: "), message
    assert words in message, message


def test_an_error_with_no_line_to_name_keeps_its_message(tmp_path):
    path = tmp_path / "study.toml"
    path.write_text('[study]\nname = "x"\n[variants.a]\n')  # no [data.*] table at all
    with pytest.raises(StudyError) as caught:
        load_study(path)
    assert str(caught.value).startswith(f"{path}: [data] = {{}}: expected at least one")


def test_key_line_reads_quoted_dotted_and_inline_keys():
    text = STUDY + '\n[data."my.house"]\npublic = "room1dk5"\n"seeds" = 3\n'
    assert key_line(text, where_path("[study] sweeps.cavi")) == 5  # the inline table
    assert key_line(text, where_path("[variants.b+sw] hyper.alpha")) == 13
    assert key_line(text, where_path("[variants.b+sw]")) == 10
    assert key_line(text, where_path("[data.my.house] seeds")) == 23
    assert key_line(text, where_path("[data.nothere] seeds")) is None
    assert key_line(text, where_path("top-level tables")) is None
    assert where_path("variants.a") == ("variants", "a")
