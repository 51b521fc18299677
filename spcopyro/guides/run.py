"""What the variational methods share above the driver: the starting q(C), the finished run
(:class:`VariationalRun`), and CAVI's run (:func:`run_variational`).

Every method is a pure ``init`` / ``step`` pair run by the shared driver
(:func:`spcopyro.inference.driver.drive`: annealing, trace, tolerance stop, thinning, progress,
Ctrl-C): CAVI's torch reference (:mod:`spcopyro.guides.cavi`) and compiled sparse backend
(:mod:`spcopyro.guides.numba_cavi`), loopy BP (:mod:`spcopyro.guides.lbp_method`), memoized VI
(:mod:`spcopyro.guides.memoized`) and SVI (:mod:`spcopyro.guides.svi_method`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import torch

import spcopyro.guides.cavi as cavi
from spcopyro._util.messages import setting
from spcopyro.config import SpCoConfig
from spcopyro.guides.cavi import one_hot
from spcopyro.guides.factors import GlobalFactors
from spcopyro.guides.options import VariationalOptions, warn_numba_only_options
from spcopyro.inference.driver import Trajectory, drive
from spcopyro.inference.initialisation import check_labels, random_labels
from spcopyro.inference.protocol import RunArgs
from spcopyro.inference.schedule import short_runs_meant_now, warn_unfinished_annealing
from spcopyro.model import DTYPE, ModelData

logger = logging.getLogger("spcopyro")

FLAT_Q_SHARE = 0.9
"""A q(C) whose mean entropy per cell is at least this share of log L ended near uniform: its
map is the argmax of nearly flat marginals (:func:`flat_entropy`, the warnings of every
variational method)."""


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
    """[S', N] int16 (int32 when L > 32768) argmax labels every ``thin`` iterations, or None."""
    sample_iterations: np.ndarray | None = None
    """[S'] the 0-based iterations of ``label_samples``."""
    stop_reason: str = ""
    """Why the run stopped: converged (the tolerance met) or the iteration ceiling reached."""

    @property
    def labels(self) -> torch.Tensor:
        """[N] every cell's most probable concept under q."""
        return self.q.argmax(-1)

    @classmethod
    def of(cls, run: Trajectory, q: torch.Tensor, factors: GlobalFactors) -> VariationalRun:
        """The run of the driver's ``run`` whose final q and factors are ``q``, ``factors``."""
        return cls(
            q, factors, run.objective, run.num_concepts, run.seconds, run.gammas,
            run.label_samples, run.sample_iterations, run.stop_reason,
        )  # fmt: skip


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
    random labels (``"one-hot"``) or a Dir(1) draw per cell (``"soft"``).

    Raises:
        ValueError: ``init="soft"`` with ``init_labels``: the labels would replace the random
            draw, so one of the two asked for would be ignored.
    """
    N, L = data.num_free, config.num_concepts
    if init == "soft" and init_labels is not None:
        raise ValueError(
            "init='soft' draws q(C) at random, but init_labels were given (q one-hot on them): "
            "pass one of the two"
        )
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


def resumed(request: RunArgs) -> tuple[torch.Tensor, Trajectory] | None:
    """``(q [N, L], record)`` of ``request.resume`` (q copied: a run writes into its own), or
    None when the run starts afresh."""
    if request.resume is None:
        return None
    return request.resume.marginals.to(DTYPE).clone(), request.resume.trajectory


def remaining(request: RunArgs) -> int:
    """The iterations left of ``request.iterations`` after those of the run resumed."""
    done = 0 if request.resume is None else len(request.resume.trajectory.objective)
    if done >= request.iterations:
        raise ValueError(
            f"the checkpoint's run has done {done} iterations: nothing left of the "
            f"{request.iterations} asked for"
        )
    return request.iterations - done


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


def run_variational(
    data: ModelData,
    config: SpCoConfig,
    iterations: int,
    *,
    options: VariationalOptions | None = None,
    q: torch.Tensor,
    progress: bool | None = None,
    description: str = "CAVI",
    thin: int = 0,
    resume: Trajectory | None = None,
) -> VariationalRun:
    """At most ``iterations`` CAVI iterations from ``q`` ``[N, L]`` (see :func:`initial_q`;
    written with the final q): :func:`spcopyro.guides.cavi.step` or, with ``options.backend``
    numba, the compiled sparse :func:`spcopyro.guides.numba_cavi.step` (``options.support``,
    ``options.threshold``: q stays sparse through the run, densified once at the end), run by the
    shared driver at the annealed coupling (``options.anneal_iterations``) until the ELBO
    settles (``options.tolerance``). ``thin`` > 0 keeps the argmax labels every ``thin``
    iterations (int16, as Gibbs' label maps). ``resume``: the record of the run ``q`` was
    reached by (a checkpoint's: :mod:`spcopyro.guides.checkpoint`), continued here."""
    options = VariationalOptions() if options is None else options
    if resolve_backend(options.backend) == "numba":
        import spcopyro.guides.numba_cavi as backend

        def labels(state: backend.SparseCAVIState) -> torch.Tensor:
            return state.field.labels()

        def marginals(state: backend.SparseCAVIState) -> torch.Tensor:
            return state.field.dense()
    else:
        backend = cavi  # type: ignore[assignment]
        warn_numba_only_options(options, description)

        def labels(state: cavi.CAVIState) -> torch.Tensor:  # type: ignore[misc]
            return state.q.argmax(-1)

        def marginals(state: cavi.CAVIState) -> torch.Tensor:  # type: ignore[misc]
            return state.q

    state = backend.init(q, data, config, options)
    warn_unfinished_annealing(options.anneal_iterations, iterations, "anneal_iterations",
                              "iteration", resume)  # fmt: skip
    run = drive(
        state, lambda state, gamma: backend.step(state, data, config, gamma, options), iterations,
        gamma=config.gamma, anneal=options.anneal_iterations, tolerance=options.tolerance,
        thin=thin, labels=labels, num_concepts=config.num_concepts, progress=progress,
        description=description, resume=resume, marginals=marginals,
    )  # fmt: skip
    final = run.state
    dense = final.q if isinstance(final, cavi.CAVIState) else final.field.dense()
    if dense is not q:
        q.copy_(dense)
    return VariationalRun.of(run, q, final.factors)


def warn_flat_q(
    q: torch.Tensor,
    config: SpCoConfig,
    method: str,
    way_out: str,
    *,
    mean_field: bool = True,
    context: str = "",
) -> bool:
    r"""Warn (logger ``"spcopyro"``) when a variational method's ``q`` ``[N, L]`` ends near
    uniform: a mean entropy per cell of at least :data:`FLAT_Q_SHARE` of :math:`\log L`
    (:func:`flat_entropy`); its argmax map is then ties and small tilts, not regions. Returns
    whether it warned (never inside :func:`~spcopyro.inference.schedule.short_runs_meant`).
    The one check and wording of every method's warning; what is the method's own comes as
    arguments: ``method`` its name in the message, ``way_out`` the sentence that ends it (what
    would order the field: :func:`restart_way_out` for CAVI, loopy BP and memoized VI),
    ``mean_field`` whether its label update is mean field's (loopy BP's is not: its
    disordered fixed point is stable on other terms than gamma < L / D), ``context`` what
    else the parenthesis says (SVI: its start).

    Why it happens (docs/variational.md): away from the observations the mean-field update of
    a cell is :math:`q_i \propto \exp(E\log\pi + \gamma \sum_{j \sim i} q_j)`; at nearly
    uniform neighbours its tilt shrinks by about :math:`\gamma D / L` per update, so the
    disordered fixed point attracts every start near uniform while :math:`\gamma < L / D`
    (D neighbours; 30 at L = 120, D = 4). SVI's default random start (``label_smoothing`` 0.9,
    max q about 0.11 at L = 120) and annealing from gamma 0 lie in its basin, and from random
    one-hot labels Adam's steps lead there too; where few cells hold observations nothing
    breaks the symmetry. CAVI from random labels at full gamma orders at once (its
    colour-block update takes each cell to its neighbours' labels).

    Measured on the embedded house on its map's cells under ``paper-dp`` (L = 120, gamma 4),
    ``fit --cell-size map``: CAVI annealed over 20 iterations, or started from Dir(1) rows
    (``init="soft"``), and loopy BP annealed over 20 ended at 1.000 of log L (ARI 0.000, 0.015,
    0.062), one concept or a hundred "in use" by the argmax, without a word; CAVI and loopy BP
    from random one-hot labels at full gamma (``anneal_iterations=0``) ordered (0.009 and 0.020
    of log L, ARI 0.25 and 0.52)."""
    L = q.shape[-1]
    entropy = flat_entropy(q)
    if entropy is None:
        return False
    degree = int(config.connectivity)
    if mean_field and config.gamma < L / degree:
        why = (f"gamma {config.gamma:g} < L / D = {L / degree:g}: mean field's disordered fixed "
               "point holds a start near uniform")  # fmt: skip
    else:
        why = "the start stayed in the label update's disordered fixed point"
    logger.warning(
        "%s's q(C) ended near uniform: mean entropy %.3f nats a cell, %.1f%% of log L = %.3f, "
        "so its map is the argmax of nearly flat marginals, close to arbitrary, whatever its "
        "concepts in use (%s%s). %s",
        method, entropy, 100 * entropy / math.log(L), math.log(L), why,
        f"; {context}" if context else "", way_out,
    )  # fmt: skip
    return True


def restart_way_out(
    anneal: int,
    anneal_name: str = "anneal_iterations",
    init: str = "one-hot",
    warm: bool = False,
) -> str:
    """The way out of :func:`warn_flat_q` for CAVI, loopy BP and memoized VI: no annealing
    (``anneal`` iterations of option ``anneal_name``; memoized VI's ``anneal_passes``), one-hot
    start rows instead of Dir(1) ones (``init="soft"`` unless the start was ``warm``: given
    labels or a resumed q), or a fitted start."""
    ways = []  # each named as the options (or fit_house) take it, then as fit does
    if anneal:
        off = f"{anneal_name}=0"
        ways.append(f"{setting(off, f'--method-option {off}')}: it annealed from gamma 0 over "
                    f"{anneal}, inside that point's basin")  # fmt: skip
    if init == "soft" and not warm:
        one_hot = setting("init='one-hot'", "--method-option init=one-hot")
        ways.append(f"{one_hot}: Dir(1) rows start near uniform")
    ways.append(f"a fitted start, e.g. of a Gibbs fit: {setting('init=result', '--init-from OUT')}")
    return "Try " + "; or ".join(ways)


def warn_flat_fit(
    q: torch.Tensor,
    config: SpCoConfig,
    method: str,
    request: RunArgs,
    resume: Trajectory | None,
    anneal: int,
    anneal_name: str = "anneal_iterations",
    *,
    init: str = "one-hot",
    mean_field: bool = True,
) -> bool:
    """:func:`warn_flat_q` at the end of a CAVI, loopy BP or memoized VI fit, its way out
    :func:`restart_way_out` (``anneal``, ``anneal_name``, ``init``): the start was warm when
    ``request`` gave start labels or the run continued ``resume``, a checkpoint's record."""
    warm = request.init_labels is not None or resume is not None
    way_out = restart_way_out(anneal, anneal_name, init=init, warm=warm)
    return warn_flat_q(q, config, method, way_out, mean_field=mean_field)


def flat_entropy(q: torch.Tensor) -> float | None:
    """The mean entropy a cell of ``q`` ``[N, L]`` when it is at least :data:`FLAT_Q_SHARE`
    of log L (q near uniform: the flat-q warnings of every variational method), else None;
    None too at L < 2 and inside :func:`~spcopyro.inference.schedule.short_runs_meant`."""
    L = q.shape[-1]
    if L < 2 or short_runs_meant_now():
        return None
    entropy = mean_cell_entropy(q)
    return entropy if entropy >= FLAT_Q_SHARE * math.log(L) else None


def mean_cell_entropy(q: torch.Tensor, rows: int = 1 << 16) -> float:
    """The mean over cells of q's entropy in nats, ``q`` ``[N, L]``: minus
    :func:`cell_xlogy_sum` (a block of ``rows`` cells at a time) over N."""
    return -cell_xlogy_sum(q, rows) / max(q.shape[0], 1)


def cell_xlogy_sum(q: torch.Tensor, rows: int = 1 << 16) -> float:
    r""":math:`\sum_{i,l} q_{il} \log q_{il}`, minus the entropy of ``q`` ``[N, L]`` summed over
    cells: xlogy summed in float64 a block of ``rows`` cells at a time, blocks in order (a
    float64 copy of a large map's whole q would be N L 8 bytes: 0.96 GB at 10^6 cells and
    L = 120, beside memoized VI's float32 q). The one loop of :func:`mean_cell_entropy` and
    memoized VI's :func:`~spcopyro.guides.memoized.exact_elbo`; each negates it its own way, so
    a one-hot q's zero keeps the sign each gave."""
    q = q.detach()
    total = 0.0
    for start in range(0, q.shape[0], rows):
        block = q[start : start + rows].to(torch.float64)  # [rows, L]
        total += float(torch.special.xlogy(block, block).sum())
    return total
