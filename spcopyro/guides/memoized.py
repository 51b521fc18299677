r"""Memoized variational inference on spatial blocks, for maps of millions of cells.

**Which stochastic VI, and why memoized.** Two ways to update the global factors q(pi), q(phi)
from part of the map at a time exist. Natural-gradient stochastic VI (Hoffman, Blei, Wang &
Paisley 2013, JMLR 14) rescales one block's expected statistics to the whole map and moves the
factors' natural parameters a Robbins-Monro step rho_t = (tau + t)^-kappa towards it; it needs
(tau, kappa) tuned, its ELBO is noisy, and it only converges as rho_t -> 0. Memoized VI (Hughes &
Sudderth 2013, NIPS) caches every block's expected sufficient statistics S_b and keeps

.. math::

    q(\pi) = \mathrm{Dir}\big(a_\pi + \textstyle\sum_b S_b^{\mathrm{cells}}\big), \qquad
    q(\phi_{ml}) = \mathrm{Dir}\big(a_m + \textstyle\sum_b S_{b,ml}^{(m)}\big),

(eqs. 14-17 in expectation, :func:`~spcopyro.guides.factors.update_factors`), replacing
block b's term when b is revisited. Because the memo of every block always equals the statistic
of its current q(C), the factors are exactly the optimal ones for the whole current q: each step
is exact block-coordinate ascent on the full ELBO (:mod:`spcopyro.guides.elbo`) -- no step
size, and at a fixed coupling the ELBO never decreases, after every step and every pass. The usual
objection to memoizing (the local parameters of the whole data set must be kept) does not apply
here: the Potts field couples every block to its neighbours, so q(C) of the whole map is kept
anyway, as the boundary condition of the next block's local step. That is why this module is
memoized VI, not SVI.

**One step** takes ``blocks_per_step`` blocks (:mod:`spcopyro.guides.blocks`: square tiles
of the grid) and

1. updates q(C_i) of their cells, colour class by colour class (``local_sweeps`` times), with
   the mean-field update of eq. (13) in expectation (:mod:`spcopyro.guides.cavi`),

   .. math::

       \log q(C_i = l) = E[\log\pi_l] + \gamma \sum_{r \sim i} q_r(l)
           + \textstyle\sum_m x_i^{(m)} \cdot E[\log\phi_{ml}] + \text{const},

   the neighbours r outside the blocks keeping their current q (the block's boundary);
2. recomputes the blocks' statistics S_b from their new q and swaps them into the running sums
   (the memo: :class:`~spcopyro.guides.memo.Memo`);
3. sets the global factors from the sums.

One *pass* visits every block once (in a fresh random order, or raster order); after it the sums
are re-added from the memo (no drift) and the ELBO is evaluated exactly, in chunks. With one block
covering the map, a step is one iteration of full-batch CAVI
(:func:`~spcopyro.guides.run.run_variational`) -- tested equal. Both are run by the shared
driver (:func:`spcopyro.inference.driver.drive`), a pass being one :func:`step`.

**Memory.** q(C) is kept as one ``[N, L]`` tensor of ``dtype`` (float32 by default: 80 MB for
10^6 cells at L = 20), updated in place; the exponentials and softmax are computed in float64 per
step, on the step's cells only (so with float32 storage each update is rounded to float32 and
the ELBO's monotonicity holds up to that rounding; ``dtype="float64"`` makes it exact). The
memo holds ``[B, L]`` concept sizes and ``[B_obs, L, K_m]`` counts for the B_obs blocks that hold
observations. The ELBO is accumulated over chunks of cells and neighbour pairs, so nothing
``[N, L]`` other than q is ever allocated. The blocks' index is O(N) int64.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np
import torch

from spcopyro._util.number_checks import is_finite_number, is_integer
from spcopyro._util.progress import setup_bar
from spcopyro.config import SpCoConfig
from spcopyro.guides.blocks import Blocks, grid_blocks
from spcopyro.guides.cavi_method import output_from_variational
from spcopyro.guides.factors import (
    GlobalFactors,
    PiFamily,
    expected_log_emissions,
    expected_log_pi,
    kl_to_prior,
    update_factors,
)
from spcopyro.guides.memo import Memo
from spcopyro.guides.run import (
    VariationalRun,
    cell_xlogy_sum,
    remaining,
    resumed,
    warn_flat_fit,
)
from spcopyro.inference.driver import Trajectory, drive
from spcopyro.inference.initialisation import check_labels, random_labels
from spcopyro.inference.protocol import InferenceMethod, InferenceOutput, RunArgs
from spcopyro.inference.schedule import warn_unfinished_annealing
from spcopyro.likelihood import ConceptStatistics
from spcopyro.model import DTYPE, ModelData

CHUNK = 1 << 16
"""Cells (or neighbour pairs) per chunk of the exact ELBO."""

COEFFICIENT_BLOCK = 1 << 22
"""Numbers (32 MiB in float64) whose lgamma :func:`chunked_coefficients` takes in one call."""

_DTYPES = {"float32": torch.float32, "float64": torch.float64}


@dataclass(frozen=True)
class StochasticOptions:
    """How memoized VI on spatial blocks runs (module docstring).

    Attributes:
        block_size: a block is a ``block_size x block_size`` tile of the grid (cells).
        blocks_per_step: blocks whose local steps share one global update.
        local_sweeps: colour-scheduled mean-field sweeps over a step's cells before the global
            update (more than one refines the blocks' q against their boundary first).
        order: ``"random"``: every pass visits the blocks in a fresh random order (drawn from the
            run's generator); ``"raster"``: in tile order.
        anneal_passes: gamma rises linearly to the model's value over this many passes (0: no
            annealing), on the schedule of every method
            (:func:`spcopyro.inference.schedule.annealed_gamma`); the ELBO rises monotonically
            only once gamma is at its value.
        pi_family: q(pi) Dirichlet (the model's) or truncated stick-breaking
            (:mod:`spcopyro.guides.factors`).
        tolerance: stop once a pass at full gamma changes the ELBO by less than
            ``tolerance * |ELBO|`` (0: run every pass; the passes asked for are a ceiling). The
            default 1e-7 is CAVI's.
        dtype: storage of q(C), ``"float32"`` (compact) or ``"float64"``.
        backend: the local sweeps and the ELBO's pair and entropy sums in torch (``"torch"``),
            compiled (``"numba"``, :mod:`spcopyro.guides.numba_memoized`; equal to rounding) or
            ``"auto"`` (numba where it imports).
    """

    block_size: int = 64
    blocks_per_step: int = 1
    local_sweeps: int = 1
    order: Literal["random", "raster"] = "random"
    anneal_passes: int = 0
    pi_family: PiFamily = "dirichlet"
    tolerance: float = 1e-7
    dtype: Literal["float32", "float64"] = "float32"
    backend: Literal["auto", "torch", "numba"] = "auto"

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"StochasticOptions.{name}={getattr(self, name)!r}: {why}")

        for name in ("block_size", "blocks_per_step", "local_sweeps"):
            value = getattr(self, name)
            if not is_integer(value) or value < 1:
                raise bad(name, "must be an integer >= 1")
        if not is_integer(self.anneal_passes) or self.anneal_passes < 0:
            raise bad("anneal_passes", "must be an integer >= 0")
        if self.order not in ("random", "raster"):
            raise bad("order", "must be 'random' or 'raster'")
        if self.pi_family not in ("dirichlet", "stick-breaking"):
            raise bad("pi_family", "must be 'dirichlet' or 'stick-breaking'")
        tolerance = self.tolerance
        if not (is_finite_number(tolerance) and tolerance >= 0):
            raise bad("tolerance", "must be a finite number >= 0")
        if self.dtype not in _DTYPES:
            raise bad("dtype", f"must be one of {sorted(_DTYPES)}")
        if self.backend not in ("auto", "torch", "numba"):
            raise bad("backend", "must be 'auto', 'torch' or 'numba'")


def compiled_path(backend: str):  # noqa: ANN201
    """The :mod:`spcopyro.guides.numba_memoized` module for ``backend`` (``"auto"``: where numba
    imports), or None for the torch path.

    Raises:
        ImportError: ``"numba"`` was asked for and numba is missing.
    """
    if backend == "torch":
        return None
    try:
        import spcopyro.guides.numba_memoized as compiled
    except ImportError:
        if backend == "numba":
            raise
        return None
    return compiled


# ---------------------------------------------------------------------------------------------
# Steps and passes
# ---------------------------------------------------------------------------------------------


def local_step(
    q: torch.Tensor,
    factors: GlobalFactors,
    data: ModelData,
    config: SpCoConfig,
    blocks: Blocks,
    batch: list[int],
    gamma: float,
    rows: torch.Tensor,
    sweeps: int = 1,
) -> None:
    """Update q(C) of the cells of the blocks in ``batch`` in place, colour class by colour
    class, given the global ``factors`` and the current q outside (module docstring, step 1).

    ``rows``: ``[N]`` each cell's row in the count matrices, -1 if unobserved
    (:meth:`ModelData.observation_rows <spcopyro.model.ModelData.observation_rows>`).
    """
    log_pi = expected_log_pi(factors)  # [L]
    log_phi = expected_log_emissions(factors)  # per modality [L, K_m]
    colours = blocks.starts.shape[1] - 1
    parts = [
        torch.cat([blocks.order[int(blocks.starts[b, c]) : int(blocks.starts[b, c + 1])]
                   for b in batch])
        for c in range(colours)
    ]  # fmt: skip
    for _ in range(sweeps):
        for cells in parts:
            if cells.numel() == 0:
                continue
            neighbours = data.neighbours[cells]  # [n, D]
            valid = (neighbours >= 0).unsqueeze(-1).to(q.dtype)  # [n, D, 1]
            around = (q[neighbours.clamp_min(0)] * valid).sum(1)  # [n, D, L] -> [n, L]
            logits = log_pi + gamma * around.to(DTYPE)  # [n, L]
            cell_rows = rows[cells]  # [n]
            observed = torch.nonzero(cell_rows >= 0).squeeze(-1)  # [n_obs]
            if observed.numel():
                obs_rows = cell_rows[observed]
                loglik = torch.zeros(observed.numel(), q.shape[1], dtype=DTYPE)  # [n_obs, L]
                for modality, lphi in zip(data.modalities, log_phi, strict=True):
                    if config.uses(modality.name):
                        loglik += modality.counts[obs_rows] @ lphi.T  # [n_obs, K_m] @ [K_m, L]
                logits[observed] += loglik
            q[cells] = torch.softmax(logits, dim=-1).to(q.dtype)


def exact_elbo(
    q: torch.Tensor,
    factors: GlobalFactors,
    statistics: ConceptStatistics,
    data: ModelData,
    config: SpCoConfig,
    coefficients: torch.Tensor | None = None,
    compiled: object = None,
) -> float:
    """The ELBO of :func:`spcopyro.guides.elbo.elbo`, accumulated over chunks (``compiled``: the
    :mod:`~spcopyro.guides.numba_memoized` module, whose loop sums the pairs and entropies).

    ``statistics`` must be q's (the memo's sums): the label and observation terms are
    sum_l N_l E[log pi_l] + sum_mlk S_mlk E[log phi_mlk], the Potts term and the entropy are
    summed over chunks of neighbour pairs and of cells (float64 accumulation).
    ``coefficients``: the observed counts' multinomial coefficients, if already computed
    (:func:`chunked_coefficients`).
    """
    if coefficients is None:
        coefficients = chunked_coefficients(data, config)
    log_pi = expected_log_pi(factors)  # [L]
    total = (statistics.cells * log_pi).sum()
    for modality, counts, lphi in zip(
        data.modalities, statistics.counts, expected_log_emissions(factors), strict=True
    ):
        if config.uses(modality.name):
            total = total + (counts * lphi).sum()
    if compiled is not None:
        agreements, entropy = compiled.pair_and_entropy_sums(q, data)
    else:
        agreements = torch.zeros((), dtype=DTYPE)
        for lo in range(0, data.pairs.shape[0], CHUNK):
            pairs = data.pairs[lo : lo + CHUNK]  # [c, 2]
            agreements += (q[pairs[:, 0]].to(DTYPE) * q[pairs[:, 1]].to(DTYPE)).sum()
        entropy = torch.zeros((), dtype=DTYPE) - cell_xlogy_sum(q, CHUNK)  # +0.0 if one-hot
    total = total + config.gamma * agreements + coefficients
    return float(total - kl_to_prior(factors, data, config) + entropy)


def chunked_coefficients(
    data: ModelData, config: SpCoConfig, advance: Callable[[int], None] | None = None
) -> torch.Tensor:
    r""":func:`~spcopyro.likelihood.multinomial_coefficients` summed over chunks of
    observed cells (the dense one holds several ``[M, K_m]`` temporaries at once);
    ``advance(k)`` after each block of k chunks (:func:`_coefficient_chunks` in all).

    A chunk of c rows adds :math:`\sum_{i \in \text{chunk}} \big(\log\Gamma(n_i + 1) -
    \sum_k \log\Gamma(x_{ik} + 1)\big)`, :math:`n_i = \sum_k x_{ik}`, to the float64 total,
    chunk after chunk. The elementwise work is done for up to ``COEFFICIENT_BLOCK`` numbers (many
    chunks) at a time, each chunk's rows then summed on their own, so the total is the same to the
    last bit as chunk by chunk; the block only sets how many torch calls there are (a dozen a
    chunk before 2026-12-05, each joining torch's thread team: on a loaded machine those waits,
    not the lgamma, were the cost; docs/speed.md, "Threads"). The density's cross term
    :math:`\sum_k x_k \log p_k` is zero at log p = 0 and not computed. Most of the image counts
    are not zero under a footprint (99.2-99.7% of them on simulated maps), so skipping zeros
    saves nothing.
    """
    total = 0.0
    for modality in data.modalities:
        if config.uses(modality.name):
            counts = modality.counts  # [M, K_m]
            rows = _chunk_rows(counts)
            span = rows * max(1, COEFFICIENT_BLOCK // (rows * counts.shape[-1]))  # whole chunks
            for lo in range(0, counts.shape[0], span):
                block = counts[lo : lo + span]  # [b, K_m]
                logs = torch.add(block, 1).lgamma_().sum(-1)  # [b] sum_k lgamma(x_k + 1)
                terms = block.sum(-1).add_(1).lgamma_() - logs  # [b] the rows' coefficients
                for start in range(0, terms.shape[0], rows):
                    total += float(terms[start : start + rows].sum())  # one chunk's rows
                if advance is not None:
                    advance(-(-terms.shape[0] // rows))
    return torch.tensor(total, dtype=DTYPE)


def _chunk_rows(counts: torch.Tensor) -> int:
    """Rows of ``counts`` ``[M, K_m]`` in a chunk of :func:`chunked_coefficients`: about
    :data:`CHUNK` numbers."""
    return max(1, CHUNK // counts.shape[-1])


def _coefficient_chunks(data: ModelData, config: SpCoConfig) -> int:
    """How many chunks :func:`chunked_coefficients` sums."""
    return sum(
        -(-m.counts.shape[0] // _chunk_rows(m.counts))
        for m in data.modalities
        if config.uses(m.name)
    )


def compact_initial_q(
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    init_labels: torch.Tensor | None = None,
    init_q: torch.Tensor | None = None,
    dtype: torch.dtype = torch.float32,
) -> torch.Tensor:
    """[N, L] the starting q(C) in ``dtype``, as :func:`~spcopyro.guides.run.initial_q`
    (the same random labels from the same generator) but never materialised in float64."""
    N, L = data.num_free, config.num_concepts
    if init_q is not None:
        init_q = torch.as_tensor(init_q)
        if init_q.shape != (N, L):
            raise ValueError(f"init_q must be [{N}, {L}], got {tuple(init_q.shape)}")
        if not torch.is_floating_point(init_q):
            raise ValueError(f"init_q must be floating point, got {init_q.dtype}")
        sums = init_q.to(DTYPE).sum(-1)
        if (init_q < 0).any() or not torch.allclose(sums, torch.ones_like(sums), atol=1e-5):
            raise ValueError("init_q's rows must be probability vectors")
        return init_q.to(dtype).clone()
    labels = random_labels(N, config, generator) if init_labels is None else init_labels
    labels = check_labels(labels, N, config)
    return torch.zeros(N, L, dtype=dtype).scatter_(1, labels.unsqueeze(1), 1.0)


class StochasticState(NamedTuple):
    """The state of memoized VI between passes. :func:`step` updates ``q`` and ``memo`` in place
    (q is the map's largest tensor) and returns the state with the new ``factors``."""

    q: torch.Tensor
    """[N, L] q(C_i = l) in the options' ``dtype``."""
    blocks: Blocks
    memo: Memo
    factors: GlobalFactors
    """q(pi) and every q(phi_m) from the memo's sums: the optimum given the whole q."""
    rows: torch.Tensor
    """[N] int64 each cell's row in the count matrices, -1 if unobserved."""
    coefficients: torch.Tensor
    """[] the observed counts' multinomial coefficients (:func:`chunked_coefficients`)."""
    local_rows: np.ndarray | None = None
    """[N] int64 scratch of the compiled path (all -1 between steps), None on the torch path."""

    def nbytes(self) -> dict[str, int]:
        """Bytes of the run's own tensors (q, the blocks' index, the memo, the row map)."""

        def size(*tensors: torch.Tensor) -> int:
            return sum(t.element_size() * t.numel() for t in tensors)

        return {
            "q": size(self.q),
            "blocks": size(*self.blocks),
            "memo": self.memo.nbytes(),
            "rows": size(self.rows),
            "scratch": 0 if self.local_rows is None else self.local_rows.nbytes,
        }


class StochasticInfo(NamedTuple):
    """What one pass of memoized VI did."""

    objective: float
    """The exact ELBO after the pass, at the model's gamma."""
    num_concepts: int
    """Concepts that are some cell's most probable one."""
    gamma: float
    """The coupling of the pass's local steps."""


def start_state(
    data: ModelData,
    config: SpCoConfig,
    q: torch.Tensor,
    options: StochasticOptions,
    blocks: Blocks | None = None,
    progress: bool | None = None,
) -> StochasticState:
    """``init``: the memo and the global factors of q ``[N, L]`` (:func:`compact_initial_q`);
    ``blocks`` overrides the tiles of ``options.block_size``. On a large map a progress bar
    counts the memo's blocks and the coefficients' chunks
    (:func:`~spcopyro._util.progress.setup_bar`; ``progress`` False: none)."""
    if q.shape != (data.num_free, config.num_concepts):
        raise ValueError(
            f"q must be [{data.num_free}, {config.num_concepts}], got {tuple(q.shape)}"
        )
    blocks = grid_blocks(data, options.block_size) if blocks is None else blocks
    if blocks.block_of.shape != (data.num_free,):
        raise ValueError(
            f"blocks were made for {blocks.block_of.shape[0]} cells, the data has {data.num_free}"
        )
    steps = blocks.num_blocks + _coefficient_chunks(data, config)
    bar = setup_bar(data.num_free, steps, f"memoized VI setup on {data.num_free:,} cells", "step",
                    progress)  # fmt: skip
    memo = Memo(q, data, config, blocks, advance=bar.update)
    factors = update_factors(memo.statistics(), data, config, options.pi_family)
    coefficients = chunked_coefficients(data, config, advance=bar.update)
    bar.close()
    scratch = None
    if compiled_path(options.backend) is not None:
        scratch = np.full(data.num_free, -1, dtype=np.int64)
    return StochasticState(q, blocks, memo, factors, data.observation_rows(), coefficients,
                           scratch)  # fmt: skip


init = start_state


def step(
    state: StochasticState,
    data: ModelData,
    config: SpCoConfig,
    gamma: float,
    options: StochasticOptions,
    generator: torch.Generator,
) -> tuple[StochasticState, StochasticInfo]:
    """One pass at coupling ``gamma`` (module docstring): the blocks in a fresh random order
    drawn from ``generator`` (or raster order), ``options.blocks_per_step`` at a time: their
    local step, their memo swapped, the globals from the sums; then the sums re-added from the
    memo and the exact ELBO."""
    num_blocks = state.blocks.num_blocks
    if options.order == "random":
        visit = torch.randperm(num_blocks, generator=generator).tolist()
    else:
        visit = list(range(num_blocks))
    factors = state.factors
    compiled = compiled_path(options.backend) if state.local_rows is not None else None
    for lo in range(0, num_blocks, options.blocks_per_step):
        batch = visit[lo : lo + options.blocks_per_step]
        if compiled is not None:
            compiled.local_step(
                state.q, factors, data, config, state.blocks, batch, gamma,
                state.memo.observed, state.local_rows, options.local_sweeps,
            )  # fmt: skip
        else:
            local_step(state.q, factors, data, config, state.blocks, batch, gamma, state.rows,
                       options.local_sweeps)  # fmt: skip
        for block in batch:
            state.memo.replace(state.q, block)
        factors = update_factors(state.memo.statistics(), data, config, options.pi_family)
    state.memo.resum()
    statistics = state.memo.statistics()
    factors = update_factors(statistics, data, config, options.pi_family)
    value = exact_elbo(state.q, factors, statistics, data, config, state.coefficients, compiled)
    used = int(torch.unique(state.q.argmax(-1)).numel())
    return state._replace(factors=factors), StochasticInfo(value, used, float(gamma))


def run_stochastic(
    data: ModelData,
    config: SpCoConfig,
    passes: int,
    *,
    q: torch.Tensor,
    generator: torch.Generator,
    options: StochasticOptions | None = None,
    blocks: Blocks | None = None,
    progress: bool | None = None,
    callback: Callable[[int, StochasticState], None] | None = None,
    description: str = "memoized VI",
    thin: int = 0,
    resume: Trajectory | None = None,
) -> VariationalRun:
    """At most ``passes`` passes of memoized VI (:func:`step`) from ``q`` ``[N, L]`` (updated in
    place; :func:`compact_initial_q`), run by the shared driver: annealed per
    ``options.anneal_passes``, stopped once the ELBO settles (``options.tolerance``).
    ``blocks`` overrides the tiles of ``options.block_size``; ``generator`` draws the random
    block orders. ``callback(pass, state)``, if given, is called after every pass; ``thin`` > 0
    keeps the argmax labels every ``thin`` passes. ``resume``: the record of the run ``q`` was
    reached by (a checkpoint's), continued here with the memo summed afresh from ``q``."""
    options = StochasticOptions() if options is None else options
    if not isinstance(options, StochasticOptions):
        raise TypeError(f"options must be StochasticOptions, got {type(options).__name__}")
    if not is_integer(passes) or passes < 1:
        raise ValueError(f"passes must be an integer >= 1, got {passes!r}")
    warn_unfinished_annealing(options.anneal_passes, passes, "anneal_passes", "pass", resume)
    run = drive(
        start_state(data, config, q, options, blocks, progress),
        lambda state, gamma: step(state, data, config, gamma, options, generator), passes,
        gamma=config.gamma, anneal=options.anneal_passes, tolerance=options.tolerance, thin=thin,
        labels=lambda state: state.q.argmax(-1), num_concepts=config.num_concepts,
        progress=progress, description=description, unit="pass", callback=callback,
        resume=resume, marginals=lambda state: state.q,
    )  # fmt: skip
    return VariationalRun.of(run, run.state.q, run.state.factors)


# ---------------------------------------------------------------------------------------------
# The inference method
# ---------------------------------------------------------------------------------------------


class StochasticVIInference(InferenceMethod):
    """Memoized VI on spatial blocks behind the common interface (registry: ``stochastic-vi``);
    ``iterations`` are passes over the blocks (a ceiling: it stops at ``options.tolerance``)."""

    name = "stochastic-vi"
    objective_name = "ELBO"
    options_type = StochasticOptions
    title = "stochastic-vi"
    resumable = True

    def fit(
        self, data: ModelData, config: SpCoConfig, options: StochasticOptions, request: RunArgs
    ) -> InferenceOutput:
        dtype = _DTYPES[options.dtype]
        q, before = resumed(request) or (
            compact_initial_q(data, config, request.generator, request.init_labels, dtype=dtype),
            None,
        )
        run = run_stochastic(
            data, config, remaining(request), q=q.to(dtype), generator=request.generator,
            options=options, progress=request.progress, thin=request.thin, resume=before,
        )  # fmt: skip
        warn_flat_fit(run.q, config, "memoized VI", request, before, options.anneal_passes,
                      "anneal_passes")  # fmt: skip
        used = "torch" if compiled_path(options.backend) is None else "numba"  # auto resolved
        record = {
            "iterations": request.iterations,
            **dataclasses.asdict(options),
            "backend_used": used,
        }
        return output_from_variational(run, record)
