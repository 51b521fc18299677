"""SpCoMapping's Gibbs sampler as a :class:`pyro.infer.mcmc.MCMCKernel`.

::

    kernel = SpCoGibbs(spcomapping_model)
    mcmc = MCMC(kernel, num_samples=500, warmup_steps=200, num_chains=2)
    mcmc.run(data, config)          # the model's arguments, as for NUTS
    mcmc.get_samples()["pi"]        # [num_samples * num_chains, L]

The work is done by the pure functions :func:`~spcopyro.gibbs.sampler.init` and
:func:`~spcopyro.gibbs.sampler.step` (the same ones the run loop uses); this class adapts them to
Pyro's MCMC driver and works around its habits:

* MCMC concatenates every saved param into one float tensor per sample, so integer sites would come
  back as floats: the kernel's ``transforms`` map ``labels`` back to int64. Pyro 1.9's
  ``mcmc.diagnostics()`` and ``mcmc.summary()`` then crash on that integer site (they fill NaN
  into an int tensor, take its mean), so use :func:`mcmc_summary` (Pyro's table of the float
  sites, and per-cell label entropies) and :func:`mcmc_diagnostics` (ESS and split R-hat of the
  float sites: a label's R-hat means nothing under label switching anyway; ``num_concepts``
  stays float for this), or save no labels (``save_params`` below).
* MCMC keeps every saved param of every sample in memory: by default every site of the model
  (``labels`` -- N values a sample --, ``pi``, ``theta``, ``w``) and the diagnostics ``log_joint``
  and ``num_concepts`` are saved, so that Pyro's :class:`~pyro.infer.Predictive` conditions on the
  whole posterior state; pass ``save_params=DEFAULT_SAVE_PARAMS`` (the small sites) for long runs
  on large maps, or use :func:`spcopyro.gibbs.run.run_gibbs` with thinned label maps.
* MCMC never calls ``end_warmup``, and with ``num_chains > 1`` runs each chain in a subprocess (the
  kernel pickles; each chain's generator is seeded from the worker's torch RNG, which MCMC seeds).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import pyro.poutine as poutine
import torch
from pyro.infer import MCMC
from pyro.infer.mcmc.mcmc_kernel import MCMCKernel
from pyro.infer.mcmc.util import diagnostics as pyro_diagnostics
from pyro.infer.mcmc.util import print_summary as pyro_print_summary
from pyro.infer.mcmc.util import summary as pyro_summary

from spcopyro.config import HYPERPARAMETER_FIELDS, SpCoConfig
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.hyperparameters import hyperparameter_names, hyperparameter_values
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.sampler import init, step, trace_point
from spcopyro.gibbs.state import GibbsState, SweepPlan, make_sweep_plan
from spcopyro.likelihood import check_model_density, log_joint_constant, num_concepts_in_use
from spcopyro.model import (
    DTYPE,
    SITE_LABELS,
    SITE_PI,
    ModelData,
    check_model_data,
    spcomapping_model,
)
from spcopyro.model_checks import refuse_foreign_sites, refuse_observed_latents, require_observed

DEFAULT_SAVE_PARAMS = ("log_joint", "num_concepts", "pi")
"""The small sites: what to save for long runs on large maps (the default saves every site)."""
ALL_PARAMS = ("labels", "log_joint", "num_concepts", "pi", "theta", "w")


def _hyper_site(name: str) -> str:
    """The site a sampled hyperparameter is saved as: ``alpha``, ``gamma``, ``chi``, ``beta``,
    and ``<name>_concentration`` for a further modality's concentration (saved under the
    modality's own name it took the name of the model's observation site, and Predictive
    conditioned the observed counts on it)."""
    return name if name in HYPERPARAMETER_FIELDS else f"{name}_concentration"


class _ToInteger:
    """A stand-in transform: MCMC calls ``transforms[name].inv(z)`` on the collected samples."""

    def __init__(self, dtype: torch.dtype) -> None:
        self.dtype = dtype

    def inv(self, value: torch.Tensor) -> torch.Tensor:
        return value.round().to(self.dtype)


class SpCoGibbs(MCMCKernel):
    """Enumerated-Gibbs kernel for :func:`~spcopyro.model.spcomapping_model`.

    Args:
        model: the Pyro model. The kernel samples
            :func:`~spcopyro.model.spcomapping_model`'s conditionals whatever model it is given
            (variants go through ``SpCoConfig`` and ``ModelData.modalities``): :meth:`setup`
            checks the model's site names and shapes against the kernel's state and its log
            density against the kernel's log joint at one point (ValueError for another model),
            so model and kernel cannot drift apart.
        init_labels: [N] starting labels (random if None).
        save_params: which of ``labels``, ``log_joint``, ``num_concepts``, ``pi``, ``theta``, ``w``
            (and the parameter site of any further modality) MCMC keeps for every sample; None
            (the default): all of them, so that ``mcmc.get_samples()`` holds every latent site
            of the model and ``Predictive(model, posterior_samples=mcmc.get_samples())``
            conditions on the posterior (with a site missing, Predictive would draw it from
            its prior: issue 24 item 4); to draw the observations too, give Predictive
            ``pyro.poutine.uncondition(model)`` (Predictive keeps observed sites at the data;
            the kernel itself takes the model, which observes them: given an unconditioned
            model it raises ValueError saying so).
            Labels cost N values a sample: pass the small sites only
            (:data:`DEFAULT_SAVE_PARAMS`) for long runs on large maps. A string is one site's
            name. Pyro's ``MCMC(kernel, ..., save_params=[...])`` sets the same request.
        options: the sampler's options (:class:`~spcopyro.gibbs.options.GibbsOptions`: backend,
            cluster moves, partial refresh); its ``anneal_sweeps`` must be 0 -- use ``anneal``.
            With ``options.hyper`` sampling hyperparameters, each sampled one (``alpha``,
            ``gamma``, ``chi``, ``beta``, ``<name>_concentration`` for a further modality) is
            saved as a site too.
        anneal: ramp the labels' coupling gamma up over MCMC's ``warmup_steps``
            (:mod:`spcopyro.gibbs.anneal`); the saved samples are all from the target model.
            ``warmup_steps=0`` with it is refused (ValueError at ``MCMC.run``).
    """

    def __init__(
        self,
        model: Callable[[ModelData, SpCoConfig], None] = spcomapping_model,
        init_labels: torch.Tensor | None = None,
        save_params: Sequence[str] | None = None,
        options: GibbsOptions = GibbsOptions(),
        anneal: bool = False,
    ) -> None:
        if not isinstance(options, GibbsOptions):
            raise TypeError(
                f"options must be a GibbsOptions (spcopyro.gibbs.options), got "
                f"{type(options).__name__}: e.g. GibbsOptions(cluster_moves=0.1)"
            )
        if not isinstance(anneal, bool):
            raise TypeError(f"anneal must be True or False, got {anneal!r}")
        if options.anneal_sweeps:
            raise ValueError(
                "SpCoGibbs anneals over MCMC's warmup steps: pass anneal=True, not "
                f"options.anneal_sweeps={options.anneal_sweeps}"
            )
        self.model = model
        self.options = options
        self._backend = get_backend(options.backend)
        self.init_labels = init_labels
        self.anneal = bool(anneal)
        self.save_params = save_params  # type: ignore[assignment]
        self.transforms = {"labels": _ToInteger(torch.long)}
        self._state: GibbsState | None = None
        self._generator: torch.Generator | None = None
        self._plan: SweepPlan | None = None
        self._steps = 0
        self._warmup_steps = 0

    def setup(self, warmup_steps: int, data: ModelData, config: SpCoConfig) -> None:
        self._data, self._config = data, config
        self._warmup_steps, self._steps = warmup_steps, 0
        if self.anneal and warmup_steps == 0:
            raise ValueError(
                "SpCoGibbs(anneal=True) ramps gamma up over MCMC's warmup steps, but "
                "warmup_steps=0: pass warmup_steps > 0 or anneal=False"
            )
        check_model_data(data, config)  # before tracing the model (its errors name no count)
        own = {"log_joint", "num_concepts", *self._sampled_hyper()}
        clash = sorted(own & {m.name for m in data.modalities})
        if clash:
            raise ValueError(
                f"modality {clash[0]!r} has the name of a site SpCoGibbs saves ({sorted(own)}): "
                "mcmc.get_samples() would hold both under one name; give the modality another"
            )
        self._check_model_sites()
        requested = self._requested_params
        self._save_params = sorted(self._all_params() if requested is None else requested)
        unknown = set(self.save_params) - set(self._all_params())
        if unknown:
            raise ValueError(
                f"unknown save_params {sorted(unknown)}; choose from {self._all_params()}"
            )
        seed = int(torch.randint(2**62, ()))  # MCMC seeds torch's global RNG per chain
        self._generator = torch.Generator().manual_seed(seed)
        self._plan = make_sweep_plan(data)
        self._state = init(data, config, self._generator, self.init_labels)
        self._log_joint_constant = float(log_joint_constant(data, config))
        self._check_model_density()
        anneal_sweeps = warmup_steps if self.anneal else 0
        self._step_options = self.options.replace(anneal_sweeps=anneal_sweeps)

    @property
    def save_params(self) -> list[str]:
        """The sites MCMC keeps, sorted (after :meth:`setup`; before it, those requested)."""
        return self._save_params

    @save_params.setter
    def save_params(self, names: Sequence[str] | None) -> None:
        """Pyro's ``MCMC(kernel, save_params=[...])`` sets this: a request, as the
        constructor's argument (``setup`` overwrote it with every site, and all were kept)."""
        if isinstance(names, str):  # one site's name, not its letters
            names = (names,)
        self._requested_params = None if names is None else tuple(names)
        self._save_params = sorted(names) if names is not None else []

    def _all_params(self) -> tuple[str, ...]:
        parameters = tuple(m.parameter for m in self._data.modalities)
        return tuple(sorted(set(ALL_PARAMS) | set(parameters) | set(self._sampled_hyper())))

    def _sampled_hyper(self) -> tuple[str, ...]:
        """The hyperparameters ``options.hyper`` samples (``alpha``, ``gamma``, ``chi``,
        ``beta``, ...): sites of their own, so that MCMC keeps their draws (they were sampled
        but never reported)."""
        hyper = self.options.hyper
        sampled = {"alpha": hyper.alpha, "gamma": hyper.gamma != "fixed"}
        names = hyperparameter_names(self._data)
        return tuple(_hyper_site(name) for name in names if sampled.get(name, hyper.concentrations))

    def _check_model_sites(self) -> None:
        model = require_observed(self.model, self._data, "SpCoGibbs")  # not uncondition(model)
        trace = poutine.trace(model).get_trace(self._data, self._config)
        refuse_foreign_sites(trace, self._data, "SpCoGibbs")
        L = self._config.num_concepts
        expected = {SITE_PI: (L,), SITE_LABELS: (self._data.num_free,)}
        for modality in self._data.modalities:
            expected[modality.parameter] = (L, modality.counts.shape[-1])
        for name, shape in expected.items():
            if name not in trace.nodes:
                raise ValueError(f"model has no sample site {name!r}, which SpCoGibbs samples")
            refuse_observed_latents(trace, (name,), "SpCoGibbs", self._data.modalities)  # drawn
            actual = tuple(trace.nodes[name]["value"].shape)
            if actual != shape:
                raise ValueError(
                    f"model site {name!r} has shape {actual}, SpCoGibbs expects {shape}"
                )

    def _check_model_density(self) -> None:
        """ValueError unless the model's log density is the one the kernel's conditionals
        sample (:func:`~spcopyro.likelihood.check_model_density`), compared at one point: every
        cell in concept 0 (all pairs agree, so the coupling counts) with uniform pi and
        emission tables (finite wherever the state's draws may underflow to 0). A model of the
        right sites but another density (a changed prior, coupling or likelihood, a further
        latent site) was sampled as if it were spcomapping_model, silently."""
        data, config = self._data, self._config
        L = config.num_concepts
        labels = torch.zeros(data.num_free, dtype=torch.long)
        log_pi = torch.full((L,), -math.log(L), dtype=DTYPE)
        log_tables = [
            torch.full((L, m.counts.shape[-1]), -math.log(max(1, m.counts.shape[-1])), dtype=DTYPE)
            for m in data.modalities
        ]
        values = {SITE_PI: log_pi.exp(), SITE_LABELS: labels}
        for modality, table in zip(data.modalities, log_tables, strict=True):
            values[modality.parameter] = table.exp()
        conditioned = poutine.condition(self.model, data=values)
        model = float(poutine.trace(conditioned).get_trace(data, config).log_prob_sum())
        check_model_density(
            model, labels, log_pi, log_tables, data, config,
            at="with every cell in concept 0, uniform pi and emissions",
            why="whose conditionals SpCoGibbs samples",
            refusal="the kernel cannot sample another model",
            constant=self._log_joint_constant,
        )  # fmt: skip

    def _params(self, state: GibbsState) -> dict[str, torch.Tensor]:
        values = {
            "labels": lambda: state.labels,
            "log_joint": lambda: torch.tensor(
                trace_point(
                    state,
                    self._data,
                    self._config,
                    self._log_joint_constant,
                    self._backend,
                    self.options,
                )[0],
                dtype=torch.float64,
            ),
            "num_concepts": lambda: torch.tensor(  # float64 whatever else is saved
                float(num_concepts_in_use(state.labels, self._config.num_concepts)),
                dtype=torch.float64,
            ),
            "pi": lambda: state.log_pi.exp(),
        }
        for modality, table in zip(self._data.modalities, state.log_emissions, strict=True):
            values[modality.parameter] = lambda table=table: table.exp()
        names = hyperparameter_names(self._data)
        for name, value in zip(names, hyperparameter_values(self._data, self._config), strict=True):
            values[_hyper_site(name)] = lambda value=value: torch.tensor(value, dtype=torch.float64)
        return {name: values[name]() for name in self.save_params}

    @property
    def initial_params(self) -> dict[str, torch.Tensor]:
        if self._state is None:
            raise RuntimeError("call setup() (MCMC.run does) before asking for initial_params")
        return self._params(self._state)

    @initial_params.setter
    def initial_params(self, params: dict[str, torch.Tensor]) -> None:
        """Start from ``params["labels"]`` (``MCMC(initial_params=...)``): integer labels, or
        floats with integer values (Pyro's unconstrained space); pi and the emission tables
        are drawn from their full conditionals given those labels (eqs. 14-17), so a value
        given for them would be lost: ValueError."""
        others = sorted(set(params) - {"labels"})
        if others:
            raise ValueError(
                f"SpCoGibbs starts from labels only: pi and the emission tables are drawn "
                f"given them, so initial values of {others} would not be used; pass "
                "initial_params={'labels': ...}"
            )
        if "labels" not in params:
            return
        labels = torch.as_tensor(params["labels"])
        if torch.is_floating_point(labels):
            fractional = labels != labels.round()
            if bool(fractional.any()):
                index = int(fractional.flatten().nonzero()[0])
                raise ValueError(
                    "initial_params['labels'] must hold whole numbers, got "
                    f"{float(labels.flatten()[index])!r} at index {index}"
                )
            labels = labels.to(torch.long)
        self.init_labels = labels

    def sample(self, params: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        assert self._state is not None and self._generator is not None, "setup() not called"
        self._state, info = step(
            self._state, self._data, self._config, self._generator, sweep=self._steps,
            options=self._step_options, backend=self._backend, plan=self._plan,
        )  # fmt: skip
        if info.config is not None and info.config != self._config:  # sampled hyperparameters
            self._config = info.config
            self._log_joint_constant = float(log_joint_constant(self._data, info.config))
        self._steps += 1
        return self._params(self._state)

    @property
    def state(self) -> GibbsState:
        """The current state of the chain (labels, log pi, log theta, log w)."""
        assert self._state is not None, "setup() not called"
        return self._state

    def logging(self) -> dict[str, float] | None:
        if self._state is None:
            return None
        stage = "warmup" if self._steps <= self._warmup_steps else "sampling"
        return {
            "stage": stage,  # type: ignore[dict-item]
            "concepts": num_concepts_in_use(self._state.labels, self._config.num_concepts),
        }

    def diagnostics(self) -> dict[str, object]:
        """The sweeps run and the divergences (none: a Gibbs sampler has no trajectories to
        diverge; ArviZ's ``az.from_pyro`` asks every kernel for them)."""
        return {"sweeps": float(self._steps), "divergences": []}


def _samples_by_chain(mcmc: MCMC) -> dict[str, torch.Tensor]:
    """``mcmc.get_samples(group_by_chain=True)``; ValueError for fewer than 4 samples a chain
    (split R-hat's minimum; Pyro's own check is a bare AssertionError)."""
    samples = mcmc.get_samples(group_by_chain=True)
    kept = min((v.shape[1] for v in samples.values()), default=0)  # [chains, samples, ...]
    if kept < 4:
        raise ValueError(
            f"diagnostics need at least 4 samples a chain (split R-hat), got {kept}: "
            "run MCMC with more num_samples"
        )
    return samples


def mcmc_diagnostics(mcmc: MCMC) -> dict[str, dict[str, torch.Tensor]]:
    """Pyro's per-site diagnostics (``n_eff``, ``r_hat``) of the floating-point sites only.

    Split R-hat needs at least 4 samples a chain; fewer raise ValueError saying so (Pyro's own
    check is a bare AssertionError)."""
    samples = _samples_by_chain(mcmc)
    return pyro_diagnostics({k: v for k, v in samples.items() if torch.is_floating_point(v)})


def label_summary(labels: torch.Tensor) -> dict[str, torch.Tensor]:
    """Per-cell statistics of label samples ``[chains, samples, N]`` (int), each chain's own:
    ``entropy`` ``[chains, N]``, the entropy (nats) of the cell's labels over the chain's
    samples (0: one label throughout; log L at most), and ``mode_share`` ``[chains, N]``, the
    share of the samples in the cell's most frequent label. Both are free of label switching
    (they ignore which number a concept has), unlike a mean or an R-hat of the labels; compare
    them between chains to see whether the chains settled the same cells."""
    chains, draws, cells = labels.shape
    width = int(labels.max()) + 1 if labels.numel() else 1
    counts = torch.zeros(chains, cells, width, dtype=torch.float64)
    counts.scatter_add_(2, labels.transpose(1, 2).long(), torch.ones(chains, cells, draws).double())
    share = counts / draws  # [chains, N, L]
    logs = torch.where(share > 0, share.log(), torch.zeros_like(share))
    return {"entropy": -(share * logs).sum(-1), "mode_share": share.amax(-1)}


def mcmc_summary(
    mcmc: MCMC, prob: float = 0.9, show: bool = True, sites: Sequence[str] | None = None
) -> dict[str, dict]:
    """``mcmc.summary()`` for an MCMC run of :class:`SpCoGibbs`, which Pyro's cannot give (its
    ``summary()`` and ``diagnostics()`` fail on the integer ``labels`` site: Pyro 1.9 fills NaN
    into an int tensor).

    Returns Pyro's per-site statistics (``mean``, ``std``, ``median``, the ``prob`` interval,
    ``n_eff``, ``r_hat``: :func:`pyro.infer.mcmc.util.summary`) of the floating-point sites
    and, where the labels were saved, :func:`label_summary` of them under ``labels``; with
    ``show`` (the default) prints Pyro's table of the former and one line for the labels. Judge
    R-hat by the label-invariant sites (``log_joint``, ``num_concepts``): a concept's ``pi``
    entry may belong to another region in another chain. At least 4 samples a chain
    (ValueError otherwise).

    ``sites``: the saved sites to summarise (a string is one site's name), e.g.
    ``("log_joint", "num_concepts")``; None (the default): every saved site. With the default
    ``save_params`` the table has one row per entry of ``pi`` ``[L]``, ``theta`` ``[L, K]`` and
    ``w`` ``[L, V]`` (26,760 rows on the README's house: L = 120, K = 205, V = 17), which
    ``sites`` leaves out.
    A name that was not saved raises ValueError listing those that were."""
    samples = _samples_by_chain(mcmc)
    if sites is not None:
        wanted = (sites,) if isinstance(sites, str) else tuple(sites)
        unknown = [name for name in wanted if name not in samples]
        if unknown:
            raise ValueError(
                f"mcmc_summary: no saved site {unknown[0]!r}; the run saved {sorted(samples)} "
                "(SpCoGibbs(save_params=...))"
            )
        samples = {name: samples[name] for name in wanted}
    floats = {k: v for k, v in samples.items() if torch.is_floating_point(v)}
    result: dict[str, dict] = pyro_summary(floats, prob=prob, group_by_chain=True)
    if show and floats:
        pyro_print_summary(floats, prob=prob, group_by_chain=True)
    if SITE_LABELS in samples:
        labels = label_summary(samples[SITE_LABELS])
        result[SITE_LABELS] = labels
        if show:
            entropy, settled = labels["entropy"].mean(0), labels["mode_share"] >= 0.9
            print(
                f"labels: {entropy.shape[0]} cells; each cell's label entropy over the samples "
                f"(nats, mean over {labels['entropy'].shape[0]} chain(s)): median "
                f"{float(entropy.median()):.3f}, max {float(entropy.max()):.3f}; one label in "
                f">= 90 % of the samples in {int(settled.all(0).sum())} cells (in every chain)"
            )
    return result
