"""The refinement on the map's own cells (spcopyro.fit.refine): the decision, the refined
settings, the start from a coarse map, the library's and the command's wiring, Ctrl-C."""

from __future__ import annotations

import dataclasses
import json
import shlex

import numpy as np
import pytest
from fit_interrupts import interrupt_fit_at

from spcopyro._util.outputs import checkpoint_path
from spcopyro.cli.fit_refine import replaced_options
from spcopyro.cli.main import main
from spcopyro.config import DataPreparation, SpCoSettings, preset
from spcopyro.data import load_house
from spcopyro.data.model_grid import model_house
from spcopyro.fit.house import fit_house, preset_fit_kwargs
from spcopyro.fit.refine import (
    SEPARATES,
    map_house,
    refine_decision,
    refined_settings,
    replaced_preparation,
)
from spcopyro.fit.starts import result_labels
from spcopyro.maps.coarse import model_cell_of
from spcopyro.synthetic import HouseSpec, make_house

pytestmark = pytest.mark.usefixtures("one_torch_thread")

SWEEPS = 30


@pytest.fixture(scope="module")
def house():
    return make_house(seed=0, spec=HouseSpec(height=36, width=44, num_rooms=3))


def _shuffled_images(house):
    """The house with its image histograms permuted among the images: the same histograms,
    no longer following the places."""
    obs = house.observations
    order = np.random.default_rng(0).permutation(obs.image_features.shape[0])
    return dataclasses.replace(
        house, observations=dataclasses.replace(obs, image_features=obs.image_features[order])
    )


@pytest.fixture(scope="module")
def coarse_fit(house):
    kwargs = {**preset_fit_kwargs("coarse"), "refine": "never"}
    return fit_house(house, preset("coarse"), sweeps=SWEEPS, seed=0, progress=False, **kwargs)


def test_refined_settings_are_auto_s_preparation_with_alpha_scaled_by_the_cells_squared():
    coarse = preset("coarse", gamma=3.5)
    refined = refined_settings(coarse, model_cells=100, map_cells=900)
    assert refined.model == coarse.model.replace(alpha=coarse.model.alpha * 81)  # gamma kept
    auto = preset("auto").data
    assert refined.data == dataclasses.replace(auto, snap_distance=coarse.data.snap_distance)
    assert refined.data.cell_size is None and refined.data.footprint_radius == 0.0


def test_the_decision_follows_the_images_not_the_labels(house, coarse_fit):
    """The same coarse map: images drawn per place separate its concepts, the same images
    shuffled among the positions do not; never and always do as they say."""
    model = model_house(house, preset("coarse").data.cell_size)
    follows = refine_decision(coarse_fit, model, "auto")
    assert follows.separation.explained >= SEPARATES and follows.refine
    assert "tell the places apart" in follows.reason
    shuffled = refine_decision(coarse_fit, _shuffled_images(model), "auto")
    assert shuffled.separation.explained < 0.2 and not shuffled.refine
    assert "do not tell" in shuffled.reason
    assert refine_decision(coarse_fit, _shuffled_images(model), "always").refine
    never = refine_decision(coarse_fit, model, "never")
    assert not never.refine and never.separation is None
    with pytest.raises(ValueError, match="refine must be one of"):
        refine_decision(coarse_fit, model, "sometimes")


def test_no_refinement_where_floor100_would_leave_the_images_out(house, coarse_fit):
    """The README's rosbag walk (``features --weights random``: 1000-class rows, every value
    below 0.01) refined, as the images told the places apart read as probabilities, and the
    refinement's floor(100 f) then left out all 180 images: six rooms became four. The same
    histograms spread over 100 times the classes separate the places as much, and are not
    refined; over 2 times (values up to 0.5) they are."""
    model = model_house(house, preset("coarse").data.cell_size)
    obs = model.observations

    def spread(times):
        features = np.repeat(obs.image_features / times, times, axis=1)  # [T, K * times]
        return dataclasses.replace(
            model, observations=dataclasses.replace(obs, image_features=features)
        )

    wide = refine_decision(coarse_fit, spread(100), "auto")
    assert wide.separation.explained >= SEPARATES and not wide.refine
    count = obs.image_features.shape[0]
    assert f"leaves nothing of {count} of {count} images" in wide.reason
    assert "stays on its model grid" in wide.reason
    assert refine_decision(coarse_fit, spread(2), "auto").refine
    assert refine_decision(coarse_fit, spread(100), "always").refine  # as asked


def test_a_coarse_result_starts_a_fit_on_the_map_s_cells_block_by_block(house, coarse_fit):
    config = preset("auto").model
    start = result_labels(coarse_fit, house, config).numpy()  # [N map]
    assert start.shape == (house.grid.num_free,)
    factor = round(coarse_fit.grid.resolution / house.grid.resolution)
    rows, cols = model_cell_of(house.grid, factor)
    coarse = coarse_fit.label_image()  # [h, w], -1 off free
    cells = np.asarray(house.grid.free_cells)
    block = coarse[rows[cells[:, 0]], cols[cells[:, 1]]]  # the model cell of each map cell
    inside = block >= 0
    assert inside.mean() > 0.5  # the others lie in blocks that hold a wall
    np.testing.assert_array_equal(start[inside], block[inside])
    assert set(np.unique(start)) <= set(np.unique(coarse_fit.labels))
    other = make_house(seed=1, spec=HouseSpec(height=40, width=40, num_rooms=2))
    with pytest.raises(ValueError, match="fitted on a"):
        result_labels(coarse_fit, other, config)


def test_fit_house_refines_where_the_images_separate_and_records_why(house, coarse_fit):
    kwargs = preset_fit_kwargs("coarse")
    assert kwargs["refine"] == "auto"  # what spcopyro fit runs by default
    result = fit_house(house, preset("coarse"), sweeps=SWEEPS, seed=0, progress=False, **kwargs)
    assert result.grid.shape == house.grid.shape  # the map's own cells
    record = result.inference["refine"]
    assert record["refine"] and record["coarse"]["free_cells"] == coarse_fit.grid.num_free
    ratio = house.grid.num_free / coarse_fit.grid.num_free
    assert record["alpha"] == pytest.approx(preset("coarse").model.alpha * ratio**2)
    assert result.preparation.feature_scaling == "floor100"
    assert result.config.alpha == pytest.approx(record["alpha"])
    kept = fit_house(_shuffled_images(house), preset("coarse"), sweeps=SWEEPS, seed=0,
                     progress=False, **kwargs)  # fmt: skip
    assert kept.grid.shape == coarse_fit.grid.shape  # not refined: the model grid
    assert kept.inference["refine"]["refine"] is False  # why, in config.json
    assert kept.inference["refine"]["separation"]["explained"] < SEPARATES


def test_the_library_names_the_settings_preparation_its_refinement_replaces(house, caplog):
    """fit_house(refine=...) replaced settings' own preparation with the refinement's without a
    word (only the command line named what it replaced): one warning names the fields, those
    the caller chose (not the preset's own, which the refinement is made to replace)."""
    kwargs = {**preset_fit_kwargs("coarse"), "refine": "always", "sweeps": 5, "progress": False}
    mine = preset("coarse", word_scaling=5.0, footprint_kernel="gaussian")
    with caplog.at_level("WARNING", logger="spcopyro"):
        result = fit_house(house, mine, **kwargs)
    assert result.preparation.word_scaling == 1.0  # replaced, as before
    said = [r.getMessage() for r in caplog.records if "replacing the settings'" in r.getMessage()]
    assert len(said) == 1, said
    named = "word_scaling 5.0 -> 1.0, footprint_kernel 'gaussian' -> 'unused (no footprint)'"
    assert named in said[0]
    assert "feature_scaling" not in said[0]  # the preset's probability: the one replaced
    caplog.clear()
    with caplog.at_level("WARNING", logger="spcopyro"):
        fit_house(house, preset("coarse"), **kwargs)
    assert not [r for r in caplog.records if "replacing" in r.getMessage()]


def test_replaced_preparation_is_the_caller_s_own_fields_the_refinement_changes():
    coarse = preset("coarse", feature_scaling=2.0, footprint_radius=0.5)
    refined = refined_settings(coarse, 100, 2500).data
    assert replaced_preparation(coarse, refined) == {
        "feature_scaling": {"given": 2.0, "refinement": "floor100"},
        "footprint_radius": {"given": 0.5, "refinement": 0.0},
    }  # word scaling 10, footprint kernel uniform: the preset's
    assert replaced_preparation(preset("coarse"), refined) == {}
    plain = SpCoSettings(data=DataPreparation(cell_size=0.25))  # no preset: every field its own
    assert replaced_preparation(plain, refined) == {
        "feature_scaling": {"given": "probability", "refinement": "floor100"}
    }  # no footprint in either stage: its kernel and field of view are not named


def test_refine_needs_a_gibbs_fit(house):
    with pytest.raises(ValueError, match="refines a Gibbs fit"):
        fit_house(house, preset("coarse"), method="cavi", sweeps=3, refine="auto")


def test_a_fit_run_until_it_converges_is_refined_for_as_many_sweeps(house):
    kwargs = {**preset_fit_kwargs("coarse"), "init": "rooms", "chains": 2, "progress": False}
    result = fit_house(house, preset("coarse"), sweeps="auto", **{**kwargs, "refine": "always"})
    assert result.grid.shape == house.grid.shape  # the map's own cells
    record = result.inference["refine"]
    assert len(result.trace.objective) == record["coarse"]["sweeps"] > 0  # the coarse chains'
    assert result.inference["point_estimate"] == "vi"  # the preset's, over the refit's samples
    with pytest.raises(ValueError, match="reports the best visited state"):
        fit_house(house, preset("coarse"), sweeps="auto", **{**kwargs, "refine": "never"})


def test_map_house_undoes_the_coarsening(house):
    model = model_house(house, 0.25)
    assert model.grid.coarsened_from is house.grid
    assert map_house(model).grid is house.grid and map_house(house) is house


# --- the command -------------------------------------------------------------------------------


@pytest.fixture(autouse=True)
def _no_progress_bars(monkeypatch):
    monkeypatch.setenv("CI", "1")  # stderr holds only what the command says


def test_fit_refines_by_default_and_writes_the_map_s_cells(home, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fit", str(home), "--out", str(out), "--sweeps", "60", "--no-figures"]) == 0
    printed = capsys.readouterr().out
    assert "refining         the concepts explain" in printed
    labels = np.load(out / "labels.npy")
    with (out / "truth.npy").open("rb") as f:
        assert labels.shape == np.load(f).shape  # the truth of the map's cells
    config = json.loads((out / "config.json").read_text())
    assert config["inference"]["refine"]["replaced"] == {}  # nothing given, nothing replaced
    assert config["inference"]["refine"]["preparation"] == config["data"]  # the refinement's
    assert not (out / "robot_map.yaml").exists()  # the result is on the robot's own map
    never = tmp_path / "never"
    argv = ["fit", str(home), "--out", str(never), "--sweeps", "60", "--no-figures"]
    assert main([*argv, "--refine", "never"]) == 0
    printed = capsys.readouterr().out
    assert "refining " not in printed and "not refined " not in printed
    assert np.load(never / "labels.npy").shape != labels.shape  # the 0.25 m model grid


def test_the_progress_bars_name_the_two_stages(home, tmp_path, capsys, monkeypatch):
    """Both stages' bars read "Gibbs sweeps:", so the user saw 5/5 and then 0/5 under the same
    label: they name the model grid and the map's cells (docs/real_houses.md), one chain (the
    sweep driver's bar) or several (run_chains')."""
    monkeypatch.delenv("CI")  # the bars on
    argv = ["fit", str(home), "--no-figures", "--refine", "always"]
    for more in (["--sweeps", "5"], ["--sweeps", "3", "--chains", "2"]):
        out = tmp_path / str(len(more))
        assert main([*argv, "--out", str(out), *more]) == 0
        err = capsys.readouterr().err.replace("\r", "\n")
        assert "Gibbs sweeps (model grid)" in err and "Gibbs sweeps (map's cells)" in err, err
        assert "Gibbs sweeps:" not in err, err
        first, second = err.index("(model grid)"), err.index("(map's cells)")
        assert first < second and "(model grid)" not in err[second:], err


def test_a_preparation_given_on_the_command_line_is_not_refined_away(home, tmp_path, capsys):
    argv = ["fit", str(home), "--sweeps", "60", "--no-figures", "--word-scaling", "10"]
    assert main([*argv, "--out", str(tmp_path / "kept")]) == 0
    printed = capsys.readouterr().out
    assert "refining " not in printed and "not refined " not in printed
    assert main([*argv, "--out", str(tmp_path / "asked"), "--refine", "always"]) == 0
    printed = capsys.readouterr()
    assert "refining " in printed.out  # unless asked for
    # ... and then the refinement's own preparation replaces it, not silently
    assert "replacing --word-scaling 10 -> 1; the first stage used yours" in printed.err
    record = json.loads((tmp_path / "asked" / "config.json").read_text())["inference"]["refine"]
    assert record["replaced"] == {"--word-scaling": {"given": 10.0, "refinement": 1.0}}
    assert record["coarse"]["preparation"]["word_scaling"] == 10.0
    assert record["preparation"]["word_scaling"] == 1.0


def test_the_command_names_an_option_the_refinement_replaces_once(home, tmp_path, capsys):
    """The command's note names its options; the library's warning, which would name the
    settings' fields made of them, is not printed too."""
    argv = ["fit", str(home), "--sweeps", "5", "--no-figures", "--word-scaling", "5"]
    assert main([*argv, "--out", str(tmp_path / "out"), "--refine", "always"]) == 0
    err = capsys.readouterr().err
    assert "replacing --word-scaling 5 -> 1; the first stage used yours" in err
    assert err.count("-> 1") == 1, err


def test_the_note_names_only_given_options_the_refinement_changes():
    given = preset("coarse", feature_scaling="probability", footprint_radius=0.5,
                   footprint_kernel="gaussian", cell_size=0.5)  # fmt: skip
    refined = refined_settings(given, 100, 2500).data
    assert replaced_options(given, refined) == {
        "--feature-scaling": {"given": "probability", "refinement": "floor100"},
        "--footprint": {"given": 0.5, "refinement": 0.0},
        "--footprint-kernel": {"given": "gaussian", "refinement": "unused (no footprint)"},
    }  # word scaling: the preset's 10, not given; the cell size: the refinement's by definition
    # the refinement's preparation keeps the kernel (it does nothing at radius 0): the record
    # says so rather than None beside a preparation holding it (found in review)
    assert refined.footprint_radius == 0.0
    uniform = preset("coarse", footprint_kernel="uniform")  # given, though the preset's value
    assert replaced_options(uniform, refined) == {
        "--footprint-kernel": {"given": "uniform", "refinement": "unused (no footprint)"}
    }
    same = preset("coarse", feature_scaling="floor100", word_scaling=1.0, footprint_radius=0.0)
    assert replaced_options(same, refined) == {}  # given, but what the refinement uses
    assert replaced_options(preset("coarse"), refined) == {}  # the default fit


def _replacing(said: str, start: str) -> dict[str, str]:
    """``name -> "given -> refinement"`` of the ``replacing ...;`` part of a note or warning,
    the values as the command line writes them (flags named as the keywords they set)."""
    part = said[said.index(start) + len(start) : said.index("; the first stage")]
    named = {}
    for change in part.split(", "):
        name, given, _, used = change.split(" ", 3)
        name = {"--footprint": "footprint_radius"}.get(name, name.lstrip("-").replace("-", "_"))
        named[name] = " -> ".join(v.strip("'").removesuffix(".0") for v in (given, used))
    return named


def test_the_command_and_the_library_name_the_same_replaced_options(home, tmp_path, capsys,
                                                                    caplog):  # fmt: skip
    """``spcopyro fit``'s note and ``fit_house``'s warning follow one rule: an option given
    counts even where it is the preset's value (--word-scaling 10, coarse's own: the library
    did not name it), and a kernel given without a footprint is not replaced (it did nothing in
    the first stage: the command named it)."""
    given = {"feature_scaling": 2.0, "word_scaling": 10.0, "footprint_radius": 0.0,
             "footprint_kernel": "gaussian"}  # fmt: skip
    argv = ["fit", str(home), "--out", str(tmp_path / "out"), "--sweeps", "3", "--no-figures",
            "--refine", "always", "--feature-scaling", "2", "--word-scaling", "10",
            "--footprint", "0", "--footprint-kernel", "gaussian"]  # fmt: skip
    assert main(argv) == 0
    note = [line for line in capsys.readouterr().err.splitlines() if "replacing" in line]
    assert len(note) == 1, note
    kwargs = {**preset_fit_kwargs("coarse"), "refine": "always", "sweeps": 3, "progress": False}
    with caplog.at_level("WARNING", logger="spcopyro"):
        fit_house(load_house(home), preset("coarse", **given), **kwargs)
    said = [r.getMessage() for r in caplog.records if "replacing the settings'" in r.getMessage()]
    assert len(said) == 1, said
    command = _replacing(note[0], "replacing ")
    library = _replacing(said[0], "replacing the settings' ")
    assert command == library == {"feature_scaling": "2 -> floor100", "word_scaling": "10 -> 1"}


def test_several_chains_are_refined_from_the_best_coarse_chain(home, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), "--sweeps", "20", "--no-figures",
            "--refine", "always", "--chains", "2"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    (line,) = [x for x in printed.splitlines() if x.startswith("refining ")]
    assert ": continuing from the best of 2 chains on the map's own 0.1 m cells (" in line, line
    assert "fitted 2 chains x 20 sweeps on 0.3 m cells (" in printed
    assert "), then 2 chains x 20 on the map's 0.1 m cells (" in printed
    chains = json.loads((out / "chains.json").read_text())
    assert chains["seeds"] == [0, 1] and len(chains["best_log_joint"]) == 2
    config = json.loads((out / "config.json").read_text())
    assert config["inference"]["refine"]["coarse"]["sweeps"] == 20


def test_refine_is_refused_where_it_does_not_apply(home, tmp_path, capsys):
    argv = ["fit", str(home), "--out", str(tmp_path / "o"), "--no-figures"]
    assert main([*argv, "--method", "cavi", "--sweeps", "3", "--refine", "auto"]) == 2
    assert "--refine auto refines a Gibbs fit" in capsys.readouterr().err


def test_a_fit_the_preset_would_refine_but_cannot_says_why(home, tmp_path, capsys):
    """Another --method or --update turned coarse's --refine auto to never silently: a cavi fit
    (the 0.3 m model grid) beside a Gibbs fit refined to the map's cells, and nothing said why
    their cells differ. The line sits where a Gibbs fit's decision does (before fitted)."""
    argv = ["fit", str(home), "--no-figures", "--sweeps", "2"]
    cavi = tmp_path / "cavi"
    assert main([*argv, "--out", str(cavi), "--method", "cavi"]) == 0
    printed = capsys.readouterr().out
    line = ("not refined      --refine refines --method gibbs fits only: --method cavi keeps the "
            "0.3 m model grid\n")  # fmt: skip
    assert line in printed and printed.index(line) < printed.index("\nfitted ")
    assert "refining " not in printed
    assert main([*argv, "--out", str(tmp_path / "u"), "--update", str(cavi)]) == 0
    assert ("not refined      --refine refines a new fit only: --update continues the saved fit "
            "on the 0.3 m model grid\n") in capsys.readouterr().out  # fmt: skip
    for more in (["--refine", "never"], ["--preset", "paper-dp"]):  # nothing left unrefined
        assert main([*argv, "--out", str(tmp_path / more[1]), "--method", "cavi", *more]) == 0
        assert "not refined" not in capsys.readouterr().out


@pytest.mark.parametrize("given", [["--footprint", "0.5"], ["--cell-size", "map"]])
def test_a_fit_with_its_own_preparation_does_not_say_not_refined(home, tmp_path, capsys, given):
    """A preparation given on the command line keeps a Gibbs fit unrefined too, silently: a
    cavi fit with one printed 'not refined --refine refines --method gibbs fits only', blaming
    --method where the preparation is the reason."""
    argv = ["fit", str(home), "--no-figures", "--sweeps", "2", "--method", "cavi"]
    assert main([*argv, "--out", str(tmp_path / "cavi"), *given]) == 0
    printed = capsys.readouterr().out
    assert "not refined" not in printed and "refining " not in printed
    assert "\nfitted " in printed


def test_no_refinement_without_a_model_grid_coarser_than_the_map(home, tmp_path, capsys):
    """``--cell-size map --refine always`` was accepted and refitted the map's cells on the same
    cells with the refinement's preparation (``--refine auto`` too, where the images separated
    the places), while --refine's help says it comes after a fit on model cells coarser than
    the map. ``always`` is refused before the fit, naming both options; ``auto`` fits once and
    says why it did not refine."""
    argv = ["fit", str(home), "--sweeps", "4", "--no-figures", "--chain-workers", "1"]
    asked = tmp_path / "always"
    assert main([*argv, "--out", str(asked), "--cell-size", "map", "--refine", "always"]) == 2
    error = capsys.readouterr().err
    assert "--refine always refits a fit on model cells coarser than the map" in error
    assert "--cell-size map fits on the map's own 0.1 m cells" in error
    assert not asked.exists()  # refused before the fit
    for options, cause in (
        (["--preset", "auto"], "--preset auto (no cell size) fits on the map's own 0.1 m cells"),
        (["--cell-size", "0.12"], "--cell-size 0.12 rounds to the map's own 0.1 m cells"),
    ):
        assert main([*argv, "--out", str(asked), *options, "--refine", "always"]) == 2
        assert cause in capsys.readouterr().err
    out = tmp_path / "auto"
    assert main([*argv, "--out", str(out), "--cell-size", "map", "--refine", "auto"]) == 0
    printed = capsys.readouterr().out
    assert "refining " not in printed
    assert ("not refined      --cell-size map fits on the map's own 0.1 m cells: there is no "
            "coarser model grid to refine from") in printed  # fmt: skip
    record = json.loads((out / "config.json").read_text())["inference"]["refine"]
    assert not record["refine"] and "no coarser model grid" in record["reason"]
    assert json.loads((out / "config.json").read_text())["data"]["feature_scaling"] == (
        "probability"  # the preset's preparation, not the refinement's floor100
    )


def test_the_library_does_not_refine_a_fit_on_the_map_s_own_cells(house, coarse_fit):
    on_map = model_house(house, None)
    decision = refine_decision(coarse_fit, on_map, "auto")
    assert not decision.refine and "no coarser model grid" in decision.reason
    with pytest.raises(ValueError, match="refine='always' refits a fit on model cells coarser"):
        refine_decision(coarse_fit, on_map, "always")
    with pytest.raises(ValueError, match="there is no coarser model grid"):  # before fitting
        fit_house(house, preset("coarse", cell_size="map"), sweeps=1, refine="always")


def test_sweeps_auto_refines_for_as_many_sweeps_as_the_chains_needed(home, tmp_path, capsys):
    argv = ["fit", str(home), "--no-figures", "--sweeps", "auto", "--max-sweeps", "20",
            "--chains", "2"]  # fmt: skip
    assert main([*argv, "--out", str(tmp_path / "default")]) == 0
    printed = capsys.readouterr().out  # decided by default, as without --sweeps auto
    assert "refining         the concepts explain" in printed or "not refined      the" in printed
    decided = json.loads((tmp_path / "default" / "config.json").read_text())["inference"]
    assert decided["refine"]["mode"] == "auto"  # config.json says why, refined or not
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out), "--refine", "always"]) == 0
    printed = capsys.readouterr().out
    assert "refining         refine='always'" in printed
    assert ": continuing from the best of 2 chains on the map's own 0.1 m cells (" in printed
    assert "--sweeps auto: 2 chains " in printed and " after 20 sweeps each" in printed
    assert "highest log joint, the refinement started from it" in printed
    assert "fitted 2 chains x 20 sweeps on 0.3 m cells (" in printed
    assert "), then 2 chains x 20 on the map's 0.1 m cells (" in printed
    assert "point estimate   vi" in printed  # the preset's, over the refinement's samples
    assert np.load(out / "labels.npy").shape == np.load(out / "truth.npy").shape  # map's cells
    config = json.loads((out / "config.json").read_text())
    assert config["inference"]["refine"]["coarse"]["sweeps"] == 20
    assert config["inference"]["point_estimate"] == "vi"
    convergence = json.loads((out / "convergence.json").read_text())
    assert convergence["seeds"] == [0, 1]  # the coarse chains', which were checked


def test_ctrl_c_while_refining_keeps_the_first_stage_and_resume_refines_again(
    home, tmp_path, capsys, monkeypatch
):
    out = tmp_path / "out"
    argv = ["fit", str(home), "--out", str(out), "--sweeps", "12", "--no-figures",
            "--refine", "always", "--chain-workers", "1"]  # fmt: skip
    with monkeypatch.context() as patch:
        interrupt_fit_at(patch, 1, 4)  # the refinement's chain, after the coarse one
        assert main(argv) == 130
    err = capsys.readouterr().err
    assert err.startswith("interrupted (while refining on the map's own cells: chain 1 of 1, 5 "
                          "of 12 sweeps done; the first stage is kept and resuming refines "
                          "again): nothing written to")  # fmt: skip
    checkpoint = checkpoint_path(out)
    assert f"saved in {checkpoint}" in err
    again = shlex.split(err.split("continue with: ")[1])
    assert main(again[1:]) == 0
    assert main([*argv[:3], str(tmp_path / "unbroken"), *argv[4:]]) == 0
    with np.load(out / "result.npz") as a, np.load(tmp_path / "unbroken" / "result.npz") as b:
        for name in a.files:
            if name != "seconds":
                np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    assert not checkpoint.exists()


def test_a_refined_fit_is_updated_on_the_map_s_cells_as_refined(home, tmp_path, capsys):
    first, second, third = (tmp_path / name for name in ("first", "second", "third"))
    argv = ["fit", str(home), "--no-figures", "--sweeps", "12"]
    assert main([*argv, "--out", str(first), "--refine", "always"]) == 0
    saved = json.loads((first / "config.json").read_text())
    assert main([*argv, "--out", str(second), "--update", str(first)]) == 0  # was an error
    assert main([*argv, "--out", str(third), "--update", str(second)]) == 0  # and again
    capsys.readouterr()
    for out in (second, third):
        config = json.loads((out / "config.json").read_text())
        assert config["model"] == saved["model"] and config["data"] == saved["data"]
        assert config["inference"]["refine"] == saved["inference"]["refine"]  # kept for the next
        assert np.load(out / "labels.npy").shape == np.load(first / "labels.npy").shape
    # a preparation of its own on the command line is checked against the saved fit's
    assert main([*argv, "--out", str(tmp_path / "x"), "--update", str(first),
                 "--word-scaling", "10"]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "cannot update" in err and "a refined fit is saved with its second stage's" in err
    # the library: the preset's (coarse) settings against the refined fit's
    from spcopyro.config import preset
    from spcopyro.data import load_house
    from spcopyro.results.result import SpCoResult
    from spcopyro.robot.online import fit_update

    with pytest.raises(ValueError, match=r"cell_size: .*\(a refined fit is saved .*settings=None"):
        fit_update(SpCoResult.load(first), load_house(home), preset("coarse"), sweeps=1)


def test_the_coarse_stage_s_sampled_hyperparameters_are_kept_and_the_printed_ones_named(
    tmp_path, capsys
):
    """With hyper.* the refinement samples its own hyperparameters from the preset's values:
    the coarse stage's posterior was dropped, and the printed line did not say whose it was."""
    out = tmp_path / "out"
    argv = ["fit", "--out", str(out), "--sweeps", "6", "--refine", "always", "--no-figures",
            "--method-option", "hyper.gamma=pseudolikelihood"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "second half, of the refinement on the map's cells)" in printed
    inference = json.loads((out / "config.json").read_text())["inference"]
    assert set(inference["refine"]["coarse"]["hyperparameters"]) == {"gamma"}
    assert set(inference["hyperparameters"]) == {"gamma"}


def test_a_large_refinement_is_announced(home, tmp_path, capsys, monkeypatch):
    """On a 228,934-cell map the refinement ran 12-18 min after a 4-min first stage whose bar
    had said nothing of it: from LARGE_REFINEMENT_CELLS free cells its decision comes with a
    note giving the cells and how to stop at the first stage (threshold lowered here)."""
    import spcopyro.cli.fit_refine as fit_refine

    argv = ["fit", str(home), "--sweeps", "5", "--no-figures", "--refine", "always"]
    assert main([*argv, "--out", str(tmp_path / "small")]) == 0
    assert "note: the refinement sweeps" not in capsys.readouterr().err
    monkeypatch.setattr(fit_refine, "LARGE_REFINEMENT_CELLS", 10)
    assert main([*argv, "--out", str(tmp_path / "large")]) == 0
    err = capsys.readouterr().err
    assert "note: the refinement sweeps the map's " in err, err
    assert "x the first stage's " in err and "--refine never keeps the first stage's map" in err


def test_the_refining_line_says_why_alpha_changed(home, tmp_path, capsys):
    """``refining ... alpha 1.22e+09`` after the model's ``alpha 1e7`` said nothing of the
    change: the line gives the sum (refined_settings: the first stage's alpha times the square
    of the free cells' ratio, map over model grid) with the counts it used, short, and the line
    under it, indented and under 100 characters, says why. The line itself is the decision's
    reason, the cells it continues on and alpha: it also said the first stage's sweeps, cells
    and log joint (the lines above and config.json say them) and the refinement's preparation
    (fit --help), 337 characters on room1ldk5 with --refine always."""
    import re

    argv = ["fit", str(home), "--out", str(tmp_path / "out"), "--sweeps", "2", "--no-figures",
            "--refine", "always"]  # fmt: skip
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    at = next(k for k, x in enumerate(lines) if x.startswith("refining"))
    match = re.search(
        r": continuing on the map's own 0\.1 m cells \(\d+ observed\), "
        r"alpha (\S+) \((\S+) x \(([\d,]+) / ([\d,]+)\)\^2\)$",
        lines[at],
    )
    assert match, lines[at]
    reason = json.loads((tmp_path / "out" / "config.json").read_text())["inference"]["refine"]
    assert lines[at][: match.start()] == f"refining         {reason['reason']}", lines[at]
    alpha, first_alpha, cells, first_cells = match.groups()
    cells, first_cells = int(cells.replace(",", "")), int(first_cells.replace(",", ""))
    # the counts are the map line's: "328 free (the model's cells, of the map's ..., 3620 free)"
    grid = next(x for x in lines if x.startswith("map "))
    assert f"{first_cells} free (the model's cells" in grid and f", {cells} free)" in grid, grid
    assert "alpha 1e7" in next(x for x in lines if x.startswith("model "))
    assert float(first_alpha) == 1e7
    assert float(alpha) == pytest.approx(1e7 * (cells / first_cells) ** 2, rel=1e-2)
    why = lines[at + 1]
    assert why == (
        "  alpha grows as the free cells squared, so the label counts' prior weighs as on the "
        "model grid"
    ), why
    assert len(why) <= 100
