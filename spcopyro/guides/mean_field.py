r"""A mean-field Pyro guide for :func:`spcopyro.model.spcomapping_model`.

.. math::

    q(\pi, \phi, C) = \mathrm{Dir}(\pi \mid a_\pi)
        \prod_m \prod_l \mathrm{Dir}(\phi_{ml} \mid a_{ml})
        \prod_i \mathrm{Cat}(C_i \mid \mathrm{softmax}(\eta_i)),

the family of :mod:`spcopyro.guides` (CAVI) written as a Pyro program, a
:class:`~pyro.nn.PyroModule` built from the model's arguments like Pyro's autoguides
(``MeanFieldGuide(data, config)``): the concentrations :math:`a_\pi` ``[L]`` and :math:`a_{ml}`
``[L, K_m]`` are :class:`~pyro.nn.PyroParam` s constrained positive (by default above their
prior's concentration, see ``bound``), the labels' logits :math:`\eta` ``[N, L]`` an
unconstrained one, all named under the module (``spcomapping_guide.pi_concentration``,
``spcomapping_guide.theta_concentration``, ..., ``spcomapping_guide.labels_logits``). Its
sample sites carry the model's names (``pi``, :func:`~spcopyro.model.parameter_site` of every
modality, ``labels``) in the model's plates, so ``pyro.infer.Predictive(model, guide=guide)``
draws the globals and the labels from q, and ``pyro.infer.SVI`` fits it with the loss of
:mod:`spcopyro.guides.loss` (Pyro's own ELBOs cannot: see there).

The guide's parameters start at the CAVI-optimal global factors for the starting q(C)
(:func:`spcopyro.guides.cavi.update_globals`, eqs. 14-17 in expectation) and at logits
``log((1 - s) q + s / L)`` for that q (label smoothing ``s`` keeps a one-hot start finite).
Each guide names its parameters with its own ``name``, so two guides can share a param store.

Only :class:`~spcopyro.guides.loss.MeanFieldELBO` fits it: run under any other
:class:`pyro.infer.ELBO` (``Trace_ELBO``, ``TraceGraph_ELBO``, ``TraceEnum_ELBO``, ...) the guide
raises :class:`WrongLossError` naming that loss, rather than letting SVI take steps that cannot
fit it (the reasons are in :mod:`spcopyro.guides.loss`).
"""

from __future__ import annotations

import logging
from typing import Literal

import pyro
import pyro.distributions as dist
import torch
from pyro.nn import PyroModule, PyroParam
from torch.distributions import constraints

from spcopyro._util.random_draws import check_generator
from spcopyro.config import SpCoConfig
from spcopyro.guides.cavi import update_globals
from spcopyro.guides.factors import GlobalFactors, prior_factors
from spcopyro.guides.loss import MeanFieldELBO
from spcopyro.guides.run import initial_q
from spcopyro.model import (
    DTYPE,
    SITE_LABELS,
    SITE_PI,
    ModelData,
    calling_elbo,
    check_config,
    check_model_data,
)

_MARGIN = 1e-3
"""Start of every concentration above its prior's under ``bound="prior"`` (expected counts)."""

GUIDE_NAME = "spcomapping_guide"
"""The default name of a guide: the start of its parameters' names in the param store."""

RANDOM_START_SMOOTHING = 0.9
"""The label smoothing of a random start: near uniform with a small random tilt (max q about
0.11 at L = 120), the start the ``svi`` method anneals from."""

GIVEN_START_SMOOTHING = 0.05
"""The label smoothing of a given start (a fitted q, a warm start's labels): 95 % of it kept."""


class WrongLossError(TypeError):
    """The guide was run by an ELBO that cannot fit it (module docstring)."""


def _warn_stored(logits_name: str, shape: tuple[int, int], name: str) -> None:
    """Log a warning where the param store already holds the guide's parameters: the store
    wins, so a second guide of the same name took the first one's trained values instead of its
    own start (its ``q`` too) silently, or failed at its first SVI step for another L."""
    store = pyro.get_param_store()
    if logits_name not in store:
        return
    held = tuple(store[logits_name].shape)
    consequence = (
        "this guide will use those values, not its own start (q, generator, label_smoothing)"
        if held == shape
        else f"they are {held} where this guide's are {shape}: SVI will fail with 'Shape mismatch'"
    )
    logging.getLogger("spcopyro").warning(
        "MeanFieldGuide: Pyro's param store already holds %r (an earlier guide's or a loaded "
        "store's): %s; call pyro.clear_param_store() first, or give the guide a name of its "
        "own (name=, now %r), to start afresh",
        logits_name,
        consequence,
        name,
    )


class MeanFieldGuide(PyroModule):
    """The mean-field guide (module docstring): call it as ``guide(data, config)``, like the model.

    Args:
        data, config: the model's arguments; they fix N, L and the modalities' sites, and the
            starting global factors are CAVI's optimum given the starting q(C).
        q: ``[N, L]`` the starting q(C) (e.g. :func:`spcopyro.guides.run.initial_q` with
            a Gibbs state's labels). By default random one-hot labels drawn with ``generator``
            (torch's global generator when ``None``).
        label_smoothing: s in the starting logits ``log((1 - s) q + s / L)``, in (0, 1). By
            default 0.9 for the random start (near uniform with a small random tilt: the start
            the ``svi`` method anneals from) and 0.05 for a given ``q`` (kept nearly as given).
        bound: the constraint of the concentrations: ``"prior"`` (the default), each above its
            prior's, ``a = a_prior + exp(u)`` with u the unconstrained parameter, or ``"zero"``,
            plain positive, ``a = exp(u)``. Every mean-field optimum lies above the prior (the
            optimal factor adds expected counts to the prior's concentration: eqs. 14-17), so
            the bound loses nothing; it gives the optimiser the scale of the *counts*. With the
            presets' pi concentration of ~1e6, a step of 0.01 in log a moves a by ~1e4, more than
            all the cells' counts, while a step in log(a - a_prior) moves the counts by 1 %.
        name: the module's name, the start of every parameter's name in the param store.
            As for any Pyro module, the param store wins: where it already holds this name's
            parameters (an earlier guide of the same name, a loaded store), those are used and
            this guide's start (``q``, ``generator``, ``label_smoothing``) is not (it logs a
            warning saying so); call
            ``pyro.clear_param_store()`` or give another ``name`` to start afresh.
    """

    def __init__(
        self,
        data: ModelData,
        config: SpCoConfig,
        *,
        q: torch.Tensor | None = None,
        generator: torch.Generator | None = None,
        label_smoothing: float | None = None,
        bound: Literal["prior", "zero"] = "prior",
        name: str = GUIDE_NAME,
    ) -> None:
        if not isinstance(data, ModelData):
            raise TypeError(
                f"MeanFieldGuide(data, config) takes the model's ModelData first, got "
                f"{type(data).__name__} (see spcopyro.fit.house.prepare_model_data)"
            )
        check_model_data(data, config)
        super().__init__(name=name)
        N, L = data.num_free, config.num_concepts
        if label_smoothing is None:
            label_smoothing = RANDOM_START_SMOOTHING if q is None else GIVEN_START_SMOOTHING
        if generator is not None:  # a seed (0 above all) fell back to torch's generator
            check_generator(generator)
        if q is None:
            q = initial_q(data, config, generator or torch.default_generator)
        q = torch.as_tensor(q)  # a NumPy array: "'numpy.ndarray' object has no attribute 'to'"
        if tuple(q.shape) != (N, L):
            raise ValueError(f"q must be [{N}, {L}], got {tuple(q.shape)}")
        # A negative or unnormalised row gave NaN logits.
        rows = q.to(DTYPE)  # [N, L]
        wrong = (
            ~torch.isfinite(rows).all(-1) | (rows < 0).any(-1) | ((rows.sum(-1) - 1).abs() > 1e-4)
        )
        if wrong.any():
            bad = int(torch.nonzero(wrong)[0])
            raise ValueError(
                f"q must hold a distribution over the {L} concepts in every row (finite, >= 0, "
                f"summing to 1); row {bad} does not: {q[bad].tolist()[:6]}"
            )
        if not 0 < label_smoothing < 1:
            raise ValueError(f"label_smoothing must lie in (0, 1), got {label_smoothing}")
        if bound not in ("prior", "zero"):
            raise ValueError(f"bound must be 'prior' or 'zero', got {bound!r}")
        smoothed = (1 - label_smoothing) * q.to(DTYPE) + label_smoothing / L  # [N, L]
        factors = update_globals(smoothed, data, config)  # Dirichlet q(pi): the prior's family
        prior = prior_factors(data, config)
        self.num_free, self.num_concepts = N, L
        self.parameter_sites = tuple(m.parameter for m in data.modalities)
        _warn_stored(self.logits_name, (N, L), name)
        self.num_items = tuple(m.counts.shape[-1] for m in data.modalities)  # K_m per modality
        starts = (factors.pi, *factors.emissions)  # [L], [L, K_m] ...
        lows = (prior.pi, *prior.emissions) if bound == "prior" else (0.0,) * len(starts)
        setattr(self, self._attribute(SITE_LABELS), PyroParam(smoothed.log()))  # [N, L]
        for site, start, low in zip((SITE_PI, *self.parameter_sites), starts, lows, strict=True):
            # start strictly above the bound: a word no cell holds has no counts to add
            if bound == "prior":
                param = PyroParam(start + _MARGIN, constraint=constraints.greater_than(low))
            else:
                param = PyroParam(start, constraint=constraints.positive)
            setattr(self, self._attribute(site), param)

    @staticmethod
    def _attribute(site: str) -> str:
        return f"{site}_{'logits' if site == SITE_LABELS else 'concentration'}"

    def _check(self, data: ModelData, config: SpCoConfig) -> None:
        check_config(config)  # svi.step(data, settings): the model's message, not AttributeError
        if (data.num_free, config.num_concepts) != (self.num_free, self.num_concepts):
            raise ValueError(
                f"this guide was made for N={self.num_free} cells and L={self.num_concepts} "
                f"concepts, called with N={data.num_free}, L={config.num_concepts}"
            )
        sites = tuple(m.parameter for m in data.modalities)
        if sites != self.parameter_sites:
            raise ValueError(f"this guide has sites {self.parameter_sites}, the data {sites}")
        items = tuple(m.counts.shape[-1] for m in data.modalities)
        if items != self.num_items:
            raise ValueError(
                f"this guide was made for modalities {self.parameter_sites} of "
                f"{self.num_items} items, called with {items}"
            )
        loss = calling_elbo()
        if loss is not None and not isinstance(loss, MeanFieldELBO):
            raise WrongLossError(
                f"{type(loss).__name__} cannot fit MeanFieldGuide: use "
                "spcopyro.guides.loss.MeanFieldELBO() as the loss, "
                "pyro.infer.SVI(spcomapping_model, guide, optim, MeanFieldELBO()). Pyro's ELBOs "
                "would estimate the labels' gradient by score functions over N Potts-coupled "
                "cells (variance growing with N) or enumerate them (cost L ** map width); "
                "MeanFieldELBO takes their expectation in closed form"
            )

    def _full_name(self, site: str) -> str:
        return f"{self._pyro_name}.{self._attribute(site)}" if self._pyro_name else site

    @property
    def logits_name(self) -> str:
        """The param store's name of the labels' logits."""
        return self._full_name(SITE_LABELS)

    def _param(self, attribute: str) -> torch.Tensor:
        """A parameter as the param store holds it: read in the module's Pyro context, which
        outside ``forward`` too syncs the module with the store (a store loaded by
        ``pyro.get_param_store().load``; a plain attribute read returned the module's stale
        copy until the next call) or creates the entry with its start value."""
        with self._pyro_context:
            return getattr(self, attribute)

    def concentration(self, site: str) -> torch.Tensor:
        """The current Dirichlet concentration of ``pi`` ``[L]`` or of a modality's site
        ``[L, K_m]`` (from the param store: created with its start value on first use)."""
        sites = (SITE_PI, *self.parameter_sites)
        if site not in sites:  # "labels" gave the logits; others "has no attribute ..."
            raise ValueError(f"the guide's Dirichlet sites are {sites}, got {site!r}")
        return self._param(self._attribute(site))

    def logits(self) -> torch.Tensor:
        """[N, L] the current logits of q(C_i) (from the param store, as :meth:`concentration`)."""
        return self._param(self._attribute(SITE_LABELS))

    def marginals(self) -> torch.Tensor:
        """[N, L] q(C_i = l), detached."""
        return torch.softmax(self.logits().detach(), dim=-1)

    def factors(self) -> GlobalFactors:
        """The current q(pi), q(phi) as :class:`~spcopyro.guides.factors.GlobalFactors`
        (detached), for :func:`spcopyro.guides.elbo.elbo` and the posterior means."""
        return GlobalFactors(
            self.concentration(SITE_PI).detach(),
            tuple(self.concentration(site).detach() for site in self.parameter_sites),
            "dirichlet",
        )

    def forward(self, data: ModelData, config: SpCoConfig) -> None:
        self._check(data, config)
        pyro.sample(SITE_PI, dist.Dirichlet(self.concentration(SITE_PI)))
        with pyro.plate("concepts", self.num_concepts, dim=-1):
            for site in self.parameter_sites:
                c = self.concentration(site)  # [L, K_m]; over no items (V = 0) the one point
                pyro.sample(site, dist.Dirichlet(c) if c.shape[-1] else dist.Delta(c, event_dim=1))
        with pyro.plate("cells", self.num_free, dim=-1):
            pyro.sample(SITE_LABELS, dist.Categorical(logits=self.logits()))  # [N]
