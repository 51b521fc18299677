"""The posterior point estimate (spcopyro.results.point_estimate): losses from contingency tables
against brute force, label switching, the greedy search's guarantee, and the agreement map."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from spcopyro.results.point_estimate import (
    LOSSES,
    _best_moves,
    _joined_rows,
    _pairs,
    _prepare,
    _sample_tables,
    agreement_probability,
    compact,
    concept_labels,
    expected_loss,
    pair_loss,
    point_estimate,
)


def _binder_brute(first: np.ndarray, second: np.ndarray) -> float:
    """Ordered pairs i != j together in one labeling and apart in the other, over N^2."""
    n = len(first)
    wrong = sum(
        (first[i] == first[j]) != (second[i] == second[j])
        for i, j in itertools.permutations(range(n), 2)
    )
    return wrong / n**2


def _vi_brute(first: np.ndarray, second: np.ndarray) -> float:
    """H(first | second) + H(second | first) from the joint frequencies, in nats."""
    n = len(first)
    joint: dict[tuple[int, int], int] = {}
    for x, y in zip(first, second, strict=True):
        joint[(x, y)] = joint.get((x, y), 0) + 1
    total = 0.0
    for (x, y), count in joint.items():
        p = count / n
        px = np.mean(first == x)
        py = np.mean(second == y)
        total -= p * (math.log(p / py) + math.log(p / px))
    return total


@pytest.mark.parametrize("seed", range(5))
def test_losses_from_contingency_tables_equal_brute_force(seed):
    rng = np.random.default_rng(seed)
    first, second = rng.integers(0, 4, 9), rng.integers(0, 3, 9) * 7  # sparse label values
    assert pair_loss(first, second, "binder") == pytest.approx(_binder_brute(first, second))
    assert pair_loss(first, second, "vi") == pytest.approx(_vi_brute(first, second))
    assert pair_loss(first, first, "vi") == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("loss", LOSSES)
def test_label_switching_changes_nothing(loss):
    rng = np.random.default_rng(1)
    samples = rng.integers(0, 5, (6, 40))
    estimate = rng.integers(0, 3, 40)
    value = expected_loss(estimate, samples, loss)
    renamed = np.stack([rng.permutation(10)[s] for s in samples])  # each sample renamed its way
    assert expected_loss(rng.permutation(7)[estimate], renamed, loss) == pytest.approx(value)
    a = point_estimate(samples, loss)
    b = point_estimate(renamed, loss)
    assert a.expected_loss == pytest.approx(b.expected_loss)
    assert pair_loss(a.labels, b.labels, loss) == pytest.approx(0.0, abs=1e-12)


def _cell_moves(estimate, k, prepared, loss, no_new=False):
    """([N] each cell's best cluster, [N] its Delta (times Z)) as a sweep of the greedy search
    takes them: :func:`_best_moves` of every (cluster, column) pair from scratch, spread to the
    pairs' cells."""
    pairs = _pairs(estimate, prepared)
    tables = _sample_tables(pairs, k + 1, prepared).tables  # S x [k + 1, J_s]
    sizes = np.bincount(estimate, minlength=k + 1).astype(np.float64)  # [k + 1]
    joined = _joined_rows(tables, None, prepared, loss)  # [U, k + 1]
    best, gain = _best_moves(sizes, pairs, tables, joined, prepared, loss, no_new)  # [P], [P]
    return best[pairs.of_cell], gain[pairs.of_cell]


@pytest.mark.parametrize("no_new", [False, True])
@pytest.mark.parametrize("loss", LOSSES)
def test_one_cell_best_moves_match_the_recomputed_loss(loss, no_new):
    """Each cell's best move and its change of the expected loss are those of moving it alone,
    recomputed: a best of the k + 1 clusters (k, the spare one, left out if ``no_new``)."""
    rng = np.random.default_rng(2)
    samples = rng.integers(0, 4, (5, 30))
    estimate, k = compact(rng.integers(0, 3, 30))
    best, gain = _cell_moves(estimate, k, _prepare(samples, loss), loss, no_new)  # [N], [N]
    scale = 30**2 if loss == "binder" else 30
    base = expected_loss(estimate, samples, loss)
    for cell in range(30):
        changes = []  # [k + 1] the loss change of moving the cell to each cluster
        for target in range(k + 1):
            moved = estimate.copy()
            moved[cell] = target
            changes.append(expected_loss(moved, samples, loss) - base)
        if no_new:
            changes[k] = np.inf
        assert gain[cell] / scale == pytest.approx(min(changes), abs=1e-12)
        ties = np.flatnonzero(np.isclose(changes, min(changes), rtol=0, atol=1e-12))
        assert best[cell] in ties and (best[cell] != k or not no_new)


@pytest.mark.parametrize("loss", LOSSES)
def test_estimate_loss_is_no_larger_than_any_samples_and_finds_the_shared_partition(loss):
    rng = np.random.default_rng(3)
    truth = np.repeat(np.arange(4), 50)  # [200] four clusters of 50
    samples = []
    for _ in range(30):  # each sample: the truth, renamed, with 15% of cells relabelled at random
        sample = rng.permutation(6)[truth]
        noisy = rng.random(200) < 0.15
        sample[noisy] = rng.integers(0, 6, noisy.sum())
        samples.append(sample)
    samples = np.stack(samples)
    result = point_estimate(samples, loss)
    each = [expected_loss(s, samples, loss) for s in samples]
    assert result.expected_loss <= min(each) + 1e-12
    assert result.best_sample_loss == pytest.approx(min(each))
    assert result.expected_loss == pytest.approx(expected_loss(result.labels, samples, loss))
    # Every sample is noisy; the estimate removes the noise: it is the truth (up to names).
    assert pair_loss(result.labels, truth, loss) == pytest.approx(0.0, abs=1e-12)
    assert result.expected_loss < min(each)


def test_cluster_cap_is_kept():
    rng = np.random.default_rng(4)
    samples = rng.integers(0, 3, (10, 60))  # three labels, noise: more clusters would help
    assert compact(point_estimate(samples, "binder").labels)[1] > 3
    result = point_estimate(samples, "binder", max_clusters=3)
    assert compact(result.labels)[1] <= 3


def test_agreement_probability():
    estimate = np.array([0, 0, 0, 1, 1, 1])
    samples = np.array(
        [
            [5, 5, 5, 2, 2, 2],  # the estimate renamed: every cell agrees
            [1, 1, 1, 0, 0, 0],
            [3, 3, 4, 4, 4, 4],  # cell 2 moved to the other cluster
            [3, 3, 3, 4, 4, 9],  # cell 5 in a cluster of its own (matched with nothing)
        ]
    )
    agree = agreement_probability(estimate, samples)
    np.testing.assert_allclose(agree, [1, 1, 0.75, 1, 1, 0.75])


def test_concept_labels_follow_the_reference_state():
    estimate = np.array([0, 0, 1, 1, 2, 2])
    reference = np.array([7, 7, 3, 3, 3, 3])  # clusters 1 and 2 both overlap concept 3 most
    named = concept_labels(estimate, reference, num_concepts=10)
    assert named[0] == 7 and named[2] == 3  # the larger overlaps keep their concepts ...
    assert named[4] not in (3, 7) and len(set(named)) == 3  # ... the rest take unused ones
    with pytest.raises(ValueError, match="more than 2 concepts"):
        concept_labels(estimate, reference, num_concepts=2)


def test_bad_samples_are_refused():
    with pytest.raises(ValueError, match="loss"):
        point_estimate(np.zeros((2, 3), dtype=int), "rand")
    with pytest.raises(ValueError, match=r"\[S, N\]"):
        point_estimate(np.zeros(3, dtype=int), "vi")
    with pytest.raises(ValueError, match="non-negative integers"):
        point_estimate(np.full((2, 3), -1), "vi")


def test_fit_reports_the_estimate_with_its_agreement_map(tmp_path, capsys):
    from spcopyro.cli.main import main
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house
    from spcopyro.gibbs import GibbsOptions
    from spcopyro.results.result import SpCoResult
    from spcopyro.synthetic import HouseSpec, make_house

    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=2))
    settings = preset("original-code", gamma=3.0, num_concepts=8)
    common = dict(sweeps=30, progress=False, marginal_samples=10, seed=3)
    options = GibbsOptions(backend="torch", merge_moves=0.5)
    visited = fit_house(house, settings, options=options, **common)
    fit = fit_house(house, settings, options=options, point_estimate="vi", **common)
    assert visited.agreement is None and "point_estimate" not in visited.inference
    assert fit.inference["point_estimate"] == "vi"
    assert fit.inference["expected_loss"] <= fit.inference["best_sample_loss"] + 1e-12
    assert fit.agreement.shape == fit.labels.shape and 0 <= fit.agreement.min() <= 1
    assert fit.agreement.max() <= 1 and fit.labels.max() < 8
    assert fit.inference["parameters"] == "posterior mean given the point labels"  # its own
    saved = SpCoResult.load(fit.save(tmp_path / "saved"))
    np.testing.assert_array_equal(saved.agreement, fit.agreement)
    with pytest.raises(ValueError, match="marginal_samples > 0"):
        fit_house(house, settings, sweeps=4, progress=False, point_estimate="binder")
    with pytest.raises(ValueError, match="point estimate 'mode'"):
        fit_house(house, settings, sweeps=4, progress=False, point_estimate="mode")

    cli = ["--preset", "original-code", "--gamma", "3", "--concepts", "8", "--sweeps", "6"]
    out = tmp_path / "cli"
    assert main(["fit", "--out", str(out), *cli, "--point-estimate", "binder",
                 "--merge-moves", "0.5", "--backend", "torch"]) == 0  # fmt: skip
    assert (out / "agreement.png").is_file() and (out / "agreement.npy").is_file()
    assert "point estimate   binder (expected loss" in capsys.readouterr().out
    assert main(["fit", "--out", str(tmp_path / "x"), *cli, "--point-estimate", "vi",
                 "--marginal-samples", "0"]) == 2  # fmt: skip
    assert "--point-estimate vi is made over" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_the_point_estimate_shows_its_progress(capsys, monkeypatch):
    """Issue 22 item 8: with many concepts the point estimate ran for minutes without a word;
    now it has a progress bar (with tqdm's time estimate) when progress is on."""
    monkeypatch.delenv("CI", raising=False)
    rng = np.random.default_rng(0)
    samples = rng.integers(0, 5, size=(6, 40))
    point_estimate(samples, "vi", progress=True)
    said = capsys.readouterr().err
    assert "point estimate (variation of information)" in said  # 'vi' read as variational
    assert "point estimate (vi)" not in said
    point_estimate(samples, "binder", progress=True)
    assert "point estimate (Binder loss)" in capsys.readouterr().err
    point_estimate(samples, "vi", progress=False)
    assert "point estimate" not in capsys.readouterr().err


@pytest.mark.parametrize("count", [-1, 2.5, True])
def test_a_bad_marginal_samples_is_refused_by_name(count):
    """-1 kept every sweep's label map (thin 1) and 2.5 failed naming ``thin``."""
    from spcopyro.fit.house import fit_house
    from spcopyro.synthetic import HouseSpec, make_house

    house = make_house(seed=1, spec=HouseSpec(height=30, width=30, num_rooms=2, num_open_plan=0,
                                              min_room_size=10))  # fmt: skip
    for method in ("gibbs", "cavi"):
        with pytest.raises(ValueError, match=r"marginal_samples must be an integer >= 0, got"):
            fit_house(house, sweeps=4, method=method, progress=False, marginal_samples=count)


def _map_like_samples(seed: int, cells: int = 3000, clusters: int = 15, count: int = 20):
    """[count, cells] samples of intervals on a line (rooms along a corridor) whose edges shift
    by up to 40 cells from sample to sample, each renamed its way, with specks of 2-9 cells of
    other labels: the greedy search moves a few edge cells a sweep, for many sweeps."""
    rng = np.random.default_rng(seed)
    specks = 30
    edges = np.sort(rng.choice(np.arange(1, cells), clusters - 1, replace=False))
    samples = []
    for _ in range(count):
        moved = np.sort(np.clip(edges + rng.integers(-40, 41, edges.shape), 1, cells - 1))
        rooms = np.searchsorted(moved, np.arange(cells), "right")  # [cells]
        sample = rng.permutation(clusters + specks)[rooms]
        for _ in range(specks // 3):
            start = rng.integers(cells - 10)
            sample[start : start + rng.integers(2, 10)] = rng.integers(clusters + specks)
        samples.append(sample)
    return np.stack(samples)


def _label_start(labels, prepared, loss, pairs=None):
    """A search's start from any labels [N] (a sample's own: _sample_start, the same to the bit,
    test_point_estimate_tables), its pairs from ``pairs`` (default: the module's _pairs)."""
    from spcopyro.results.point_estimate import _expected, _pairs, _sample_tables, _Start

    estimate, k = compact(labels)
    found = (pairs or _pairs)(estimate, prepared)
    tables = _sample_tables(found, k + 1, prepared)
    return _Start(estimate, k, found, tables, _expected(estimate, k, prepared, loss, tables))


def _greedy_from_scratch(start, prepared, loss, max_clusters):
    """The greedy search as written before 2026-12-05: every sweep's changes and every halving
    trial's exact loss computed from scratch."""
    from spcopyro.results.point_estimate import MAX_SWEEPS, RELATIVE_TOLERANCE, _expected

    estimate, k = compact(start)
    value = _expected(estimate, k, prepared, loss)
    for _ in range(MAX_SWEEPS):
        before = value
        target, gain = _cell_moves(estimate, k, prepared, loss,
                                   max_clusters is not None and k >= max_clusters)  # fmt: skip
        movers = np.flatnonzero(gain < -1e-9)
        if movers.size == 0:
            break
        movers = movers[np.argsort(gain[movers])]
        improved = False
        while movers.size:
            trial = estimate.copy()
            trial[movers] = target[movers]
            codes, kk = compact(trial)
            trial_value = _expected(codes, kk, prepared, loss)
            if trial_value < value - 1e-12:
                estimate, k, value, improved = codes, kk, trial_value, True
                break
            movers = movers[: movers.size // 2]
        if not improved or before - value < RELATIVE_TOLERANCE * value:
            break
    return estimate, value


@pytest.mark.parametrize("loss", LOSSES)
@pytest.mark.parametrize(("seed", "cap"), [(0, None), (1, None), (2, 17), (3, 12)])
def test_the_incremental_search_is_the_search_from_scratch_to_the_bit(loss, seed, cap, monkeypatch):
    """The search keeps the join terms of clusters a sweep left alone and rejects clearly worse
    halving trials from their changed table entries: the same estimate and the same loss, bit
    for bit, as recomputing everything (Binder's spare cluster has join terms S, not 0: a
    version that kept it at 0 found other estimates). Its pairs' best moves go in chunks of
    CHUNK pairs (here also 37, so that a map has many)."""
    import spcopyro.results.point_estimate as module
    from spcopyro.results.point_estimate import _greedy, _sample_start

    if seed % 2:
        monkeypatch.setattr(module, "CHUNK", 37)
    prepared = _prepare(_map_like_samples(seed, cells=1000 + 500 * seed), loss)
    for s in range(3):
        ours, our_value = _greedy(_sample_start(s, prepared, loss), prepared, loss, cap)
        theirs, their_value = _greedy_from_scratch(prepared.codes[s], prepared, loss, cap)
        assert np.array_equal(ours, theirs)
        assert our_value == their_value


def test_the_search_recomputes_only_what_a_sweep_changed(monkeypatch):
    """Issue 25: on a 64,319-cell map the three greedy searches took 89 s and the 50 samples'
    expected losses 3 s: every sweep recomputed the join terms of every cluster against every
    sample and every halving trial's expected loss from scratch, though after the first sweep
    a sweep moves a few cells between a few clusters. Now a sweep recomputes the terms of the
    clusters it changed, and only a trial that may be better gets its exact loss."""
    import spcopyro.results.point_estimate as module

    prepared = _prepare(_map_like_samples(3, cells=4000, clusters=30), "vi")
    exact, rows = [0], []
    expected, joined_rows = module._expected, module._joined_rows

    def counting_expected(*args, **kwargs):
        exact[0] += 1
        return expected(*args, **kwargs)

    def counting_rows(tables, which, *args):
        rows.append(tables[0].shape[0] if which is None else which.shape[0])
        return joined_rows(tables, which, *args)

    monkeypatch.setattr(module, "_expected", counting_expected)
    monkeypatch.setattr(module, "_joined_rows", counting_rows)
    for s in range(3):
        exact[0], rows[:] = 0, []
        module._greedy(module._sample_start(s, prepared, "vi"), prepared, "vi", None)
        sweeps = len(rows)
        assert sweeps > 5  # the search ran on after its first sweeps
        assert exact[0] <= sweeps + 1  # the start's loss, then about one per sweep
        # all clusters once, then the changed ones: on average under half of them
        assert sum(rows[1:]) < 0.5 * rows[0] * (sweeps - 1), rows


def test_the_progress_bar_counts_each_search_in_sweeps():
    """A search adds MAX_SWEEPS x SWEEP_STEPS to the bar whether it stops early or not, so
    the bar's total (samples, then searches in their sweeps) is reached at the end."""
    from spcopyro.results.point_estimate import MAX_SWEEPS, SWEEP_STEPS, _greedy, _sample_start

    class Bar:
        n = 0

        def update(self, steps=1):
            self.n += steps

    prepared = _prepare(_map_like_samples(6), "vi")
    for s in range(2):
        bar = Bar()
        _greedy(_sample_start(s, prepared, "vi"), prepared, "vi", None, bar)
        assert bar.n == MAX_SWEEPS * SWEEP_STEPS


def test_moved_tables_are_the_tables_of_the_moved_estimate():
    """The accepted trial's tables come from the current ones (rows kept, a spare row, the
    movers' counts moved), bit for bit those counted from scratch, also when a move empties a
    cluster (its row dropped; a version that subtracted from row -1 wrote into the sample
    before)."""
    from spcopyro.results.point_estimate import _moved_tables, _pairs, _sample_tables

    prepared = _prepare(_map_like_samples(7, cells=800), "vi")
    estimate, k = compact(prepared.codes[0])
    tables = _sample_tables(_pairs(estimate, prepared), k + 1, prepared)
    emptied = np.flatnonzero(estimate == estimate[0])  # all of cluster estimate[0]
    movers = np.unique(np.concatenate([emptied, np.arange(100, 140)]))
    target = estimate.copy()
    target[emptied] = k  # into the spare cluster
    target[100:140] = (estimate[100:140] + 1) % k
    trial = estimate.copy()
    trial[movers] = target[movers]
    codes, kk = compact(trial)
    kept = np.flatnonzero(np.bincount(trial, minlength=k + 1))
    assert kk == k  # one emptied, one opened
    moved = _moved_tables(tables, kept, movers, estimate, target, prepared)
    again = _sample_tables(_pairs(codes, prepared), kk + 1, prepared)
    assert np.array_equal(moved.offsets, again.offsets)
    assert np.array_equal(moved.flat, again.flat)
