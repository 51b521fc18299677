"""The names a user chooses from (``spcopyro fit --method/--init/--backend``), in a module that
imports nothing, so that the command line lists them without importing torch.

:data:`INFERENCE_METHOD_NAMES` are the keys of :data:`spcopyro.fit.registry.INFERENCE_METHODS`,
:data:`INITS` the starts of :func:`spcopyro.fit.starts.initial_labels`, :data:`BACKENDS` the Gibbs
sweep's implementations (:class:`spcopyro.gibbs.options.GibbsOptions`); tests check each against
the table it names; :data:`SAMPLERS` those of them that sample.
"""

INFERENCE_METHOD_NAMES = ("gibbs", "cavi", "lbp", "svi", "stochastic-vi", "vi-gibbs")
"""The inference methods by name (:mod:`spcopyro.fit.registry`)."""

SAMPLERS = ("gibbs", "vi-gibbs")
"""The methods that draw samples: a Gibbs chain's sweeps (vi-gibbs: after its CAVI start), whose
kept label maps (``marginal_samples``) give the marginals and the point estimate, and whose trace
is a chain's. Spelt once here, imported by :mod:`spcopyro.fit.house`,
:mod:`spcopyro.figures.trace` and the torch-free :mod:`spcopyro.cli.fit_options`."""

ESTIMATED_OBJECTIVES = ("svi",)
"""The methods whose objective is a stochastic estimate (SVI's ELBO: ``num_particles`` draws of
the globals a step), not the value itself."""


def objective_draws(method: str, inference: dict[str, object]) -> int:
    """The draws a step of ``method``'s objective estimate (``inference['num_particles']``, 1
    where unrecorded), or 0 for an objective computed exactly. The one rule of trace.png's axis
    ("ELBO estimate ... (1 draw a step)") and ``spcopyro fit``'s "stopped" line ("final ELBO
    estimate"): each tested ``method == "svi"`` itself."""
    if method not in ESTIMATED_OBJECTIVES:
        return 0
    return int(inference.get("num_particles") or 1)  # type: ignore[call-overload]


DEFAULT_METHOD = "gibbs"
"""Algorithm 1 of the paper."""

INITS = ("random", "gaussian", "spcoa", "rooms")
"""The named starts of a fit (:func:`spcopyro.fit.starts.initial_labels`; ``fit --init``): uniformly
random labels, k-means Gaussians over the observed cells, SpCoA pre-learning, or one concept per
geometric room."""

BACKENDS = ("auto", "torch", "numba")
"""The Gibbs sweep's implementations: ``auto`` takes numba when it is installed."""
