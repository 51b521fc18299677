"""Mean-field CAVI as an :class:`~spcopyro.inference.protocol.InferenceMethod` (registry:
``cavi``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from spcopyro.config import SpCoConfig
from spcopyro.guides.factors import mean_emissions, mean_pi
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.run import (
    VariationalRun,
    initial_q,
    resolve_backend,
    run_variational,
)
from spcopyro.inference.protocol import InferenceOutput, Trace, method_options
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


class CAVIInference:
    """Mean-field coordinate ascent (:mod:`spcopyro.guides.cavi`) behind the common
    interface."""

    name = "cavi"
    objective_name = "ELBO"

    def default_options(self) -> VariationalOptions:
        return VariationalOptions()

    def run(
        self,
        data: ModelData,
        config: SpCoConfig,
        *,
        iterations: int,
        generator: torch.Generator,
        init_labels: torch.Tensor | None = None,
        options: VariationalOptions | None = None,
        progress: bool | None = None,
        thin: int = 0,
    ) -> InferenceOutput:
        options = method_options(options, VariationalOptions, "CAVI")
        q = initial_q(data, config, generator, init_labels, init=options.init)
        run = run_variational(
            data, config, iterations, options=options, q=q, progress=progress, thin=thin
        )
        record = {
            "iterations": iterations,
            **dataclasses.asdict(options),
            "backend_used": resolve_backend(options.backend),
        }
        return output_from_variational(run, record)
