"""A house of images only (a robot that has heard nothing yet) is fitted from its images and the
Potts prior: the words modality carries V = 0 items, each concept's w is the one point of the
empty simplex. Was: cell_counts refused "the observations hold no words", its way out
(vocabulary=()) then refused by check_model_data, and load_house refused a folder without
St.csv."""

from __future__ import annotations

import dataclasses
import math
import shutil

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem, without_words
from statistical_checks import assert_conditionals_match_model

from spcopyro.config import preset
from spcopyro.data import load_house, save_house
from spcopyro.fit.house import fit_house
from spcopyro.gibbs.hyper_options import HyperparameterOptions
from spcopyro.gibbs.hyper_targets import dirichlet_multinomial_log_marginal
from spcopyro.gibbs.hyperparameters import update_hyperparameters
from spcopyro.gibbs.sampler import init
from spcopyro.model import DTYPE
from spcopyro.results.result import SpCoResult
from spcopyro.results.semantic_map import UnknownWordError, word_index
from spcopyro.synthetic import make_house


def _without_words(house):
    obs = dataclasses.replace(
        house.observations,
        utterances=(),
        word_xy=np.zeros((0, 2)),
        word_trial=np.zeros(0, dtype=np.int64),
    )
    return dataclasses.replace(house, observations=obs)


@pytest.mark.parametrize("use_words", [False, True])
def test_conditionals_match_model_without_words(use_words):
    cfg = config(use_words=use_words)
    _, data = random_problem(seed=3, connectivity=cfg.connectivity)
    data = without_words(data)
    state = init(data, cfg, torch.Generator().manual_seed(1))
    cells = torch.cat([data.obs_cells, torch.tensor([0, data.num_free - 1])]).unique()
    assert_conditionals_match_model(state, data, cfg, cells)


def test_concentration_sampling_on_a_house_of_images_only_moves_chi_and_beta():
    """beta's Dirichlet-multinomial term over V = 0 words is 0, not nan, so its target is its
    prior alone and its moves are accepted (was: nan, none ever accepted)."""
    cfg = config()
    _, data = random_problem(seed=3, connectivity=cfg.connectivity)
    data = without_words(data)
    assert dirichlet_multinomial_log_marginal(torch.zeros(3, 0, dtype=DTYPE), 0.1) == 0.0
    generator = torch.Generator().manual_seed(2)
    state = init(data, cfg, generator)
    hyper = HyperparameterOptions(concentrations=True, concentration_moves=20)
    _, new_config, moves = update_hyperparameters(state, data, cfg, generator, hyper)
    assert moves.accepted["chi"] > 0 and moves.accepted["beta"] > 0
    assert new_config.beta != cfg.beta and math.isfinite(new_config.beta)


@pytest.mark.parametrize("method", ["gibbs", "cavi", "lbp", "svi"])
def test_a_house_of_images_only_is_fitted(method, tmp_path):
    house = _without_words(make_house(seed=0))
    objectives = []
    for use_words in (False, True):  # no words: the same fit either way
        settings = preset("original-code", cell_size=None, use_words=use_words, num_concepts=4)
        result = fit_house(house, settings, method=method, sweeps=5, progress=False)
        assert math.isfinite(result.trace.objective[-1])
        assert result.vocabulary == ()
        objectives.append(result.trace.objective[-1])
    assert objectives[0] == objectives[1]
    if method == "gibbs":
        loaded = SpCoResult.load(result.save(tmp_path / "fit"))
        assert loaded.vocabulary == ()
        np.testing.assert_array_equal(loaded.labels, result.labels)


def test_where_says_no_words_were_heard():
    with pytest.raises(UnknownWordError, match="the fit heard no words"):
        word_index((), "kitchen")


def test_a_house_folder_without_word_files_loads(tmp_path, caplog):
    room = save_house(make_house(seed=0), tmp_path)
    for path in [*room.glob("St*.csv"), *room.glob("word_*.csv")]:
        path.unlink()
    house = load_house(room)
    assert house.observations.num_utterances == 0
    assert house.observations.num_images > 0
    assert "fitted on its images alone" in caplog.text


def test_a_house_of_images_only_round_trips_through_save_house(tmp_path, caplog):
    """save_house writes no St.csv, StXtx.csv, StXty.csv or word_K.csv for a house without
    utterances (as it writes no Ft.csv or pose_K.csv for one without images), also over a saved
    house with words. Was: ValueError 'no utterances (St.csv would be empty)'."""
    house = make_house(seed=0)
    save_house(house, tmp_path)
    room = save_house(_without_words(house), tmp_path, overwrite=True)
    assert not [*room.glob("St*.csv"), *room.glob("word_*.csv")]
    assert (room / "Ft.csv").is_file() and [*room.glob("pose_*.csv")]
    loaded = load_house(room).observations
    assert "fitted on its images alone" in caplog.text
    saved = house.observations
    assert loaded.utterances == () and loaded.word_xy.shape == (0, 2)
    assert loaded.word_trial.shape == (0,)
    np.testing.assert_array_equal(loaded.image_features, saved.image_features)
    np.testing.assert_array_equal(loaded.image_xy, saved.image_xy)
    np.testing.assert_array_equal(loaded.image_trial, saved.image_trial)


def test_an_empty_st_csv_names_the_way_out(tmp_path):
    room = save_house(make_house(seed=0), tmp_path)
    (room / "St.csv").write_text("")
    with pytest.raises(ValueError, match="leaves out St.csv"):
        load_house(room)
    shutil.rmtree(room)


@pytest.mark.parametrize("method", ["gibbs", "cavi"])
def test_a_fit_of_images_only_is_updated_with_words(method):
    """An update of a fit that heard no words onto observations with words: every word is new
    and takes all of w's mass. Was (Gibbs): extend_emission drew S_l ~ Beta(beta * 0 + 0, .),
    'gamma concentration must be finite and positive'."""
    from spcopyro.robot.online import fit_update

    house = make_house(seed=0)
    settings = preset("original-code", cell_size=None, num_concepts=4)
    saved = fit_house(_without_words(house), settings, sweeps=3, progress=False)
    assert saved.vocabulary == ()
    (result,) = fit_update(saved, house, settings, method=method, sweeps=3, progress=False)
    assert result.vocabulary == house.observations.vocabulary
    assert math.isfinite(result.trace.objective[-1])
    np.testing.assert_allclose(result.w.sum(axis=1), 1.0)


def test_new_words_of_a_fit_without_words_take_all_the_mass():
    from spcopyro.robot.online import extend_emission

    empty = np.zeros((3, 0))  # [L=3, V=0]
    mean = extend_emission(empty, np.zeros(3), 0.5, 4)  # [3, 4]
    np.testing.assert_array_equal(mean, np.full((3, 4), 0.25))
    drawn = extend_emission(empty, np.zeros(3), 0.5, 4, torch.Generator().manual_seed(0))
    assert np.isfinite(drawn).all()
    np.testing.assert_allclose(drawn.sum(axis=1), 1.0)
