"""Per-cell uncertainty and "where" probabilities for every method, warm starts both ways
(a Gibbs fit starting CAVI, a CAVI fit starting Gibbs) and the VI-then-Gibbs method."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from spcopyro.cli.main import main
from spcopyro.config import preset
from spcopyro.fit.house import fit_house, prepare_model_data
from spcopyro.fit.registry import get_method
from spcopyro.gibbs import GibbsOptions
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.vi_gibbs import VIGibbsOptions
from spcopyro.metrics import adjusted_rand_index
from spcopyro.results.uncertainty import (
    align_samples,
    cell_entropy,
    cell_probabilities,
    free_cells_image,
    label_frequencies,
    where_probability,
)
from spcopyro.synthetic import HouseSpec, make_house

SETTINGS = preset("original-code", gamma=3.0, num_concepts=8)


@pytest.fixture(scope="module")
def house():
    return make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=3))


@pytest.fixture(scope="module")
def gibbs_fit(house):
    return fit_house(house, SETTINGS, sweeps=60, progress=False, marginal_samples=10)


def test_label_frequencies_count_each_cells_labels():
    samples = np.array([[0, 1, 2], [0, 1, 1], [0, 2, 1], [0, 1, 1]])  # [S=4, N=3]
    frequencies = label_frequencies(samples, 3)
    np.testing.assert_allclose(
        frequencies, [[1, 0, 0], [0, 0.75, 0.25], [0, 0.75, 0.25]], rtol=0, atol=1e-7
    )
    with pytest.raises(ValueError, match=r"\[S >= 1, N\]"):
        label_frequencies(np.zeros((0, 3), dtype=int), 3)
    with pytest.raises(ValueError, match=r"labels must lie in \[0, 3\), got -1\.\.1"):
        label_frequencies(samples - 1, 3)  # a bincount would count -1 in the previous cell
    with pytest.raises(ValueError, match=r"labels must lie in \[0, 2\)"):
        align_samples(samples, samples[0], 2)


def test_counting_and_renaming_equal_their_loops_on_random_samples():
    """The vectorised counts (one bincount of cell * L + label; a sample's contingency table
    as one bincount) give what a loop over samples and cells gives, to the bit."""
    from scipy.optimize import linear_sum_assignment

    rng = np.random.default_rng(7)
    S, N, L = 6, 200, 9
    reference = rng.integers(0, 4, N) * 2  # [N] ids 0, 2, 4, 6
    samples = np.where(rng.random((S, N)) < 0.7, reference, rng.integers(0, L, (S, N)))
    counts = np.zeros((N, L), dtype=np.float32)
    for labels in samples:
        counts[np.arange(N), labels] += 1.0
    np.testing.assert_array_equal(label_frequencies(samples, L), counts / S)
    ref_ids = np.unique(reference)
    free_ids = np.setdiff1d(np.arange(L), ref_ids)
    aligned = align_samples(samples, reference, L)
    for labels, renamed in zip(samples, aligned, strict=True):
        ids = np.unique(labels)
        overlap = np.array([[np.sum((labels == a) & (reference == b)) for b in ref_ids]
                            for a in ids])  # fmt: skip
        rows, cols = linear_sum_assignment(overlap, maximize=True)
        rename = dict(zip(ids[rows], ref_ids[cols], strict=True))
        spare = iter(free_ids)
        rename.update({a: next(spare) for a in ids if a not in rename})
        np.testing.assert_array_equal(renamed, [rename[a] for a in labels])


def test_samples_are_renamed_to_the_reported_maps_concepts():
    """Issue 22 item 1: a kept sample whose regions carry other names (a merge move renamed
    them after the best state) counted as they are puts the reported region's probability on
    another concept. Renamed one-to-one by overlap, it speaks of the reported concepts."""
    reference = np.array([0, 0, 0, 1, 1, 2, 2, 2])  # the reported map
    renamed = np.array([5, 5, 5, 0, 0, 1, 1, 1])  # the same regions, other names
    drifted = np.array([5, 5, 0, 0, 0, 1, 1, 3])  # one cell moved, one new speck
    samples = np.stack([renamed, drifted])  # [S=2, N=8]
    mixed = label_frequencies(samples, 6)
    assert mixed[np.arange(8), reference].min() == 0.0  # counted as they are: wrong names
    aligned = align_samples(samples, reference, 6)
    np.testing.assert_array_equal(aligned[0], reference)
    np.testing.assert_array_equal(aligned[1][[0, 1, 3, 4, 5, 6]], reference[[0, 1, 3, 4, 5, 6]])
    assert aligned[1][7] not in (0, 1, 2)  # the speck keeps a name of its own
    frequencies = label_frequencies(aligned, 6)
    assert (frequencies.argmax(1) == reference).all()


def test_the_defaults_marginals_and_where_probability_follow_the_reported_map():
    """A default fit (split-merge moves, the VI point estimate): every cell's most frequent
    concept over the kept samples is mostly its reported concept, and the 'where' probability
    is high inside the answer's own region."""
    from spcopyro.results.uncertainty import where_probability

    house = make_house(seed=0, spec=HouseSpec())
    result = fit_house(house, preset(), sweeps=300, init="rooms", progress=False,
                       marginal_samples=30, point_estimate="vi",
                       options=GibbsOptions(merge_moves=0.5))  # fmt: skip
    assert (result.marginals.argmax(1) == result.labels).mean() > 0.95
    word = "kitchen"
    answer = result.where(word)
    probability = where_probability(result, word)  # [N]
    inside = answer.region[result.grid.free]  # [N] bool
    assert probability[inside].mean() > 0.7


def test_gibbs_marginals_are_the_second_half_label_frequencies(gibbs_fit, house):
    marginals = gibbs_fit.marginals
    assert marginals.shape == (house.grid.num_free, 8)
    np.testing.assert_allclose(marginals.sum(1), 1.0, rtol=1e-6)
    # 60 sweeps, thin = 60 // 20 = 3: samples at sweeps 2, 5, ..., 59; the second half (>= 30)
    # holds 10 of them, so every frequency is a multiple of 1/10.
    assert gibbs_fit.inference["marginal_samples"] == 10
    np.testing.assert_allclose(marginals * 10, np.round(marginals * 10), atol=1e-5)
    # The MAP-visited labels come from the same chain: mostly the cells' most frequent labels.
    assert (marginals.argmax(1) == gibbs_fit.labels).mean() > 0.8


def test_entropy_and_where_probability_follow_their_formulas(gibbs_fit):
    p = gibbs_fit.marginals.astype(np.float64)
    entropy = cell_entropy(gibbs_fit)
    expected = -np.where(p > 0, p * np.log(np.where(p > 0, p, 1)), 0).sum(1)
    np.testing.assert_allclose(entropy, expected, rtol=1e-6)
    assert (entropy >= 0).all() and (entropy <= np.log(8) + 1e-9).all()
    word = gibbs_fit.vocabulary[0]
    probability = where_probability(gibbs_fit, word)
    np.testing.assert_allclose(probability, p @ gibbs_fit.concept_given_word(word), rtol=1e-6)
    assert (probability >= 0).all() and (probability <= 1 + 1e-9).all()
    image = free_cells_image(gibbs_fit, entropy)
    assert np.isnan(image[~gibbs_fit.grid.free]).all()
    np.testing.assert_allclose(image[gibbs_fit.grid.free], entropy)


def test_a_point_estimate_has_no_uncertainty_and_a_constant_probability_per_concept(house):
    point = fit_house(house, SETTINGS, sweeps=5, progress=False)
    assert point.marginals is None and cell_entropy(point) is None
    word = point.vocabulary[0]
    np.testing.assert_allclose(
        where_probability(point, word), point.concept_given_word(word)[point.labels]
    )
    assert (cell_probabilities(point).sum(1) == 1).all()


def test_gibbs_state_starts_cavi_and_cavi_starts_gibbs(house, gibbs_fit):
    cavi = fit_house(house, SETTINGS, method="cavi", sweeps=1, init=gibbs_fit,
                     progress=False)  # fmt: skip
    assert cavi.inference["init"] == "result of gibbs"
    # One CAVI iteration from a one-hot start at the Gibbs labels stays close to them; a random
    # start does not.
    random_start = fit_house(house, SETTINGS, method="cavi", sweeps=1, progress=False)
    agree = adjusted_rand_index(cavi.label_image(), gibbs_fit.label_image())
    assert agree > 0.9 > adjusted_rand_index(random_start.label_image(), gibbs_fit.label_image())

    gibbs = fit_house(house, SETTINGS, sweeps=1, init=cavi, progress=False)
    assert gibbs.inference["init"] == "result of cavi"
    assert adjusted_rand_index(gibbs.label_image(), cavi.label_image()) > 0.8


def test_a_warm_start_from_another_map_or_more_concepts_is_refused(house, gibbs_fit):
    other = make_house(seed=2, spec=HouseSpec(height=40, width=60, num_rooms=3, num_trials=2))
    with pytest.raises(ValueError, match="map"):
        fit_house(other, SETTINGS, method="cavi", sweeps=1, init=gibbs_fit, progress=False)
    fewer = preset("original-code", gamma=3.0, num_concepts=2)
    assert gibbs_fit.labels.max() >= 2
    with pytest.raises(ValueError, match="num_concepts = 2"):
        fit_house(house, fewer, method="cavi", sweeps=1, init=gibbs_fit, progress=False)


def test_a_warm_start_on_other_free_cells_of_as_many_is_refused(house, gibbs_fit):
    """Labels are indexed by free cell: a fit on a map with as many free cells, one of them
    moved, was made on another map (only the count was compared, and its labels landed on the
    wrong cells)."""
    import dataclasses

    from spcopyro.fit.starts import result_labels
    from spcopyro.maps import FREE, OCCUPIED

    occupancy = np.array(house.grid.occupancy)  # [H, W]
    free_cell = tuple(np.argwhere(occupancy == FREE)[0])
    wall_cell = tuple(np.argwhere(occupancy == OCCUPIED)[0])
    occupancy[free_cell], occupancy[wall_cell] = OCCUPIED, FREE
    moved = dataclasses.replace(gibbs_fit, grid=house.grid.with_occupancy(occupancy))
    assert moved.grid.num_free == house.grid.num_free
    with pytest.raises(ValueError, match=r"\(2 cells differ in being free\)"):
        result_labels(moved, house, SETTINGS.model)
    assert result_labels(gibbs_fit, house, SETTINGS.model).shape == (house.grid.num_free,)


def test_a_refused_warm_start_names_both_maps_as_python_writes_them(house, gibbs_fit):
    """The two maps' origins, a hundredth of a cell apart at x = 500000.0005 m, read apart
    (``:g`` wrote both as 500000), and the sentence reads 'a (40, 50) map with ...'."""
    import dataclasses
    import re

    from spcopyro.fit.starts import result_labels
    from spcopyro.maps import OccupancyGrid

    grid = house.grid
    far = OccupancyGrid(grid.occupancy, grid.resolution, (500000.0005, 0.0, 0.0))
    off = (500000.0005 + grid.resolution / 100, 0.0, 0.0)
    other = dataclasses.replace(house, grid=OccupancyGrid(grid.occupancy, grid.resolution, off))
    with pytest.raises(ValueError) as refused:
        result_labels(dataclasses.replace(gibbs_fit, grid=far), other, SETTINGS.model)
    cells = f"a {grid.shape} map with {grid.num_free} free cells of {grid.resolution!r} m"
    assert str(refused.value) == (
        f"the starting result was fitted on {cells}, origin (500000.0005, 0.0, 0.0); this "
        f"house's map is {cells}, origin ({off[0]!r}, 0.0, 0.0)"
    )
    assert re.search(r"a \(40, 50\) map with \d+ free cells of 0\.\d+ m", str(refused.value))


def test_vi_then_gibbs_starts_the_sampler_where_cavi_ended(house):
    counts, data = prepare_model_data(house, SETTINGS)
    options = VIGibbsOptions(vi_iterations=30, variational=VariationalOptions(anneal_iterations=10))
    output = get_method("vi-gibbs").run(
        data, SETTINGS.model, iterations=10, generator=torch.Generator().manual_seed(0),
        options=options, progress=False,
    )  # fmt: skip
    assert output.trace.objective_name == "log joint" and len(output.trace.objective) == 10
    labels = np.full(house.grid.shape, -1)
    labels[house.grid.free] = output.labels
    assert adjusted_rand_index(labels, house.truth) > 0.8
    assert output.trace.seconds[0] > output.options["vi_seconds"] > 0
    assert np.isfinite(output.options["vi_elbo"])
    with pytest.raises(ValueError, match="vi_iterations"):
        VIGibbsOptions(vi_iterations=0)
    with pytest.raises(TypeError, match="VIGibbsOptions"):
        get_method("vi-gibbs").run(
            data, SETTINGS.model, iterations=1, generator=torch.Generator(),
            options=VariationalOptions(),
        )  # fmt: skip


def test_vi_then_gibbs_honours_its_cavi_options(house):
    """Issue 23: vi-gibbs accepted VariationalOptions.init and ignored it (its CAVI always
    started one-hot). Each CAVI option now reaches the CAVI run and the record says what ran:
    the start (``init``), the stopping rule (``tolerance``) and the schedule."""
    _, data = prepare_model_data(house, SETTINGS)

    def run(**variational):
        options = VIGibbsOptions(vi_iterations=40, variational=VariationalOptions(**variational))
        return get_method("vi-gibbs").run(
            data, SETTINGS.model, iterations=2, generator=torch.Generator().manual_seed(0),
            options=options, progress=False,
        ).options  # fmt: skip

    one_hot, soft = run(init="one-hot", tolerance=0.0), run(init="soft", tolerance=0.0)
    assert soft["variational"]["init"] == "soft" and one_hot["vi_elbo"] != soft["vi_elbo"]
    assert one_hot["vi_iterations_run"] == 40 and "ran the 40 iterations" in one_hot["vi_stopped"]
    stopped = run(tolerance=1e-3)
    assert stopped["vi_iterations_run"] < 40 and "converged after" in stopped["vi_stopped"]
    annealed = run(anneal_iterations=20, tolerance=0.0)
    assert annealed["vi_elbo"] != one_hot["vi_elbo"]


def test_fit_writes_the_uncertainty_map_and_where_its_probability_map(tmp_path, capsys):
    common = ["--preset", "original-code", "--gamma", "3", "--concepts", "8"]
    gibbs, cavi = tmp_path / "gibbs", tmp_path / "cavi"
    assert main(["fit", "--out", str(gibbs), "--sweeps", "20", *common]) == 0
    assert (gibbs / "uncertainty.png").is_file()
    entropy = np.load(gibbs / "uncertainty.npy")
    assert np.isfinite(entropy).sum() == np.load(gibbs / "labels.npy").__ge__(0).sum()
    assert main(["fit", "--out", str(cavi), "--method", "cavi", "--sweeps", "5",
                 "--init-from", str(gibbs), *common]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    assert f"starting from    the gibbs fit in {gibbs}\n" in printed and "5 iterations" in printed
    # svi smooths its start toward uniform (label_smoothing): how much of the fit it keeps,
    # 95% unless set (0.9 for every start before 2026-12-05 kept 10%); and it does not anneal
    # a given start unless anneal_iterations is set (100 for every start lost it at L = 120)
    svi = ["fit", "--method", "svi", "--sweeps", "2", "--init-from", str(gibbs), *common]
    assert main([*svi, "--out", str(tmp_path / "svi"), "--no-figures"]) == 0
    printed = capsys.readouterr().out
    assert (
        f"gibbs fit in {gibbs} (95% of its labels in q's start: label_smoothing 0.05, the "
        "default for given labels)\n" in printed
    ), printed
    # the inference line names what the unset options are here (it printed None)
    assert "anneal iterations 0 (given start)" in printed, printed
    assert "label smoothing 0.05 (given start)" in printed, printed
    svi_options = json.loads((tmp_path / "svi" / "config.json").read_text())["inference"]
    assert svi_options["label_smoothing"] == 0.05, svi_options  # what the start ran with
    assert svi_options["anneal_iterations"] == 0, svi_options
    smoothing = ["--method-option", "label_smoothing=0.9", "--method-option",
                 "anneal_iterations=2", "--no-figures"]  # fmt: skip
    assert main([*svi, "--out", str(tmp_path / "svi10"), *smoothing]) == 0
    said = "(10% of its labels in q's start: label_smoothing 0.9, as set; left unset, 0.05 keeps"
    printed = capsys.readouterr().out
    assert said in printed, printed
    assert "gamma annealed from 0 over 2 steps, as set, can still lose them" in printed, printed
    ran = json.loads((tmp_path / "svi10" / "config.json").read_text())["inference"]
    assert ran["anneal_iterations"] == 2 and ran["label_smoothing"] == 0.9, ran  # as set
    # an update by svi starts from the saved labels smoothed the same way
    update = ["fit", "--method", "svi", "--sweeps", "2", "--update", str(gibbs), *common]
    assert main([*update, "--out", str(tmp_path / "svi_update"), "--no-figures"]) == 0
    assert (
        "with all of this data (95% of its labels in q's start: label_smoothing 0.05,"
        in capsys.readouterr().out
    )
    updated = json.loads((tmp_path / "svi_update" / "config.json").read_text())["inference"]
    assert updated["anneal_iterations"] == 0, updated  # saved labels: not annealed
    assert json.loads((cavi / "config.json").read_text())["inference"]["init"] == "result of gibbs"
    assert (cavi / "uncertainty.png").is_file()

    missing = tmp_path / "missing"
    assert main(["fit", "--out", str(tmp_path / "x"), "--init-from", str(missing), *common]) == 2
    assert f"{missing}/result.npz: no fitted result here" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()

    none = tmp_path / "none"
    assert main(["fit", "--out", str(none), "--sweeps", "4", "--marginal-samples", "0",
                 *common]) == 0  # fmt: skip
    assert not (none / "uncertainty.png").exists()

    word = json.loads((cavi / "concepts.json").read_text())[0]["top_words"][0][0]
    assert main(["where", str(cavi), word, "--out", str(tmp_path / "w.png")]) == 0
    assert (tmp_path / "w_probability.png").is_file()
    assert "probability of being the place exceeds 0.5" in capsys.readouterr().out
    assert main(["where", str(cavi), word, "--out", str(tmp_path / "w.jpg")]) == 0
    assert (tmp_path / "w_probability.jpg").read_bytes()[:2] == b"\xff\xd8"  # a JPEG, as asked


def test_vi_then_gibbs_fits_carry_label_frequencies_too(house):
    options = VIGibbsOptions(vi_iterations=10, variational=VariationalOptions(anneal_iterations=5))
    fit = fit_house(house, SETTINGS, method="vi-gibbs", sweeps=40, options=options,
                    progress=False, marginal_samples=10)  # fmt: skip
    assert fit.inference["marginal_samples"] == 10
    np.testing.assert_allclose(fit.marginals.sum(1), 1.0, rtol=1e-6)
    assert cell_entropy(fit) is not None
    plain = fit_house(house, SETTINGS, method="vi-gibbs", sweeps=4, options=options,
                      progress=False)  # fmt: skip
    assert plain.marginals is None


def test_the_uncertainty_figure_draws_the_entropy_fit_saved(gibbs_fit, tmp_path, monkeypatch):
    """spcopyro fit computes cell_entropy for uncertainty.npy, then plot_uncertainty drew the
    same map from its own second computation; now the entropy is computed once per result
    (kept read-only, each caller given a copy) and the figure draws those values."""
    import dataclasses

    from spcopyro.figures import plotting
    from spcopyro.results.result import SpCoResult

    computed = []
    once = SpCoResult.computed_once

    def counted(self, key, compute):
        return once(self, key, lambda: computed.append(key) or compute())

    monkeypatch.setattr(SpCoResult, "computed_once", counted)
    result = dataclasses.replace(gibbs_fit)  # a new result: nothing computed on it yet
    saved = cell_entropy(result)  # [N] what fit writes to uncertainty.npy
    drawn = []
    monkeypatch.setattr(
        plotting, "_plot_cell_values", lambda result, values, path, **_: drawn.append(values)
    )
    plotting.plot_uncertainty(result, tmp_path / "uncertainty.png")
    assert len(drawn) == 1
    np.testing.assert_array_equal(drawn[0], saved)
    assert computed == ["cell_entropy"]  # once, for both


def test_cell_entropy_is_the_callers_to_change(gibbs_fit):
    """``h = cell_entropy(r); h[mask] = 0`` raised "assignment destination is read-only" (the
    array kept on the result); each call returns a writable copy, and changing it changes
    neither the kept array nor what the next caller gets."""
    import dataclasses

    result = dataclasses.replace(gibbs_fit)  # a new result: nothing computed on it yet
    first = cell_entropy(result)  # [N]
    expected = first.copy()
    assert first.flags.writeable
    first[first < np.median(first)] = 0.0  # a user's masking
    again = cell_entropy(result)
    assert again is not first and again.flags.writeable
    np.testing.assert_array_equal(again, expected)


def test_a_start_of_more_concepts_says_how_many_to_fit_or_how_to_renumber(house, gibbs_fit):
    """A start fitted with more concepts was refused with 'uses concept 7, beyond this fit's
    num_concepts = 4' alone: the refusal now says the setting to fit with, as a library caller
    and ``fit`` give it, and, when the start's concepts are few enough, how to renumber them."""
    import dataclasses

    from spcopyro.config import SpCoConfig
    from spcopyro.fit.starts import result_labels
    from spcopyro.inference.initialisation import check_labels

    labels = np.where(np.arange(house.grid.num_free) % 2 == 0, 1, 7)  # [N] concepts 1 and 7
    start = dataclasses.replace(gibbs_fit, labels=labels)
    with pytest.raises(ValueError) as refused:
        result_labels(start, house, dataclasses.replace(SETTINGS.model, num_concepts=4))
    assert str(refused.value) == (
        "the starting result uses concept 7, beyond this fit's num_concepts = 4 (concepts 0..3): "
        "fit with num_concepts=8 (fit's --concepts 8) or more, or renumber its 2 concepts to "
        "0..1 (spcopyro.results.renumber.renumbered(result, perm))"
    )
    with pytest.raises(ValueError) as refused:  # 2 concepts do not fit in 1: only more concepts
        result_labels(start, house, dataclasses.replace(SETTINGS.model, num_concepts=1))
    assert str(refused.value).endswith(": fit with num_concepts=8 (fit's --concepts 8) or more")
    config = SpCoConfig(num_concepts=4)
    with pytest.raises(ValueError) as refused:  # labels of one's own (run_gibbs, init_labels)
        check_labels(torch.as_tensor(labels), len(labels), config)
    assert str(refused.value) == (
        "initial labels must lie in [0, 4), got values in [1, 7]: fit with num_concepts=8 "
        "(fit's --concepts 8) or more, or renumber its 2 concepts to 0..1 "
        "(torch.unique(labels, return_inverse=True)[1])"
    )
    with pytest.raises(ValueError) as refused:  # a negative label: no concept count helps
        check_labels(torch.as_tensor(labels) - 2, len(labels), config)
    assert str(refused.value) == "initial labels must lie in [0, 4), got values in [-1, 5]"
