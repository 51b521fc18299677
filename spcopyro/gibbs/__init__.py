"""The enumerated-Gibbs sampler of SpCoMapping: pure sweep functions, a run loop, a Pyro kernel.

``sweep.py`` is the readable PyTorch reference (eqs. 13-17); ``numba_sweep.py`` the compiled
backend with the same distribution; ``api.run_gibbs`` the run loop; ``kernel.SpCoGibbs`` the
:class:`pyro.infer.mcmc.MCMCKernel`.
"""

from spcopyro.gibbs.api import GibbsRun, run_gibbs
from spcopyro.gibbs.kernel import SpCoGibbs, mcmc_diagnostics
from spcopyro.gibbs.state import GibbsState
from spcopyro.gibbs.sweep import gibbs_sweep, label_log_conditionals, log_joint

__all__ = [
    "GibbsRun",
    "GibbsState",
    "SpCoGibbs",
    "gibbs_sweep",
    "label_log_conditionals",
    "log_joint",
    "mcmc_diagnostics",
    "run_gibbs",
]
