"""``DataPreparation.word_footprint_radius`` (issue 21): the utterances' own footprint radius, the
images keeping ``footprint_radius``'s (0: each utterance counted whole at its own cell).

Checked: the counts (words as without a footprint, images as with it, and the converse), None
the same as ``footprint_radius``, bad values refused, the saved preparation (no key where unset,
so an existing config.json is unchanged; round-trips where set), ``spcopyro fit --word-footprint``
reaching config.json and the loaded result, the fit's data line, and the refinement (which counts
words at their cell) replacing it only where it differs.
"""

from __future__ import annotations

import argparse
import dataclasses
import json

import numpy as np
import pytest
from gibbs_problems import tiny_grid
from test_footprint import ROWS, observations

from spcopyro.cli.fit_refine import prepares_data, replaced_options
from spcopyro.cli.fit_summary import data_line
from spcopyro.cli.main import main
from spcopyro.config import DataPreparation, preset
from spcopyro.data import cell_counts, prepared_cell_counts
from spcopyro.fit.gibbs_chains import preparation_record
from spcopyro.fit.refine import UNUSED, refined_settings, replaced_preparation
from spcopyro.fit.setting_warnings import preparation_warnings
from spcopyro.gibbs.checkpoint import differences
from spcopyro.results.result import SpCoResult
from spcopyro.synthetic import HouseSpec, write_synthetic


@pytest.fixture
def problem(rng):
    grid = tiny_grid(ROWS)
    return grid, observations(grid, rng)


def _prepared(grid, obs, **changes):
    data = DataPreparation(snap_distance=0.0, word_weighting="count", **changes)
    return prepared_cell_counts(grid, obs, data)


def _rows(counts, cells: np.ndarray, matrix: str) -> np.ndarray:
    """``counts``' rows of ``matrix`` at the free indices ``cells`` (zero where not observed)."""
    values = getattr(counts, matrix)  # [M, K]
    out = np.zeros((cells.size, values.shape[1]))
    at = np.searchsorted(counts.cells, cells)
    found = (at < counts.cells.size) & (
        counts.cells[np.minimum(at, counts.cells.size - 1)] == cells
    )
    out[found] = values[at[found]]
    return out


def test_words_at_their_cell_while_the_images_keep_the_footprint(problem):
    grid, obs = problem
    plain = cell_counts(grid, obs, snap_distance=0.0)
    spread = cell_counts(grid, obs, snap_distance=0.0, footprint_radius=0.3)
    mixed = _prepared(grid, obs, footprint_radius=0.3, word_footprint_radius=0.0)
    # the images (and further modalities) as with the footprint, on the cells they reach
    np.testing.assert_array_equal(_rows(mixed, spread.cells, "image_counts"), spread.image_counts)
    assert mixed.image_counts.sum() == pytest.approx(spread.image_counts.sum())
    objects = mixed.modalities[0].counts  # [M, 2]
    np.testing.assert_array_equal(
        objects[np.isin(mixed.cells, spread.cells)],
        spread.modalities[0].counts[np.isin(spread.cells, mixed.cells)],
    )
    assert objects.sum() == pytest.approx(spread.modalities[0].counts.sum())
    assert set(mixed.cells) < set(spread.cells)  # the words' spread reached more
    # the words: whole at their own cell, as without a footprint, and nowhere else
    np.testing.assert_array_equal(_rows(mixed, plain.cells, "word_counts"), plain.word_counts)
    assert mixed.word_counts.sum() == plain.word_counts.sum()
    assert np.count_nonzero(mixed.word_counts.sum(axis=1)) == len(obs.utterances)
    spread_words = _rows(mixed, spread.cells, "word_counts")  # the footprint spread them
    assert not np.allclose(spread_words, spread.word_counts)
    # the factored form a sampler may read is the same counts
    np.testing.assert_allclose(mixed.spread["words"].dense(), mixed.word_counts)


def test_words_may_have_a_footprint_while_the_images_count_at_their_cell(problem):
    grid, obs = problem
    plain = cell_counts(grid, obs, snap_distance=0.0)
    spread = cell_counts(grid, obs, snap_distance=0.0, footprint_radius=0.3)
    words = _prepared(grid, obs, footprint_radius=0.0, word_footprint_radius=0.3)
    np.testing.assert_allclose(_rows(words, spread.cells, "word_counts"), spread.word_counts)
    np.testing.assert_array_equal(_rows(words, plain.cells, "image_counts"), plain.image_counts)
    assert words.image_counts.sum() == pytest.approx(plain.image_counts.sum())


def test_none_is_the_footprint_s_radius(problem):
    grid, obs = problem
    same = _prepared(grid, obs, footprint_radius=0.3, word_footprint_radius=0.3)
    unset = _prepared(grid, obs, footprint_radius=0.3)
    for name in ("cells", "image_counts", "word_counts"):
        np.testing.assert_array_equal(getattr(same, name), getattr(unset, name))
    assert DataPreparation(footprint_radius=0.75).words_radius == 0.75
    assert DataPreparation(footprint_radius=0.75, word_footprint_radius=0).words_radius == 0


@pytest.mark.parametrize("value", [-0.5, float("nan"), float("inf"), "0", True])
def test_a_bad_word_footprint_is_refused(value):
    with pytest.raises(ValueError, match=r"DataPreparation.word_footprint_radius=.*metres >= 0"):
        DataPreparation(word_footprint_radius=value)


def test_the_saved_preparation_leaves_it_out_unless_set():
    before = ["feature_scaling", "word_weighting", "snap_distance", "footprint_radius",
              "footprint_kernel", "footprint_fov", "word_scaling", "cell_size"]  # fmt: skip
    reach = ["footprint_reach_share", "footprint_reach_door_width"]  # coarse's since 2026-12-06
    for data, keys in ((DataPreparation(), before), (preset("coarse").data, before + reach),
                       (preset("paper-dp").data, before)):  # fmt: skip
        saved = data.to_json()
        assert sorted(saved) == sorted(keys)  # no word_footprint_radius: as before the option
        assert saved == {k: v for k, v in dataclasses.asdict(data).items() if k in keys}
        assert DataPreparation(**saved) == data
    words = preset("coarse", word_footprint_radius=0.0).data
    assert words.to_json()["word_footprint_radius"] == 0.0
    assert DataPreparation(**json.loads(json.dumps(words.to_json()))) == words


def test_fit_word_footprint_reaches_config_json_and_the_loaded_result(tmp_path):
    out = tmp_path / "fit"
    argv = [
        "fit",
        "--sweeps",
        "3",
        "--backend",
        "torch",
        "--footprint",
        "0.5",
        "--word-footprint",
        "0",
        "--no-figures",
        "--refine",
        "never",
        "--out",
        str(out),
    ]
    assert main(argv) == 0  # fmt: skip
    saved = json.loads((out / "config.json").read_text())["data"]
    assert saved["footprint_radius"] == 0.5 and saved["word_footprint_radius"] == 0.0
    loaded = SpCoResult.load(out).preparation
    assert loaded.footprint_radius == 0.5 and loaded.word_footprint_radius == 0.0


def test_the_data_line_names_the_words_footprint():
    assert "footprint 0.75 m (uniform, words at cell)" in data_line(
        preset("coarse", word_footprint_radius=0.0).data
    )
    assert "footprint 0 m (uniform, words 0.5 m)" in data_line(
        DataPreparation(word_footprint_radius=0.5)
    )
    assert "words" not in data_line(preset("coarse", word_footprint_radius=0.75).data)


def test_the_refinement_counts_words_at_their_cell():
    spread = preset("coarse", word_footprint_radius=0.5)
    refined = refined_settings(spread, 100, 2500).data
    assert refined.word_footprint_radius is None and refined.words_radius == 0.0
    assert replaced_options(spread, refined) == {
        "--word-footprint": {"given": 0.5, "refinement": 0.0}
    }
    at_cell = preset("coarse", word_footprint_radius=0.0)  # what the refinement does too
    assert replaced_options(at_cell, refined_settings(at_cell, 100, 2500).data) == {}
    given = argparse.Namespace(word_footprint=0.0)
    assert prepares_data(given)  # a preparation of its own: no refinement by default


# -- any footprint on: the words' own reads the kernel, the images' alone the field of view --------


WORDS_ONLY = {"footprint_radius": 0.0, "word_footprint_radius": 0.5}


def test_a_words_only_footprint_keeps_the_kernel_in_the_checkpoint_record():
    """The words' footprint reads footprint_kernel, so a checkpoint records it (it dropped it
    with footprint_radius 0, and a resume with another --footprint-kernel went unnoticed)."""
    saved = preparation_record(preset("auto", **WORDS_ONLY))
    here = preparation_record(preset("auto", **WORDS_ONLY, footprint_kernel="gaussian"))
    assert saved["footprint_kernel"] == "uniform" and saved["word_footprint_radius"] == 0.5
    assert differences({"p": saved}, {"p": here}) == [
        "p.footprint_kernel: 'uniform' in the checkpoint, 'gaussian' here"
    ]
    # no footprint at all: the record of before the footprint existed, as ever
    assert not {"footprint_radius", "footprint_kernel", "footprint_fov"} & set(
        preparation_record(preset("auto", footprint_kernel="gaussian"))
    )


def test_a_words_only_footprint_leaves_the_unread_fov_out_of_the_checkpoint_record():
    """--footprint-fov applies to the images' footprint only: with a words-only footprint it does
    nothing, so the record leaves it out and a resume changing only it is not refused (the
    record kept it beside the kernel, and the resume was refused over a setting doing nothing)."""
    saved = preparation_record(preset("auto", **WORDS_ONLY))
    here = preparation_record(preset("auto", **WORDS_ONLY, footprint_fov=90.0))
    assert "footprint_fov" not in saved and "footprint_fov" not in here
    assert differences({"p": saved}, {"p": here}) == []
    # the images' footprint reads it: recorded, and a change named
    images = {"footprint_radius": 0.5, "word_footprint_radius": 0.0}
    saved = preparation_record(preset("auto", **images))
    here = preparation_record(preset("auto", **images, footprint_fov=90.0))
    assert differences({"p": saved}, {"p": here}) == [
        "p.footprint_fov: None in the checkpoint, 90.0 here"
    ]


@pytest.mark.parametrize("radius", [0.0, 0.5])
def test_a_word_footprint_equal_to_the_footprint_is_left_out_of_the_checkpoint_record(radius):
    """--word-footprint R with --footprint R (0 and 0 too) counts as leaving it out: the record
    leaves it out, so a resume without --word-footprint is not refused (the record kept it,
    and differences() named a setting that changes nothing)."""
    given = preparation_record(
        preset("auto", footprint_radius=radius, word_footprint_radius=radius)
    )
    unset = preparation_record(preset("auto", footprint_radius=radius))
    assert given == unset and differences({"p": given}, {"p": unset}) == []
    # unset or truly different: recorded as before (to_json's, less the unread fields)
    assert "word_footprint_radius" not in unset
    other = preparation_record(preset("auto", footprint_radius=radius, word_footprint_radius=0.3))
    assert other["word_footprint_radius"] == 0.3
    named = "p.word_footprint_radius: 0.3 in the checkpoint, None here"
    assert named in differences({"p": other}, {"p": unset})


def test_reads_is_the_per_field_rule():
    for data, kernel, fov in [
        (DataPreparation(), False, False),
        (DataPreparation(**WORDS_ONLY), True, False),
        (DataPreparation(footprint_radius=0.5, word_footprint_radius=0.0), True, True),
    ]:
        assert (data.reads("footprint_kernel"), data.reads("footprint_fov")) == (kernel, fov)
    with pytest.raises(ValueError, match="'cell_size' is not"):
        DataPreparation().reads("cell_size")


def test_the_refinement_replaces_a_kernel_a_words_only_footprint_read():
    first = preset("auto", **WORDS_ONLY, footprint_kernel="gaussian", footprint_fov=90.0)
    replaced = replaced_preparation(first, refined_settings(first, 100, 2500).data)
    assert replaced == {
        "footprint_kernel": {"given": "gaussian", "refinement": UNUSED},
        "word_footprint_radius": {"given": 0.5, "refinement": 0.0},
    }  # the fov did nothing (no images' footprint): not replaced


def test_a_fov_with_a_words_only_footprint_warns_instead_of_needing_yaw(rng, tmp_path, capsys):
    """--footprint-fov applies to images only: with --footprint 0 and a words' footprint it does
    nothing, on data without yaw too (it raised 'footprint_fov needs each image's yaw')."""
    grid = tiny_grid(ROWS)
    obs = observations(grid, rng, yaw=False)
    counts = _prepared(grid, obs, **WORDS_ONLY, footprint_fov=90.0)
    plain = _prepared(grid, obs, **WORDS_ONLY)
    for name in ("cells", "image_counts", "word_counts"):
        np.testing.assert_array_equal(getattr(counts, name), getattr(plain, name))
    (fov,) = preparation_warnings(DataPreparation(**WORDS_ONLY, footprint_fov=90.0))
    assert fov.startswith("footprint_fov=90 (fit's --footprint-fov 90) does nothing without")
    assert "each image counts in its own cell only" in fov
    assert preparation_warnings(DataPreparation(**WORDS_ONLY, footprint_kernel="gaussian")) == []
    room = write_synthetic(
        tmp_path / "data", seed=1, spec=HouseSpec(height=30, width=40, num_rooms=2)
    )
    for trial in [*room.glob("pose_*.csv"), *room.glob("word_*.csv")]:
        trial.unlink()  # no pose files: no image yaw
    argv = ["fit", str(room), "--sweeps", "2", "--concepts", "6", "--footprint", "0",
            "--word-footprint", "0.5", "--footprint-fov", "90", "--refine", "never",
            "--no-figures", "--out", str(tmp_path / "out")]  # fmt: skip
    assert main(argv) == 0
    assert "warning: footprint_fov=90 (fit's --footprint-fov 90) does nothing" in (
        capsys.readouterr().err
    )


def test_the_data_line_leaves_out_a_fov_the_images_do_not_read():
    line = data_line(DataPreparation(**WORDS_ONLY, footprint_fov=90.0))
    assert "footprint 0 m (uniform, words 0.5 m)" in line and "deg" not in line
    assert "(uniform, images 90 deg wide)" in data_line(
        DataPreparation(footprint_radius=0.5, footprint_fov=90.0)
    )


@pytest.mark.parametrize(
    ("words", "expected"),
    [(0.0, "0.75 m footprints (words at cell)"), (0.5, "0.75 m, words' 0.5 m footprints")],
)
def test_the_observed_cells_line_names_the_words_footprint_as_the_data_line(words, expected):
    """With ``--word-footprint 0`` the summary's observed cells line said "within their 0.75 m,
    words' 0 m footprints" beside the data line's "words at cell": both say "words at cell"."""
    from spcopyro.cli.common import _summary
    from spcopyro.data.model_grid import model_house
    from spcopyro.synthetic import make_house

    data = preset("coarse", word_footprint_radius=words).data
    house = model_house(make_house(seed=0, spec=HouseSpec.embedded()), data.cell_size)
    lines = _summary(house, warn=False, preparation=data).splitlines()
    observed = next(x for x in lines if x.startswith("observed cells"))
    # and coarse's Voronoi cells within rooms after them (its default since 2026-12-06)
    assert observed.endswith(
        f" within their {expected} and Voronoi cells within rooms at 1 m doors"
    )
    assert ("words at cell" in data_line(data)) == (words == 0.0)
