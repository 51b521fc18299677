"""Mean-field CAVI (spcopyro.guides): the ELBO's monotonicity, the compiled sparse backend
against the dense torch reference, coordinate optimality of each step, the analytic ELBO against
a Monte-Carlo estimate from the Pyro model's density, thinning and quality on a synthetic house."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem
from statistical_checks import model_log_density
from test_modalities import objects_config, with_objects

from spcopyro.config import preset
from spcopyro.fit.house import prepare_model_data
from spcopyro.gibbs.state import GibbsState
from spcopyro.guides.cavi import update_globals, update_labels
from spcopyro.guides.cavi_method import CAVIInference
from spcopyro.guides.elbo import elbo
from spcopyro.guides.factors import GlobalFactors, update_factors
from spcopyro.guides.lbp_method import LBPOptions, run_lbp
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.run import initial_q, run_variational
from spcopyro.likelihood import concept_statistics
from spcopyro.metrics.truth import adjusted_rand_index
from spcopyro.model import DTYPE
from spcopyro.synthetic import make_house

try:  # the compiled backend is the fast extra's; the torch reference's tests run without it
    from spcopyro.guides import numba_cavi
except ImportError:
    numba_cavi = None
needs_numba = pytest.mark.skipif(numba_cavi is None, reason="numba is not installed (.[fast])")

EXACT = dict(support=0, threshold=0.0, active_tolerance=0.0)  # the numba backend without truncation


def problem(variant: str, seed: int = 0):
    """(data, config, pi_family) of one prior / modality variant on the 5 x 6 test map."""
    grid, data = random_problem(seed, num_observed=8)
    family = "dirichlet"
    cfg = config(num_concepts=4, gamma=1.2)
    if variant == "dirichlet":
        cfg = config(num_concepts=4, gamma=1.2, prior="dirichlet", alpha=2.0)
    elif variant == "stick-breaking":
        family = "stick-breaking"
    elif variant == "no-images":
        cfg = config(num_concepts=4, gamma=1.2, use_images=False)
    elif variant == "no-words":
        cfg = config(num_concepts=4, gamma=1.2, use_words=False)
    elif variant == "objects":
        data = with_objects(grid, data, seed)
        cfg = objects_config(num_concepts=4, gamma=1.2)
    return data, cfg, family


VARIANTS = ["dp", "dirichlet", "stick-breaking", "no-images", "no-words", "objects"]
BACKENDS = {
    "torch": dict(backend="torch"),
    "numba": dict(backend="numba", **EXACT),
    "numba-top2": dict(backend="numba", support=2, threshold=0.0),
    "numba-active": dict(backend="numba", support=0, threshold=0.0, active_tolerance=0.05),
}
PLAIN = dict(anneal_iterations=0, tolerance=0.0)  # exact coordinate ascent, every iteration


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize(
    "backend", [pytest.param(b, marks=() if b == "torch" else needs_numba) for b in BACKENDS]
)
def test_elbo_never_decreases(variant, backend):
    """Without annealing or damping every iteration is coordinate ascent: the ELBO rises (also
    for top-K truncation alone, the optimum over "q_i with at most K concepts", and with an
    active set, whose skipped cells keep their value)."""
    data, cfg, family = problem(variant)
    for seed in range(2):
        for init in ("one-hot", "soft"):
            options = VariationalOptions(pi_family=family, init=init, **BACKENDS[backend], **PLAIN)
            q = initial_q(data, cfg, torch.Generator().manual_seed(seed), init=init)
            run = run_variational(data, cfg, 12, options=options, q=q)
            steps = np.diff(run.objective)
            assert steps.min() > -1e-9 * np.abs(run.objective).max(), (seed, init, steps.min())


@needs_numba
@pytest.mark.parametrize("variant", VARIANTS)
def test_numba_equals_the_torch_reference_without_truncation(variant):
    data, cfg, family = problem(variant, seed=1)
    q0 = initial_q(data, cfg, torch.Generator().manual_seed(3), init="soft")
    runs = {}
    for backend in ("torch", "numba"):
        options = VariationalOptions(
            pi_family=family, **BACKENDS[backend], anneal_iterations=3, tolerance=0.0
        )
        runs[backend] = run_variational(data, cfg, 12, options=options, q=q0.clone())
    np.testing.assert_allclose(runs["numba"].objective, runs["torch"].objective, rtol=1e-10)
    torch.testing.assert_close(runs["numba"].q, runs["torch"].q, atol=1e-10, rtol=0)


@needs_numba
@pytest.mark.parametrize("damping", [0.0, 0.4])
def test_numba_damping_equals_the_reference_without_truncation(damping):
    data, cfg, _ = problem("dp", seed=2)
    q0 = initial_q(data, cfg, torch.Generator().manual_seed(0), init="soft")
    factors = update_globals(q0, data, cfg)
    field = numba_cavi.SparseMeanField(q0, data, cfg, damping=damping, **EXACT)
    field.update(factors, 1.5)
    expected = update_labels(q0.clone(), factors, data, cfg, 1.5, damping)
    torch.testing.assert_close(field.dense(), expected, atol=1e-12, rtol=0)


@needs_numba
def test_truncation_loss_stays_within_its_bound():
    """With a mass threshold an iteration may lower the ELBO, by at most the reported bound
    sum_i -log(kept fraction_i); the truncated q is a valid distribution with <= K entries."""
    data, cfg, _ = problem("dp", seed=3)
    cfg = dataclasses.replace(cfg, num_concepts=6)
    q = initial_q(data, cfg, torch.Generator().manual_seed(1), init="soft")
    field = numba_cavi.SparseMeanField(q, data, cfg, support=3, threshold=0.05)
    factors = update_factors(field.statistics(), data, cfg)
    before = field.elbo(factors)
    lost_any = False
    for _ in range(10):
        field.update(factors, cfg.gamma)
        after_labels = field.elbo(factors)
        assert after_labels >= before - field.truncation_bound - 1e-9
        lost_any |= field.truncation_bound > 0
        factors = update_factors(field.statistics(), data, cfg)
        before = field.elbo(factors)
        assert before >= after_labels - 1e-9  # the globals' update is exact
    assert lost_any
    dense = field.dense()
    assert ((dense > 0).sum(1) <= 3).all()
    torch.testing.assert_close(dense.sum(1), torch.ones(data.num_free, dtype=DTYPE))


@needs_numba
def test_numba_statistics_and_elbo_equal_the_dense_formulas():
    """Statistics, ELBO, labels and concepts in use read from the sparse state equal the dense
    reference's functions of the same q."""
    data, cfg, _ = problem("objects", seed=4)
    q = initial_q(data, cfg, torch.Generator().manual_seed(2), init="soft")
    field = numba_cavi.SparseMeanField(q, data, cfg, support=2, threshold=0.0)
    factors = update_factors(field.statistics(), data, cfg)
    field.update(factors, 0.7)
    dense = field.dense()
    expected = concept_statistics(dense, data, cfg)
    got = field.statistics()
    torch.testing.assert_close(got.cells, expected.cells)
    for a, b in zip(got.counts, expected.counts, strict=True):
        torch.testing.assert_close(a, b)
    assert field.elbo(factors) == pytest.approx(float(elbo(dense, factors, data, cfg)), rel=1e-12)
    assert torch.equal(field.labels(), dense.argmax(-1))
    assert field.num_used() == int(torch.unique(dense.argmax(-1)).numel())


def _perturbed(q: torch.Tensor, cell: int, generator: torch.Generator, size: float = 0.05):
    other = torch.rand(q.shape[1], generator=generator, dtype=DTYPE)
    changed = q.clone()
    changed[cell] = (1 - size) * q[cell] + size * other / other.sum()
    return changed


@pytest.mark.parametrize("variant", ["dp", "objects"])
def test_each_label_block_update_is_a_coordinate_optimum(variant):
    """After a block's update (globals fixed), moving any of its cells' q lowers the ELBO; after
    the globals' update, moving their concentrations lowers it too."""
    data, cfg, _ = problem(variant, seed=5)
    generator = torch.Generator().manual_seed(0)
    q = initial_q(data, cfg, generator, init="soft")
    factors = update_globals(q, data, cfg)
    for _ in range(3):
        q = update_labels(q, factors, data, cfg)
        factors = update_globals(q, data, cfg)
    for block in range(len(data.colours)):
        # update only this block: its cells are then at their optimum given everything else
        cells = data.colours[block]
        single = data._replace(colours=(cells,))
        q_block = update_labels(q.clone(), factors, single, cfg)
        best = float(elbo(q_block, factors, data, cfg))
        for cell in cells.tolist():
            assert float(elbo(_perturbed(q_block, cell, generator), factors, data, cfg)) < best
    best = float(elbo(q, factors, data, cfg))
    for scale in (0.9, 1.1):
        moved = GlobalFactors(factors.pi * scale, tuple(e * scale for e in factors.emissions))
        assert float(elbo(q, moved, data, cfg)) < best


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_block_update_is_a_stationary_point_of_the_elbo(variant):
    """The first-order conditions, read off the ELBO's gradient by autograd (no second backend
    needed): after a colour block's label update, with everything else fixed, the gradient of
    the ELBO with respect to each of its cells' q_i is the same for every concept (the Lagrange
    condition on the simplex, all q_i(l) > 0); after the globals' update, the gradient with
    respect to every concentration vanishes. A wrong term in either update (say the digamma
    expectation E[log pi_l] replaced by log E[pi_l]) leaves a gradient that these catch."""
    data, cfg, family = problem(variant, seed=11)
    q = initial_q(data, cfg, torch.Generator().manual_seed(1), init="soft")
    factors = update_globals(q, data, cfg, family)
    for cells in data.colours:
        q = update_labels(q, factors, data._replace(colours=(cells,)), cfg)
        leaf = q.clone().requires_grad_(True)
        (gradient,) = torch.autograd.grad(elbo(leaf, factors, data, cfg), leaf)  # [N, L]
        block = gradient[cells]  # [n, L]
        spread = block.max(-1).values - block.min(-1).values  # [n]: 0 at a stationary point
        assert float(spread.max()) < 1e-9 * (1 + float(block.abs().max())), float(spread.max())
    factors = update_globals(q, data, cfg, family)
    leaves = [factors.pi.clone().requires_grad_(True)]
    leaves += [table.clone().requires_grad_(True) for table in factors.emissions]
    moved = GlobalFactors(leaves[0], tuple(leaves[1:]), family)
    for name, gradient in zip(["pi", *range(len(leaves) - 1)],
                              torch.autograd.grad(elbo(q, moved, data, cfg), leaves),
                              strict=True):  # fmt: skip
        assert float(gradient.abs().max()) < 1e-8, (name, float(gradient.abs().max()))
    not_updated = update_labels(q.clone(), factors, data, cfg)  # a control: the test can fail
    leaf = (0.5 * (q + not_updated)).requires_grad_(True)
    (gradient,) = torch.autograd.grad(elbo(leaf, factors, data, cfg), leaf)
    assert float((gradient.max(-1).values - gradient.min(-1).values).max()) > 1e-3


def test_update_factors_is_the_conjugate_update():
    """q(pi) = Dir(a_pi + sum_i q_i), q(phi_ml) = Dir(a_m + sum_obs q_i(l) x_i) (eqs. 14-17 in
    expectation), written out cell by cell; the stick-breaking Betas likewise."""
    data, cfg, _ = problem("objects", seed=6)
    q = initial_q(data, cfg, torch.Generator().manual_seed(0), init="soft")
    L = cfg.num_concepts
    factors = update_factors(concept_statistics(q, data, cfg), data, cfg)
    pi = torch.full((L,), cfg.pi_concentration, dtype=DTYPE)
    for i in range(data.num_free):
        pi = pi + q[i]
    torch.testing.assert_close(factors.pi, pi)
    for modality, table in zip(data.modalities, factors.emissions, strict=True):
        expected = torch.full_like(table, cfg.concentration(modality.name))
        for row, cell in enumerate(data.obs_cells.tolist()):
            expected += q[cell][:, None] * modality.counts[row][None, :]
        torch.testing.assert_close(table, expected)
    sticks = update_factors(concept_statistics(q, data, cfg), data, cfg, "stick-breaking").pi
    sizes = q.sum(0)
    for l in range(L - 1):
        assert float(sticks[l, 0]) == pytest.approx(1 + float(sizes[l]))
        assert float(sticks[l, 1]) == pytest.approx(cfg.alpha + float(sizes[l + 1 :].sum()))


@pytest.mark.parametrize("variant", ["dp", "dirichlet", "objects", "no-words"])
def test_analytic_elbo_equals_a_monte_carlo_estimate_from_the_pyro_model(variant):
    """ELBO = E_q[log p*(C, x, pi, phi)] - E_q[log q]: the first term estimated with the log
    density of the Pyro model (``spcomapping_model``) at draws from q, within 4 standard
    errors. This ties the analytic ELBO (and so CAVI's objective) to model.py."""
    data, cfg, _ = problem(variant, seed=7)
    cfg = dataclasses.replace(cfg, num_concepts=3)
    generator = torch.Generator().manual_seed(0)
    q = initial_q(data, cfg, generator, init="soft")
    options = VariationalOptions(backend="torch", **PLAIN)
    run = run_variational(data, cfg, 3, options=options, q=q)
    q, factors = run.q, run.factors
    q = 0.8 * q + 0.2 / cfg.num_concepts  # keep every label probable: a lower variance
    factors = update_globals(q, data, cfg)
    torch.manual_seed(0)
    draws = []
    for _ in range(250):
        pi = torch.distributions.Dirichlet(factors.pi).sample()
        tables = [torch.distributions.Dirichlet(a).sample() for a in factors.emissions]
        labels = torch.multinomial(q, 1).squeeze(-1)
        log_q = torch.distributions.Dirichlet(factors.pi).log_prob(pi)
        log_q = log_q + sum(
            torch.distributions.Dirichlet(a).log_prob(t).sum()
            for a, t in zip(factors.emissions, tables, strict=True)
        )
        log_q = log_q + q.log().gather(1, labels[:, None]).sum()
        state = GibbsState(labels, pi.log(), tuple(t.log() for t in tables))
        draws.append(float(model_log_density(state, data, cfg) - log_q))
    draws = np.asarray(draws)
    error = draws.std(ddof=1) / np.sqrt(len(draws))
    analytic = float(elbo(q, factors, data, cfg))
    assert abs(draws.mean() - analytic) < 4 * error, (draws.mean(), analytic, error)


def test_thin_keeps_argmax_labels():
    data, cfg, _ = problem("dp")
    generator = torch.Generator().manual_seed(0)
    for backend in ("torch", "numba") if numba_cavi is not None else ("torch",):
        exact = {} if backend == "torch" else EXACT
        options = VariationalOptions(backend=backend, **exact, **PLAIN)
        out = CAVIInference().run(
            data, cfg, iterations=10, generator=generator, options=options, thin=3
        )
        assert out.label_samples.dtype == np.int16
        assert out.label_samples.shape == (3, data.num_free)
        np.testing.assert_array_equal(out.sample_iterations, [2, 5, 8])
    q = initial_q(data, cfg, generator)
    options = VariationalOptions(backend="torch", **PLAIN)
    run = run_variational(data, cfg, 4, options=options, q=q, thin=4)
    np.testing.assert_array_equal(run.label_samples[-1], run.labels.numpy())
    none = run_variational(data, cfg, 2, q=initial_q(data, cfg, generator))
    assert none.label_samples is None and none.sample_iterations is None
    with pytest.raises(ValueError, match="thin"):
        run_variational(data, cfg, 2, q=initial_q(data, cfg, generator), thin=-1)


def test_the_torch_backend_says_it_ignores_the_numba_only_options(caplog):
    data, cfg, _ = problem("dp")
    q = initial_q(data, cfg, torch.Generator().manual_seed(0))
    run_variational(data, cfg, 1, options=VariationalOptions(backend="torch"), q=q)
    assert "ignores" not in caplog.text  # defaults: nothing to say
    options = VariationalOptions(backend="torch", support=5, threshold=0.0)
    run_variational(data, cfg, 1, options=options, q=q)
    assert "CAVI runs on the torch backend, which ignores support=5, threshold=0.0" in caplog.text
    caplog.clear()
    lbp = LBPOptions(backend="torch", active_tolerance=0.0)
    run_lbp(data, cfg, 1, q=q, options=lbp, progress=False)
    assert "loopy BP runs on the torch backend, which ignores active_tolerance=0.0" in caplog.text


def test_bad_options_and_inputs_are_refused():
    with pytest.raises(ValueError, match="support"):
        VariationalOptions(support=-1)
    with pytest.raises(ValueError, match="threshold"):
        VariationalOptions(threshold=1.0)
    with pytest.raises(ValueError, match="init"):
        VariationalOptions(init="zeros")
    with pytest.raises(ValueError, match="active_tolerance"):
        VariationalOptions(active_tolerance=-1e-3)
    with pytest.raises(ValueError, match="active_tolerance"):
        VariationalOptions(active_tolerance=float("inf"))
    data, cfg, _ = problem("dp")
    if numba_cavi is not None:
        with pytest.raises(ValueError, match=r"q must be \["):
            numba_cavi.SparseMeanField(torch.ones(3, cfg.num_concepts), data, cfg)


@needs_numba
@pytest.mark.parametrize(
    "argument, message",
    [
        ("support", r"support must be an integer >= 0 \(0: all L concepts\)"),
        ("threshold", r"threshold must be a number in \[0, 1\)"),
        ("active_tolerance", "active_tolerance must be a finite number >= 0"),
    ],
)
@pytest.mark.parametrize("flag", [True, False])
def test_the_sparse_mean_field_refuses_a_bool_for_a_count_or_a_number(argument, message, flag):
    """SparseMeanField (built by a library caller, not only from checked VariationalOptions)
    compared only bounds: ``support=True`` was 1 concept, ``threshold=True`` failed only the
    bound (False passed as 0), ``active_tolerance=True`` was 1."""
    data, cfg, _ = problem("dp")
    q = initial_q(data, cfg, torch.Generator().manual_seed(0))
    with pytest.raises(ValueError, match=f"{message}, got {flag!r}"):
        numba_cavi.SparseMeanField(q, data, cfg, **{argument: flag})


@needs_numba
def test_defaults_reach_a_high_ari_on_an_easy_synthetic_house():
    """The default options (numba backend, exact but for masses < 1e-4) recover the rooms of
    a synthetic house whose data have a say (the released code's values, gamma 3; ARI 0.93
    when written). Under ``paper-dp`` mean field does not (ARI 0.23; docs/variational.md)."""
    house = make_house(seed=0)
    settings = preset("original-code", gamma=3.0)
    _, data = prepare_model_data(house, settings)
    out = CAVIInference().run(
        data, settings.model, iterations=100, generator=torch.Generator().manual_seed(0)
    )
    truth = house.truth[house.grid.free]
    assert adjusted_rand_index(out.labels, truth) > 0.8


def _truncate(rows: torch.Tensor, support: int, threshold: float):
    """(rows cut to their top ``support`` entries, those below ``threshold`` dropped (the largest
    kept), renormalised; sum over rows of -log(kept mass))."""
    top = rows.topk(support, dim=1)
    kept = torch.zeros_like(rows).scatter_(1, top.indices, top.values)
    largest = kept.argmax(1)
    keep = kept >= threshold
    keep[torch.arange(rows.shape[0]), largest] = True
    kept = torch.where(keep, kept, 0.0)
    mass = kept.sum(1)
    return kept / mass[:, None], float(-mass.log().sum())


@needs_numba
@pytest.mark.parametrize("support, threshold", [(2, 0.0), (3, 0.05), (6, 0.1)])
def test_truncated_update_is_the_exact_update_cut_block_by_block(support, threshold):
    """One sparse pass equals, block after block, the dense reference's update of that block
    (given the earlier blocks' truncated values) cut to the top K entries above the threshold;
    its truncation bound is the mass it dropped, sum_i -log(kept_i)."""
    data, cfg, _ = problem("objects", seed=8)
    cfg = dataclasses.replace(cfg, num_concepts=6)
    q = initial_q(data, cfg, torch.Generator().manual_seed(4), init="soft")
    field = numba_cavi.SparseMeanField(q, data, cfg, support=support, threshold=threshold)
    factors = update_factors(field.statistics(), data, cfg)
    field.update(factors, cfg.gamma)
    factors = update_factors(field.statistics(), data, cfg)
    state = field.dense()
    field.update(factors, 1.7)
    got = field.dense()
    lost = 0.0
    for cells in data.colours:
        exact = update_labels(state.clone(), factors, data._replace(colours=(cells,)), cfg, 1.7)
        expected, dropped = _truncate(exact[cells], support, threshold)
        torch.testing.assert_close(got[cells], expected, atol=1e-12, rtol=0)
        state[cells] = got[cells]
        lost += dropped
    assert field.truncation_bound == pytest.approx(lost, rel=1e-9, abs=1e-12)


def _active_field(tolerance: float, seed: int = 9):
    data, cfg, _ = problem("objects", seed=seed)
    q = initial_q(data, cfg, torch.Generator().manual_seed(seed), init="soft")
    field = numba_cavi.SparseMeanField(q, data, cfg, active_tolerance=tolerance, **EXACT_CUT)
    return data, cfg, field


EXACT_CUT = dict(support=0, threshold=0.0)


@needs_numba
@pytest.mark.parametrize("tolerance", [0.02, 0.2])
def test_active_set_keeps_each_cell_within_its_bound_of_the_exact_update(tolerance):
    """With an active set (no truncation), every cell after a pass is within a factor
    exp(+-2 tolerance) of the exact update of its block (given the earlier blocks' values and
    the current globals): a skipped cell's logits moved by at most the tolerance since its
    last update. Some cells are skipped, and some skipped ones differ from the exact update
    (so the bound is what is tested, not equality)."""
    data, cfg, field = _active_field(tolerance)
    factors = update_factors(field.statistics(), data, cfg)
    skipped_any = differs = False
    for _ in range(25):
        state = field.dense()
        field.update(factors, cfg.gamma)
        got = field.dense()
        skipped_any |= field.updated_cells < data.num_free
        for cells in data.colours:
            one = data._replace(colours=(cells,))
            exact = update_labels(state.clone(), factors, one, cfg, cfg.gamma)[cells]
            gap = (got[cells].log() - exact.log()).abs().max()
            assert gap <= 2 * tolerance + 1e-9, (gap, tolerance)
            differs |= bool(gap > 1e-9)
            state[cells] = got[cells]
        factors = update_factors(field.statistics(), data, cfg)
    assert skipped_any and differs


@needs_numba
def test_active_set_tolerance_zero_skips_only_unchanged_cells():
    """Tolerance 0 skips a cell only when nothing it reads changed: with the globals and the
    coupling held fixed, a second pass after convergence recomputes nothing and changes
    nothing; the first pass after a change of the coupling recomputes every cell."""
    data, cfg, field = _active_field(0.0)
    factors = update_factors(field.statistics(), data, cfg)
    for _ in range(200):
        field.update(factors, cfg.gamma)
    before = field.dense()
    field.update(factors, cfg.gamma)
    assert field.updated_cells == 0
    torch.testing.assert_close(field.dense(), before, atol=0, rtol=0)
    field.update(factors, 0.5 * cfg.gamma)
    assert field.updated_cells == data.num_free


@needs_numba
@pytest.mark.parametrize("damping", [0.0, 0.3])
def test_running_sums_equal_a_recount_and_the_dense_formulas(damping):
    """The statistics, entropy and pairs' term kept up to date cell by cell (also while the
    active set skips cells) equal their recomputation from scratch and the dense reference's
    functions of the same q, after many updates."""
    data, cfg, _ = problem("objects", seed=10)
    q = initial_q(data, cfg, torch.Generator().manual_seed(5), init="soft")
    field = numba_cavi.SparseMeanField(
        q, data, cfg, support=3, threshold=0.01, damping=damping, active_tolerance=0.05
    )
    factors = update_factors(field.statistics(), data, cfg)
    for _ in range(numba_cavi.RECOUNT_EVERY - 3):  # no recount in between
        field.update(factors, cfg.gamma)
        factors = update_factors(field.statistics(), data, cfg)
    running = (field.sizes.copy(), field._argmax_cells.copy(), field.totals.copy())
    dense = field.dense()
    assert field.elbo(factors) == pytest.approx(float(elbo(dense, factors, data, cfg)), rel=1e-12)
    field._recount()
    np.testing.assert_allclose(running[0], field.sizes, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(running[1], field._argmax_cells)
    np.testing.assert_allclose(running[2], field.totals, rtol=1e-12, atol=1e-10)
    torch.testing.assert_close(field.statistics().cells, concept_statistics(dense, data, cfg).cells)


def test_dirichlet_kl_equals_torch_distributions():
    """The closed form over the entries that differ equals torch's KL, with and without
    entries equal to the prior (rows equal to it, single entries, broadcast prior)."""
    from torch.distributions import Dirichlet, kl_divergence

    from spcopyro.guides.factors import dirichlet_kl

    generator = torch.Generator().manual_seed(0)
    a = torch.rand(6, 5, generator=generator, dtype=DTYPE) * 30 + 0.01
    b = torch.rand(5, generator=generator, dtype=DTYPE) + 0.1
    a[1] = b
    a[2, 3] = b[3]
    expected = kl_divergence(Dirichlet(a), Dirichlet(b.expand_as(a))).sum()
    assert float(dirichlet_kl(a, b)) == pytest.approx(float(expected), rel=1e-12)
    assert float(dirichlet_kl(a[0], b)) == pytest.approx(
        float(kl_divergence(Dirichlet(a[0]), Dirichlet(b))), rel=1e-12
    )
    assert float(dirichlet_kl(b.expand(3, 5), b)) == 0.0


def test_a_degenerate_stick_breaking_prior_is_warned_about_once(caplog):
    """pi_family='stick-breaking' at the presets' weak-limit alpha (1e7) gave one concept over
    the whole map without a word on why: the truncation's last stick holds ~all of pi's mass."""
    from spcopyro.config import SpCoConfig
    from spcopyro.guides import factors

    assert factors.stick_breaking_warning(SpCoConfig(alpha=1.0)) is None
    assert "99.999% of pi's mass on the last concept" in factors.stick_breaking_warning(
        SpCoConfig(alpha=1e7)
    )
    # 99.71% was printed "100%": near 100 the share takes the digits it needs to stay below.
    said = factors.stick_breaking_warning(SpCoConfig(alpha=1e4, num_concepts=30))
    assert "puts 99.7% of pi's mass" in said
    said = factors.stick_breaking_warning(SpCoConfig(alpha=1e8, num_concepts=2))
    assert "puts more than 99.9999% of pi's mass" in said
    said = factors.stick_breaking_warning(SpCoConfig(alpha=1e3, num_concepts=30))
    assert "puts 97% of pi's mass" in said
    cfg = SpCoConfig(alpha=123456789.0, num_concepts=7)
    _, data = random_problem(seed=0)
    for _ in range(3):
        factors.prior_factors(data, cfg, "stick-breaking")
    said = [r for r in caplog.records if "pi_family='stick-breaking'" in r.getMessage()]
    assert len(said) == 1


@pytest.mark.parametrize("backend", ["torch", pytest.param("numba", marks=needs_numba)])
def test_stick_breaking_with_one_concept_is_the_dirichlet_fit(backend, caplog):
    """L = 1 has no stick (pi = 1 under either family): CAVI raised a bare RuntimeError "cannot
    reshape tensor of 0 elements" from torch's Beta over the empty [0, 2] sticks, and the
    degenerate-prior warning told the user to lower alpha, which L = 1 ignores."""
    _, data = random_problem(seed=0, num_observed=8)
    cfg = config(num_concepts=1, alpha=1e7)
    elbos = {}
    for family in ("dirichlet", "stick-breaking"):
        options = VariationalOptions(backend=backend, pi_family=family, **PLAIN)
        q = initial_q(data, cfg, torch.Generator().manual_seed(0))
        run = run_variational(data, cfg, 5, options=options, q=q, progress=False)
        elbos[family] = float(run.objective[-1])
    assert elbos["stick-breaking"] == pytest.approx(elbos["dirichlet"], rel=1e-12)
    assert not [r for r in caplog.records if "pi_family='stick-breaking'" in r.getMessage()]


def test_soft_start_with_start_labels_is_refused():
    """``init="soft"`` asks for a random q; start labels would replace it. The library refused
    nothing before: the labels won and soft was ignored silently."""
    data, cfg, _ = problem("dp")
    labels = torch.zeros(data.num_free, dtype=torch.long)
    with pytest.raises(ValueError, match="init='soft'.*init_labels"):
        initial_q(data, cfg, torch.Generator().manual_seed(0), labels, init="soft")
    with pytest.raises(ValueError, match="init='soft'"):
        CAVIInference().run(
            data, cfg, iterations=2, generator=torch.Generator().manual_seed(0),
            options=VariationalOptions(backend="torch", init="soft"), init_labels=labels,
        )  # fmt: skip
    q = initial_q(data, cfg, torch.Generator().manual_seed(0), labels)  # one-hot: still fine
    assert torch.equal(q.argmax(-1), labels)


def test_a_q_that_ends_near_uniform_is_warned_about(caplog):
    """CAVI annealed from gamma 0, or started from Dir(1) rows, and loopy BP annealed, ended at
    q(C) uniform (1.000 of log L) under paper-dp at L = 120 without a word: "1 concept in use"
    (argmax's tie) or a hundred, ARI 0.00-0.06. They warn as SVI does, naming what orders the
    field; CAVI from random one-hot labels at full gamma orders (0.01 of log L) and says nothing."""
    from spcopyro.guides.lbp_method import LBPInference
    from spcopyro.synthetic import HouseSpec

    house = make_house(seed=0, spec=HouseSpec.scaled(30, 40, num_rooms=2))
    settings = preset("paper-dp")
    _, data = prepare_model_data(house, settings)

    def said(method, options) -> list[str]:
        caplog.clear()
        with caplog.at_level("WARNING", logger="spcopyro"):
            method.run(data, settings.model, iterations=60, options=options, progress=False,
                       generator=torch.Generator().manual_seed(0))  # fmt: skip
        return [r.getMessage() for r in caplog.records if "ended near uniform" in r.getMessage()]

    (annealed,) = said(CAVIInference(), VariationalOptions(anneal_iterations=20))
    assert annealed.startswith("CAVI's q(C) ended near uniform: mean entropy 4.787 nats a cell")
    assert "gamma 4 < L / D = 30" in annealed and "Try anneal_iterations=0" in annealed
    (soft,) = said(CAVIInference(), VariationalOptions(anneal_iterations=0, init="soft"))
    assert "Try init='one-hot'" in soft and "anneal_iterations=0" not in soft
    (bp,) = said(LBPInference(), LBPOptions(anneal_iterations=20))
    assert bp.startswith("loopy BP's q(C) ended near uniform") and "mean field" not in bp
    assert said(CAVIInference(), VariationalOptions(anneal_iterations=0)) == []
