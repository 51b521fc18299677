"""An online update keeps the saved fit's concept numbers (spcopyro.results.renumber): the
matching of new concepts to saved ones, a renumbered result that answers as before, and an update
whose sampler moved places to other numbers."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from test_online_update import _trials

import spcopyro.robot.online as online
from spcopyro.config import preset
from spcopyro.data.model_grid import model_house
from spcopyro.fit.house import fit_house, prepare_model_data, preset_fit_kwargs
from spcopyro.likelihood import log_joint_variable
from spcopyro.model import DTYPE
from spcopyro.results.renumber import matching_permutation, moved_numbers, renumbered
from spcopyro.robot.online import fit_update
from spcopyro.synthetic import make_house

ORIGINAL = preset("original-code", gamma=3.0)


@pytest.fixture(scope="module")
def house():
    return make_house(0)


def test_the_matching_is_a_bijection_that_undoes_a_renumbering():
    rng = np.random.default_rng(0)
    L = 12
    saved = rng.choice([0, 2, 5, 7, 11], size=400)  # [N] five concepts in use
    assert np.array_equal(matching_permutation(saved, saved, L), np.arange(L))  # unchanged
    sigma = rng.permutation(L)  # the same places under other numbers
    perm = matching_permutation(saved, sigma[saved], L)
    assert np.array_equal(np.sort(perm), np.arange(L))
    assert np.array_equal(perm[sigma[saved]], saved)  # every place gets its saved number back
    noisy = sigma[saved]
    noisy[:30] = 4  # a new concept on cells of several saved ones, the largest share of none
    perm = matching_permutation(saved, noisy, L)
    assert np.array_equal(np.sort(perm), np.arange(L))
    assert np.array_equal(perm[sigma[saved]][30:], saved[30:])


def test_unmatched_concepts_take_the_free_numbers_in_order_and_ties_keep_their_own():
    saved = np.array([0, 0, 0, 1, 1, 2])
    new = np.array([3, 3, 3, 4, 4, 5])  # one to one: 3 -> 0, 4 -> 1, 5 -> 2
    assert matching_permutation(saved, new, 6).tolist() == [3, 4, 5, 0, 1, 2]
    saved = np.array([0, 0, 0, 5, 5, 2])
    new = np.array([3, 3, 3, 1, 5, 4])  # saved 5 splits in two: new 1 or new 5 may be it
    perm = matching_permutation(saved, new, 6)
    assert perm[3] == 0 and perm[5] == 5 and perm[4] == 2  # the tie keeps 5 its number
    assert perm[[0, 1, 2]].tolist() == [1, 3, 4]  # the rest, ascending, the free numbers
    with pytest.raises(ValueError, match="same cells"):
        matching_permutation(saved, new[:5], 6)
    with pytest.raises(ValueError, match=r"0\.\.5"):
        matching_permutation(saved, new + 1, 6)


@pytest.fixture(scope="module")
def fitted(house):
    """A short fit of all trials, with marginals and a final state."""
    return fit_house(house, ORIGINAL, sweeps=40, seed=0, progress=False, marginal_samples=10)


def _log_joint(result, data, config) -> float:
    def log(p):  # an emptied concept's draws can underflow to 0
        return torch.as_tensor(np.log(np.maximum(p, np.finfo(np.float64).tiny)), dtype=DTYPE)

    tables = [log(result.emission(m.name).probabilities) for m in data.modalities]
    labels = torch.as_tensor(result.labels, dtype=torch.long)
    return float(log_joint_variable(labels, log(result.pi), tables, data, config))


def test_a_renumbered_result_answers_where_the_same_and_has_the_same_log_joint(house, fitted):
    L = len(fitted.pi)
    perm = np.random.default_rng(1).permutation(L)
    moved = renumbered(fitted, perm)
    assert fitted.marginals is not None and fitted.labels_final is not None
    assert np.array_equal(moved.labels, perm[fitted.labels])
    assert np.array_equal(moved.labels_final, perm[fitted.labels_final])
    for l in range(L):
        k = perm[l]
        assert moved.pi[k] == fitted.pi[l]
        for old, new in zip(fitted.emissions, moved.emissions, strict=True):
            assert np.array_equal(new.probabilities[k], old.probabilities[l]), old.name
        assert np.array_equal(moved.marginals[:, k], fitted.marginals[:, l])
        assert np.array_equal(moved.concept_totals[k], fitted.concept_totals[l])
        assert np.array_equal(moved.word_counts[k], fitted.word_counts[l])
    for word in fitted.vocabulary:
        before, after = fitted.where(word), moved.where(word)
        assert after.concept == perm[before.concept], word
        assert np.array_equal(after.region, before.region), word
        assert after.probability == pytest.approx(before.probability, rel=1e-12)
        assert after.runner_up == perm[before.runner_up]  # warnings name the new numbers
        assert len(after.warnings) == len(before.warnings)
        assert [w for w, *_ in after.shared_with] == [w for w, *_ in before.shared_with]
        for new, old in zip(after.shared_with, before.shared_with, strict=True):
            np.testing.assert_allclose(new[1:], old[1:], rtol=1e-12)  # to rounding
    listed = {perm[c["concept"]]: (c["cells"], c["top_words"]) for c in fitted.concepts()}
    assert {c["concept"]: (c["cells"], c["top_words"]) for c in moved.concepts()} == listed
    _, data = prepare_model_data(house, ORIGINAL)
    assert _log_joint(moved, data, ORIGINAL.model) == pytest.approx(
        _log_joint(fitted, data, ORIGINAL.model), rel=1e-12
    )
    assert np.array_equal(renumbered(fitted, np.arange(L)).labels, fitted.labels)
    with pytest.raises(ValueError, match="permutation"):
        renumbered(fitted, np.zeros(L, dtype=np.int64))


def test_an_update_keeps_the_saved_fits_numbers(house):
    """The default preset (coarse: merge and region moves, VI point estimate) on trials 0-1, then
    20 update sweeps with trial 2: without the matching, the update's sampler had moved the
    region of saved concept 3 (one of the six rooms) to another number."""
    settings = preset()
    kwargs = {k: v for k, v in preset_fit_kwargs("coarse").items() if k != "refine"}
    saved = fit_house(_trials(house, [0, 1]), settings, sweeps=100, seed=0, progress=False,
                      **kwargs)  # fmt: skip
    update_kwargs = {k: v for k, v in kwargs.items() if k != "init"}
    every = model_house(house, settings.data.cell_size)
    (result,) = fit_update(saved, every, settings, sweeps=20, progress=False, **update_kwargs)
    sizes = np.bincount(saved.labels)
    rooms = np.flatnonzero(sizes >= 0.05 * saved.labels.size)  # the saved fit's places
    assert len(rooms) >= 5
    for concept in rooms:
        now = np.bincount(result.labels[saved.labels == concept]).argmax()
        assert now == concept, f"saved concept {concept} is concept {now} after the update"
    assert np.mean(result.labels == saved.labels) > 0.8


def test_moved_numbers_lists_the_concepts_whose_number_changed():
    assert moved_numbers(np.arange(5)) == {}
    perm = np.array([1, 0, 2, 4, 3])  # concept 0 numbered 1, 1 numbered 0, 3 and 4 swapped
    assert moved_numbers(perm) == {"0": 1, "1": 0, "3": 4, "4": 3}
    perm = np.array([2, 0, 1])  # a cycle: new number 2 was concept 0, 0 was 1, 1 was 2
    assert moved_numbers(perm) == {"0": 1, "1": 2, "2": 0}


def test_an_update_records_the_renumbering_so_raw_samples_can_be_read(house, fitted, monkeypatch):
    """config.json did not say which concepts an update renumbered, so a user comparing the
    sampler's raw samples with the result could not undo it: update_of.renumbered now says."""
    raw: list[np.ndarray] = []
    L = len(fitted.pi)
    cycle = np.arange(L)
    cycle[[0, 1, 2]] = [1, 2, 0]  # the sampler's 0, 1, 2 numbered 1, 2, 0

    def matching(saved, new, num_concepts):
        raw.append(np.array(new))  # [N] the update's labels in the sampler's own numbers
        return cycle

    monkeypatch.setattr(online, "matching_permutation", matching)
    every = model_house(house, ORIGINAL.data.cell_size)
    (result,) = fit_update(fitted, every, ORIGINAL, sweeps=2, progress=False)
    record = result.inference["update_of"]["renumbered"]
    assert record == {"0": 2, "1": 0, "2": 1}
    undo = np.array([record.get(str(n), n) for n in range(L)])  # [L] result number -> raw
    assert np.array_equal(undo[result.labels], raw[0])
