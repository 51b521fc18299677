r"""A mean-field Pyro guide for :func:`spcopyro.model.spcomapping_model`.

.. math::

    q(\pi, \phi, C) = \mathrm{Dir}(\pi \mid a_\pi)
        \prod_m \prod_l \mathrm{Dir}(\phi_{ml} \mid a_{ml})
        \prod_i \mathrm{Cat}(C_i \mid \mathrm{softmax}(\eta_i)),

the family of :mod:`spcopyro.variational` (CAVI) written as a Pyro program: the concentrations
:math:`a_\pi` ``[L]`` and :math:`a_{ml}` ``[L, K_m]`` are ``pyro.param`` s constrained positive
(by default above their prior's concentration, see ``bound``), the labels' logits :math:`\eta`
``[N, L]`` an unconstrained ``pyro.param``. Its
sample sites carry the model's names (``pi``, :func:`~spcopyro.model.parameter_site` of every
modality, ``labels``) in the model's plates, so ``pyro.infer.Predictive(model, guide=guide)``
draws the globals and the labels from q, and ``pyro.infer.SVI`` fits it with the loss of
:mod:`spcopyro.guides.loss` (Pyro's own ELBOs cannot: see there).

The guide's parameters start at the CAVI-optimal global factors for the starting q(C)
(:func:`spcopyro.variational.cavi.update_globals`, eqs. 14-17 in expectation) and at logits
``log((1 - s) q + s / L)`` for that q (label smoothing ``s`` keeps a one-hot start finite).
Each guide names its parameters with its own ``prefix``, so two guides can share a param store.
"""

from __future__ import annotations

from typing import Literal

import pyro
import pyro.distributions as dist
import torch
from torch.distributions import constraints

from spcopyro.config import SpCoConfig
from spcopyro.model import DTYPE, SITE_LABELS, SITE_PI, ModelData
from spcopyro.variational.cavi import update_globals
from spcopyro.variational.factors import GlobalFactors, prior_factors

_MARGIN = 1e-3
"""Start of every concentration above its prior's under ``bound="prior"`` (expected counts)."""


class MeanFieldGuide:
    """The mean-field guide (module docstring): call it as ``guide(data, config)``, like the model.

    Args:
        q: ``[N, L]`` the starting q(C) (e.g. :func:`spcopyro.variational.run.initial_q`).
        data, config: the model's arguments; the starting global factors are CAVI's optimum
            given ``q``.
        label_smoothing: s in the starting logits ``log((1 - s) q + s / L)``, in (0, 1).
        bound: the constraint of the concentrations: ``"prior"`` (the default), each above its
            prior's, ``a = a_prior + exp(u)`` with u the unconstrained parameter, or ``"zero"``,
            plain positive, ``a = exp(u)``. Every mean-field optimum lies above the prior (the
            optimal factor adds expected counts to the prior's concentration: eqs. 14-17), so
            the bound loses nothing; it gives the optimiser the scale of the *counts*. With the
            presets' pi concentration of ~1e6, a step of 0.01 in log a moves a by ~1e4, more than
            all the cells' counts, while a step in log(a - a_prior) moves the counts by 1 %.
        prefix: the start of every ``pyro.param`` name of this guide.
    """

    def __init__(
        self,
        q: torch.Tensor,
        data: ModelData,
        config: SpCoConfig,
        *,
        label_smoothing: float = 0.05,
        bound: Literal["prior", "zero"] = "prior",
        prefix: str = "spcomapping_guide",
    ) -> None:
        N, L = data.num_free, config.num_concepts
        if tuple(q.shape) != (N, L):
            raise ValueError(f"q must be [{N}, {L}], got {tuple(q.shape)}")
        if not 0 < label_smoothing < 1:
            raise ValueError(f"label_smoothing must lie in (0, 1), got {label_smoothing}")
        if bound not in ("prior", "zero"):
            raise ValueError(f"bound must be 'prior' or 'zero', got {bound!r}")
        smoothed = (1 - label_smoothing) * q.to(DTYPE) + label_smoothing / L  # [N, L]
        factors = update_globals(smoothed, data, config)  # Dirichlet q(pi): the prior's family
        prior = prior_factors(data, config)
        self.prefix = prefix
        self.num_free, self.num_concepts = N, L
        self.parameter_sites = tuple(m.parameter for m in data.modalities)
        starts = (factors.pi, *factors.emissions)  # [L], [L, K_m] ...
        lows = (prior.pi, *prior.emissions) if bound == "prior" else (0.0,) * len(starts)
        self._init, self._constraints = {self._name(SITE_LABELS): smoothed.log()}, {}
        for site, start, low in zip((SITE_PI, *self.parameter_sites), starts, lows, strict=True):
            # start strictly above the bound: a word no cell holds has no counts to add
            self._init[self._name(site)] = start + _MARGIN if bound == "prior" else start
            self._constraints[self._name(site)] = (
                constraints.greater_than(low) if bound == "prior" else constraints.positive
            )

    def _name(self, site: str) -> str:
        kind = "logits" if site == SITE_LABELS else "concentration"
        return f"{self.prefix}.{site}_{kind}"

    def _check(self, data: ModelData, config: SpCoConfig) -> None:
        if (data.num_free, config.num_concepts) != (self.num_free, self.num_concepts):
            raise ValueError(
                f"this guide was made for N={self.num_free} cells and L={self.num_concepts} "
                f"concepts, called with N={data.num_free}, L={config.num_concepts}"
            )
        sites = tuple(m.parameter for m in data.modalities)
        if sites != self.parameter_sites:
            raise ValueError(f"this guide has sites {self.parameter_sites}, the data {sites}")

    @property
    def logits_name(self) -> str:
        """The ``pyro.param`` name of the labels' logits."""
        return self._name(SITE_LABELS)

    def concentration(self, site: str) -> torch.Tensor:
        """The current Dirichlet concentration of ``pi`` ``[L]`` or of a modality's site
        ``[L, K_m]`` (a ``pyro.param``: created with its start value on first use)."""
        name = self._name(site)
        return pyro.param(name, lambda: self._init[name], constraint=self._constraints[name])

    def logits(self) -> torch.Tensor:
        """[N, L] the current logits of q(C_i)."""
        name = self._name(SITE_LABELS)
        return pyro.param(name, lambda: self._init[name])

    def marginals(self) -> torch.Tensor:
        """[N, L] q(C_i = l), detached."""
        return torch.softmax(self.logits().detach(), dim=-1)

    def factors(self) -> GlobalFactors:
        """The current q(pi), q(phi) as :class:`~spcopyro.variational.factors.GlobalFactors`
        (detached), for :func:`spcopyro.variational.elbo.elbo` and the posterior means."""
        return GlobalFactors(
            self.concentration(SITE_PI).detach(),
            tuple(self.concentration(site).detach() for site in self.parameter_sites),
            "dirichlet",
        )

    def __call__(self, data: ModelData, config: SpCoConfig) -> None:
        self._check(data, config)
        pyro.sample(SITE_PI, dist.Dirichlet(self.concentration(SITE_PI)))
        with pyro.plate("concepts", self.num_concepts, dim=-1):
            for site in self.parameter_sites:
                pyro.sample(site, dist.Dirichlet(self.concentration(site)))  # [L, K_m]
        with pyro.plate("cells", self.num_free, dim=-1):
            pyro.sample(SITE_LABELS, dist.Categorical(logits=self.logits()))  # [N]
