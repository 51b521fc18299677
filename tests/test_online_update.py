"""Online updates (spcopyro.robot.online, ``spcopyro fit DATA --update OUT``): a saved fit continued
with new observations -- vocabulary union, new words under the prior, the saved state at sweep
0, clear errors for another map or other settings, and the command end to end."""

from __future__ import annotations

import dataclasses
import json
import logging
import pickle

import numpy as np
import pytest
import torch

from spcopyro.cli.main import main
from spcopyro.config import preset
from spcopyro.data import Observations, save_house
from spcopyro.fit.house import fit_house
from spcopyro.guides.options import VariationalOptions
from spcopyro.results.result import SpCoResult
from spcopyro.robot.online import (
    UpdateMismatchError,
    check_compatible,
    extend_emission,
    fit_update,
    merge_vocabulary,
    renormalise_vocabulary,
    start_update,
    start_update_chain,
)
from spcopyro.synthetic import make_house

SETTINGS = preset("original-code", gamma=3.0)


def _trials(house, trials):
    return dataclasses.replace(house, observations=house.observations.select_trials(trials))


@pytest.fixture(scope="module")
def house():
    return make_house(0)


@pytest.fixture(scope="module")
def saved(house):
    """A short fit of trials 0-1 of the synthetic house (whose trial 2 adds two words)."""
    return fit_house(_trials(house, [0, 1]), SETTINGS, sweeps=60, seed=0, progress=False)


def test_merge_vocabulary_keeps_the_saved_columns():
    merge = merge_vocabulary(("c", "a", "b"), ("b", "e", "a", "d", "e"))
    assert merge.vocabulary == ("c", "a", "b", "e", "d")  # saved columns, then first heard
    assert merge.old_size == 3 and merge.new_words == ("e", "d")
    assert merge.unheard_words == ("c",)
    assert merge.column("b") == 2 and merge.column("d") == 4
    assert merge_vocabulary(("a",), ()).vocabulary == ("a",)


def test_update_counts_words_in_the_merged_columns(house, saved):
    start = start_update(saved, house, SETTINGS)
    vocabulary = start.counts.vocabulary
    assert vocabulary[: len(saved.vocabulary)] == saved.vocabulary
    assert set(start.merge.new_words) == set(house.observations.vocabulary) - set(saved.vocabulary)
    assert start.merge.new_words  # trial 2 of this house holds words trials 0-1 do not
    tokens = [t for u in house.observations.utterances for t in u]
    totals = start.counts.word_counts.sum(axis=0)  # [V'] every utterance is placed here
    for word in vocabulary:
        assert totals[start.merge.column(word)] == tokens.count(word), word


def test_new_words_get_the_prior_mean_and_draws_of_the_conditional():
    w = np.array([[0.5, 0.3, 0.2], [0.1, 0.1, 0.8]])  # [L=2, V=3]
    totals, beta = np.array([10.0, 0.0]), 2.0
    mean = extend_emission(w, totals, beta, 2)  # [2, 5]
    np.testing.assert_allclose(mean.sum(axis=1), 1.0)
    # Dir(beta + n) extended by two words without counts: each new word's mean is
    # beta / (beta V' + n_l), and the old words keep their ratios.
    np.testing.assert_allclose(mean[:, 3:], (beta / (beta * 5 + totals))[:, None] * np.ones(2))
    np.testing.assert_allclose(mean[:, :3] / mean[:, :3].sum(1, keepdims=True), w)
    generator = torch.Generator().manual_seed(0)
    many = np.repeat(w, 4000, axis=0)  # [8000, 3]
    drawn = extend_emission(many, np.repeat(totals, 4000), beta, 2, generator)  # [8000, 5]
    np.testing.assert_allclose(drawn.sum(axis=1), 1.0)
    np.testing.assert_allclose(drawn[:, :3] / drawn[:, :3].sum(1, keepdims=True), many)
    for row, expected in ((slice(0, 4000), mean[0]), (slice(4000, None), mean[1])):
        new_mass = drawn[row, 3:].sum(axis=1)  # Beta(beta V', n + beta V) ... its mean:
        np.testing.assert_allclose(new_mass.mean(), expected[3:].sum(), rtol=0.05)
    assert np.array_equal(extend_emission(w, totals, beta, 0), w)


def test_an_update_starts_from_the_saved_state(house, saved):
    chain, start = start_update_chain(saved, house, SETTINGS, seed=3)
    assert chain.sweeps_done == 0
    assert np.array_equal(chain.state.labels.numpy(), saved.labels)
    np.testing.assert_allclose(chain.state.log_pi.exp().numpy(), saved.pi, rtol=1e-12)
    np.testing.assert_allclose(chain.state.log_theta.exp().numpy(), saved.theta, rtol=1e-12)
    w = chain.state.log_w.exp().numpy()  # [L, V']
    old = len(saved.vocabulary)
    np.testing.assert_allclose(w.sum(axis=1), 1.0)
    np.testing.assert_allclose(w[:, :old] / w[:, :old].sum(1, keepdims=True), saved.w,
                               rtol=1e-9, atol=1e-300)  # fmt: skip
    assert (w[:, old:] > 0).all()


def test_an_update_runs_on_all_the_data_with_the_merged_vocabulary(house, saved):
    (result,) = fit_update(saved, house, SETTINGS, sweeps=5, progress=False)
    assert result.vocabulary[: len(saved.vocabulary)] == saved.vocabulary
    assert set(result.vocabulary) == set(house.observations.vocabulary)
    assert len(result.trace.objective) == 5
    record = result.inference["update_of"]
    assert record["iterations"] == len(saved.trace.objective) and record["new_words"]
    (cavi,) = fit_update(saved, house, SETTINGS, method="cavi", sweeps=2, progress=False)
    assert cavi.w.shape[1] == len(result.vocabulary) and cavi.method == "cavi"


def test_renormalise_vocabulary_reads_old_words_as_the_tokenizer_does_now():
    saved = renormalise_vocabulary(("TV", "stove.", "tv", "...", "\ufeffsink", "sink"))
    assert saved.vocabulary == ("tv", "stove", "...", "sink")
    assert saved.columns.tolist() == [0, 1, 0, 2, 3, 3]
    assert saved.renamed == (("TV", "tv"), ("stove.", "stove"), ("\ufeffsink", "sink"))
    assert saved.unmatchable == ("...",)
    w = np.array([[0.1, 0.2, 0.3, 0.1, 0.2, 0.1]])  # [L=1, V=6]
    np.testing.assert_allclose(saved.fold(w), [[0.4, 0.2, 0.1, 0.3]])
    same = renormalise_vocabulary(("kitchen", "tv"))  # today's words: nothing changes
    assert same.vocabulary == ("kitchen", "tv") and not same.renamed and not same.unmatchable
    assert np.array_equal(same.fold(w[:, :2]), w[:, :2])


def test_an_update_of_a_fit_with_words_the_tokenizer_no_longer_makes(house, saved, caplog):
    """A fit saved before the tokenizer case-folded and stripped punctuation held ``TV`` and
    ``stove.``, which the new data's ``tv`` and ``stove`` never equal: the update counted them
    as new words from the prior and kept the saved ones unheard (what the fit learnt of them
    lost), and said the data lacked the old trials' words."""
    old = {"tv": "TV", "stove": "stove.", "sink": "..."}
    tables = tuple(
        dataclasses.replace(t, items=tuple(old.get(w, w) for w in t.items)) if t.name == "words"
        else t for t in saved.emissions
    )  # fmt: skip
    older = dataclasses.replace(saved, emissions=tables)
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        start = start_update(older, house, SETTINGS, where="old/fit")
    assert start.merge.new_words == ("sink", "kitchen", "sofa")  # in order of first appearance
    assert start.merge.unheard_words == ("...",)
    assert start.merge.vocabulary[: start.merge.old_size] == tuple(
        {"TV": "tv", "stove.": "stove"}.get(w, w) for w in older.vocabulary
    )
    w = start.log_emissions[1].exp().numpy()  # [L, V'] the saved w, extended as before
    reference = start_update(saved, house, SETTINGS).log_emissions[1].exp().numpy()
    keep = [k for k, word in enumerate(saved.vocabulary) if word != "sink"]
    np.testing.assert_allclose(w[:, keep] / w[:, keep].sum(1, keepdims=True),
                               reference[:, keep] / reference[:, keep].sum(1, keepdims=True),
                               rtol=1e-9, atol=1e-300)  # fmt: skip
    said = caplog.text
    assert "update of old/fit: 2 word(s) of its vocabulary are not words the tokenizer" in said
    assert "'stove.' -> 'stove'" in said and "'TV' -> 'tv'" in said
    assert "can match no word of the data (kept, without counts): '...'" in said


def test_the_unmatchable_saved_words_warning_says_how_many_it_leaves_out(caplog):
    """The update's warning names 10 saved words no token matches, then '... (2 more)': it cut
    the list at 10 without saying that more were left out."""
    from spcopyro.robot import online

    words = tuple("." * k for k in range(1, 13))  # 12 words of punctuation alone
    saved = renormalise_vocabulary(("kitchen", *words))
    assert saved.unmatchable == words
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        online._warn_renormalised(saved, "many/fit")
    assert "12 word(s) of its vocabulary are no word the tokenizer makes now" in caplog.text
    shown = ", ".join(repr(w) for w in words[:10])
    assert f"(kept, without counts): {shown}, ... (2 more)" in caplog.text


def _regridded(grid, scale, shift_cells):
    """``grid``'s cells at ``scale`` times its resolution, its origin moved by ``shift_cells``."""
    from spcopyro.maps import OccupancyGrid

    shift = shift_cells * grid.resolution
    origin = (grid.origin[0] + shift, grid.origin[1] - shift, 0.0)
    return OccupancyGrid(grid.occupancy, grid.resolution * scale, origin)


@pytest.mark.parametrize(
    "scale, shift_cells, same",
    [
        (1 + 2e-5, 4e-6, True),  # map_saver's %f: 0.05 / 3 as 0.016667, an origin 5e-7 m off
        (1.0, 0.01, False),  # an origin a hundredth of a cell off: another map
        (1.01, 0.0, False),  # cells 1% larger: another map
        # cells 0.05% finer, the origin 0.99975 thousandths of the saved cell off: over a
        # thousandth of the finer cell, which same_frame (OccupancyGrid ==, a --init start)
        # measures in; an update measured in the saved fit's cell and took it
        (1 - 5e-4, 1e-3 * (1 - 2.5e-4), False),
    ],
)
def test_every_comparison_of_two_maps_frames_follows_one_rule(
    house, saved, scale, shift_cells, same
):
    """A map saved again with rounded floats is the fit's map to OccupancyGrid's ==, to an
    update (check_compatible: np.isclose / np.allclose, which refused an origin 4e-7 m off), to
    a warm start (result_labels: shape and free cells only, which took a map of other cells) and
    to is_coarsening; a really different resolution or origin is refused by all four."""
    from spcopyro.fit.starts import result_labels
    from spcopyro.maps.coarse import coarsen_grid, is_coarsening

    grid = _regridded(house.grid, scale, shift_cells)
    moved = dataclasses.replace(house, grid=grid)
    assert (grid == house.grid) is same and (house.grid == grid) is same
    assert is_coarsening(coarsen_grid(house.grid, 2), grid) is same
    if same:
        check_compatible(saved, moved, SETTINGS)
        assert result_labels(saved, moved, SETTINGS.model).shape == (house.grid.num_free,)
    else:
        with pytest.raises(ValueError, match="map (resolution|origin)"):
            check_compatible(saved, moved, SETTINGS)
        with pytest.raises(ValueError, match="starting result was fitted on"):
            result_labels(saved, moved, SETTINGS.model)


def test_other_settings_map_or_image_classes_are_clear_errors(house, saved):
    with pytest.raises(ValueError, match=r"gamma: saved fit 3\.0, this run 4\.0"):
        check_compatible(saved, house, SETTINGS.replace(gamma=4.0))
    with pytest.raises(ValueError, match=r"word_weighting: saved fit 'count', this run 'tfidf'"):
        check_compatible(saved, house, SETTINGS.replace(word_weighting="tfidf"))
    other = make_house(1)
    with pytest.raises(ValueError, match=r"map"):
        check_compatible(saved, other, SETTINGS)
    obs = house.observations
    wider = Observations(
        image_features=np.hstack([obs.image_features, np.zeros((obs.num_images, 1))]),
        image_xy=obs.image_xy, image_trial=obs.image_trial, utterances=obs.utterances,
        word_xy=obs.word_xy, word_trial=obs.word_trial,
    )  # fmt: skip
    classes = obs.num_feature_classes
    with pytest.raises(ValueError, match=rf"image classes: saved fit {classes}, this run's "
                                         rf"Ft.csv {classes + 1}"):  # fmt: skip
        start_update(saved, dataclasses.replace(house, observations=wider), SETTINGS)
    check_compatible(saved, house, SETTINGS)  # the same house and settings: no error


def test_the_refusal_of_an_update_is_a_value_error_of_its_own_type(house, saved):
    """check_compatible's refusal is an UpdateMismatchError, a ValueError (as it was), carrying each
    difference as the message names them, whole through pickle with a note added (what
    gibbs.chain_processes adds to an error before pickling it): fit
    --update's hint (cli/fit.py) tells it by its type, no longer by the message's opening words
    (the hint itself: test_an_update_of_a_fit_without_the_reach_share_names_the_flag)."""
    with pytest.raises(UpdateMismatchError) as caught:
        check_compatible(saved, house, SETTINGS.replace(gamma=4.0, beta=0.2), where="OLD")
    error = caught.value
    assert isinstance(error, ValueError)
    assert error.problems == (
        "beta: saved fit 0.1, this run 0.2",
        "gamma: saved fit 3.0, this run 4.0",
    )
    assert str(error).startswith("cannot update OLD with this run: " + "; ".join(error.problems))
    error.add_note("raised in a worker")
    again = pickle.loads(pickle.dumps(error))
    assert type(again) is UpdateMismatchError
    assert (str(again), again.problems) == (str(error), error.problems)
    assert again.__notes__ == ["raised in a worker"]


def test_fit_update_command_end_to_end(tmp_path, house, capsys):
    """The synthetic house split in two: trials 0-1 fitted, then updated with all three."""
    save_house(_trials(house, [0, 1]), tmp_path / "old")
    save_house(house, tmp_path / "all")
    flags = ["--preset", "original-code", "--gamma", "3", "--seed", "1"]
    first = tmp_path / "first"
    assert main(["fit", str(tmp_path / "old" / "synthetic"), "--out", str(first),
                 "--sweeps", "40", *flags]) == 0  # fmt: skip
    updated = tmp_path / "updated"
    assert main(["fit", str(tmp_path / "all" / "synthetic"), "--out", str(updated),
                 "--update", str(first), "--sweeps", "20", *flags]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "new words        2: kitchen, sofa" in out
    assert f"updating         the gibbs fit in {first} (40 sweeps) with all of this data" in out
    saved, result = SpCoResult.load(first), SpCoResult.load(updated)
    assert result.vocabulary == saved.vocabulary + ("kitchen", "sofa")
    assert len(result.trace.objective) == 20
    config = json.loads((updated / "config.json").read_text())
    assert config["inference"]["update_of"]["new_words"] == ["kitchen", "sofa"]
    assert config["inference"]["init"] == "update of the fit in update_of"
    # Other settings than the saved fit's: exit 2, naming the difference, nothing written.
    again = tmp_path / "again"
    assert main(["fit", str(tmp_path / "all" / "synthetic"), "--out", str(again),
                 "--update", str(first), "--sweeps", "20", "--preset", "original-code",
                 "--gamma", "3.5"]) == 2  # fmt: skip
    assert "gamma: saved fit 3.0, this run 3.5" in capsys.readouterr().err
    assert not again.exists()
    # --resume given a finished fit points to --update.
    assert main(["fit", str(tmp_path / "all" / "synthetic"), "--out", str(again),
                 "--resume", str(first), *flags]) == 2  # fmt: skip
    assert f"use --update {first}" in capsys.readouterr().err
    assert main(["fit", "--out", str(again), "--update", str(tmp_path)]) == 2
    assert "no finished fit there" in capsys.readouterr().err


def test_a_variational_update_keeps_its_q_as_the_marginals(house, saved):
    """An update by CAVI reports q(C) as its marginals (the uncertainty map), as a fit does: the
    label frequencies of its argmax maps, kept every few iterations, replaced them (entropy near
    0, ``marginal_samples`` in its record), when the update made them a sampler's."""
    (cavi,) = fit_update(
        saved, house, SETTINGS, method="cavi", sweeps=20, progress=False, marginal_samples=5,
        options=VariationalOptions(tolerance=0.0),
    )  # fmt: skip
    assert "marginal_samples" not in cavi.inference
    multiples = np.asarray(cavi.marginals) * 5  # label frequencies over 5 maps: k / 5
    assert not np.allclose(multiples, np.round(multiples))
    assert np.allclose(np.asarray(cavi.marginals).sum(axis=1), 1.0)


def test_a_patch_of_with_sample_marginals_reaches_an_update(house, saved, monkeypatch):
    """fit_update calls gibbs_chains.with_sample_marginals through its module: a test's patch
    there reaches it (online bound the name when first imported: such a patch was missed)."""
    import spcopyro.fit.gibbs_chains as gibbs_chains

    calls, real = [], gibbs_chains.with_sample_marginals

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(gibbs_chains, "with_sample_marginals", counted)
    fit_update(saved, house, SETTINGS, sweeps=5, progress=False)
    assert calls == [1]


def test_an_update_of_a_fit_without_the_reach_share_names_the_flag(tmp_path, house, capsys):
    """A default fit saved before preset coarse's reach share (share 0, no door width), updated
    under the default: the refusal names ``--footprint-reach-share 0``, which updates it; a
    share given on the command line gets no hint (cli.fit_update.reach_share_hint). Refused
    before the house's summary and the 'updating' line are printed (cli.fit_update.check_update):
    they read as a fit begun."""
    save_house(house, tmp_path / "all")
    data = str(tmp_path / "all" / "synthetic")
    first, again = tmp_path / "first", tmp_path / "again"
    flags = ["--sweeps", "5", "--refine", "never", "--no-figures"]
    assert main(["fit", data, "--out", str(first), "--footprint-reach-share", "0", *flags]) == 0
    assert "footprint_reach_share" not in json.loads((first / "config.json").read_text())["data"]
    capsys.readouterr()
    hint = "pass --footprint-reach-share 0 to update it as it was fitted"
    assert main(["fit", data, "--out", str(again), "--update", str(first), *flags]) == 2
    out, err = capsys.readouterr()
    assert "footprint_reach_share: saved fit 0.0, this run 0.2" in err and hint in err
    assert out == "", out  # no summary, no "updating" line
    assert not again.exists()
    given = ["--footprint-reach-share", "0.3", *flags]
    assert main(["fit", data, "--out", str(again), "--update", str(first), *given]) == 2
    err = capsys.readouterr().err
    assert "footprint_reach_share: saved fit 0.0, this run 0.3" in err and hint not in err
    off = ["--footprint-reach-share", "0", *flags]
    assert main(["fit", data, "--out", str(again), "--update", str(first), *off]) == 0
    assert SpCoResult.load(again).preparation.footprint_reach_share == 0
