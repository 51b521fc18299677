"""VI then Gibbs (registry: ``vi-gibbs``): mean-field CAVI finds the regions fast, Gibbs sampling
then starts from q's most probable labels and explores the posterior around them.

This is the warm start from a variational result to the sampler; the other direction (a Gibbs
state starting VI) is any variational method run with ``init_labels`` (a one-hot q) -- e.g.
``spcopyro fit --method cavi --init-from GIBBS_OUT``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from spcopyro._util.number_checks import is_int
from spcopyro.config import SpCoConfig
from spcopyro.gibbs.method import gibbs_record, output_from_run
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.gibbs.run import run_gibbs
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.run import initial_q, run_variational
from spcopyro.inference.driver import DriveInterrupted
from spcopyro.inference.protocol import InferenceMethod, InferenceOutput, RunArgs
from spcopyro.inference.schedule import short_runs_meant, warn_unfinished_annealing
from spcopyro.model import ModelData


@dataclass(frozen=True)
class VIGibbsOptions:
    """``vi_iterations`` CAVI iterations (with ``variational`` options), then Gibbs sweeps (with
    ``gibbs`` options) from argmax q."""

    vi_iterations: int = 100
    variational: VariationalOptions = field(default_factory=VariationalOptions)
    gibbs: GibbsOptions = field(default_factory=GibbsOptions)

    def __post_init__(self) -> None:
        if not is_int(self.vi_iterations) or self.vi_iterations < 1:
            raise ValueError(
                f"VIGibbsOptions.vi_iterations={self.vi_iterations!r}: must be an integer >= 1"
            )
        # A wrong type failed later, in the fit, as an AttributeError naming neither field.
        for name, kind in (("variational", VariationalOptions), ("gibbs", GibbsOptions)):
            value = getattr(self, name)
            if not isinstance(value, kind):  # ValueError, as every options class's check
                raise ValueError(
                    f"VIGibbsOptions.{name} must be a {kind.__name__}, got {type(value).__name__}"
                )


class VIGibbsInference(InferenceMethod):
    """CAVI, then Gibbs from its labels. ``iterations`` counts the Gibbs sweeps; the trace is the
    sampler's log joint, its clock starting at the CAVI time (so quality-against-time curves
    include the warm start); the CAVI part is recorded in the options (``vi_seconds``,
    ``vi_elbo``). Every option reaches its part: ``variational`` (its init, annealing, tolerance,
    backend, ...) the CAVI run of at most ``vi_iterations``, ``gibbs`` the sampler; ``thin``
    the sampler's label maps."""

    name = "vi-gibbs"
    objective_name = "log joint"
    options_type = VIGibbsOptions
    title = "VI-then-Gibbs"

    def fit(
        self, data: ModelData, config: SpCoConfig, options: VIGibbsOptions, request: RunArgs
    ) -> InferenceOutput:
        generator, progress = request.generator, request.progress
        q = initial_q(data, config, generator, request.init_labels, init=options.variational.init)
        warn_unfinished_annealing(options.variational.anneal_iterations, options.vi_iterations,
                                  "variational.anneal_iterations", "iteration",
                                  length="vi_iterations")  # fmt: skip
        try:
            with short_runs_meant():  # warned above in vi-gibbs's names (--sweeps is Gibbs's)
                vi = run_variational(
                    data, config, options.vi_iterations, options=options.variational, q=q,
                    progress=progress,
                )  # fmt: skip
        except DriveInterrupted as stop:  # its count is CAVI's, not of the sweeps asked for
            stop.progress = (f"in its CAVI start, {len(stop.trajectory.objective)} of at most "
                             f"{options.vi_iterations} iterations done")  # fmt: skip
            raise
        try:
            run = run_gibbs(
                data, config, request.iterations, options=options.gibbs, generator=generator,
                init_labels=vi.labels, progress=progress, thin=request.thin,
            )  # fmt: skip
        except DriveInterrupted as stop:
            stop.progress = (f"{len(stop.trajectory.objective)} of {request.iterations} Gibbs "
                             f"sweeps done after its CAVI start")  # fmt: skip
            raise
        offset = float(vi.seconds[-1])
        run = dataclasses.replace(run, seconds=np.asarray(run.seconds) + offset)
        record = {
            **gibbs_record(options.gibbs, request.iterations, run.backend),
            "vi_iterations": options.vi_iterations,
            "variational": dataclasses.asdict(options.variational),
            "vi_seconds": offset,
            "vi_elbo": float(vi.objective[-1]),
            "vi_iterations_run": len(vi.objective),
            "vi_stopped": vi.stop_reason,
        }
        return output_from_run(run, record)
