"""Numerics and limits: counts too large or not finite, a log joint that is not finite, more
concepts than int16 holds, extreme hyperparameters, maps without free space or observations off
it. Bad input gives one clear error (exit code 2 from the CLI) and writes nothing."""

from __future__ import annotations

import dataclasses
import logging
import math
import re

import numpy as np
import pytest
import torch

from spcopyro.cli.main import main
from spcopyro.config import SpCoConfig, preset
from spcopyro.data import (
    MAX_COUNT_TOTAL,
    DataFormatError,
    Observations,
    cell_counts,
    check_count_totals,
    load_house,
)
from spcopyro.fit.house import (
    FREEZING_GAMMA,
    config_warnings,
    preparation_warnings,
    prepare_model_data,
)
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import NonFiniteLogJointError, label_dtype, run_gibbs
from spcopyro.likelihood import log_joint_constant, log_joint_terms, log_joint_variable
from spcopyro.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from spcopyro.synthetic import HouseSpec, make_house, write_synthetic
from tests.gibbs_problems import model_data, random_problem, tiny_grid


@pytest.fixture
def room(tmp_path):
    """A small synthetic house written in the dataset layout (its map at ../map/)."""
    return write_synthetic(
        tmp_path / "data", seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3)
    )


def _set_value(path, line: int, column: int, value: str) -> None:
    """Replace the value at 1-based ``line``, ``column`` of a CSV file."""
    lines = path.read_text().split("\n")
    fields = lines[line - 1].split(",")
    fields[column - 1] = value
    lines[line - 1] = ",".join(fields)
    path.write_text("\n".join(lines))


def _fit_fails(argv: list[str], out, capsys) -> str:
    """Run ``spcopyro fit``; assert exit code 2 and that nothing was written; the error."""
    assert main(["fit", *argv, "--out", str(out), "--sweeps", "3", "--concepts", "10"]) == 2
    err = capsys.readouterr().err
    assert not out.exists()
    return err.strip().splitlines()[-1]


# -- 1. counts: finite, totals bounded -----------------------------------------------------------


def test_a_huge_image_feature_is_rejected_naming_file_line_and_value(room, tmp_path, capsys):
    _set_value(room / "Ft.csv", 3, 2, "1e308")
    house = load_house(room)  # a finite number: the loader takes it
    with pytest.raises(DataFormatError, match=r"Ft\.csv, line 3, column 2: image 2: the count "
                       r"becomes inf under feature_scaling='floor100': 1e\+308"):  # fmt: skip
        prepare_model_data(house, preset("original-code"))
    with pytest.raises(DataFormatError, match=r"Ft\.csv, line 3, column 2: image 2: its counts "
                       r"total 1e\+308 .*MAX_COUNT_TOTAL = 1e\+15"):  # fmt: skip
        prepare_model_data(house, preset("paper-dp"))
    for options in ([], ["--preset", "original-code", "--gamma", "3"]):
        err = _fit_fails([str(room), *options], tmp_path / "out", capsys)
        assert err.startswith("error: ") and "Ft.csv, line 3, column 2" in err and "1e+308" in err


def test_count_totals_are_bounded_per_observation_and_in_all():
    ok = np.array([[MAX_COUNT_TOTAL / 2, MAX_COUNT_TOTAL / 2], [0.0, 0.0]])  # [T, K]
    check_count_totals(ok, "images")  # exactly at the bound: accepted
    row = np.array([[1.0, 1.0], [6e14, 6e14]])  # one observation's total 1.2e15
    with pytest.raises(ValueError, match=r"image 1, column 0: its counts total 1\.2e\+15"):
        check_count_totals(row, "images")
    spread = np.full((3, 2), 2e14)  # each 4e14, together 1.2e15
    with pytest.raises(ValueError, match=r"the 3 observations of 'images' total 1\.2e\+15"):
        check_count_totals(spread, "images")
    with pytest.raises(ValueError, match=r"utterance 1 \(entry 2\), column 0: the count becomes "):
        check_count_totals(np.array([[1.0], [math.inf]]), "words")
    with pytest.raises(DataFormatError, match=r"St\.csv, line 1, column 1: utterance 1 "):
        check_count_totals(np.array([[1.0], [math.inf]]), "words", source="/house")
    with pytest.raises(DataFormatError, match=r"modality_wifi\.csv, line 3, column 2: "
                       r"observation 1 of modality 'wifi'"):  # fmt: skip
        check_count_totals(np.array([[0.0, 1.0], [1.0, 2e15]]), "wifi", source="/house")


def test_a_non_finite_log_joint_stops_the_chain_naming_sweep_and_term(backend):
    grid, data = random_problem(0)
    config = SpCoConfig(num_concepts=3, alpha=2.0, beta=1.0, chi=1.0, gamma=1.0)
    images = data.modalities[0].counts.clone()  # [M, K]
    images[1, 0] = 1e308  # past cell_counts' checks: lgamma(n + 1) overflows
    bad = model_data(grid, data.obs_cells.numpy(), images.numpy(), data.modalities[1].counts)
    options = GibbsOptions(backend=backend.name)
    with pytest.raises(NonFiniteLogJointError, match=r"sweep 0 .*images coefficients = nan"):
        run_gibbs(bad, config, 5, seed=0, options=options, progress=False)
    assert issubclass(NonFiniteLogJointError, ValueError)  # the CLI's bad-input exit code 2
    run = run_gibbs(data, config, 5, seed=0, options=options, progress=False)
    assert np.isfinite(run.log_joint).all() and run.best_sweep >= 0


def test_log_joint_terms_sum_to_the_log_joint():
    grid, data = random_problem(1)
    config = SpCoConfig(num_concepts=4, alpha=3.0, beta=0.5, chi=2.0, gamma=0.7)
    run = run_gibbs(data, config, 3, seed=1, progress=False)
    state = run.final_state
    terms = log_joint_terms(state.labels, state.log_pi, state.log_emissions, data, config)
    assert {"normalisers", "images coefficients", "potts", "words data"} <= set(terms)
    total = log_joint_constant(data, config) + log_joint_variable(
        state.labels, state.log_pi, state.log_emissions, data, config
    )
    assert sum(terms.values()) == pytest.approx(float(total), rel=1e-12)
    assert run.log_joint[-1] == pytest.approx(float(total), rel=1e-12)


# -- 2. labels of more than 32767 concepts -------------------------------------------------------


def test_label_storage_holds_more_concepts_than_int16(backend):
    assert label_dtype(120) == label_dtype(32768) == torch.int16  # labels 0..32767
    assert label_dtype(32769) == torch.int32
    grid = tiny_grid(["....", "...."])
    data = model_data(grid, [0, 5], [[1.0, 0.0], [0.0, 1.0]], [[1.0], [1.0]])
    L = 40000
    config = SpCoConfig(num_concepts=L, alpha=1e8, beta=1.0, chi=1.0, gamma=100.0)
    start = torch.full((grid.num_free,), L - 1, dtype=torch.long)  # 39999 > int16's 32767
    run = run_gibbs(data, config, 2, seed=0, init_labels=start, thin=1, progress=False,
                    options=GibbsOptions(backend=backend.name))  # fmt: skip
    assert run.label_samples.dtype == np.int32
    assert (run.label_samples == L - 1).all()  # gamma 100 keeps every cell with its neighbours
    assert (run.best_state.labels == L - 1).all() and (run.final_state.labels == L - 1).all()


def test_a_result_with_labels_out_of_range_is_never_written(tmp_path):
    from spcopyro.fit.house import fit_house

    house = make_house(seed=0, spec=HouseSpec(height=30, width=40, num_rooms=2))
    result = fit_house(house, preset("original-code", gamma=3.0, num_concepts=5), sweeps=2,
                       progress=False)  # fmt: skip
    for labels in (result.labels - 40000, result.labels + 5, result.labels[:-1]):
        broken = dataclasses.replace(result, labels=labels)
        with pytest.raises(ValueError, match="not saving a corrupt result"):
            broken.save(tmp_path / "out")
        assert not (tmp_path / "out").exists()


# -- 3. extreme but legal hyperparameters --------------------------------------------------------


def test_extreme_hyperparameters_are_warned_about_with_the_reason():
    assert config_warnings(preset("paper-dp").model) == []
    assert config_warnings(preset("paper-dirichlet", num_concepts=5).model) == []
    (below,) = config_warnings(preset("original-code").model)
    assert "below the Potts critical coupling" in below
    assert config_warnings(SpCoConfig(gamma=FREEZING_GAMMA - 0.01)) == []
    (frozen,) = config_warnings(SpCoConfig(gamma=FREEZING_GAMMA))
    assert "freezes" in frozen and "117 of 120" in frozen
    assert "the Gibbs sampler freezes" in frozen and "not the variational methods" in frozen
    for name in ("alpha", "beta", "chi"):
        assert config_warnings(SpCoConfig(**{name: 1e12})) == []
        assert config_warnings(SpCoConfig(**{name: 1e-3})) == []
        (high,) = config_warnings(SpCoConfig(**{name: 1e300}))
        assert high.startswith(f"{name} = 1e+300 is above 1e+12") and "rounding noise" in high
        (low,) = config_warnings(SpCoConfig(**{name: 1e-300}))
        assert low.startswith(f"{name} = 1e-300 is below 0.001") and "mean" in low
        # the trace they spoil is the sampler's: a variational method's objective is its ELBO
        assert "the Gibbs sampler's log joint" in high and "the Gibbs sampler's log joint" in low
    (further,) = config_warnings(SpCoConfig(concentrations={"wifi": 1e13}))
    assert further.startswith("concentration 'wifi' = 1e+13")


def test_the_concentrations_warned_about_are_the_configs_hyperparameters_but_gamma():
    """The concentrations checked are alpha and the modalities' (config.CONCENTRATION_FIELDS, as
    config.HYPERPARAMETER_FIELDS orders them, gamma, the MRF's coupling, left out), then each
    further modality's: they were named by hand as alpha, beta, chi, another order than the
    config's alpha, chi, beta."""
    fields = ["alpha", "chi", "beta"]
    extreme = SpCoConfig(**dict.fromkeys(fields, 1e13), concentrations={"wifi": 1e13})
    said = config_warnings(extreme)
    assert [w.split(" = ")[0] for w in said] == [*fields, "concentration 'wifi'"]


def test_fit_prints_and_logs_every_config_warning(room, tmp_path, capsys, caplog):
    argv = ["fit", str(room), "--out", str(tmp_path / "f"), "--sweeps", "2", "--concepts", "10",
            "--gamma", "20", "--chi", "1e-300"]  # fmt: skip
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        assert main(argv) == 0
    err = capsys.readouterr().err
    assert err.count("warning: gamma = 20 is at or above 10") == 1  # printed once, not twice
    assert err.count("warning: chi = 1e-300 is below 0.001") == 1
    logged = [r.getMessage() for r in caplog.records]  # prepare_model_data's
    assert any(m.startswith("gamma = 20 is at or above") for m in logged)
    assert any(m.startswith("chi = 1e-300 is below") for m in logged)
    # a refined fit prepares its data twice (coarse cells, then the map's): warned once
    assert main([*argv, "--refine", "always", "--out", str(tmp_path / "r")]) == 0
    assert capsys.readouterr().err.count("warning: gamma = 20 is at or above 10") == 1


def test_a_footprint_kernel_or_fov_without_a_footprint_is_warned_about_once(
    room, tmp_path, capsys, caplog
):
    """A kernel or field of view given with footprint_radius 0 did nothing, and nothing said
    so; now one warning names them and the option that makes them take effect, once per fit
    (the refinement, whose preparation has no footprint, does not say it again)."""
    assert preparation_warnings(preset("coarse").data) == []
    assert preparation_warnings(preset("coarse", footprint_kernel="gaussian").data) == []
    (kernel,) = preparation_warnings(
        preset("coarse", footprint_kernel="gaussian", footprint_radius=0).data
    )
    assert kernel.startswith("footprint_kernel='gaussian' (fit's --footprint-kernel gaussian) "
                             "does nothing without a footprint")  # fmt: skip
    assert "footprint_radius=R (fit's --footprint R)" in kernel
    (both,) = preparation_warnings(preset("auto", footprint_kernel="gaussian",
                                          footprint_fov=90.0).data)  # fmt: skip
    assert "and footprint_fov=90 (fit's --footprint-fov 90) do nothing" in both
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        settings = preset("coarse", footprint_kernel="gaussian", footprint_radius=0)
        prepare_model_data(load_house(room), settings.replace(cell_size=None))
    assert [r.getMessage() for r in caplog.records].count(kernel) == 1
    capsys.readouterr()
    said = "warning: footprint_kernel='gaussian' (fit's --footprint-kernel gaussian) does nothing"
    argv = ["fit", str(room), "--sweeps", "2", "--concepts", "10", "--footprint", "0",
            "--footprint-kernel", "gaussian"]  # fmt: skip
    for refine in ("never", "always"):
        assert main([*argv, "--refine", refine, "--out", str(tmp_path / refine)]) == 0
        assert capsys.readouterr().err.count(said) == 1, refine


def test_the_gibbs_samplers_setting_warnings_are_given_to_samplers_only(room, tmp_path, capsys):
    """gamma >= 10 ("the Gibbs sampler freezes ..., not the variational methods") and the
    concentrations' warnings (the sampler's log joint) were printed for --method cavi and lbp,
    where they are noise; gibbs and vi-gibbs still give them, every method the critical one."""
    frozen = SpCoConfig(gamma=20.0, chi=1e-300)
    assert len(config_warnings(frozen)) == len(config_warnings(frozen, sampled=True)) == 2
    assert config_warnings(frozen, sampled=False) == []
    below = preset("original-code").model
    assert config_warnings(below, sampled=False) == config_warnings(below) != []
    argv = ["fit", str(room), "--sweeps", "2", "--concepts", "10", "--gamma", "20",
            "--chi", "1e-300"]  # fmt: skip
    for method, said in (("cavi", 0), ("lbp", 0), ("vi-gibbs", 1)):
        assert main([*argv, "--method", method, "--out", str(tmp_path / method)]) == 0
        err = capsys.readouterr().err
        assert err.count("warning: gamma = 20 is at or above 10") == said, (method, err)
        assert err.count("warning: chi = 1e-300 is below 0.001") == said, (method, err)


# -- 4. maps without free space, observations off it ---------------------------------------------


def _without_truth(room):
    for name in ("truth.npy", "categories.json"):
        (room / name).unlink()


def test_a_map_without_free_cells_stops_before_sampling(room, tmp_path, capsys):
    house = load_house(room)
    walls = np.full(house.grid.shape, OCCUPIED, dtype=np.int8)
    no_free = dataclasses.replace(house, grid=house.grid.with_occupancy(walls), truth=None,
                                  category_names=None)  # fmt: skip
    with pytest.raises(ValueError, match="has no free cell"):
        prepare_model_data(no_free, preset())
    _without_truth(room)
    yaml = room.parent / "map" / f"{room.name}.yaml"
    yaml.write_text(yaml.read_text().replace("free_thresh: 0.196", "free_thresh: 0.0"))
    err = _fit_fails([str(room)], tmp_path / "out", capsys)
    assert "has no free cell" in err and str(yaml) in err


def _negate(text: str) -> str:
    assert "negate: 0" in text
    return text.replace("negate: 0", "negate: 1")  # free space becomes walls and vice versa


def _shift_origin(text: str) -> str:
    shifted = re.sub(r"origin: \[([-+0-9.e]+)", lambda m: f"origin: [{float(m[1]) - 100}", text)
    assert shifted != text
    return shifted  # the map 100 m away from the observations


@pytest.mark.parametrize("change", [_negate, _shift_origin])
def test_no_observation_on_free_space_stops_before_sampling(room, tmp_path, capsys, change):
    _without_truth(room)
    yaml = room.parent / "map" / f"{room.name}.yaml"
    yaml.write_text(change(yaml.read_text()))
    err = _fit_fails([str(room)], tmp_path / "out", capsys)
    obs = load_house(room).observations
    total = obs.num_images + obs.num_utterances
    assert f"error: no observation lands on free space: {total} of {total} observations" in err
    if change is _negate:  # the other negate places them: its yaml line blamed, as the cause
        line = next(i for i, t in enumerate(yaml.read_text().splitlines(), 1) if "negate" in t)
        assert f"{yaml}:{line}: negate 1 on a map whose free space is drawn white" in err
    else:
        assert "negate" in err and "origin" in err


@pytest.mark.parametrize(
    ("scale", "said"),
    [(1000.0, "divided by 1000 land on free space: are they in millimetres?"),
     (100.0, "divided by 100 land on free space: are they in centimetres?"),
     (1.0, None)],
)  # fmt: skip
def test_positions_in_millimetres_are_named_as_such(scale, said):
    """A robot's own files in millimetres ended in 'no observation lands on free space ... the
    map or its origin is wrong', blaming the map. (The house is centred on its origin, so
    millimetres divided by 100 land on free space too, squeezed into its middle.)"""
    house = make_house(seed=0)  # 6 x 8 m, centred on its origin
    obs = house.observations
    moved = dataclasses.replace(obs, image_xy=obs.image_xy * scale, word_xy=obs.word_xy * scale)
    placed = cell_counts(house.grid, moved)
    if said is None:  # where they are: no hint
        assert placed.placement.hint == ""
        return
    with pytest.raises(ValueError, match="no observation lands on free space") as error:
        placed.placement.check_on_free()
    assert said in str(error.value)


def _observations(cells, grid):
    """One image and one utterance at each (row, col) of ``cells``."""
    xy = grid.cell_to_world(np.array(cells))  # [T, 2]
    n = len(cells)
    return Observations(
        image_features=np.full((n, 2), 0.5), image_xy=xy, image_trial=np.zeros(n, dtype=int),
        utterances=[("kitchen",)] * n, word_xy=xy, word_trial=np.zeros(n, dtype=int),
    )  # fmt: skip


def test_most_observations_off_free_space_are_warned_about(caplog):
    occupancy = np.array([[FREE, FREE, FREE, OCCUPIED, UNKNOWN, UNKNOWN]], dtype=np.int8)
    grid = OccupancyGrid(occupancy, 1.0, (0.0, 0.0, 0.0))
    for cells, warned in (
        ([(0, 0), (0, 1), (0, 3), (0, 4)], False),  # half off free space: 4 of 8
        ([(0, 0), (0, 3), (0, 4), (0, 5)], True),  # 6 of 8: 2 snapped, 4 unplaced
    ):
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="spcopyro"):
            counts = cell_counts(grid, _observations(cells, grid), snap_distance=1.0)
        messages = [r.getMessage() for r in caplog.records if "wrong map" in r.getMessage()]
        assert len(messages) == warned
        counts.placement.check_on_free()  # some are on free space: no error
    assert messages[0].startswith("6 of 8 observations are not on a free cell")
    assert "2 snapped to free space within 1 m, 4 left out" in messages[0]
    report = cell_counts(grid, _observations([(0, 3), (0, 4)], grid), snap_distance=1.0).placement
    assert (report.num_on_free, report.num_snapped, report.num_observations) == (0, 2, 4)
    assert report.num_placed == 2  # on free cells, snapped ones included
    with pytest.raises(ValueError, match="no observation lands on free space: 4 of 4"):
        report.check_on_free()
