"""The enumerated-Gibbs sampler of SpCoMapping (Algorithm 1).

Read in this order: ``sweep.py`` (the readable PyTorch reference of eqs. 13-17: one sweep),
``sampler.py`` (:func:`init` and :func:`step`: a sweep with the options' moves composed around
it), ``run.py`` (the run loop: a resumable chain, :func:`run_gibbs`), ``kernel.py``
(:class:`SpCoGibbs`, a :class:`pyro.infer.mcmc.MCMCKernel`), ``convergence.py`` (``--sweeps
auto``). ``numba_sweep.py`` is the compiled backend (same distribution), ``batched.py`` the
sweep of B chains in lock step as one batch of tensors (on a GPU when one is lent;
``batched_run.py`` records them as :func:`run_gibbs` records one), ``backends.py`` what a
backend supplies, ``options.py`` the sampler's options, ``cluster.py`` the Swendsen-Wang move,
``anneal.py`` the gamma schedule, ``hyperparameters.py`` (with ``hyper_targets.py`` and
``hyper_options.py``) alpha, the concentrations and gamma sampled inside the chain. The model's
per-cell math is shared with every other inference method in :mod:`spcopyro.likelihood`.

The kernel's names (:class:`SpCoGibbs` and its summaries) are imported on first use: the kernel
imports Pyro (about 200 modules), which a fit that runs the sampler itself never calls.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from spcopyro._util.lazy import lazy_names
from spcopyro.gibbs.hyper_options import HyperparameterOptions
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import GibbsChain, GibbsRun, advance, run_gibbs, start_chain
from spcopyro.gibbs.sampler import StepInfo, init, step
from spcopyro.gibbs.state import GibbsState
from spcopyro.gibbs.sweep import gibbs_sweep, label_log_conditionals, log_joint

if TYPE_CHECKING:  # pragma: no cover
    from spcopyro.gibbs.kernel import (
        DEFAULT_SAVE_PARAMS,
        SpCoGibbs,
        label_summary,
        mcmc_diagnostics,
        mcmc_summary,
    )

_HOMES = dict.fromkeys(
    ("DEFAULT_SAVE_PARAMS", "SpCoGibbs", "label_summary", "mcmc_diagnostics", "mcmc_summary"),
    "kernel",
)
"""The names imported on first use and the module (of this package) that defines each."""

__all__ = [
    "DEFAULT_SAVE_PARAMS",
    "GibbsChain",
    "GibbsOptions",
    "GibbsRun",
    "GibbsState",
    "HyperparameterOptions",
    "SpCoGibbs",
    "StepInfo",
    "advance",
    "gibbs_sweep",
    "init",
    "label_log_conditionals",
    "label_summary",
    "log_joint",
    "mcmc_diagnostics",
    "mcmc_summary",
    "run_gibbs",
    "start_chain",
    "step",
]


__getattr__, __dir__ = lazy_names(__name__, _HOMES)
