"""Mean-field CAVI as an :class:`~spcopyro.inference.protocol.InferenceMethod` (registry:
``cavi``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from spcopyro.config import SpCoConfig
from spcopyro.guides.factors import mean_emissions, mean_pi
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.run import (
    VariationalRun,
    initial_q,
    remaining,
    resolve_backend,
    resumed,
    run_variational,
    warn_flat_fit,
)
from spcopyro.inference.protocol import InferenceMethod, InferenceOutput, RunArgs, Trace
from spcopyro.model import ModelData


def output_from_variational(run: VariationalRun, options: dict[str, object]) -> InferenceOutput:
    """A variational run's output: argmax q as the labels, q as the marginals (float32), the
    posterior means of pi and phi, the ELBO per iteration as the trace; why it stopped is the
    record's ``stopped``."""
    if run.stop_reason:
        options = {**options, "stopped": run.stop_reason}
    return InferenceOutput(
        labels=run.labels.numpy().astype("int64"),
        pi=mean_pi(run.factors).numpy(),
        emissions=tuple(e.numpy() for e in mean_emissions(run.factors)),
        trace=Trace(run.objective, run.num_concepts, run.seconds, "ELBO"),
        best_iteration=len(run.objective) - 1,
        marginals=run.q.numpy().astype(np.float32),
        options=options,
        label_samples=run.label_samples,
        sample_iterations=run.sample_iterations,
    )


class CAVIInference(InferenceMethod):
    """Mean-field coordinate ascent (:mod:`spcopyro.guides.cavi`) behind the common
    interface."""

    name = "cavi"
    objective_name = "ELBO"
    options_type = VariationalOptions
    title = "CAVI"
    resumable = True

    def fit(
        self, data: ModelData, config: SpCoConfig, options: VariationalOptions, request: RunArgs
    ) -> InferenceOutput:
        q, before = resumed(request) or (
            initial_q(data, config, request.generator, request.init_labels, init=options.init),
            None,
        )
        run = run_variational(data, config, remaining(request), options=options, q=q,
                              progress=request.progress, thin=request.thin,
                              resume=before)  # fmt: skip
        warn_flat_fit(run.q, config, self.title, request, before, options.anneal_iterations,
                      init=options.init)  # fmt: skip
        record = {
            "iterations": request.iterations,
            **dataclasses.asdict(options),
            "backend_used": resolve_backend(options.backend),
        }
        # options.init, q's random start, as q_init: "init" names the start labels (fit_house
        # writes it for every method, which overwrote this one); given labels replace it
        q_init = record.pop("init")
        record["q_init"] = q_init if request.init_labels is None else "one-hot start labels"
        return output_from_variational(run, record)
