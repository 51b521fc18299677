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
        "footprint 0.75 m (uniform), reach share 0.2 (Voronoi cells within rooms at 1 m doors)"
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


def test_the_data_line_gives_the_cells_the_model_uses_beside_those_asked():
    """The model's cells are a whole number of the map's: 0.25 m asked on a 0.1 m map is fitted
    on 0.3 m cells (the "map" line's), and the data line said ``cells 0.25 m``."""
    import dataclasses

    import numpy as np

    from spcopyro.maps.coarse import coarsen_grid
    from spcopyro.maps.grid import FREE, OCCUPIED, OccupancyGrid

    data = preset().data  # cell_size 0.25
    free = np.full((60, 80), FREE, dtype=np.int8)
    map_grid = OccupancyGrid(free, 0.1, (0.0, 0.0, 0.0))
    line = data_line(data, coarsen_grid(map_grid, 3))
    assert line.startswith(
        "data             cells 0.3 m (0.25 m asked: a whole number of the map's 0.1 m cells), "
        "feature scaling probability"
    )
    # as asked: the size alone
    on_quarters = OccupancyGrid(free, 0.05, (0.0, 0.0, 0.0))
    assert data_line(data, coarsen_grid(on_quarters, 5)) == data_line(data)
    assert data_line(data, coarsen_grid(on_quarters, 5)).startswith(
        "data             cells 0.25 m, "
    )
    # rounded to the map's own cells
    finer = dataclasses.replace(data, cell_size=0.12)
    assert data_line(finer, map_grid).startswith(
        "data             the map's own 0.1 m cells (0.12 m asked: a whole number of the map's "
        "0.1 m cells), "
    )
    # coarser cells leave no free cell: the fit falls back to the map's own (model_house)
    thin = np.full((60, 80), OCCUPIED, dtype=np.int8)
    thin[30, :] = FREE
    thin_grid = OccupancyGrid(thin, 0.1, (0.0, 0.0, 0.0))
    assert data_line(data, thin_grid).startswith(
        "data             the map's own 0.1 m cells (0.25 m asked leaves no free cell of the "
        "map's 0.1 m cells), "
    )
    # the map's own cells asked (None): unchanged
    own = dataclasses.replace(data, cell_size=None)
    assert data_line(own, map_grid).startswith("data             the map's own cells, ")


def test_the_stopped_line_and_trace_png_tell_an_estimated_objective_by_one_rule(monkeypatch):
    """Whether a method's objective is an estimate (SVI's: "ELBO estimate") was decided twice,
    by ``method == "svi"`` in the "stopped" line and again in trace.png's axis: one rule now
    (:func:`spcopyro.inference.names.objective_draws`), so both follow a change to it."""
    import dataclasses

    import numpy as np
    from hand_results import two_rooms

    from spcopyro.cli.fit_summary import stopped_line
    from spcopyro.figures.trace import trace_figure
    from spcopyro.inference import names
    from spcopyro.inference.protocol import Trace

    trace = Trace(np.linspace(-50.0, -10.0, 20), np.full(20, 2), np.arange(1.0, 21.0), "ELBO")
    svi = dataclasses.replace(two_rooms(), method="svi", trace=trace, best_iteration=19,
                              inference={"num_particles": 2, "stopped": "converged"})  # fmt: skip
    cavi = dataclasses.replace(svi, method="cavi", inference={"stopped": "converged"})
    assert "final ELBO estimate -10.0 nats" in stopped_line(svi)
    assert "final ELBO -10.0 nats" in stopped_line(cavi)
    assert trace_figure(svi).axes[0].get_ylabel().endswith("(2 draws a step)")
    monkeypatch.setattr(names, "ESTIMATED_OBJECTIVES", ("cavi",))  # the rule changed: both follow
    assert "final ELBO estimate -10.0 nats" in stopped_line(cavi)
    assert "final ELBO -10.0 nats" in stopped_line(svi)
    label = trace_figure(cavi).axes[0].get_ylabel()
    assert label.startswith("ELBO estimate (nats)") and label.endswith("(1 draw a step)"), label
    assert trace_figure(svi).axes[0].get_ylabel().startswith("ELBO (nats)")
