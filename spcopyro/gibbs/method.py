"""Gibbs sampling as an :class:`~spcopyro.inference.protocol.InferenceMethod` (its registry
entry)."""

from __future__ import annotations

import dataclasses

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.hyper_options import as_hyper_options
from spcopyro.gibbs.hyperparameters import hyperparameter_summary
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import GibbsRun, run_gibbs
from spcopyro.inference.protocol import InferenceMethod, InferenceOutput, RunArgs, Trace
from spcopyro.model import ModelData


def output_from_run(run: GibbsRun, options: dict[str, object] | None = None) -> InferenceOutput:
    """A run's :class:`InferenceOutput`: the MAP-visited state as the point estimate, the last
    state's labels beside it, the log joint per sweep as the trace. pi and the emissions are
    that state's draws (``parameters_drawn``): a result reports their posterior means given the
    labels instead (:mod:`spcopyro.results.posterior_means`). With sampled hyperparameters,
    ``options["hyperparameters"]`` holds their summary (initial, final, posterior mean and sd over
    the second half of the sweeps:
    :func:`~spcopyro.gibbs.hyperparameters.hyperparameter_summary`)."""
    best = run.best_state
    options = dict(options or {})
    if run.hyperparameters is not None and "hyper" in options:
        hyper = as_hyper_options(options["hyper"])
        options["hyperparameters"] = hyperparameter_summary(
            run.hyperparameters, run.initial_config, hyper
        )
    return InferenceOutput(
        labels=best.labels.numpy().astype("int64"),
        pi=best.log_pi.exp().numpy(),
        emissions=tuple(table.exp().numpy() for table in best.log_emissions),
        trace=Trace(run.log_joint, run.num_concepts, run.seconds, "log joint"),
        best_iteration=run.best_sweep,
        labels_final=run.final_state.labels.numpy().astype("int64"),
        options=options,
        label_samples=run.label_samples,
        sample_iterations=run.sample_sweeps,
        parameters_drawn=True,
    )


def gibbs_record(options: GibbsOptions, sweeps: int | str, backend_used: str) -> dict[str, object]:
    """The sampler's part of ``config.json``: the sweeps, the options (``backend`` as asked,
    e.g. ``"auto"``) and ``backend_used``, the backend that ran (the torch and numba backends
    draw different random streams from one seed)."""
    return {"sweeps": sweeps, **dataclasses.asdict(options), "backend_used": backend_used}


class GibbsInference(InferenceMethod):
    """Algorithm 1 (:func:`spcopyro.gibbs.run.run_gibbs`) behind the common interface."""

    name = "gibbs"
    objective_name = "log joint"
    options_type = GibbsOptions
    title = "Gibbs sampling"

    def fit(
        self, data: ModelData, config: SpCoConfig, options: GibbsOptions, request: RunArgs
    ) -> InferenceOutput:
        run = run_gibbs(
            data, config, request.iterations, options=options, generator=request.generator,
            init_labels=request.init_labels, progress=request.progress, thin=request.thin,
        )  # fmt: skip
        return output_from_run(run, gibbs_record(options, request.iterations, run.backend))
