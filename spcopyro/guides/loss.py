r"""The SVI loss of the mean-field guide: globals reparameterised, labels in closed form.

For the guide :math:`q(\pi, \phi, C) = q(\pi) \prod_{ml} q(\phi_{ml}) \prod_i q(C_i)` of
:mod:`spcopyro.guides.mean_field` the ELBO of the model's unnormalised joint
(:func:`spcopyro.model.spcomapping_model`; the same bound as
:func:`spcopyro.guides.elbo.elbo`) splits as

.. math::

    \mathcal{L} = E_{q(\pi, \phi)}\Big[\log p(\pi) + \sum_{ml} \log p(\phi_{ml})
        - \log q(\pi) - \sum_{ml} \log q(\phi_{ml}) + F(q_C; \pi, \phi)\Big] + H[q(C)],

    F(q_C; \pi, \phi) = E_{q(C)}[\log p^*(C, x \mid \pi, \phi)]
        = \sum_{i,l} q_i(l) \log\pi_l + \gamma \sum_{(a,b)} q_a \cdot q_b
        + \sum_{i \in \mathrm{obs}} \sum_l q_i(l)\, \ell_{il}(\phi) + \text{coefficients},

with :math:`\ell_{il}(\phi) = \sum_m x^{(m)}_i \cdot \log\phi_{ml}` (eqs. 5, 6, 13). F is exact:
under a factorised q(C) the expectation of the Potts statistic (eq. 8) is the sum over neighbour
pairs of :math:`q_a \cdot q_b`, and every other label term is linear in one q_i.

**The estimator.** One draw :math:`(\tilde\pi, \tilde\phi)` from q by reparameterisation
(``Dirichlet.rsample``: implicit reparameterisation gradients, Figurnov, Mohamed & Mnih 2018)
gives

.. math::

    \hat{\mathcal{L}} = \log p(\tilde\pi) + \sum \log p(\tilde\phi)
        - \log q(\tilde\pi) - \sum \log q(\tilde\phi)
        + F(q_C; \tilde\pi, \tilde\phi) + H[q(C)],

averaged over ``num_particles`` draws. Its value and its gradients are **unbiased** for the
ELBO and its gradient (reparameterisation for the concentrations, exact differentiation of F and
H for the logits at the drawn globals). Its **variance comes from the globals only**: the N
labels never are sampled (under this loss the guide's ``labels`` site is set to q(C)'s mode, not
drawn: ``_LabelsAtTheMode``). The first four terms are read from the model's and the guide's
own traces (``poutine.trace`` of the guide, ``poutine.replay`` of the model on it: the Dirichlet
log densities of ``pi`` and every modality's site); F reuses
:mod:`spcopyro.likelihood` (:func:`~spcopyro.likelihood.expected_agreements`,
:func:`~spcopyro.likelihood.observation_log_likelihood`), and H is the guide's ``labels``
distribution's entropy. So that loss and model cannot drift apart, the model's log density at
the first draw for a model (labels at their mode) is compared with spcomapping_model's
(ValueError for another model: its label terms would be replaced by these, silently). Taking
:math:`\log p - \log q` of the same draw (rather than a closed-form KL) makes the globals'
terms cancel where q(phi_ml) is still its prior (an unused concept), where a closed-form
entropy plus a sampled log p would add noise of order :math:`K_m \psi'(a)`.

**Why not Pyro's estimators.** :class:`pyro.infer.TraceEnum_ELBO` would sum the labels out
exactly, but the Potts factor couples every cell, so its cost grows as L to the power of the
grid's width (a test oracle on 3x3 maps at most). A score-function estimator over the labels
(:class:`pyro.infer.TraceGraph_ELBO`; Ranganath, Gerrish & Blei 2014, "Black box variational
inference") is unbiased but its variance grows with N: the Potts factor and the observation sites
depend on all N labels, so the Rao-Blackwellisation by the dependency graph removes nothing and
every cell's score is multiplied by a sum of O(N) noisy terms. Relaxed categoricals
(Gumbel-softmax / Concrete, Jang, Gu & Poole 2017; Maddison, Mnih & Teh 2017) are reparameterised
but biased for every temperature > 0 (the Potts and label terms are evaluated off the simplex's
vertices) and their variance grows as the temperature falls. The mean-field expectation F costs
the same O(N D L + M sum_m K_m L) as one CAVI update and removes the labels' noise altogether;
it is the "local expectations" idea of Hoffman, Blei, Wang & Paisley (2013, stochastic
variational inference) with the local factors kept as free parameters.

**References:** M. D. Hoffman, D. M. Blei, C. Wang, J. Paisley, "Stochastic variational
inference", JMLR 14, 2013. R. Ranganath, S. Gerrish, D. M. Blei, "Black box variational
inference", AISTATS 2014. E. Jang, S. Gu, B. Poole, "Categorical reparameterization with
Gumbel-softmax", ICLR 2017. C. J. Maddison, A. Mnih, Y. W. Teh, "The Concrete distribution",
ICLR 2017. M. Figurnov, S. Mohamed, A. Mnih, "Implicit reparameterization gradients", NeurIPS
2018.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import pyro
import torch
from pyro import poutine
from pyro.infer import ELBO
from pyro.poutine.messenger import Messenger
from torch.distributions import Categorical

from spcopyro.config import SpCoConfig
from spcopyro.likelihood import (
    check_model_density,
    expected_agreements,
    multinomial_coefficients,
    observation_log_likelihood,
)
from spcopyro.model import (
    DTYPE,
    SITE_LABELS,
    SITE_PI,
    ModelData,
)
from spcopyro.model_checks import refuse_observed_latents, require_observed

Program = Callable[[ModelData, SpCoConfig], None]

_TINY = torch.finfo(DTYPE).tiny


def expected_label_terms(
    q: torch.Tensor,
    log_pi: torch.Tensor,
    log_parameters: tuple[torch.Tensor, ...],
    data: ModelData,
    config: SpCoConfig,
) -> torch.Tensor:
    """F(q_C; pi, phi) (module docstring): E_q(C)[log p*(C, x | pi, phi)] at one value of the
    globals, ``q`` ``[N, L]``, ``log_pi`` ``[L]``, one ``[L, K_m]`` log table per modality."""
    loglik = observation_log_likelihood(log_parameters, data, config)  # [M, L]
    total = (q.sum(0) * log_pi).sum() + config.gamma * expected_agreements(q, data.pairs)
    return total + (q[data.obs_cells] * loglik).sum() + multinomial_coefficients(data, config)


def _global_log_density(trace: poutine.Trace, sites: tuple[str, ...]) -> torch.Tensor:
    """Sum of the log densities of ``sites`` in ``trace`` at their values."""
    total = torch.zeros((), dtype=DTYPE)
    for name in sites:
        site = trace.nodes[name]
        total = total + site["fn"].log_prob(site["value"]).sum()
    return total


class _LabelsAtTheMode(Messenger):
    """Sets the value of the guide's ``labels`` site to its Categorical's mode (``[N]``, the
    argmax of q(C_i)) in place of a draw. The estimate reads q(C) itself (its probabilities and
    entropy) and no label value: the model, replayed on the guide's trace, takes the labels only
    into sites whose log densities the estimate does not read (``labels``, ``potts``, the
    observations) and into the first step's check of the model's density (:func:`_check_model`),
    which holds at any labels. A draw cost about 30 % of a step on room1dk5 (N = 18,622,
    L = 120: N L exponentials) and moved torch's random stream for nothing. Only under this
    loss: the guide run plainly (``Predictive``, ``poutine.trace``) still draws its labels from
    q(C). A value already given (``poutine.condition``, ``poutine.replay`` around the loss) wins."""

    def _pyro_sample(self, msg: dict) -> None:
        fn = msg["fn"]
        if msg["name"] == SITE_LABELS and msg["value"] is None and isinstance(fn, Categorical):
            msg["value"] = fn.mode  # [N]; its probs, computed here, are the ones F reads


def traces(
    model: Program, guide: Program, data: ModelData, config: SpCoConfig
) -> tuple[poutine.Trace, poutine.Trace]:
    """The model's and the guide's trace of one draw of the globals: the guide run with its
    labels at q(C)'s mode, not drawn (``_LabelsAtTheMode``), the model replayed on it."""
    guide_trace = poutine.trace(_LabelsAtTheMode()(guide)).get_trace(data, config)
    model = require_observed(model, data, "MeanFieldELBO")  # not poutine.uncondition(model)
    model_trace = poutine.trace(poutine.replay(model, trace=guide_trace)).get_trace(data, config)
    return model_trace, guide_trace


def _check_model(model_trace: poutine.Trace, data: ModelData, config: SpCoConfig) -> bool:
    """ValueError unless the model's log density at the trace's draw (globals from the guide,
    labels at q(C)'s mode: ``_LabelsAtTheMode``) is
    :func:`~spcopyro.model.spcomapping_model`'s there
    (:func:`~spcopyro.likelihood.check_model_density`): the label terms F are taken in closed
    form from :mod:`spcopyro.likelihood`, whatever model SVI is given. True once compared;
    False where the model's value is not finite (a label whose drawn pi underflowed to 0:
    nothing to compare)."""
    with torch.no_grad():
        model = float(model_trace.log_prob_sum())
        if not math.isfinite(model):
            return False
        labels = model_trace.nodes[SITE_LABELS]["value"]  # [N]
        log_pi = model_trace.nodes[SITE_PI]["value"].log()  # [L]
        log_parameters = [model_trace.nodes[m.parameter]["value"].log() for m in data.modalities]
        check_model_density(
            model, labels, log_pi, log_parameters, data, config,
            at="at a draw of the guide",
            why="whose label terms MeanFieldELBO takes in closed form",
            refusal="it cannot fit another model",
        )  # fmt: skip
    return True


def particle_estimate(
    model_trace: poutine.Trace, guide_trace: poutine.Trace, data: ModelData, config: SpCoConfig
) -> torch.Tensor:
    """The ELBO estimate of one draw's (model trace, guide trace) (:func:`traces`)."""
    sites = (SITE_PI, *(m.parameter for m in data.modalities))
    for name in (*sites, SITE_LABELS):
        for trace, who in ((guide_trace, "guide"), (model_trace, "model")):
            if name not in trace.nodes or trace.nodes[name]["type"] != "sample":
                raise ValueError(f"the {who} has no sample site {name!r}")
        refuse_observed_latents(model_trace, (name,), "MeanFieldELBO", data.modalities)  # q scored
    log_ratio = _global_log_density(model_trace, sites) - _global_log_density(guide_trace, sites)
    labels = guide_trace.nodes[SITE_LABELS]["fn"]  # Categorical, batch [N]
    q = labels.probs  # [N, L]
    values = [model_trace.nodes[name]["value"] for name in sites]
    log_pi, *log_parameters = [v.clamp_min(_TINY).log() for v in values]  # [L], [L, K_m] ...
    expected = expected_label_terms(q, log_pi, tuple(log_parameters), data, config)
    return log_ratio + expected + labels.entropy().sum()


class MeanFieldELBO(ELBO):
    """The loss of the module docstring for ``pyro.infer.SVI(model, guide, optim, loss)``:
    ``model`` is :func:`~spcopyro.model.spcomapping_model`, ``guide`` a
    :class:`~spcopyro.guides.mean_field.MeanFieldGuide` (any guide with Dirichlet ``pi`` and
    parameter sites and a Categorical ``labels`` site works), both called as
    ``(data, config)``. ``loss`` is minus the ELBO estimate averaged over ``num_particles``
    draws, taken one after another: ``vectorize_particles=True`` is refused (the model takes
    one draw of pi at a time; its Potts factor is not batched), where Pyro's ELBOs would batch.
    """

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        if self.vectorize_particles:
            raise ValueError(
                "MeanFieldELBO draws its particles one at a time (spcomapping_model takes one "
                "sample of pi and its Potts factor is not batched): vectorize_particles=True "
                "would be ignored; leave it False (num_particles still averages the draws)"
            )

    def _get_trace(self, model, guide, args, kwargs):
        """One (model trace, guide trace) pair, as Pyro's ELBOs return it."""
        return traces(model, guide, *args, **kwargs)

    def differentiable_loss(
        self, model: Program, guide: Program, data: ModelData, config: SpCoConfig
    ) -> torch.Tensor:
        """Minus the ELBO estimate, with the autograd graph to the guide's params. The first
        draw for a model is checked against the label terms taken in closed form
        (:func:`_check_model`: ValueError for another model), once per model."""
        total = torch.zeros((), dtype=DTYPE)
        for _ in range(self.num_particles):
            model_trace, guide_trace = traces(model, guide, data, config)
            if getattr(self, "_checked_model", None) != model:
                if _check_model(model_trace, data, config):
                    self._checked_model = model
            total = total + particle_estimate(model_trace, guide_trace, data, config)
        return -total / self.num_particles

    def loss(self, model: Program, guide: Program, data: ModelData, config: SpCoConfig) -> float:
        with torch.no_grad():
            return float(self.differentiable_loss(model, guide, data, config))

    def loss_and_grads(
        self, model: Program, guide: Program, data: ModelData, config: SpCoConfig
    ) -> float:
        loss = self.differentiable_loss(model, guide, data, config)
        if loss.requires_grad:
            loss.backward(retain_graph=self.retain_graph)
        value = float(loss.detach())
        pyro.util.warn_if_nan(value, "loss")
        return value
