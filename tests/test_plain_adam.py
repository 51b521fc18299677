"""spcopyro.guides.adam: torch.optim.Adam's updates, bit for bit, without torch._dynamo."""

from __future__ import annotations

import subprocess
import sys

import pyro
import pyro.optim
import pytest
import torch
from torch.distributions import constraints

from spcopyro.guides.adam import PlainAdam, plain_adam


@pytest.mark.parametrize(
    ("dtype", "lr", "betas", "eps"),
    [
        (torch.float64, 0.1, (0.9, 0.999), 1e-8),
        (torch.float64, 1e-3, (0.8, 0.99), 1e-6),
        (torch.float32, 0.05, (0.9, 0.999), 1e-8),
    ],
)
def test_the_updates_are_torch_adams_bit_for_bit(dtype, lr, betas, eps):
    g = torch.Generator().manual_seed(0)
    start = torch.randn(40, 7, generator=g, dtype=dtype)
    mine, theirs = start.clone().requires_grad_(), start.clone().requires_grad_()
    plain = PlainAdam([mine], lr=lr, betas=betas, eps=eps)
    reference = torch.optim.Adam([theirs], lr=lr, betas=betas, eps=eps)
    for _ in range(60):  # gradients of both signs and scales, some exactly zero
        grad = torch.randn(start.shape, generator=g, dtype=dtype) * 10 ** torch.randint(
            -4, 3, start.shape, generator=g
        )
        grad[grad.abs() < 1e-4] = 0
        mine.grad, theirs.grad = grad.clone(), grad.clone()
        plain.step()
        reference.step()
        assert torch.equal(mine, theirs)
    state = reference.state[theirs]
    assert torch.equal(plain.state[0]["exp_avg_sq"], state["exp_avg_sq"])
    assert torch.equal(plain.state[0]["step"], state["step"])  # a 0-d tensor, as torch's
    assert plain.state[0]["step"].dtype == state["step"].dtype


def test_a_state_saved_with_a_number_for_the_step_loads_and_goes_on():
    """Before PlainAdam called torch's functional adam its step was a Python float; such a
    state still loads (the step made a 0-d tensor) and gives the steps an unbroken run gives."""
    g = torch.Generator().manual_seed(1)
    grads = [torch.randn(5, generator=g, dtype=torch.float64) for _ in range(12)]
    start = torch.randn(5, generator=g, dtype=torch.float64)

    def run(optimiser: PlainAdam, param: torch.Tensor, steps: list[torch.Tensor]) -> None:
        for grad in steps:
            param.grad = grad.clone()
            optimiser.step()

    whole = start.clone().requires_grad_()
    run(PlainAdam([whole], lr=0.1), whole, grads)
    half = start.clone().requires_grad_()
    first = PlainAdam([half], lr=0.1)
    run(first, half, grads[:5])
    saved = first.state_dict()
    saved["state"][0]["step"] = float(saved["state"][0]["step"])  # the old format: 5.0
    second = PlainAdam([half], lr=0.1)
    second.load_state_dict(saved)
    run(second, half, grads[5:])
    assert torch.equal(half, whole)
    assert torch.equal(second.state[0]["step"], torch.tensor(12.0))


def test_a_pyro_svi_run_is_pyro_adams_bit_for_bit_and_its_state_round_trips(tmp_path):
    def run(optimiser: pyro.optim.PyroOptim, steps: int) -> torch.Tensor:
        def model():
            pyro.sample("x", pyro.distributions.Normal(torch.zeros(3), 1.0).to_event(1))

        def guide():
            loc = pyro.param("loc", torch.tensor([1.0, -2.0, 0.5]))
            scale = pyro.param("scale", torch.ones(3), constraint=constraints.positive)
            pyro.sample("x", pyro.distributions.Normal(loc, scale).to_event(1))

        svi = pyro.infer.SVI(model, guide, optimiser, pyro.infer.Trace_ELBO())
        for _ in range(steps):
            svi.step()
        return pyro.param("loc").detach().clone()

    results = []
    for optimiser in (pyro.optim.Adam({"lr": 0.05}), plain_adam({"lr": 0.05})):
        with pyro.get_param_store().scope():
            pyro.set_rng_seed(3)
            results.append(run(optimiser, 25))
    assert torch.equal(results[0], results[1])

    with pyro.get_param_store().scope():  # saved after 10 steps and loaded: the same 25 steps
        pyro.set_rng_seed(3)
        first = plain_adam({"lr": 0.05})
        run(first, 10)
        first.save(tmp_path / "adam.pt")
        second = plain_adam({"lr": 0.05})
        second.load(tmp_path / "adam.pt")
        assert torch.equal(run(second, 15), results[1])


def test_a_seeded_svi_fit_is_the_one_with_pyros_adam(monkeypatch):
    from spcopyro.config import preset
    from spcopyro.fit.house import prepare_model_data
    from spcopyro.guides import svi_method
    from spcopyro.guides.run import initial_q
    from spcopyro.synthetic import HouseSpec, make_house

    spec = HouseSpec(height=24, width=30, num_rooms=2, num_trials=2, min_room_size=8)
    settings = preset("original-code", gamma=3.0, num_concepts=5)
    _, data = prepare_model_data(make_house(seed=1, spec=spec), settings)

    def fit():
        q = initial_q(data, settings.model, torch.Generator().manual_seed(0))
        return svi_method.fit_svi(data, settings.model, 30, q=q, progress=False,
                                  generator=torch.Generator().manual_seed(0))  # fmt: skip

    plain = fit()
    monkeypatch.setattr(svi_method, "plain_adam", pyro.optim.Adam)
    torchs = fit()
    assert torch.equal(plain.q, torchs.q)
    assert (plain.objective == torchs.objective).all()


def test_svi_fits_without_importing_torch_dynamo():
    """Every torch.optim optimiser imports torch._dynamo (1.1 s a process) on construction;
    the ``svi`` method's default Adam does not."""
    code = """
import sys, torch
from spcopyro.config import preset
from spcopyro.fit.house import prepare_model_data
from spcopyro.guides.run import initial_q
from spcopyro.guides.svi_method import fit_svi
from spcopyro.synthetic import HouseSpec, make_house
house = make_house(seed=1, spec=HouseSpec(height=24, width=30, num_rooms=2, num_trials=2,
                                          min_room_size=8))
settings = preset("original-code", gamma=3.0, num_concepts=4)
_, data = prepare_model_data(house, settings)
q = initial_q(data, settings.model, torch.Generator().manual_seed(0))
run = fit_svi(data, settings.model, 5, q=q, generator=torch.Generator().manual_seed(0),
              progress=False)
assert len(run.objective) == 5, run.objective
print("torch._dynamo" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.strip() == "False"
