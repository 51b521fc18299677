"""The variational run loop: alternate the global factors and a label-field update, trace the
objective, stop at convergence.

Every variational method here shares it and differs only in how it updates q(C) given the
global factors: mean field (:func:`spcopyro.guides.cavi.update_labels`), loopy belief
propagation, or a compiled mean-field backend. A :class:`LabelUpdate` is that step.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from tqdm.auto import tqdm

from spcopyro._util.progress import progress_enabled
from spcopyro.config import SpCoConfig
from spcopyro.guides.cavi import one_hot, update_labels
from spcopyro.guides.elbo import elbo
from spcopyro.guides.factors import GlobalFactors, update_factors
from spcopyro.guides.options import VariationalOptions
from spcopyro.inference.initialisation import check_labels, random_labels
from spcopyro.likelihood import ConceptStatistics, concept_statistics
from spcopyro.model import DTYPE, ModelData

LabelUpdate = Callable[[torch.Tensor, GlobalFactors, float], torch.Tensor]
"""``update(q, factors, gamma) -> q``: one pass over the label field at coupling ``gamma``."""

Objective = Callable[[torch.Tensor, GlobalFactors], float]
"""``objective(q, factors)``: the value traced each iteration (the model's ELBO by default)."""


@dataclass
class VariationalRun:
    """A finished variational fit: q and what each iteration recorded."""

    q: torch.Tensor
    """[N, L] float64 q(C_i = l)."""
    factors: GlobalFactors
    objective: np.ndarray
    """[S] the objective after each iteration (the ELBO at the model's gamma)."""
    num_concepts: np.ndarray
    """[S] concepts that are some cell's most probable one."""
    seconds: np.ndarray
    """[S] cumulative wall-clock seconds."""
    gammas: np.ndarray
    """[S] the coupling each iteration's label update used."""
    label_samples: np.ndarray | None = None
    """[S', N] int16 (int32 when L > 32767) argmax labels every ``thin`` iterations, or None."""
    sample_iterations: np.ndarray | None = None
    """[S'] the 0-based iterations of ``label_samples``."""
    stop_reason: str = ""
    """Why the run stopped: converged (the tolerance met) or the iteration ceiling reached."""

    @property
    def labels(self) -> torch.Tensor:
        """[N] every cell's most probable concept under q."""
        return self.q.argmax(-1)


def initial_q(
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    init_labels: torch.Tensor | None = None,
    init_q: torch.Tensor | None = None,
    init: str = "one-hot",
) -> torch.Tensor:
    """[N, L] the starting q(C): ``init_q`` as given (checked), one-hot ``init_labels`` (a Gibbs
    state's labels: the warm start from a sampler), or else by ``init``: one-hot uniformly
    random labels (``"one-hot"``) or a Dir(1) draw per cell (``"soft"``)."""
    N, L = data.num_free, config.num_concepts
    if init_q is not None:
        if init_q.shape != (N, L):
            raise ValueError(f"init_q must be [{N}, {L}], got {tuple(init_q.shape)}")
        q = init_q.to(DTYPE).clone()
        if (q < 0).any() or not torch.allclose(q.sum(-1), torch.ones(N, dtype=DTYPE)):
            raise ValueError("init_q's rows must be probability vectors")
        return q
    if init_labels is None and init == "soft":
        q = -torch.log(torch.rand(N, L, generator=generator, dtype=DTYPE))  # [N, L] Exp(1)
        return q / q.sum(-1, keepdim=True)  # Dir(1) rows
    if init not in ("one-hot", "soft"):
        raise ValueError(f"init must be 'one-hot' or 'soft', got {init!r}")
    labels = random_labels(N, config, generator) if init_labels is None else init_labels
    return one_hot(check_labels(labels, N, config), L)


def mean_field_update(data: ModelData, config: SpCoConfig, damping: float = 0.0) -> LabelUpdate:
    """The dense mean-field label update (:func:`spcopyro.guides.cavi.update_labels`)."""

    def update(q: torch.Tensor, factors: GlobalFactors, gamma: float) -> torch.Tensor:
        return update_labels(q, factors, data, config, gamma, damping)

    return update


def resolve_backend(backend: str) -> str:
    """``"torch"`` or ``"numba"``: ``"auto"`` is numba where it imports, else torch.

    Raises:
        ImportError: ``"numba"`` was asked for and numba is missing.
    """
    if backend == "torch":
        return "torch"
    try:
        import spcopyro.guides.numba_cavi  # noqa: F401
    except ImportError:
        if backend == "numba":
            raise
        return "torch"
    return "numba"


class _DenseField:
    """The torch reference's label field: a dense q [N, L] and a :class:`LabelUpdate`."""

    def __init__(
        self,
        q: torch.Tensor,
        data: ModelData,
        config: SpCoConfig,
        label_update: LabelUpdate,
        objective: Objective,
    ) -> None:
        self.q, self.data, self.config = q, data, config
        self.label_update, self.objective = label_update, objective

    def update(self, factors: GlobalFactors, gamma: float) -> None:
        self.q = self.label_update(self.q, factors, gamma)

    def statistics(self) -> ConceptStatistics:
        return concept_statistics(self.q, self.data, self.config)

    def elbo(self, factors: GlobalFactors) -> float:
        return self.objective(self.q, factors)

    def labels(self) -> torch.Tensor:
        return self.q.argmax(-1)

    def num_used(self) -> int:
        return int(torch.unique(self.q.argmax(-1)).numel())

    def dense(self, out: torch.Tensor) -> torch.Tensor:
        return self.q


def run_variational(
    data: ModelData,
    config: SpCoConfig,
    iterations: int,
    *,
    options: VariationalOptions | None = None,
    q: torch.Tensor,
    label_update: LabelUpdate | None = None,
    objective: Objective | None = None,
    progress: bool | None = None,
    description: str = "CAVI",
    thin: int = 0,
) -> VariationalRun:
    """``iterations`` rounds of: global factors from q(C), then ``label_update`` (mean field by
    default) at the annealed coupling. Stops early when ``options.tolerance`` says so.

    ``q`` ``[N, L]`` is the start (see :func:`initial_q`) and is updated in place. With neither
    ``label_update`` nor ``objective`` given, ``options.backend`` picks the mean-field update:
    the dense torch reference or the compiled sparse one
    (:class:`spcopyro.guides.numba_cavi.SparseMeanField`, ``options.support`` and
    ``options.threshold``), which keeps q sparse through the run and writes the dense q once at
    the end. ``thin`` > 0 keeps the argmax labels every ``thin`` iterations (int16, as Gibbs'
    label maps).
    """
    options = VariationalOptions() if options is None else options
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    if not isinstance(thin, int) or thin < 0:
        raise ValueError(f"thin must be an integer >= 0, got {thin!r}")
    custom = label_update is not None or objective is not None
    backend = "torch" if custom else resolve_backend(options.backend)
    if backend == "numba":
        from spcopyro.guides.numba_cavi import SparseMeanField

        field: _DenseField | SparseMeanField = SparseMeanField(
            q, data, config, support=options.support, threshold=options.threshold,
            damping=options.damping, active_tolerance=options.active_tolerance,
        )  # fmt: skip
    else:
        if objective is None:

            def objective(q: torch.Tensor, factors: GlobalFactors) -> float:
                return float(elbo(q, factors, data, config))

        update = label_update or mean_field_update(data, config, options.damping)
        field = _DenseField(q, data, config, update, objective)

    label_dtype = np.int16 if config.num_concepts <= np.iinfo(np.int16).max else np.int32
    values, used, seconds, gammas, samples, sampled = [], [], [], [], [], []
    start = time.perf_counter()
    bar = tqdm(total=iterations, desc=description, unit="it",
               disable=not progress_enabled(progress))  # fmt: skip
    factors = update_factors(field.statistics(), data, config, options.pi_family)
    with bar:
        for iteration in range(iterations):
            gamma = options.gamma_at(iteration, config.gamma)
            field.update(factors, gamma)
            factors = update_factors(field.statistics(), data, config, options.pi_family)
            values.append(field.elbo(factors))
            used.append(field.num_used())
            if thin and (iteration + 1) % thin == 0:
                samples.append(field.labels().numpy().astype(label_dtype))
                sampled.append(iteration)
            seconds.append(time.perf_counter() - start)
            gammas.append(gamma)
            bar.update()
            bar.set_postfix(objective=f"{values[-1]:.4g}", concepts=used[-1])
            if _converged(values, gammas, config.gamma, options.tolerance):
                reason = (
                    f"converged after {iteration + 1} iterations: the objective changed by less "
                    f"than tolerance {options.tolerance:g} x |objective|"
                )
                break
        else:
            reason = f"ran the {iterations} iterations asked for (not converged within them"
            reason += f" at tolerance {options.tolerance:g})" if options.tolerance else ")"
    q = field.dense(q)
    return VariationalRun(
        q, factors, np.asarray(values), np.asarray(used, dtype=np.int64),
        np.asarray(seconds), np.asarray(gammas),
        np.stack(samples) if samples else None,
        np.asarray(sampled, dtype=np.int64) if samples else None,
        reason,
    )  # fmt: skip


def _converged(values: list[float], gammas: list[float], gamma: float, tolerance: float) -> bool:
    """The last iteration at full gamma raised the objective by < tolerance * |objective|."""
    if tolerance <= 0 or len(values) < 2 or gammas[-2] != gamma:
        return False
    return abs(values[-1] - values[-2]) < tolerance * abs(values[-1])
