"""`spcopyro export`'s mask file names for words with characters unsafe in a file name: each
word gets its own files, safe and distinct, and nav2_export.json maps each word to them."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
from hand_results import two_rooms

from spcopyro.cli.main import main
from spcopyro.results.result import EmissionTable
from spcopyro.robot.nav2 import MAX_NAME_CHARS, export_nav2, mask_names

ODD = ("x", "x params", "a/b", ".hidden", "y" * 300, "台所", "cafe", "café", "two words")


def odd_words():
    result = two_rooms()
    w = np.full((3, len(ODD)), 1.0 / len(ODD))  # [L, V]
    words = EmissionTable("words", ODD, w)
    return dataclasses.replace(result, emissions=(result.emissions[0], words))


def test_every_word_gets_safe_distinct_files_and_the_index_maps_them(tmp_path):
    """QA: a 300-letter word made a file name over the 255-byte limit (the export failed with
    "File name too long"), and 'x params' was named keepout_x_params, whose mask file is the
    params file of 'x' (keepout_x_params.yaml): one replaced the other."""
    export = export_nav2(odd_words(), tmp_path / "nav2", list(ODD))
    assert [m.word for m in export.masks] == list(ODD)
    files = [f for m in export.masks for f in (m.mask_yaml.name, m.params_yaml.name)]
    assert len(set(files)) == len(files), files
    for mask in export.masks:
        assert mask.mask_yaml.is_file() and mask.params_yaml.is_file()
        assert mask.mask_yaml.with_suffix(".pgm").is_file()
        assert mask.name.startswith("keepout_") and len(mask.name) <= len("keepout_") + 64
        assert all(c.isascii() and (c.isalnum() or c == "_") for c in mask.name), mask.name
    names = {m.word: m.name for m in export.masks}
    assert names["x"] == "keepout_x" and names["x params"] == "keepout_x_params_2"
    assert names["台所"] == "keepout_word5" and names["café"] == "keepout_cafe_2"
    record = json.loads((tmp_path / "nav2" / "nav2_export.json").read_text())
    assert {m["word"]: (m["name"], m["mask"], m["params"]) for m in record["masks"]} == {
        m.word: (m.name, m.mask_yaml.name, m.params_yaml.name) for m in export.masks
    }


def test_a_name_another_names_params_file_is_moved_on_in_either_order():
    assert mask_names("speed", ["x_params", "x"], [0, 1]) == ["speed_x_params", "speed_x_2"]
    assert mask_names("speed", ["x", "x_params"], [0, 1]) == ["speed_x", "speed_x_params_2"]
    long = mask_names("speed", ["z" * 300, "z" * 301], [0, 1])
    assert long == ["speed_" + "z" * MAX_NAME_CHARS, "speed_" + "z" * MAX_NAME_CHARS + "_2"]


def test_the_command_exports_a_long_word(tmp_path, capsys):
    fit = odd_words().save(tmp_path / "fit")
    assert main(["export", str(fit), "--nav2", str(tmp_path / "nav2"), "--word", "y" * 300]) == 0
    assert f"keepout_{'y' * MAX_NAME_CHARS}.yaml" in capsys.readouterr().out
