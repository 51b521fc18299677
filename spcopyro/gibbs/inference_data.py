r"""Gibbs runs as ArviZ ``InferenceData``: trace plots, R-hat and ESS with the ecosystem's tools.

::

    mcmc = MCMC(SpCoGibbs(), num_samples=500, warmup_steps=500, num_chains=2)
    mcmc.run(data, config)
    idata = to_inference_data(mcmc)          # or the chains of run_gibbs / fit_house_chains
    az.summary(idata, var_names=["log_joint", "num_concepts", "pi_sorted"])
    az.plot_trace(idata, var_names=["log_joint", "num_concepts"])

**Why an exporter and not** ``az.from_pyro(mcmc)``: ArviZ's Pyro converter asks Pyro's
``mcmc.diagnostics()`` for divergences, and Pyro 1.9 computes ESS of every saved site there,
which crashes on the integer ``labels`` site (it fills NaN into an int64 tensor). With
``SpCoGibbs(save_params=DEFAULT_SAVE_PARAMS)`` (no labels) ``az.from_pyro(mcmc,
log_likelihood=False)`` works (the kernel reports its divergences: none, a Gibbs sampler has no
trajectories to diverge), but it drops what this function adds: the observations under the
modalities' names, the dims and coords below, ``lp`` in ``sample_stats`` and the label-invariant
``pi_sorted``. ArviZ's log-likelihood group is left out either way: it needs the model traced
over a batch of samples, and :func:`~spcopyro.model.spcomapping_model` takes one at a time.

**The groups** (C chains, D draws, L concepts, K_m items of modality m, M observed cells):

* ``posterior``: ``log_joint`` ``[C, D]`` (eq. 13's unnormalised log joint, the Potts
  normaliser left out), ``num_concepts`` ``[C, D]``, and from an MCMC run every saved site:
  ``pi`` ``[C, D, L]``, ``theta`` / ``w`` / further ``<name>_probs`` ``[C, D, L, K_m]``,
  ``pi_sorted`` ``[C, D, L]`` (pi in decreasing order) and, with ``include_labels``, ``labels``
  ``[C, D, N]``.
* ``sample_stats``: ``lp``, ArviZ's name for the log density, = ``log_joint``.
* ``observed_data`` (from an MCMC run): each modality's counts ``[M, K_m]``.

**Label switching.** Concept numbers are arbitrary and differ between chains (notebook 2), so
R-hat of ``pi[l]``, ``theta[l]`` or a label compares different concepts across chains: large
values there say nothing about convergence. ``log_joint``, ``num_concepts`` and ``pi_sorted``
(the weights ranked, whatever their numbers) are invariant to relabelling; judge the chains by
them, as ``--sweeps auto`` does (:mod:`spcopyro.gibbs.convergence`).

**Warm-up.** An MCMC run's samples are already past its ``warmup_steps``. Per-sweep traces
(:class:`~spcopyro.gibbs.run.GibbsRun`, :class:`~spcopyro.results.result.SpCoResult`) hold every
sweep: ``warmup`` sweeps (by default the first half, as :mod:`spcopyro.gibbs.convergence` discards)
go to ``warmup_posterior``, the rest to ``posterior``.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from pyro.infer import MCMC

from spcopyro._util.messages import with_article
from spcopyro.gibbs.run import GibbsRun
from spcopyro.model import SITE_LABELS, SITE_PI, ModelData

if TYPE_CHECKING:  # arviz is optional: imported when a conversion runs
    import arviz

LOG_JOINT, NUM_CONCEPTS, PI_SORTED = "log_joint", "num_concepts", "pi_sorted"
"""The posterior's label-invariant variables (module docstring)."""


def _arviz() -> Any:
    try:
        return importlib.import_module("arviz")
    except ImportError as error:
        raise ImportError(
            "to_inference_data needs ArviZ: pip install 'spcopyro[arviz]' (or pip install arviz)"
        ) from error


def _per_sweep_traces(source: object) -> tuple[np.ndarray, np.ndarray]:
    """[S] log joint and [S] concepts in use of one chain (a GibbsRun or a Gibbs result)."""
    if isinstance(source, GibbsRun):
        return source.log_joint, source.num_concepts
    trace = getattr(source, "trace", None)
    method = getattr(source, "method", "gibbs")
    if trace is None or not hasattr(trace, "objective"):
        raise TypeError(
            "to_inference_data takes a pyro.infer.MCMC run, a GibbsRun, an SpCoResult or a "
            f"sequence of them (chains), got {type(source).__name__}"
        )
    if getattr(trace, "objective_name", "log joint") != "log joint":  # vi-gibbs samples too
        raise ValueError(
            f"{with_article(repr(method))} result's trace is an optimiser's objective, not a "
            "Markov chain: only Gibbs chains (gibbs, vi-gibbs) go to ArviZ"
        )
    return np.asarray(trace.objective), np.asarray(trace.num_concepts)


def _from_chains(chains: Sequence[object], warmup: int | None) -> dict[str, Any]:
    traces = [_per_sweep_traces(chain) for chain in chains]
    lengths = sorted({len(log_joint) for log_joint, _ in traces})
    if len(lengths) != 1:
        raise ValueError(
            f"the chains ran different numbers of sweeps ({lengths}): ArviZ needs [chain, draw] "
            "arrays of one length; run them for the same number of sweeps"
        )
    (sweeps,) = lengths
    warmup = sweeps // 2 if warmup is None else warmup
    if not 0 <= warmup < sweeps:
        raise ValueError(f"warmup must lie in [0, {sweeps}) for chains of {sweeps} sweeps")
    log_joint = np.stack([lj for lj, _ in traces]).astype(np.float64)  # [C, S]
    concepts = np.stack([nc for _, nc in traces]).astype(np.int64)  # [C, S]
    posterior = {LOG_JOINT: log_joint[:, warmup:], NUM_CONCEPTS: concepts[:, warmup:]}
    groups: dict[str, Any] = {
        "posterior": posterior,
        "sample_stats": {"lp": log_joint[:, warmup:]},
    }
    if warmup:
        groups["warmup_posterior"] = {
            LOG_JOINT: log_joint[:, :warmup],
            NUM_CONCEPTS: concepts[:, :warmup],
        }
        groups["warmup_sample_stats"] = {"lp": log_joint[:, :warmup]}
        groups["save_warmup"] = True
    return groups


def _model_data(mcmc: MCMC) -> ModelData | None:
    args = getattr(mcmc, "_args", ())  # what mcmc.run(data, config) was given
    return args[0] if args and isinstance(args[0], ModelData) else None


def _from_mcmc(mcmc: MCMC, include_labels: bool) -> dict[str, Any]:
    samples = mcmc.get_samples(group_by_chain=True)  # name -> [C, D, ...]
    missing = {LOG_JOINT, NUM_CONCEPTS} - set(samples)
    if missing:
        raise ValueError(
            f"the MCMC run saved no {sorted(missing)}: run SpCoGibbs with them in save_params "
            "(DEFAULT_SAVE_PARAMS has them)"
        )
    if include_labels and SITE_LABELS not in samples:  # it was ignored silently
        raise ValueError(
            "include_labels: the MCMC run saved no labels (SpCoGibbs' save_params "
            f"{sorted(samples)}); run it with 'labels' in save_params (the default saves them)"
        )
    posterior: dict[str, np.ndarray] = {}
    for name, values in samples.items():
        if name == SITE_LABELS and not include_labels:
            continue
        posterior[name] = values.detach().cpu().numpy()
    posterior[NUM_CONCEPTS] = posterior[NUM_CONCEPTS].round().astype(np.int64)
    if SITE_PI in posterior:
        posterior[PI_SORTED] = -np.sort(-posterior[SITE_PI], axis=-1)  # [C, D, L] decreasing
    groups: dict[str, Any] = {
        "posterior": posterior,
        "sample_stats": {"lp": posterior[LOG_JOINT]},
    }
    data = _model_data(mcmc)
    if data is not None:
        groups["observed_data"] = {
            m.name: m.counts.detach().cpu().numpy() for m in data.modalities
        }  # name -> [M, K_m]
    return groups


def _dims(groups: dict[str, Any], mcmc: MCMC | None) -> dict[str, list[str]]:
    """The named dimensions of every variable (ArviZ's ``dims``)."""
    dims = {SITE_PI: ["concept"], PI_SORTED: ["rank"], SITE_LABELS: ["cell"]}
    data = _model_data(mcmc) if mcmc is not None else None
    for modality in data.modalities if data is not None else ():
        item = f"{modality.name}_item"
        dims[modality.parameter] = ["concept", item]
        dims[modality.name] = ["observation", item]
    present = set(groups["posterior"]) | set(groups.get("observed_data", {}))
    return {name: dim for name, dim in dims.items() if name in present}


def to_inference_data(
    source: MCMC | GibbsRun | object | Sequence[object],
    *,
    warmup: int | None = None,
    include_labels: bool = False,
    coords: dict[str, Any] | None = None,
) -> arviz.InferenceData:
    """An ArviZ ``InferenceData`` of Gibbs chains (module docstring for its groups).

    Args:
        source: a ``pyro.infer.MCMC`` run of :class:`~spcopyro.gibbs.kernel.SpCoGibbs` (one
            chain or several), or one chain's :class:`~spcopyro.gibbs.run.GibbsRun` /
            Gibbs (or vi-gibbs) :class:`~spcopyro.results.result.SpCoResult`, or a sequence
            of them (several chains of the same number of sweeps, e.g. from
            :func:`~spcopyro.fit.house.fit_house_chains`).
        warmup: per-sweep traces only: how many first sweeps are warm-up (default: half);
            ValueError for an MCMC run, whose warm-up is MCMC's ``warmup_steps``.
        include_labels: put the saved ``labels`` ``[C, D, N]`` in the posterior too (large,
            and their R-hat is meaningless under label switching).
        coords: ArviZ coordinates to add, e.g. ``{"words_item": vocabulary}``.
    """
    az = _arviz()
    mcmc = source if isinstance(source, MCMC) else None
    if mcmc is not None:
        if warmup is not None:  # it was ignored silently
            raise ValueError(
                "warmup applies to per-sweep traces only: an MCMC run keeps no warm-up "
                "samples (set MCMC's warmup_steps instead)"
            )
        groups = _from_mcmc(mcmc, include_labels)
    else:
        if include_labels:  # it was ignored silently
            raise ValueError(
                "include_labels applies to an MCMC run's saved labels: per-sweep traces "
                "(run_gibbs chains, fit results) go to ArviZ without them"
            )
        chains = list(source) if isinstance(source, (list, tuple)) else [source]
        if not chains:
            raise ValueError("to_inference_data got no chains")
        groups = _from_chains(chains, warmup)
    concepts = groups["posterior"].get(SITE_PI)
    all_coords: dict[str, Any] = {}
    if concepts is not None:
        all_coords["concept"] = np.arange(concepts.shape[-1])
        all_coords["rank"] = np.arange(1, concepts.shape[-1] + 1)
    all_coords.update(coords or {})
    attrs = {"inference_library": "spcopyro", "sampler": "SpCoGibbs (Algorithm 1)"}
    return az.from_dict(**groups, coords=all_coords, dims=_dims(groups, mcmc), attrs=attrs)
