"""Word lists a person can read: posterior means of w (not one draw), the lift of a word for a
concept, "no words heard here", the new keys of concepts.json, and the words on the figures."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch
from hand_results import WORDS, two_rooms
from matplotlib.collections import PathCollection
from matplotlib.contour import ContourSet

from spcopyro.cli.concept_listing import print_concepts
from spcopyro.config import preset
from spcopyro.data import Observations
from spcopyro.figures.map_pieces import region_text, utterance_concepts
from spcopyro.figures.plotting import (
    ANSWER_RGB,
    FREE_RGB,
    RUNNER_UP_RGB,
    semantic_map_figure,
    where_figure,
    where_image,
)
from spcopyro.fit.house import fit_house, prepare_model_data
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.sweep import sample_globals
from spcopyro.results.concept_words import (
    NO_WORDS,
    distinctive_items,
    format_concept_words,
    heard_words,
    lift,
    shown_top_words,
    shown_words,
)
from spcopyro.results.posterior_means import concept_totals, posterior_means
from spcopyro.results.result import EmissionTable, SpCoResult
from spcopyro.synthetic import HouseSpec, make_house


@pytest.fixture(scope="module")
def small_house():
    return make_house(seed=3, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=1))


def _prepared(house, **overrides):
    settings = preset("original-code", num_concepts=5, **overrides)
    _, data = prepare_model_data(house, settings)
    return data, settings.model


def test_posterior_mean_equals_the_average_of_the_samplers_draws(small_house):
    """E[w_l | C, x] = (beta + n_lv) / (V beta + n_l) (and likewise theta, pi) against the mean
    of 800 conjugate draws of the sampler's global update (eqs. 14-17) with the labels fixed:
    every entry within 5 Monte Carlo standard errors."""
    data, config = _prepared(small_house, beta=0.5, chi=2.0)
    generator = torch.Generator().manual_seed(0)
    labels = torch.randint(0, 4, (data.num_free,), generator=generator)  # [N], concept 4 empty
    pi, (theta, w) = posterior_means(labels, data, config)
    draws = 800
    tables = [np.zeros_like(pi), np.zeros_like(theta), np.zeros_like(w)]
    squares = [np.zeros_like(t) for t in tables]
    for _ in range(draws):
        log_pi, (log_theta, log_w) = sample_globals(labels, data, config, generator)
        for k, value in enumerate((log_pi.exp(), log_theta.exp(), log_w.exp())):
            tables[k] += value.numpy()
            squares[k] += value.numpy() ** 2
    for mean, total, square in zip((pi, theta, w), tables, squares, strict=True):
        average = total / draws
        error = np.sqrt(np.maximum(square / draws - average**2, 1e-30) / draws)
        assert np.all(np.abs(average - mean) < 5 * error + 1e-12)
    # by hand for the words: counts of the cells labelled 1
    counts = np.zeros(w.shape[1])
    observed = labels[data.obs_cells].numpy()
    counts += data.modality("words").counts.numpy()[observed == 1].sum(0)
    V = w.shape[1]
    np.testing.assert_allclose(w[1], (0.5 + counts) / (V * 0.5 + counts.sum()), rtol=1e-12)
    np.testing.assert_allclose(w[4], np.full(V, 1 / V))  # no cell: the prior mean, uniform


def test_posterior_means_average_over_label_samples(small_house):
    data, config = _prepared(small_house)
    generator = torch.Generator().manual_seed(1)
    maps = torch.randint(0, 5, (3, data.num_free), generator=generator)  # [S, N]
    pi, tables = posterior_means(maps, data, config)
    singles = [posterior_means(m, data, config) for m in maps]
    np.testing.assert_allclose(pi, np.mean([p for p, _ in singles], axis=0))
    for m, table in enumerate(tables):
        np.testing.assert_allclose(table, np.mean([t[m] for _, t in singles], axis=0))
    with pytest.raises(ValueError, match="concepts in 0..4"):
        posterior_means(maps + 5, data, config)


def test_a_gibbs_result_reports_posterior_means_not_draws(small_house):
    """fit_house's Gibbs result: w, theta, pi are the means given its labels (or averaged over
    the kept label maps with marginal_samples), and config.json's inference says which."""
    settings = preset("original-code", gamma=3.0, num_concepts=8)
    options = GibbsOptions(backend="torch")
    result = fit_house(small_house, settings, options=options, sweeps=20, progress=False)
    _, data = prepare_model_data(small_house, settings)
    pi, (theta, w) = posterior_means(result.labels, data, settings.model)
    np.testing.assert_allclose(result.w, w, rtol=1e-12)
    np.testing.assert_allclose(result.theta, theta, rtol=1e-12)
    np.testing.assert_allclose(result.pi, pi, rtol=1e-12)
    assert result.inference["parameters"] == "posterior mean given the point labels"
    totals = concept_totals(result.labels, data, settings.model)
    np.testing.assert_array_equal(result.concept_totals, totals)
    assert totals[:, 0].sum() == len(data.obs_cells)  # every observed cell in one concept
    # each word's count in each concept: n_lv of w's mean, adding up to the concepts' totals
    counts = result.word_counts  # [L, V]
    words = data.modality("words").counts.numpy()  # [M, V]
    observed = result.labels[data.obs_cells.numpy()]  # [M]
    np.testing.assert_allclose(counts[3], words[observed == 3].sum(0))
    np.testing.assert_allclose(counts.sum(1), totals[:, 2])
    np.testing.assert_allclose(counts.sum(0), result.word_totals)
    sampled = fit_house(small_house, settings, options=options, sweeps=20, progress=False,
                        marginal_samples=5)  # fmt: skip
    assert "averaged over 5 label samples" in sampled.inference["parameters"]
    np.testing.assert_allclose(sampled.w.sum(-1), 1.0)


def test_lift_by_hand_and_as_the_where_bayes_ratio():
    """two_rooms: concept sizes 150, 149, 1; p(kitchen) = (150 .6 + 149 .1 + 1 .7) / 300."""
    result = two_rooms()
    p_kitchen = (150 * 0.6 + 149 * 0.1 + 1 * 0.7) / 300
    ratios = result.lift()  # [L, V]
    assert ratios[0, 0] == pytest.approx(0.6 / p_kitchen)
    assert ratios[1, 0] == pytest.approx(0.1 / p_kitchen)
    np.testing.assert_allclose(lift(result.w, [150, 149, 1]), ratios)
    # lift = p(C = l | v) / p(C = l) under the area prior of "where is v?"
    sizes = result.concept_sizes() / result.concept_sizes().sum()
    for v, word in enumerate(WORDS):
        np.testing.assert_allclose(ratios[:, v], result.concept_given_word(word) / sizes)
    assert distinctive_items(result.w[1], ratios[1], WORDS, n=3) == [
        ("bed", pytest.approx(0.6 / ((150 * 0.2 + 149 * 0.6 + 0.15) / 300)), 0.6),
        ("sofa", pytest.approx(0.3 / ((150 * 0.2 + 149 * 0.3 + 0.15) / 300)), 0.3),
    ]  # kitchen's lift (0.28) is below MIN_LIFT: not distinctive


def _silent_speck() -> SpCoResult:
    """two_rooms, where words were heard in the two rooms but none on the speck (concept 2)."""
    result = two_rooms()
    totals = np.array([[3.0, 3.0, 5.0], [2.0, 2.0, 4.0], [0.0, 0.0, 0.0]])  # [L, 1 + 2]
    return dataclasses.replace(result, concept_totals=totals)


def test_a_concept_where_no_word_was_heard_says_so(capsys):
    result = _silent_speck()
    summaries = {c["concept"]: c for c in result.concepts()}
    assert summaries[2]["words_note"] == NO_WORDS
    assert summaries[2]["top_words"] == [] and summaries[2]["distinctive_words"] == []
    assert summaries[0]["words_note"] is None and summaries[0]["top_words"][0][0] == "kitchen"
    assert format_concept_words([], [], 0.0) == f"({NO_WORDS})"
    # a top word at 0.00 is left out ("bedroom 0.56, bed 0.42, entrance 0.00"), the first kept
    assert format_concept_words([("bed", 0.56), ("door", 0.004)], [], 3.0) == "bed 0.56"
    assert format_concept_words([("bed", 0.004)], [], 3.0) == "bed 0.00"
    assert region_text(result, 2) == f"[2]\n{NO_WORDS}"
    assert region_text(result, 0).splitlines()[1] == "kitchen 0.60 x1.7"
    print_concepts(result)
    lines = capsys.readouterr().out.splitlines()
    # concept 2 holds under 0.5 % of the cells: a speck, listed on the specks' line
    assert not any(line.strip().startswith("concept   2:") for line in lines)
    assert any(line.strip().startswith("+ 1 speck of") and "under 0.1 words were heard (concept 2; "
               "concepts.json lists it)" in line for line in lines)  # fmt: skip
    assert any("concept   1:" in line and "distinctive: bed x1.5" in line for line in lines)
    silent_room = dataclasses.replace(
        result, concept_totals=np.array([[3.0, 3.0, 5.0], [2.0, 2.0, 0.0], [0.0, 0.0, 0.0]])
    )  # concept 1 (149 cells) heard nothing: a region, listed, saying so
    print_concepts(silent_room)
    lines = capsys.readouterr().out.splitlines()
    assert any(line.strip().startswith("concept   1:") and NO_WORDS in line for line in lines)


def test_one_cell_and_one_word_are_singular_in_the_listing(capsys):
    """A one-cell concept where one utterance was heard printed '1 cells    1 words'."""
    result = two_rooms()
    totals = np.array([[3.0, 3.0, 5.0], [2.0, 2.0, 4.0], [1.0, 1.0, 1.0]])  # concept 2: 1 cell
    print_concepts(dataclasses.replace(result, concept_totals=totals))
    lines = capsys.readouterr().out.splitlines()
    assert "  concept   2:      1 cell     1 word   kitchen 0.70" in lines[-1]
    assert "  concept   1:    149 cells    4 words  bed 0.60" in lines[-2]  # the columns align


def test_a_concept_outside_0_to_L_is_refused_by_name():
    result = _silent_speck()  # L = 3
    assert result.top_words(2) == result.top_words(np.int64(2))
    for bad in (-1, 3, 1.0, True):  # -1 read the last concept's row
        for ask in (result.top_words, result.heard, result.distinctive_words):
            with pytest.raises(ValueError, match=r"concept must be an integer in 0\.\.2"):
                ask(bad)


def test_concepts_json_keeps_the_old_keys_and_adds_the_new(tmp_path):
    result = _silent_speck()
    result.save(tmp_path)
    concepts = json.loads((tmp_path / "concepts.json").read_text())
    old = {"concept", "cells", "pi", "top_words"}
    new = {"observed_cells", "words_heard", "distinctive_words", "words_note"}
    assert all(old | new <= set(c) for c in concepts)
    first = concepts[0]
    assert first["observed_cells"] == 3 and first["words_heard"] == 5.0
    assert first["distinctive_words"][0][0] == "kitchen" and first["distinctive_words"][0][1] > 1
    loaded = SpCoResult.load(tmp_path)
    np.testing.assert_array_equal(loaded.concept_totals, result.concept_totals)
    # a result that does not know its counts (an old one) shows its words as before
    unknown = two_rooms()
    assert unknown.heard(2) is None and unknown.concepts()[0]["words_heard"] is None
    assert unknown.concepts()[-1]["top_words"]


def test_semantic_map_figure_writes_words_on_their_regions_and_marks_utterances():
    result = _silent_speck()
    image = result.label_image()
    observations = Observations(
        image_features=np.zeros((0, 2)), image_xy=np.zeros((0, 2)),
        image_trial=np.zeros(0, dtype=int),
        utterances=(("kitchen",), ("bed",)),
        word_xy=np.array([[0.55, 0.55], [2.25, 0.35]]), word_trial=np.zeros(2, dtype=int),
    )  # fmt: skip
    np.testing.assert_array_equal(utterance_concepts(result, observations.word_xy), [0, 1])
    # Heard on the wall (x 1.5-1.6 m), 2 cm from either room: the concept of the cell the fit
    # counted it in, as the fit snaps it; far off the map: left out (-1, drawn grey).
    off_free = [[1.52, 0.55], [1.58, 0.55], [5.0, 5.0]]
    np.testing.assert_array_equal(utterance_concepts(result, off_free), [0, 1, -1])
    figure = semantic_map_figure(result, observations=observations, min_region_fraction=0.0)
    ax = figure.axes[0]
    texts = {t.get_text(): t.get_position() for t in ax.texts}
    for concept in (0, 1, 2):
        text = next(t for t in texts if t.startswith(f"[{concept}]"))
        row, col = result.grid.world_to_cell(np.array(texts[text]))
        assert image[row, col] == concept  # written on its own region
    assert f"[2]\n{NO_WORDS}" in texts
    assert any(t.get_path_effects() for t in ax.texts)  # the readable outline
    markers = [c for c in ax.collections if isinstance(c, PathCollection)]
    assert len(markers) == 1 and len(markers[0].get_offsets()) == 2
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("where a word was heard" in t for t in legend)
    # a speck: one line for them all, saying where they are listed
    speck = "1 speck of 1 cell where under 0.1 words were heard (concept 2; concepts.json lists it)"
    assert speck in legend
    assert not any(t.startswith("[2]") for t in legend)
    assert any("distinctive: kitchen x1.7" in t for t in legend)
    totals = np.array([[3.0, 3.0, 5.0], [2.0, 2.0, 0.0], [0.0, 0.0, 0.0]])  # room 1 heard none
    silent_room = dataclasses.replace(result, concept_totals=totals)
    legend = semantic_map_figure(silent_room, min_region_fraction=0.0).axes[0].get_legend()
    assert f"[1] 149 cells: {NO_WORDS}" in [t.get_text() for t in legend.get_texts()]


def test_where_figure_draws_the_answer_over_the_grey_map():
    result = _silent_speck()
    answer = result.where("bed")
    rgb = where_image(result, answer)  # [H, W, 3] point estimate: filled regions
    image = result.label_image()
    assert (rgb[answer.region] == ANSWER_RGB).all()
    assert (rgb[image == answer.runner_up] == RUNNER_UP_RGB).all()
    others = ~answer.region & (image >= 0) & (image != answer.runner_up)
    assert (rgb[others] == FREE_RGB).all()
    assert not where_figure(result, answer).axes[0].collections  # no outline needed
    # with marginals: the per-cell probability as a colour scale and the regions outlined
    marginals = np.eye(3)[result.labels] * 0.8 + 0.2 / 3  # [N, L]
    soft = dataclasses.replace(result, marginals=marginals)
    figure = where_figure(soft, soft.where("bed"))
    ax = figure.axes[0]
    assert len(ax.images) == 2  # the grey map, then the probability
    assert ax.images[1].get_cmap().name == "Reds"
    outlines = [c for c in ax.collections if isinstance(c, ContourSet)] or [
        c for c in ax.collections
    ]
    assert len(outlines) >= 2  # answer and runner-up
    assert len(ax.child_axes) == 1  # and its colour bar, an inset as tall as the map


def test_tables_use_the_posterior_mean_of_sampled_hyperparameters(small_house):
    """With hyper.concentrations (and alpha) sampled, w, theta and pi are the posterior means
    given the labels under the sampled values' posterior means, not under the preset's."""
    from spcopyro.gibbs import HyperparameterOptions
    from spcopyro.gibbs.hyperparameters import config_at_posterior_mean

    settings = preset("original-code", gamma=3.0, num_concepts=8)
    hyper = HyperparameterOptions(alpha=True, concentrations=True)
    options = GibbsOptions(backend="torch", hyper=hyper)
    result = fit_house(small_house, settings, options=options, sweeps=30, progress=False)
    summary = result.inference["hyperparameters"]
    assert {"alpha", "beta", "chi"} <= set(summary)
    sampled = config_at_posterior_mean(settings.model, summary)
    assert sampled.beta == summary["beta"]["posterior_mean"] != settings.model.beta
    assert sampled.chi == summary["chi"]["posterior_mean"] != settings.model.chi
    assert sampled.alpha == summary["alpha"]["posterior_mean"] != settings.model.alpha
    _, data = prepare_model_data(small_house, settings)
    pi, (theta, w) = posterior_means(result.labels, data, sampled)
    np.testing.assert_allclose(result.w, w, rtol=1e-12)
    np.testing.assert_allclose(result.theta, theta, rtol=1e-12)
    np.testing.assert_allclose(result.pi, pi, rtol=1e-12)
    assert config_at_posterior_mean(settings.model, None) == settings.model


def test_word_ranks_ignore_last_bit_noise_between_ties():
    """Two words with the same counts tie; their lifts come from a matrix product whose last bits
    differ between columns and CPUs (OpenBLAS picks its kernel by CPU). Ranked as computed, the
    order of such a tie followed the machine (the pinned ``fit-numba-options`` concept table
    differed between an AVX-512 and an AVX2 machine); ranked after rounding, ties go in item
    order."""
    from spcopyro.results.concept_words import ranked

    tie = 0.28767123287671231
    noisy = np.array([0.1, tie, np.nextafter(tie, 1.0), 0.5])  # items 1 and 2 tie but for one ulp
    assert list(ranked(noisy)) == [3, 1, 2, 0]
    assert list(np.argsort(-noisy, kind="stable")) == [3, 2, 1, 0]  # what it guards against
    lifts = np.array([3.1955102, np.nextafter(3.1955102, 0.0), 1.1 + 1e-15, 0.5])
    rows = np.array([np.nextafter(tie, 0.0), tie, 0.3, 0.1])  # a and b tie in probability too
    chosen = distinctive_items(rows, lifts, ["a", "b", "c", "d"], n=4)
    assert [item for item, _, _ in chosen] == [
        "a",
        "b",
    ]  # the tie in item order; 1.1 + 1e-15 is 1.1


def test_labels_and_counts_read_as_written():
    """A map label left out words at 0.00 ("entrance 0.00" under "bedroom 0.56, bed 0.42"),
    and counts of one are singular ("1 doorways", "1 rooms")."""
    from hand_results import two_rooms

    from spcopyro._util.messages import plural
    from spcopyro.results.result import EmissionTable

    result = two_rooms()
    w = np.array([[0.6, 0.398, 0.002], [0.1, 0.6, 0.3], [0.7, 0.15, 0.15]])  # [L, V]
    emissions = tuple(EmissionTable("words", WORDS, w) if e.name == "words" else e
                      for e in result.emissions)  # fmt: skip
    result = dataclasses.replace(result, emissions=emissions)
    assert region_text(result, 0) == "[0]\nkitchen 0.60 x1.7\nbed 0.40"  # no "sofa 0.00"
    assert plural(1, "doorway") == "1 doorway" and plural(3, "room") == "3 rooms"
    assert plural(0, "place") == "0 places"


def test_one_concept_says_why_no_word_is_distinctive_and_few_words_are_not_near_uniform(capsys):
    """A one-room fit printed "no concept has a distinctive word (every lift <= 1.1)" (the lift
    against the concept's own mix is 1) and called (0.67, 0.22, 0.11) over three words "close to
    uniform" (the bound was twice uniform alone)."""
    from spcopyro.results.concept_words import near_uniform

    result = two_rooms()
    one = dataclasses.replace(
        result, labels=np.zeros_like(result.labels), concept_totals=np.array([[5.0, 5.0, 9.0]])
    )
    print_concepts(one)
    out = capsys.readouterr().out
    assert "one concept in use: no word can be distinctive" in out
    assert "no concept has a distinctive word" not in out
    assert not near_uniform(np.array([[0.666, 0.222, 0.112]]))
    assert near_uniform(np.array([[0.4, 0.3, 0.3]]))
    assert near_uniform(np.full((2, 50), 0.02)) and not near_uniform(
        np.array([[0.05] + [0.95 / 49] * 49])
    )
    assert not near_uniform(np.empty((0, 3)))


def _bathroom_fit() -> SpCoResult:
    """two_rooms with posterior-mean word tables (beta 0.1 over 5 words): 9 words heard in the
    left room (bathroom 6, bathtub 3), 8 in the right (kitchen 4, sofa 4), none on the speck."""
    result = two_rooms()
    vocabulary = ("bathroom", "bathtub", "restroom", "kitchen", "sofa")
    counts = np.array([[6, 3, 0, 0, 0], [0, 0, 0, 4, 4], [0, 0, 0, 0, 0]], dtype=np.float64)
    w = (counts + 0.1) / (counts.sum(1, keepdims=True) + 5 * 0.1)  # [L, V]
    images = result.emissions[0]
    totals = np.array([[3.0, 3.0, 9.0], [2.0, 2.0, 8.0], [0.0, 0.0, 0.0]])  # [L, 1 + 2]
    return dataclasses.replace(
        result,
        emissions=(images, EmissionTable("words", vocabulary, w)),
        concept_totals=totals,
        inference={"parameters": "posterior mean given the point labels"},
    )


def test_a_word_never_heard_in_a_concept_is_not_listed_among_its_words(tmp_path, capsys):
    """The default house's fit listed "bathroom 0.57, bathtub 0.29, restroom 0.01" for a concept
    where 9 words were heard, none of them 'restroom': 0.01 = beta / (V beta + 9) is the prior's
    share of any unheard word, 'restroom' first of 15 such words by tie order only. fit's
    listing, the legend, the map's labels and `where` now list only the words above it; words
    tied above it (kitchen and sofa, 4 each) stay."""
    from spcopyro.cli.main import main
    from spcopyro.figures.map_pieces import concept_handles

    result = _bathroom_fit()
    assert [w for w, _ in result.top_words(0)] == ["bathroom", "bathtub", "restroom"]
    print_concepts(result)
    lines = capsys.readouterr().out.splitlines()
    (left,) = [line for line in lines if line.strip().startswith("concept   0:")]
    assert left.endswith("9 words  bathroom 0.64, bathtub 0.33 | distinctive: bathroom x2.0, "
                         "bathtub x1.9"), left  # fmt: skip
    (right,) = [line for line in lines if line.strip().startswith("concept   1:")]
    assert "8 words  kitchen 0.48, sofa 0.48 |" in right, right
    assert main(["where", str(result.save(tmp_path / "fit")), "bathtub"]) == 0
    out = capsys.readouterr().out
    assert "its words: bathroom (0.64), bathtub (0.33); distinctive:" in out, out
    assert "restroom" not in out
    assert region_text(result, 0).splitlines()[1:] == ["bathroom 0.64 x2.0", "bathtub 0.33 x1.9"]
    colours = np.zeros((3, 3), dtype=np.uint8)
    labels = [h.get_label() for h in concept_handles(result, colours)]
    assert labels[0].startswith("[0] 150 cells, 9 words heard: bathroom 0.64, bathtub 0.33\n")
    # the one filter all four print through: a concept of the result, its own row beside it
    assert [w for w, _ in shown_top_words(result, 0, 3)] == ["bathroom", "bathtub"]
    assert shown_top_words(result, 1, 3) == shown_words(result.top_words(1, 3), result.w[1])
    # a draw's row (no two words equal) keeps a word at 0.01: nothing says it went unheard
    drawn = np.array([0.64, 0.33, 0.011, 0.01, 0.009])
    top = list(zip("abc", drawn[:3], strict=True))
    assert [w for w, _ in shown_words(top, drawn)] == ["a", "b", "c"]


def counted_words(
    w: np.ndarray, counts: np.ndarray, totals: np.ndarray, inference: dict | None = None
) -> SpCoResult:
    """The two rooms' result with the word table ``w`` [L, V], the concepts' ``totals``
    [L, 1 + M] and each word's ``counts`` [L, V] in each concept (``word_counts``); its
    ``inference`` ``{}`` unless given: a variational fit's, words as the method estimates them."""
    base = two_rooms()
    return dataclasses.replace(
        base,
        emissions=(base.emissions[0], EmissionTable("words", WORDS, w)),
        concept_totals=totals,
        word_counts=counts,
        inference={} if inference is None else inference,
    )


def test_a_word_heard_as_rarely_as_the_rarest_is_listed(tmp_path, capsys):
    """Every word heard in the left room, bed and sofa once each: their posterior mean (1.1 / 6.3)
    is the row's minimum, shared by two words, which :func:`prior_share` reads as the share of
    a word never heard there; the listing, the legend, the map's labels and ``where`` said
    "kitchen 0.65" alone. The result keeps each word's count in each concept
    (``word_counts``), so a heard word stays; a result saved without them reads as before."""
    from spcopyro.cli.main import main
    from spcopyro.figures.map_pieces import concept_handles
    from spcopyro.results.concept_words import heard_words

    counts = np.array([[4.0, 1.0, 1.0], [0.0, 4.0, 2.0], [0.0, 0.0, 0.0]])  # [L, V]
    w = (counts + 0.1) / (counts.sum(1, keepdims=True) + 3 * 0.1)  # [L, V]
    totals = np.array([[3.0, 3.0, 6.0], [2.0, 2.0, 6.0], [0.0, 0.0, 0.0]])  # [L, 1 + M]
    result = counted_words(
        w, counts, totals, {"parameters": "posterior mean given the point labels"}
    )
    base = two_rooms()  # no counts kept
    assert heard_words(result, 0) == {"kitchen", "bed", "sofa"}
    assert heard_words(result, 1) == {"bed", "sofa"} and heard_words(base, 0) is None
    assert shown_top_words(result, 0, 3) == result.top_words(0, 3)
    print_concepts(result)
    (left,) = [line for line in capsys.readouterr().out.splitlines() if "concept   0:" in line]
    assert "6 words  kitchen 0.65, bed 0.17, sofa 0.17" in left, left
    assert region_text(result, 0).splitlines()[1:] == ["kitchen 0.65 x1.9", "bed 0.17", "sofa 0.17"]
    labels = [h.get_label() for h in concept_handles(result, np.zeros((3, 3), dtype=np.uint8))]
    assert labels[0].startswith("[0] 150 cells, 6 words heard: kitchen 0.65, bed 0.17, sofa 0.17")
    saved = result.save(tmp_path / "fit")
    assert main(["where", str(saved), "kitchen"]) == 0
    assert "its words: kitchen (0.65), bed (0.17), sofa (0.17)" in capsys.readouterr().out
    loaded = SpCoResult.load(saved)
    np.testing.assert_array_equal(loaded.word_counts, counts)
    assert shown_top_words(loaded, 0, 3) == result.top_words(0, 3)
    # a fit saved before the counts were kept: loads, and its lists read as they did
    with np.load(saved / "result.npz") as z:
        arrays = {k: z[k] for k in z.files if k != "word_counts"}
    np.savez(saved / "result.npz", **arrays)
    old = SpCoResult.load(saved)
    assert old.word_counts is None
    assert [w for w, _ in shown_top_words(old, 0, 3)] == ["kitchen"]


def test_a_variational_concept_lists_only_the_words_heard_there(tmp_path, capsys):
    """The default house's svi fit listed "door 0.86, entrance 0.01, bathroom 0.01" for a
    concept of 16 cells where only 'door' was heard: a variational E_q[w] has no row minimum
    shared by the unheard words (no :func:`prior_share`), so the floor rule kept them. Where
    the result keeps its counts, the words heard decide: fit's listing, the legend, the map's
    labels and `where` list 'kitchen' alone; concepts.json's top words are unchanged."""
    from spcopyro.cli.main import main
    from spcopyro.figures.map_pieces import concept_handles

    counts = np.array([[5.0, 0.0, 0.0], [0.0, 4.0, 2.0], [0.0, 0.0, 0.0]])  # [L, V]
    w = np.array([[0.80, 0.15, 0.05], [0.1, 0.6, 0.3], [0.7, 0.16, 0.14]])  # [L, V], no ties
    totals = np.array([[3.0, 3.0, 5.0], [2.0, 2.0, 6.0], [0.0, 0.0, 0.0]])  # [L, 1 + M]
    result = counted_words(w, counts, totals)  # a variational fit's: words as it estimates them
    assert [w for w, _ in result.top_words(0, 3)] == ["kitchen", "bed", "sofa"]
    assert [w for w, _ in shown_top_words(result, 0, 3)] == ["kitchen"]
    assert [w for w, _ in shown_top_words(result, 1, 3)] == ["bed", "sofa"]
    print_concepts(result)
    lines = capsys.readouterr().out.splitlines()
    (left,) = [line for line in lines if "concept   0:" in line]
    assert left.split(" | ")[0].endswith("5 words  kitchen 0.80"), left
    assert region_text(result, 0).splitlines()[1:] == ["kitchen 0.80 x1.8"]
    labels = [h.get_label() for h in concept_handles(result, np.zeros((3, 3), dtype=np.uint8))]
    assert labels[0].startswith("[0] 150 cells, 5 words heard: kitchen 0.80\n"), labels[0]
    assert main(["where", str(result.save(tmp_path / "fit")), "kitchen"]) == 0
    out = capsys.readouterr().out
    assert "its words: kitchen (0.80);" in out, out


def test_a_one_cell_concept_is_singular_in_the_legend():
    """The semantic map's legend said "[89] 1 cells, 0.1 words heard: ..." (default house,
    svi): a one-cell concept where a word was heard is no speck and gets its own entry."""
    from spcopyro.figures.map_pieces import concept_handles

    totals = np.array([[3.0, 3.0, 5.0], [2.0, 2.0, 4.0], [1.0, 1.0, 1.0]])  # concept 2: 1 cell
    result = dataclasses.replace(two_rooms(), concept_totals=totals)
    labels = [h.get_label() for h in concept_handles(result, np.zeros((3, 3), dtype=np.uint8))]
    assert labels[0].startswith("[0] 150 cells, 5 words heard: "), labels
    (one,) = [label for label in labels if label.startswith("[2] ")]
    assert one.startswith("[2] 1 cell, 1 word heard: kitchen 0.70"), one


def test_a_variational_concept_ranks_its_heard_words_before_cutting(capsys):
    """A variational E_q[w] can rank a heard word below unheard ones: cutting to the top ``n``
    first listed fewer than ``n`` heard words, and where none of the top ``n`` was heard it
    printed an unheard one (the first, by the "first always" fallback). The ``n`` shown are
    the most probable heard words. A posterior-mean row (unheard words at its floor, Gibbs)
    lists as the cut-first rule did."""
    counts = np.array([[0.0, 0.0, 2.0], [3.0, 4.0, 0.0], [1.0, 0.0, 0.0]])  # [L, V]
    w = np.array([[0.6, 0.25, 0.15], [0.1, 0.6, 0.3], [0.7, 0.16, 0.14]])  # [L, V], no floor
    totals = np.array([[3.0, 3.0, 2.0], [2.0, 2.0, 7.0], [1.0, 1.0, 1.0]])  # [L, 1 + M]
    result = counted_words(w, counts, totals)
    assert [w for w, _ in shown_top_words(result, 0, 1)] == ["sofa"]  # not kitchen, unheard
    assert [w for w, _ in shown_top_words(result, 1, 2)] == ["bed", "kitchen"]
    assert shown_top_words(result, 1, 0) == []
    print_concepts(result)  # its top words come from concepts(): the heard ones still listed
    lines = capsys.readouterr().out.splitlines()
    (left,) = [line for line in lines if "concept   0:" in line]
    assert left.split(" | ")[0].endswith("2 words  sofa 0.15"), left
    assert region_text(result, 0).splitlines()[1].startswith("sofa 0.15"), region_text(result, 0)
    floor = np.array([[0.5, 0.25, 0.25], [0.1, 0.1, 0.8], [0.6, 0.2, 0.2]])  # [L, V], Gibbs
    heard = np.array([[4.0, 1.0, 0.0], [0.0, 0.0, 5.0], [1.0, 0.0, 0.0]])  # [L, V]
    gibbs = counted_words(floor, heard, totals)
    for concept in range(3):
        for n in range(4):
            known = heard_words(gibbs, concept)  # never empty here
            top = gibbs.top_words(concept, n)  # cut first, then filtered by the words heard
            cut_first = shown_words([(w, p) for w, p in top if w in known])
            assert shown_top_words(gibbs, concept, n) == cut_first, (concept, n)


def test_a_concept_no_word_answers_is_named_by_its_most_probable_heard_word():
    """Where no word's ``where`` answer is a concept, it was named by its top word; a variational
    E_q[w] gives unheard words mass, so the speck (concept 2, one cell), where only 'bed' was
    heard, was named "kitchen" (its w 0.70, never heard there) while its word list read 'bed'.
    Its name is now its most probable heard word (:func:`shown_top_words`); a result without
    counts, or whose counts hold none for it, is named by its top word as before, and one where
    no word was heard, or whose fit did not model its words, ``concept 2``."""
    from spcopyro.results.concept_names import answered_words, concept_name

    counts = np.array([[5.0, 0.0, 0.0], [0.0, 4.0, 2.0], [0.0, 1.0, 0.0]])  # [L, V]
    w = np.array([[0.6, 0.2, 0.2], [0.1, 0.6, 0.3], [0.7, 0.16, 0.14]])  # [L, V], no floor
    totals = np.array([[3.0, 3.0, 5.0], [2.0, 2.0, 6.0], [1.0, 1.0, 1.0]])  # [L, 1 + M]
    result = counted_words(w, counts, totals)
    assert 2 not in answered_words(result, heard_only=True)  # kitchen: 0's, bed and sofa: 1's
    assert result.top_words(2, 1)[0][0] == "kitchen"
    assert concept_name(result, 2) == "bed"
    assert {c["concept"]: c["name"] for c in result.concepts()} == {0: "kitchen", 1: "bed",
                                                                   2: "bed"}  # fmt: skip
    assert region_text(result, 2, largest=False) == "[2] bed"
    unknown = dataclasses.replace(result, word_counts=None)  # a fit saved before the counts
    assert concept_name(unknown, 2) == "kitchen"
    none_counted = dataclasses.replace(result, word_counts=counts * [[1], [1], [0]])
    assert concept_name(none_counted, 2) == "kitchen"
    unmodelled = dataclasses.replace(result, config=result.config.replace(use_words=False))
    assert concept_name(unmodelled, 2) == "concept 2"  # w the prior's: no word names it
    silent = dataclasses.replace(result, concept_totals=totals * [[1], [1], [0]])
    assert concept_name(silent, 2) == "concept 2"


def test_distinctive_words_are_words_heard_in_the_concept(capsys):
    """A variational E_q[w] gives unheard words mass, so a concept's list read "bed 0.60 |
    distinctive: sofa x1.7, bed x1.6" with 'sofa' never heard there (the word list had just
    left it out). Where the result keeps its counts only the heard words are candidates; a
    result saved without them ranks every word, as before."""
    counts = np.array([[5.0, 0.0, 0.0], [0.0, 4.0, 0.0], [1.0, 0.0, 0.0]])  # [L, V]
    w = np.array([[0.80, 0.15, 0.05], [0.1, 0.6, 0.3], [0.7, 0.16, 0.14]])  # [L, V]
    totals = np.array([[3.0, 3.0, 5.0], [2.0, 2.0, 4.0], [1.0, 1.0, 1.0]])  # [L, 1 + M]
    result = counted_words(w, counts, totals)
    old = dataclasses.replace(result, word_counts=None)
    assert [w for w, _, _ in old.distinctive_words(1, 3)] == ["sofa", "bed"]
    assert [w for w, _, _ in result.distinctive_words(1, 3)] == ["bed"]
    (one,) = [c for c in result.concepts() if c["concept"] == 1]
    assert [w for w, _, _ in one["distinctive_words"]] == ["bed"]
    print_concepts(result)
    (line,) = [x for x in capsys.readouterr().out.splitlines() if "concept   1:" in x]
    assert line.endswith("bed 0.60 | distinctive: bed x1.6"), line
