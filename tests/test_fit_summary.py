"""fit's "model", "data" and "inference" lines (:mod:`spcopyro.cli.fit_summary`): the preset and
the values that matter as ``name value``; they printed the dataclasses' reprs, e.g.
``GibbsOptions(backend='auto', ..., hyper=HyperparameterOptions(alpha=False, ...))``."""

from spcopyro.cli.fit_summary import data_line, inference_line, model_line
from spcopyro.config import preset
from spcopyro.gibbs.options import GibbsOptions


def test_the_default_preset_reads_as_names_and_values():
    settings = preset()
    assert model_line(settings.model, "coarse") == (
        "model            preset coarse: 120 concepts (dp, alpha 1e7), gamma 3 (4-neighbour), "
        "beta 0.1, chi 1"
    )
    assert data_line(settings.data) == (
        "data             cells 0.25 m, feature scaling probability, word scaling 10, "
        "footprint 1 m (uniform)"
    )
    options = GibbsOptions(merge_moves=0.2, region_moves=0.2)
    assert inference_line("gibbs", options, False, "5000 sweeps", "OUT") == (
        "inference        gibbs: 5000 sweeps, merge moves 0.2, region moves 0.2 "
        "(every setting: OUT/config.json)"
    )


def test_what_is_off_is_left_out_and_what_is_set_is_shown():
    settings = preset(
        "paper-dirichlet", num_concepts=7, connectivity=8, word_weighting="tfidf",
        footprint_radius=0.5, footprint_fov=90.0, snap_distance=0.5, use_images=False,
        concentrations={"objects": 2.0},
    )  # fmt: skip
    line = model_line(settings.model, "paper-dirichlet")
    assert line == (
        "model            preset paper-dirichlet: 7 concepts (finite Dirichlet, alpha 5e7), "
        "gamma 3 (8-neighbour), beta 100, chi 10000, objects 2, no images"
    )
    assert data_line(settings.data) == (
        "data             the map's own cells, feature scaling probability, word weighting "
        "tfidf, footprint 0.5 m (uniform, images 90 deg wide), snap distance 0.5 m"
    )
    # nothing sampled: the hyper options are left out; something sampled: shown, with tuning
    assert "hyper" not in inference_line("gibbs", GibbsOptions(), False, "9 sweeps", "O")
    sampled = GibbsOptions(hyper={"alpha": True, "gamma": "exchange", "log_alpha_sd": 2.0})
    assert inference_line("gibbs", sampled, False, "9 sweeps", "O") == (
        "inference        gibbs: 9 sweeps, sampled hyperparameters (alpha, gamma exchange, "
        "log alpha sd 2) (every setting: O/config.json)"
    )


def test_a_house_without_images_reads_words_only():
    line = model_line(preset().model, "coarse", images_missing=True)
    assert line.endswith(", chi 1, words only (no images here: use_images=True, as config.json "
                         "records it, has none to use)")  # fmt: skip
