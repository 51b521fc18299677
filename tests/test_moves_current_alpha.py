"""The split-merge and region relabel moves read the chain's *current* alpha.

Both moves' acceptance ratios hold the label-count term of the collapsed target, log Gamma(a_pi
+ m_l) with a_pi = alpha / L (``prior="dp"``) or alpha (``"dirichlet"``). When alpha is sampled
(``GibbsOptions.hyper.alpha``) it changes from sweep to sweep, and a move that kept the chain's
first alpha would leave the wrong posterior invariant. tests/test_hyperparameters.py's Geweke
test with moves cannot see that (max |z| 1.0-2.8 with such a bug, limit 4: commit a806c26), so
here, deterministically:

* each move's target difference (the first argument of its ``_log_acceptance_ratio``) equals
  the enumerator's log evidence difference (spcopyro.guides.testing, not the moves' own
  target) under the alpha the move was given, for alphas given one after another in one
  process (a cached first alpha fails the second), on the torch and numba paths, both priors;
* the drivers (the run loop and the Pyro kernel) give the moves of sweep s the config the
  hyperparameter update of sweep s - 1 returned (alpha moves during the run).

Power (mutations applied by a scratch pytest plugin's monkeypatches, not committed):
``concept_log_marginals`` (both moves' target) computing with the first alpha it saw fails all
8 cases of the two target tests (at alpha 0.05, the second given); ``step`` giving its moves the
first config it saw fails all 4 driver cases; the run loop stepping under the chain's starting
config (``GibbsChain.model_config`` returning ``config``) fails both run-driver cases. Correct
code: 12 pass in 22 s (the slowest case 3.5 s).
"""

from __future__ import annotations

import math

import pytest
import torch
from gibbs_problems import all_labelings, random_problem
from test_merge_move import _tiny_problem

import spcopyro.gibbs.merge as merge
import spcopyro.gibbs.region_move as region_move
import spcopyro.gibbs.sampler as sampler
from spcopyro.gibbs.hyper_options import HyperparameterOptions
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import advance, start_chain
from spcopyro.guides.testing import labelling_log_evidence
from spcopyro.model import potts_agreements

pytestmark = pytest.mark.usefixtures("one_torch_thread")  # small tensors

ALPHAS = (3.0, 0.05, 40.0)
"""Given one after another: a_pi 1, 1/60, 40/3 under the DP prior with L = 3."""


def _recorded_deltas(monkeypatch, module) -> list[float]:
    """The target differences ``module``'s ``_log_acceptance_ratio`` is called with, and every
    proposal accepted (so the returned labels are the proposal, whatever its ratio)."""
    deltas: list[float] = []
    real = module._log_acceptance_ratio

    def recording(delta: float, log_forward: float, log_reverse: float) -> float:
        deltas.append(delta)
        return real(delta, log_forward, log_reverse)

    monkeypatch.setattr(module, "_log_acceptance_ratio", recording)
    monkeypatch.setattr(module, "metropolis_accept", lambda log_ratio, generator: True)
    return deltas


def _check_move_targets(move, module, expected_delta, compiled, prior, monkeypatch) -> None:
    """``move(labels, data, cfg, generator)`` from every 5th labelling of the tiny map and 3
    seeds per alpha of :data:`ALPHAS`: its recorded target difference is
    ``expected_delta(before, after, cfg)``; at least 10 proposals per alpha."""
    if compiled:
        pytest.importorskip("numba")
    base, n, data = _tiny_problem()
    deltas = _recorded_deltas(monkeypatch, module)
    starts = all_labelings(n, base.num_concepts)[::5]
    for alpha in ALPHAS:
        cfg = base.replace(prior=prior, alpha=alpha)
        checked = 0
        for labels in starts:
            for seed in range(3):
                deltas.clear()
                new, info = move(labels, data, cfg, torch.Generator().manual_seed(seed), compiled)
                if not math.isfinite(info.log_ratio):  # nothing to propose
                    continue
                assert len(deltas) == 1 and not torch.equal(new, labels)
                expected = expected_delta(labels, new, data, cfg)
                assert deltas[0] == pytest.approx(expected, abs=1e-9), (alpha, labels, seed)
                checked += 1
        assert checked >= 10, (alpha, checked)


def _evidence_difference(before, after, data, cfg) -> float:
    """log p(after | x) - log p(before | x) by the enumerator, pi, theta and w integrated."""
    evidence = labelling_log_evidence(torch.stack([before, after]), data, cfg)  # [2]
    return float(evidence[1] - evidence[0])


@pytest.mark.parametrize("prior", ["dp", "dirichlet"])
@pytest.mark.parametrize("compiled", [False, True], ids=["torch", "numba"])
def test_split_merge_target_is_the_evidence_under_the_alpha_given(compiled, prior, monkeypatch):
    def move(labels, data, cfg, generator, compiled):
        return merge.split_merge_labels(labels, data, cfg, generator, 1, compiled)

    _check_move_targets(move, merge, _evidence_difference, compiled, prior, monkeypatch)


@pytest.mark.parametrize("prior", ["dp", "dirichlet"])
@pytest.mark.parametrize("compiled", [False, True], ids=["torch", "numba"])
def test_region_relabel_target_is_the_evidence_under_the_alpha_given(compiled, prior, monkeypatch):
    """The region move's target difference leaves out the share BOND_SHARE of the Potts change
    that the bonds' cut cancels (region_move's module doc)."""

    def move(labels, data, cfg, generator, compiled):
        return region_move.region_relabel_labels(labels, data, cfg, generator, compiled=compiled)

    def expected(before, after, data, cfg):
        agreements = potts_agreements(torch.stack([before, after]), data.pairs)  # [2]
        cut = region_move.BOND_SHARE * cfg.gamma * float(agreements[1] - agreements[0])
        return _evidence_difference(before, after, data, cfg) - cut

    _check_move_targets(move, region_move, expected, compiled, prior, monkeypatch)


def _record_driver_configs(monkeypatch):
    """(configs the split-merge move saw, those the region move saw, configs the hyperparameter
    updates returned), one per sweep each, recorded at the moves' entries and at the update
    step() calls."""
    seen: dict[str, list] = {"merge": [], "region": [], "updated": []}

    def recorder(module, name, key):
        real = getattr(module, name)

        def recording(labels, data, cfg, *args, **kwargs):
            seen[key].append(cfg)
            return real(labels, data, cfg, *args, **kwargs)

        monkeypatch.setattr(module, name, recording)

    recorder(merge, "split_merge_labels", "merge")
    recorder(region_move, "region_relabel_labels", "region")
    real_update = sampler.update_hyperparameters

    def update(*args, **kwargs):
        state, cfg, *rest = real_update(*args, **kwargs)
        seen["updated"].append(cfg)
        return (state, cfg, *rest)

    monkeypatch.setattr(sampler, "update_hyperparameters", update)
    return seen


SWEEPS = 12


@pytest.mark.parametrize("driver", ["run", "kernel"])
@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_moves_get_the_alpha_of_the_last_hyperparameter_update(backend, driver, monkeypatch):
    """Every sweep makes both moves (probability 1) and then updates alpha; the moves of sweep
    s must see the config that sweep s - 1's update returned (the start's at s = 0)."""
    if backend == "numba":
        pytest.importorskip("numba")
    cfg = _tiny_problem()[0].replace(alpha=2.0, gamma=0.8)
    _, data = random_problem(17)
    hyper = HyperparameterOptions(alpha=True, alpha_step=1.0, aux_sweeps=1)
    options = GibbsOptions(backend=backend, hyper=hyper, merge_moves=1.0, region_moves=1.0)
    seen = _record_driver_configs(monkeypatch)
    if driver == "run":
        chain = advance(start_chain(data, cfg, options=options, seed=3), SWEEPS, progress=False)
        trace = chain.to_run().hyperparameters["alpha"]  # [SWEEPS]
        assert trace.tolist() == [c.alpha for c in seen["updated"]]
    else:
        from pyro.infer import MCMC

        from spcopyro.gibbs.kernel import SpCoGibbs

        torch.manual_seed(3)  # the kernel seeds its generator from torch's
        kernel = SpCoGibbs(save_params=("labels",), options=options)
        MCMC(kernel, num_samples=SWEEPS - 2, warmup_steps=2, disable_progbar=True).run(data, cfg)
    expected = [cfg, *seen["updated"][:-1]]  # the config each sweep starts with
    assert len(seen["updated"]) == SWEEPS
    assert len({c.alpha for c in expected}) >= 3, [c.alpha for c in expected]  # alpha moved
    assert [c.alpha for c in seen["merge"]] == [c.alpha for c in expected]
    assert [c.alpha for c in seen["region"]] == [c.alpha for c in expected]
    assert seen["merge"] == expected and seen["region"] == expected  # the whole config
