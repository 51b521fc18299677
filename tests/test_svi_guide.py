"""The mean-field Pyro guide and its SVI loss (spcopyro.guides), and the ``svi`` method.

The loss's estimate is checked against the closed-form ELBO of spcopyro.guides.elbo at the
same variational parameters (value and gradient, within Monte Carlo error); the guide against
``pyro.infer.SVI`` and ``pyro.infer.Predictive`` used the plain way; the method against an easy
synthetic house (ARI to the truth) and against CAVI's ELBO on the same data.
"""

from __future__ import annotations

import numpy as np
import pyro
import pyro.optim
import pytest
import torch
from pyro import poutine

from spcopyro.config import preset
from spcopyro.fit.house import fit_house, prepare_model_data
from spcopyro.fit.registry import get_method
from spcopyro.guides.elbo import elbo
from spcopyro.guides.factors import GlobalFactors
from spcopyro.guides.loss import MeanFieldELBO, particle_estimate, traces
from spcopyro.guides.mean_field import MeanFieldGuide, WrongLossError
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.run import initial_q, run_variational
from spcopyro.guides.svi_method import SVIInference, SVIOptions, fit_svi
from spcopyro.guides.svi_method import init as svi_init
from spcopyro.inference.driver import Trajectory
from spcopyro.metrics import adjusted_rand_index
from spcopyro.model import DTYPE, SITE_LABELS, SITE_PI, spcomapping_model
from spcopyro.synthetic import HouseSpec, make_house


@pytest.fixture(scope="module")
def small():
    """A two-room house of 340 free cells, 5 concepts: the unit tests' map."""
    house = make_house(
        seed=1, spec=HouseSpec(height=24, width=30, num_rooms=2, num_trials=2, min_room_size=8)
    )
    settings = preset("original-code", gamma=3.0, num_concepts=5)
    _, data = prepare_model_data(house, settings)
    return data, settings.model


@pytest.fixture
def store():
    """A fresh param store for the test, the caller's restored afterwards."""
    with pyro.get_param_store().scope():
        yield pyro.get_param_store()


def soft_guide(data, config, seed: int = 0, bound: str = "prior") -> MeanFieldGuide:
    """A guide away from any optimum: soft random q(C), globals CAVI-optimal for it."""
    g = torch.Generator().manual_seed(seed)
    logits = 2 * torch.randn(data.num_free, config.num_concepts, generator=g, dtype=DTYPE)
    return MeanFieldGuide(data, config, q=torch.softmax(logits, -1), bound=bound)


def analytic_elbo(guide: MeanFieldGuide, data, config) -> torch.Tensor:
    """spcopyro.guides.elbo.elbo at the guide's current params (differentiable)."""
    factors = GlobalFactors(
        guide.concentration(SITE_PI),
        tuple(guide.concentration(m.parameter) for m in data.modalities),
    )
    return elbo(torch.softmax(guide.logits(), -1), factors, data, config)


def test_the_estimate_averages_to_the_analytic_elbo(small, store):
    data, config = small
    guide = soft_guide(data, config)
    loss = MeanFieldELBO()
    draws = np.array([-loss.loss(spcomapping_model, guide, data, config) for _ in range(150)])
    exact = float(analytic_elbo(guide, data, config).detach())
    error = draws.std(ddof=1) / np.sqrt(len(draws))
    assert 0 < error < 1.0  # the labels are exact: only the globals' draw is noisy
    assert abs(draws.mean() - exact) < 4 * error, (draws.mean(), exact, error)


@pytest.mark.parametrize("bound", ["prior", "zero"])
def test_the_gradient_averages_to_the_analytic_gradient(small, store, bound):
    data, config = small
    guide = soft_guide(data, config, seed=1, bound=bound)
    guide(data, config)  # a call puts the params in the store
    leaves = [store.get_param(name).unconstrained() for name in store.keys()]
    exact = torch.autograd.grad(analytic_elbo(guide, data, config), leaves)
    loss = MeanFieldELBO()

    def estimate() -> torch.Tensor:
        return -loss.differentiable_loss(spcomapping_model, guide, data, config)

    grads = [torch.autograd.grad(estimate(), leaves) for _ in range(100)]
    for k, (name, target) in enumerate(zip(store.keys(), exact, strict=True)):
        draws = torch.stack([g[k] for g in grads])  # [draws, *shape]
        error = draws.std(0) / len(grads) ** 0.5
        scale = target.abs().max()
        gap = (draws.mean(0) - target).abs()
        assert (gap <= 5 * error + 1e-6 * scale).all(), (name, float((gap - 5 * error).max()))


def test_the_loss_takes_the_labels_at_their_mode_with_the_estimate_of_a_draw(small, store):
    """Under MeanFieldELBO the guide's labels are q(C)'s mode, not a draw (a draw of N L
    exponentials that the estimate never reads): with the same globals drawn, the value and the
    gradient are the same bits as with the labels drawn, the old path. The guide run plainly
    (Predictive) still draws its labels from q(C)."""
    data, config = small
    guide = soft_guide(data, config, seed=2)
    guide(data, config)  # a call puts the params in the store
    leaves = [store.get_param(name).unconstrained() for name in store.keys()]
    mode = guide.marginals().argmax(-1)  # [N]

    def drawn_labels_estimate() -> torch.Tensor:  # the old path: the guide's labels drawn
        guide_trace = poutine.trace(guide).get_trace(data, config)
        replayed = poutine.replay(spcomapping_model, trace=guide_trace)
        model_trace = poutine.trace(replayed).get_trace(data, config)
        assert (guide_trace.nodes[SITE_LABELS]["value"] != mode).any()  # a draw, soft q
        return particle_estimate(model_trace, guide_trace, data, config)

    for seed in range(3):
        torch.manual_seed(seed)
        before = drawn_labels_estimate()
        torch.manual_seed(seed)
        model_trace, guide_trace = traces(spcomapping_model, guide, data, config)
        assert torch.equal(guide_trace.nodes[SITE_LABELS]["value"], mode)
        assert torch.equal(model_trace.nodes[SITE_LABELS]["value"], mode)
        after = particle_estimate(model_trace, guide_trace, data, config)
        assert torch.equal(after, before)
        for old, new in zip(
            torch.autograd.grad(before, leaves), torch.autograd.grad(after, leaves), strict=True
        ):
            assert torch.equal(old, new)
        torch.manual_seed(seed)  # the loss itself: minus the same estimate, the model checked
        assert torch.equal(
            -MeanFieldELBO().differentiable_loss(spcomapping_model, guide, data, config), before
        )
    draws = pyro.infer.Predictive(spcomapping_model, guide=guide, num_samples=2)(data, config)
    assert (draws[SITE_LABELS] != mode).any(-1).all()  # drawn from q(C), not its mode


def test_svi_with_the_plain_api_raises_the_elbo(small, store):
    data, config = small
    guide = soft_guide(data, config)
    before = float(analytic_elbo(guide, data, config).detach())
    svi = pyro.infer.SVI(spcomapping_model, guide, pyro.optim.Adam({"lr": 0.05}), MeanFieldELBO())
    losses = [svi.step(data, config) for _ in range(60)]
    assert np.mean(losses[-10:]) < np.mean(losses[:10]) - 50
    assert float(analytic_elbo(guide, data, config).detach()) > before + 50
    assert np.isfinite(svi.evaluate_loss(data, config))
    L = config.num_concepts
    shapes = {name: tuple(store[name].shape) for name in store.keys()}
    assert shapes == {
        "spcomapping_guide.pi_concentration": (L,),
        **{
            f"spcomapping_guide.{m.parameter}_concentration": (L, m.counts.shape[-1])
            for m in data.modalities
        },  # fmt: skip
        "spcomapping_guide.labels_logits": (data.num_free, L),
    }
    clipped = pyro.infer.SVI(
        spcomapping_model, guide, pyro.optim.ClippedAdam({"lr": 0.05}), MeanFieldELBO(2)
    )
    assert np.isfinite(clipped.step(data, config))


def test_predictive_draws_every_site_from_the_guide(small, store):
    data, config = small
    N, L = data.num_free, config.num_concepts
    labels = torch.arange(N) % L
    q = torch.nn.functional.one_hot(labels, L).to(DTYPE)
    guide = MeanFieldGuide(data, config, q=q, label_smoothing=1e-12)
    draws = pyro.infer.Predictive(spcomapping_model, guide=guide, num_samples=4)(data, config)
    assert draws[SITE_PI].reshape(4, L).shape == (4, L)  # Pyro pads pi to [S, 1, L]
    assert torch.allclose(draws[SITE_PI].sum(-1), torch.ones((), dtype=DTYPE))
    for m in data.modalities:
        assert draws[m.parameter].shape == (4, L, m.counts.shape[-1])
        assert draws[m.name].shape == (4, *m.counts.shape)
    assert draws[SITE_LABELS].shape == (4, N)
    assert (draws[SITE_LABELS] == labels).all()  # drawn from the guide's (near one-hot) q(C)
    mean_pi = guide.factors().pi / guide.factors().pi.sum()
    assert torch.allclose(draws[SITE_PI].reshape(4, L), mean_pi, atol=0.01)


def test_the_method_is_registered_reproducible_and_leaves_the_param_store(small, store):
    data, config = small
    pyro.param("someone_elses", torch.ones(2))
    method = get_method("svi")
    assert isinstance(method, SVIInference) and method.objective_name == "ELBO"

    def run(seed: int):
        g = torch.Generator().manual_seed(seed)
        return method.run(data, config, iterations=5, generator=g, progress=False)

    first, again, other = run(0), run(0), run(1)
    assert list(store.keys()) == ["someone_elses"]
    np.testing.assert_array_equal(first.marginals, again.marginals)
    np.testing.assert_array_equal(first.trace.objective, again.trace.objective)
    assert not np.array_equal(first.trace.objective, other.trace.objective)
    assert first.marginals.shape == (data.num_free, config.num_concepts)
    assert first.trace.objective.shape == (5,) and np.isfinite(first.trace.objective).all()
    assert first.options["iterations"] == 5 and first.options["learning_rate"] == 0.1
    np.testing.assert_allclose(first.pi.sum(), 1.0)
    for m, table in zip(data.modalities, first.emissions, strict=True):
        assert table.shape == (config.num_concepts, m.counts.shape[-1])
    start = torch.arange(data.num_free) % 2
    warm = method.run(data, config, iterations=1, generator=torch.Generator(),
                      init_labels=start, options=SVIOptions(label_smoothing=0.01))  # fmt: skip
    assert (warm.labels == start.numpy()).mean() > 0.9


def test_the_guide_is_a_pyro_module_built_from_the_models_arguments(small, store):
    """Issue 24 item 4: built like Pyro's autoguides from (data, config), parameters named
    under the module (its ``name``), a torch module's parameters, a random start by default."""
    data, config = small
    guide = MeanFieldGuide(data, config, generator=torch.Generator().manual_seed(0))
    assert isinstance(guide, pyro.nn.PyroModule)
    guide(data, config)
    names = {f"spcomapping_guide.{m.parameter}_concentration" for m in data.modalities}
    names |= {"spcomapping_guide.pi_concentration", "spcomapping_guide.labels_logits"}
    assert set(store.keys()) == names and guide.logits_name == "spcomapping_guide.labels_logits"
    assert len(list(guide.parameters())) == len(names)  # the unconstrained values, in torch
    q = guide.marginals()  # the default start: near uniform (smoothing 0.9), randomly tilted
    L = config.num_concepts
    assert ((q - 1 / L).abs() < 1 / L).all() and (q.argmax(-1) != q.argmax(-1)[0]).any()
    other = MeanFieldGuide(data, config, name="second")
    other(data, config)
    assert "second.labels_logits" in store.keys() and len(store.keys()) == 2 * len(names)
    with pytest.raises(TypeError, match="takes the model's ModelData first"):
        MeanFieldGuide(spcomapping_model, config)


@pytest.mark.parametrize(
    "loss",
    [
        pyro.infer.Trace_ELBO(),
        pyro.infer.TraceGraph_ELBO(),
        pyro.infer.TraceMeanField_ELBO(),
        pyro.infer.TraceEnum_ELBO(max_plate_nesting=1),
    ],
    ids=lambda loss: type(loss).__name__,
)
def test_an_elbo_that_cannot_fit_the_guide_is_a_named_error(small, store, loss):
    """Issue 24 item 6 / 4: Pyro's ELBOs took steps on the guide without error although they
    cannot fit it; now the guide refuses to run under them and names the loss that can."""
    data, config = small
    guide = soft_guide(data, config)
    svi = pyro.infer.SVI(spcomapping_model, guide, pyro.optim.Adam({"lr": 0.05}), loss)
    with pytest.raises(WrongLossError, match=rf"{type(loss).__name__} cannot fit MeanFieldGuide"
                       r".*MeanFieldELBO\(\)"):  # fmt: skip
        svi.step(data, config)
    good = pyro.infer.SVI(spcomapping_model, guide, pyro.optim.Adam({"lr": 0.05}), MeanFieldELBO())
    assert np.isfinite(good.step(data, config))  # the guide itself is fine
    guide(data, config)  # and a plain call (no ELBO) runs


def test_bad_input_is_a_clear_error(small):
    data, config = small
    with pytest.raises(ValueError, match="learning_rate"):
        SVIOptions(learning_rate=0)
    with pytest.raises(ValueError, match="num_particles"):
        SVIOptions(num_particles=0)
    with pytest.raises(ValueError, match="bound"):
        SVIOptions(bound="one")
    with pytest.raises(TypeError, match="SVIOptions"):
        SVIInference().run(data, config, iterations=1, generator=torch.Generator(),
                           options=VariationalOptions())  # fmt: skip
    with pytest.raises(ValueError, match=r"q must be \[340, 5\]"):
        MeanFieldGuide(data, config, q=torch.ones(3, 5, dtype=DTYPE) / 5)
    for value, row in ((-0.2, 7), (0.3, 7), (float("nan"), 7)):  # negative rows gave NaN logits
        q = torch.ones(340, 5, dtype=DTYPE) / 5
        q[row, 0] = value
        with pytest.raises(ValueError, match="a distribution over the 5 concepts.*row 7"):
            MeanFieldGuide(data, config, q=q)
    guide = soft_guide(data, config)
    with pytest.raises(ValueError, match="L=6"):
        guide(data, config.replace(num_concepts=6))
    # Pyro's ELBOs batch their particles under vectorize_particles; this one looped silently
    with pytest.raises(ValueError, match="one at a time.*vectorize_particles=True"):
        MeanFieldELBO(num_particles=4, vectorize_particles=True)
    assert MeanFieldELBO(num_particles=4).num_particles == 4


@pytest.mark.parametrize("tolerance", [False, np.int64(0), np.float32(0.0), -1e-9, float("inf")])
def test_svi_tolerance_refuses_what_is_not_a_finite_number_at_least_zero(tolerance):
    """SVIOptions.tolerance is a finite number >= 0 as StochasticOptions' is: False,
    np.int64(0) and np.float32(0.0) equal 0 but are no numbers (a bool; NumPy scalars other than
    np.float64), refused as every other SVIOptions number refuses them. They passed while the
    check was ``positive or == 0`` (-1e-9 and inf were refused then too)."""
    with pytest.raises(ValueError, match=r"SVIOptions.tolerance=.*: must be a finite number >= 0"):
        SVIOptions(tolerance=tolerance)
    assert SVIOptions(tolerance=0).tolerance == 0  # 0 and 0.0 stay allowed: no stopping test
    assert SVIOptions(tolerance=0.0).tolerance == 0.0


@pytest.mark.slow
def test_svi_finds_the_rooms_and_ends_near_cavi():
    """On an easy house (the one tests/test_inference_interface.py fits), from the same random
    starts as annealed CAVI (seeds 0-3), SVI with its default options (300 steps) finds the
    rooms and ends near CAVI's ELBO. From one start the two often land in different local
    optima: over seeds 0-7 SVI ended from 6 % above to 10 % below CAVI, ARI 0.74 to 0.96, with
    its labels drawn (before 2026-12-06) as with them at their mode (measured, 300 steps each),
    so a single seed passed or failed by its draws (seed 0 gave -1.7 %, ARI 0.93 with the
    labels drawn, -6.4 %, ARI 0.86 without); over seeds 0-3 the mean |gap| was 3.8 % and 4.9 %,
    the mean ARI 0.85 both ways. Started at CAVI's optimum, 100 SVI steps stay within 1 % of it
    (measured 0.45 %: the noise floor of a constant step size) and keep its labels."""
    house = make_house(seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3, num_trials=3))
    settings = preset("original-code", gamma=3.0, num_concepts=8)
    _, data = prepare_model_data(house, settings)
    config = settings.model
    gaps, scores = [], []
    for seed in range(4):
        q = initial_q(data, config, torch.Generator().manual_seed(seed))
        svi = fit_svi(data, config, 300, q=q.clone(),
                      generator=torch.Generator().manual_seed(seed), progress=False)  # fmt: skip
        cavi = run_variational(data, config, 60, options=VariationalOptions(anneal_iterations=30),
                               q=q.clone(), progress=False)  # fmt: skip
        svi_elbo = float(elbo(svi.q, svi.factors, data, config))
        cavi_elbo = float(elbo(cavi.q, cavi.factors, data, config))
        gaps.append(abs(svi_elbo - cavi_elbo) / abs(cavi_elbo))
        image = np.full(house.grid.shape, -1)
        image[house.grid.free] = svi.labels.numpy()
        scores.append(adjusted_rand_index(image, house.truth))
        # the traced estimate tracks the exact ELBO at the end (noise of ~10 nats)
        assert abs(svi.objective[-20:].mean() - svi_elbo) < 0.005 * abs(svi_elbo)
    assert np.mean(gaps) < 0.07 and max(gaps) < 0.1, gaps
    assert np.mean(scores) > 0.8 and min(scores) > 0.7, scores

    warm = SVIOptions(label_smoothing=0.001, anneal_iterations=0)
    kept = fit_svi(data, config, 100, q=cavi.q.clone(), generator=torch.Generator(),
                   options=warm, progress=False)  # fmt: skip
    kept_elbo = float(elbo(kept.q, kept.factors, data, config))
    assert abs(kept_elbo - cavi_elbo) < 0.01 * abs(cavi_elbo), (kept_elbo, cavi_elbo)
    assert (kept.labels == cavi.labels).double().mean() > 0.99

    result = fit_house(house, settings, method="svi", sweeps=3, progress=False)
    assert result.method == "svi" and result.trace.objective_name == "ELBO"


def test_a_resumed_run_goes_on_from_the_elbo_reached(small):
    """``resume`` starts the guide at the q the interrupted run reached: smoothed as a fresh
    start (0.9 toward uniform) it fell back near the first step's ELBO."""
    data, config = small
    options = SVIOptions(tolerance=0.0, anneal_iterations=0)
    q0 = initial_q(data, config, torch.Generator().manual_seed(0))
    first = fit_svi(data, config, 60, q=q0, generator=torch.Generator().manual_seed(1),
                    options=options, progress=False)  # fmt: skip
    reached, start = first.objective[-10:].mean(), first.objective[:3].mean()
    assert reached > start + 100  # the run went somewhere to fall back from
    record = Trajectory(None, first.objective, first.num_concepts, first.seconds, first.gammas,
                        None, None, "interrupted")  # fmt: skip
    resumed = fit_svi(data, config, 5, q=first.q, generator=torch.Generator().manual_seed(2),
                      options=options, progress=False, resume=record)  # fmt: skip
    assert len(resumed.objective) == 65
    assert abs(resumed.objective[60] - reached) < 0.2 * (reached - start)


def test_a_step_size_that_diverges_is_one_clear_error(small):
    """learning_rate 10 took the guide's concentrations out of their support and ended with
    torch's 'Expected parameter ... to satisfy the constraint' and some 30 lines of tensor and
    trace shapes; it says what diverged and which option to lower."""
    data, config = small
    q = initial_q(data, config, torch.Generator().manual_seed(0))
    said = r"SVI diverged: .*learning_rate=1000\).*lower learning_rate"
    with pytest.raises(ValueError, match=said):
        fit_svi(data, config, 30, q=q, generator=torch.Generator().manual_seed(0), progress=False,
                options=SVIOptions(learning_rate=1000.0, anneal_iterations=0))  # fmt: skip


@pytest.fixture(scope="module")
def sparse_l120():
    """The unit tests' house under paper-dp (L = 120, gamma 4, beta 500): the case whose q
    stays at mean field's disordered fixed point under SVI (docs/variational.md)."""
    house = make_house(
        seed=1, spec=HouseSpec(height=24, width=30, num_rooms=2, num_trials=2, min_room_size=8)
    )
    settings = preset("paper-dp")
    _, data = prepare_model_data(house, settings)
    return data, settings.model


def mean_entropy_share(q: torch.Tensor) -> float:
    """Mean entropy per cell of q ``[N, L]`` as a share of log L."""
    q = q.to(torch.float64)
    return float(-(q * q.clamp_min(1e-300).log()).sum(-1).mean()) / np.log(q.shape[-1])


def test_a_fit_whose_q_ends_near_uniform_says_so(sparse_l120, caplog):
    """At L = 120 and gamma 4 < L / D = 30 the near-uniform start (label_smoothing 0.9) and the
    annealing stay in the disordered fixed point: q ends flat, and the fit now says so (it
    returned flat marginals silently: the map, their argmax, close to arbitrary)."""
    data, config = sparse_l120
    q0 = initial_q(data, config, torch.Generator().manual_seed(0))
    with caplog.at_level("WARNING", logger="spcopyro"):
        run = fit_svi(data, config, 30, q=q0, generator=torch.Generator().manual_seed(0),
                      options=SVIOptions(anneal_iterations=10), progress=False)  # fmt: skip
    assert mean_entropy_share(run.q) > 0.99
    flat = [r.getMessage() for r in caplog.records if "ended near uniform" in r.getMessage()]
    assert len(flat) == 1, caplog.text
    assert "gamma 4 < L / D = 30" in flat[0] and "label_smoothing=0.05" in flat[0], flat[0]


@pytest.fixture(scope="module")
def cavi_l120(sparse_l120):
    """CAVI's ordered q on :func:`sparse_l120` (50 iterations from random labels)."""
    data, config = sparse_l120
    q0 = initial_q(data, config, torch.Generator().manual_seed(0))
    return run_variational(data, config, 50, options=VariationalOptions(), q=q0, progress=False)


def test_a_warm_start_kept_by_small_smoothing_stays_ordered_and_is_not_warned(
    sparse_l120, cavi_l120, caplog
):
    """CAVI's ordered q, kept by label_smoothing 0.05, stays ordered under SVI (no warning); the
    same start smoothed by 0.9 (the random start's) falls to the disordered fixed point."""
    data, config = sparse_l120
    cavi = cavi_l120
    assert mean_entropy_share(cavi.q) < 0.05
    ends = {}
    for smoothing in (0.05, 0.9):
        caplog.clear()
        with caplog.at_level("WARNING", logger="spcopyro"):
            options = SVIOptions(anneal_iterations=0, label_smoothing=smoothing)
            run = fit_svi(data, config, 10, q=cavi.q.to(DTYPE), progress=False,
                          generator=torch.Generator().manual_seed(0), options=options)  # fmt: skip
        ends[smoothing] = (mean_entropy_share(run.q), "ended near uniform" in caplog.text)
    assert ends[0.05][0] < 0.1 and not ends[0.05][1], ends
    assert ends[0.9][0] > 0.9 and ends[0.9][1], ends


def test_given_start_labels_are_kept_by_default(sparse_l120, cavi_l120, caplog):
    """Start labels (``init_labels``; ``fit --init-from``) are smoothed by 0.05 unless
    ``label_smoothing`` is set, as MeanFieldGuide does with a given q: the default was 0.9 for
    every start, which kept 10 % of them, and at L = 120 the warm start from CAVI's labels fell
    to the disordered fixed point (mean entropy 1.000 of log L)."""
    data, config = sparse_l120
    start = cavi_l120.q.argmax(-1)  # [N]
    q = initial_q(data, config, torch.Generator(), start)  # [N, L] one-hot on them
    with pyro.get_param_store().scope():
        guide = svi_init(q, data, config, SVIOptions(), given_start=True).guide
        kept = guide.marginals().detach()  # [N, L] the guide's start q
    assert torch.equal(kept.argmax(-1), start)
    assert mean_entropy_share(kept) < 0.1, mean_entropy_share(kept)  # 0.09 at 0.05
    with pyro.get_param_store().scope():
        as_set = svi_init(q, data, config, SVIOptions(label_smoothing=0.9), given_start=True)
        assert mean_entropy_share(as_set.guide.marginals().detach()) > 0.9  # still honoured
    with caplog.at_level("WARNING", logger="spcopyro"):
        out = SVIInference().run(data, config, iterations=10, init_labels=start, progress=False,
                                 generator=torch.Generator().manual_seed(0),
                                 options=SVIOptions(anneal_iterations=0))  # fmt: skip
    assert out.options["label_smoothing"] == 0.05  # what the start ran with
    assert mean_entropy_share(torch.as_tensor(out.marginals)) < 0.05  # measured 0.024
    assert (out.labels == start.numpy()).all()
    assert "ended near uniform" not in caplog.text


def test_a_random_start_is_smoothed_as_before(small):
    """Without start labels the unset ``label_smoothing`` is the 0.9 it was: the same fit, step
    for step, recorded as 0.9."""
    data, config = small

    def run(options: SVIOptions):
        return SVIInference().run(data, config, iterations=5, options=options, progress=False,
                                  generator=torch.Generator().manual_seed(3))  # fmt: skip

    default = run(SVIOptions())
    before = run(SVIOptions(label_smoothing=0.9, anneal_iterations=100))  # the old defaults
    np.testing.assert_array_equal(default.marginals, before.marginals)
    np.testing.assert_array_equal(default.trace.objective, before.trace.objective)
    assert default.options["label_smoothing"] == 0.9
    assert default.options["anneal_iterations"] == 100
    assert SVIOptions().start_smoothing(given_start=False) == 0.9
    assert SVIOptions().start_annealing(given_start=False) == 100
    with pytest.raises(ValueError, match=r"SVIOptions.label_smoothing=1.0: must be None or lie"):
        SVIOptions(label_smoothing=1.0)
    with pytest.raises(ValueError, match=r"SVIOptions.anneal_iterations=-1: must be None or an"):
        SVIOptions(anneal_iterations=-1)


def test_given_start_labels_are_not_annealed_by_default(sparse_l120, cavi_l120):
    """``anneal_iterations`` None anneals a random start over 100 steps (above) and given start
    labels over none: it was 100 for every start, and annealed from gamma 0 CAVI's labels, kept
    at 95 %, were at 0.41 of log L after 10 steps (1.000, flat, after 100); a value set is
    used. config.json records the value that ran."""
    data, config = sparse_l120
    start = cavi_l120.q.argmax(-1)  # [N]

    def run(options: SVIOptions):
        seeded = torch.Generator().manual_seed(0)
        return SVIInference().run(data, config, iterations=10, init_labels=start, progress=False,
                                  generator=seeded, options=options)  # fmt: skip

    default = run(SVIOptions())
    assert default.options["anneal_iterations"] == 0, default.options
    assert mean_entropy_share(torch.as_tensor(default.marginals)) < 0.1  # measured 0.024
    assert SVIOptions().start_annealing(given_start=True) == 0
    annealed = run(SVIOptions(anneal_iterations=100))  # as set: honoured
    assert annealed.options["anneal_iterations"] == 100
    assert mean_entropy_share(torch.as_tensor(annealed.marginals)) > 0.3  # measured 0.41


def test_svi_step_with_the_settings_not_their_model_is_a_named_error(small, store):
    """``svi.step(data, settings)`` (the SpCoSettings, not settings.model) raised a bare
    AttributeError from the guide ('SpCoSettings' object has no attribute 'num_concepts'); the
    model and MCMC say to pass settings.model, and now so does the guide."""
    data, config = small
    settings = preset("original-code", gamma=3.0, num_concepts=5)
    assert settings.model == config
    with store.scope():
        state = svi_init(initial_q(data, config, torch.Generator().manual_seed(0)), data, config,
                         SVIOptions())  # fmt: skip
        with pytest.raises(
            TypeError, match=r"config must be an SpCoConfig \(pass settings.model\)"
        ):
            state.svi.step(data, settings)
        guide = state.guide
        with pytest.raises(TypeError, match=r"pass settings.model"):
            guide(data, settings)


def test_a_checkpoint_from_before_the_start_dependent_defaults_resumes(small, tmp_path):
    """Checkpoints made before 2026-12-05 record label_smoothing 0.9 and anneal_iterations 100
    (the defaults then): resumed with the options unset (None) they were refused as made for
    other settings ('label_smoothing: 0.9 in the checkpoint, None here'), though a resumed run
    does not read the smoothing. The smoothing is no longer compared and the annealing is
    compared as it runs: a random start's 100 resumes; a given start's 0 differs from the
    checkpoint's 100 (its schedule would change), refused naming the unset option."""
    from spcopyro.fit.variational_checkpoint import VariationalSaving
    from spcopyro.gibbs.run import SweepInfo
    from spcopyro.guides.checkpoint import load_variational, save_variational
    from spcopyro.inference.driver import drive

    data, config = small
    settings = preset("original-code", gamma=3.0, num_concepts=5)
    record = drive(0, lambda s, g: (s + 1, SweepInfo(-1.0, 1, g)), 2, gamma=config.gamma,
                   progress=False)  # fmt: skip
    q = initial_q(data, config, torch.Generator().manual_seed(0))  # [N, L]

    def saving(init: str) -> VariationalSaving:
        return VariationalSaving(get_method("svi"), None, data, settings, 10, [0], init)

    old = SVIOptions(label_smoothing=0.9, anneal_iterations=100)  # as recorded before
    for init in ("random", "gaussian"):
        path = save_variational(tmp_path / f"{init}.npz", q, record, method="svi", options=old,
                                config=config, data=data,
                                record=saving(init)._record())  # fmt: skip
        if init == "random":
            resumed = saving(init).load(path)
            assert torch.equal(resumed.marginals, q)
        else:
            with pytest.raises(ValueError, match=r"anneal_iterations: 100 in the checkpoint, 0 "
                               r"here \(anneal_iterations unset") as refused:  # fmt: skip
                saving(init).load(path)
            assert "label_smoothing" not in str(refused.value)
    # a smoothing set otherwise is not compared either: the resumed run does not read it
    load_variational(tmp_path / "random.npz", data, config, method="svi",
                     options=SVIOptions(label_smoothing=0.05, anneal_iterations=100))  # fmt: skip
    with pytest.raises(ValueError, match=r"anneal_iterations: 100 in the checkpoint, 7 here"):
        load_variational(tmp_path / "random.npz", data, config, method="svi",
                         options=SVIOptions(anneal_iterations=7))  # fmt: skip


def test_a_checkpoint_for_another_fit_names_the_options_that_differ(small, tmp_path):
    """VariationalSaving.load told the options that differed from the ValueError's text (an
    option's name followed by ': ' anywhere in it), so a difference elsewhere whose text held
    one, here the checkpoint's folder, was explained as that option left unset.
    load_variational raises CheckpointMismatchError (a ValueError) naming the options that
    differ, where it finds them."""
    from spcopyro.fit.variational_checkpoint import VariationalSaving
    from spcopyro.gibbs.run import SweepInfo
    from spcopyro.guides.checkpoint import (
        CheckpointMismatchError,
        load_variational,
        save_variational,
    )
    from spcopyro.inference.driver import drive

    data, config = small
    settings = preset("original-code", gamma=3.0, num_concepts=5)
    record = drive(0, lambda s, g: (s + 1, SweepInfo(-1.0, 1, g)), 2, gamma=config.gamma,
                   progress=False)  # fmt: skip
    q = initial_q(data, config, torch.Generator().manual_seed(0))  # [N, L]

    def saving(sweeps: int) -> VariationalSaving:  # given start labels: anneal_iterations 0
        return VariationalSaving(get_method("svi"), None, data, settings, sweeps, [0], "gaussian")

    folder = tmp_path / "anneal_iterations: 0"
    folder.mkdir()
    ran = saving(10)._options()
    path = save_variational(folder / "q.npz", q, record, method="svi", options=ran,
                            config=config, data=data, record=saving(10)._record())  # fmt: skip
    with pytest.raises(CheckpointMismatchError) as refused:
        saving(11).load(path)
    assert str(refused.value) == (  # was: "... 11 here (anneal_iterations unset: ...)"
        f"{path} was made for other data or settings: sweeps: 10 in the checkpoint, 11 here"
    )
    assert isinstance(refused.value, ValueError) and refused.value.options == ()
    with pytest.raises(CheckpointMismatchError) as refused:
        load_variational(path, data, config, method="svi", record=saving(10)._record(),
                         options=SVIOptions(anneal_iterations=7, window=3))  # fmt: skip
    assert refused.value.options == ("anneal_iterations", "window")
    with pytest.raises(CheckpointMismatchError) as refused:
        load_variational(path, data, config, method="cavi", options=None)
    assert (
        refused.value.options == ()
        and "resume it with method='svi' (fit's --method svi)" in str(refused.value)
    )
    old = save_variational(tmp_path / "old.npz", q, record, method="svi",
                           options=SVIOptions(label_smoothing=0.9, anneal_iterations=100),
                           config=config, data=data, record=saving(10)._record())  # fmt: skip
    with pytest.raises(CheckpointMismatchError) as refused:
        saving(10).load(old)
    assert refused.value.options == ("anneal_iterations",)
    assert str(refused.value).endswith(
        "anneal_iterations: 100 in the checkpoint, 0 here (anneal_iterations unset: the start's "
        "default, 'here' above, which changed on 2026-12-05; to resume, set the checkpoint's "
        "value in options= (fit's --method-option NAME=VALUE))"
    )
