r"""A compiled (numba) Gibbs sweep: the conditionals of :mod:`spcopyro.gibbs.sweep`, faster.

:func:`gibbs_sweep_numba` is a drop-in for :func:`~spcopyro.gibbs.sweep.gibbs_sweep` (same
arguments, same :class:`~spcopyro.gibbs.state.GibbsState` out) that samples from the same
distribution, though not with the same random numbers.

**Cell labels (eq. 13).** The cells are visited colour block after colour block in the plan's
order, each drawn from

.. math::

    p(C_i = l \mid \text{rest}) \propto \pi_l \, e^{\gamma n_l(i)}
        \prod_{t \in i} \theta_{l, f_t} \, w_{l, S_t}
        = B_l(i) \, e^{\gamma n_l(i)},

B(i) being the cell's *background*: pi for a cell without observations, and for observed cell m
the row :math:`B_{ml} = \exp(\log\pi_l + \mathrm{loglik}_{ml} - \max_{l'}(\cdot))` of one
[M + 1, L] table computed per sweep (the loglik [M, L] of
:func:`~spcopyro.gibbs.sweep.observation_log_likelihood` is one matrix product; row M holds pi).
No cell of a colour block neighbours another cell of the same block, so updating the labels in
place while looping over a block draws each cell of the block from its conditional given the
other blocks: exactly the reference's block update. Every cell then uses the reference's
background + neighbour mixture (module docstring of :mod:`~spcopyro.gibbs.sweep`), writing
e^{gamma n} = 1 + expm1(gamma n),

.. math::

    p(C_i = l) \propto B_l + \sum_{s=1}^{D} \delta_{l a_s} \, B_{a_s}
        \frac{\mathrm{expm1}(\gamma n_{a_s}(i))}{n_{a_s}(i)},

a_s being the label in neighbour slot s (slots sharing a label add up to that label's part, and
a missing neighbour carries a sentinel label L + s of background weight 0): with probability
sum(B) / (sum(B) + neighbour mass) the label comes from B (a binary search in pi's CDF, or a
scan of an observed cell's row), else from the slots. That is O(D^2 + log L) a cell without
observations and O(D^2 + L) one with; the kernel is compiled per D, its slot loops unrolled and
branch-free.

**Globals (eqs. 14-17).** pi ~ Dir(pi_concentration + m), theta_l ~ Dir(chi + image counts of
the cells labelled l), w_l ~ Dir(beta + word counts of those cells), drawn in log space from
log-gamma variates (Marsaglia & Tsang, 2000, with log G(a) = log G(a + 1) + log(U) / a for
a < 1) and normalised by log-sum-exp, so concentrations far below 1 (alpha / L) never underflow.
A switched-off modality contributes zero statistics (its distributions are drawn from the prior),
as in the reference.

**Randomness** (:mod:`spcopyro.gibbs.numba_random`): each call draws one seed from the given
:class:`torch.Generator` and runs its own xoshiro256++ stream from it. A seeded run is
reproducible bit for bit, but its numbers differ from the torch backend's: only the
distributions agree (what the tests check). The sweep plan is flattened and checked once per
plan (:mod:`spcopyro.gibbs.numba_plan`).

**Limits.** exp(gamma D) must stay finite: :class:`~spcopyro.config.SpCoConfig` keeps
``gamma * D <= 700``. The first call compiles the kernels (seconds); ``cache=True`` stores them
next to this file for later processes. Importing this module raises :class:`ImportError` when
numba is missing (:func:`~spcopyro.gibbs.backends.get_backend` relies on that).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import torch
from numba import njit

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.numba_plan import flat_plan
from spcopyro.gibbs.numba_random import (
    draw_seed,
    fill_log_gamma,
    normalise_log_rows,
    rng_state,
    sample_log_gamma_numba,
    sample_standard_normal_numba,
    uniform,
)
from spcopyro.gibbs.state import GibbsState, SweepPlan
from spcopyro.model import ModelData

__all__ = [
    "gibbs_sweep_numba",
    "potts_agreements_numba",
    "sample_globals_numba",
    "sample_labels_numba",
    "sample_log_gamma_numba",
    "sample_standard_normal_numba",
]

# ------------------------------------------------------------------------------ label kernels


@njit(cache=True, inline="always")
def _upper_bound(cdf: np.ndarray, x: float) -> int:
    """The first l with cdf[l] > x (cdf [L] non-decreasing, x < cdf[L - 1]), branch-free."""
    base = 0
    length = cdf.shape[0]
    while length > 1:
        half = length >> 1
        base = base + half if cdf[base + half - 1] <= x else base
        length -= half
    return base


@njit(cache=True)
def _prepare_labels(labels: np.ndarray, out: np.ndarray, num_concepts: int) -> int:
    """Copy labels [N] into out [N + D] with sentinels L + s at N + s; the first label outside
    [0, L) gives its position (-1 if all are valid)."""
    N = labels.shape[0]
    bad = -1
    for i in range(N):
        value = labels[i]
        if bad < 0 and (value < 0 or value >= num_concepts):
            bad = i
        out[i] = value
    for s in range(out.shape[0] - N):
        out[N + s] = num_concepts + s
    return bad


@njit(cache=True)
def _background_sums(background: np.ndarray, num_concepts: int) -> tuple[np.ndarray, np.ndarray]:
    """(totals [M + 1] row sums of background[:, :L], cdf [L] of its last row, pi's).

    Summed in the order the background draws scan them, so a uniform below a total always
    finds its label.
    """
    rows = background.shape[0]
    totals = np.empty(rows)
    cdf = np.empty(num_concepts)
    for r in range(rows):
        running = 0.0
        for l in range(num_concepts):
            running += background[r, l]
            if r == rows - 1:
                cdf[l] = running
        totals[r] = running
    return totals, cdf


@njit(cache=True, inline="always")
def _background_label(
    background: np.ndarray, totals: np.ndarray, pi_cdf: np.ndarray, r: int, state: np.ndarray
) -> int:
    """A label l drawn with probability background[r, l] / totals[r].

    Row M (no observations, pi): binary search in pi's CDF; an observed row: a linear scan.
    """
    x = uniform(state) * totals[r]
    while x >= totals[r]:  # U * total can round up to total (probability ~1e-16): redraw
        x = uniform(state) * totals[r]
    if r == totals.shape[0] - 1:
        return _upper_bound(pi_cdf, x)
    running = 0.0
    label = 0
    while label < pi_cdf.shape[0] - 1:  # x < totals[r], the running sum's last value
        running += background[r, label]
        if running > x:
            break
        label += 1
    return label


@functools.cache
def label_kernel(num_neighbours: int) -> Callable[..., None]:
    """The compiled label sweep for D = ``num_neighbours`` (one compilation per D).

    D is a compile-time constant of the kernel (a closure variable), so its loops over the
    neighbour slots unroll and the D^2 label comparisons run branch-free. The kernel's arguments:
    labels [N + D] int64 (sentinels L + s at N + s), redrawn in place; cells [N], neighbours
    [N, D], rows [N] (M where unobserved) of the :class:`FlatPlan`; background [M + 1, L + D]
    (zero columns L..L+D-1); tilt [D + 1] expm1(gamma k) / k; state the RNG.
    """
    D = num_neighbours

    @njit(cache=True)
    def sample_labels(
        labels: np.ndarray,
        cells: np.ndarray,
        neighbours: np.ndarray,
        rows: np.ndarray,
        background: np.ndarray,
        tilt: np.ndarray,
        state: np.ndarray,
    ) -> None:
        L = background.shape[1] - D
        totals, pi_cdf = _background_sums(background, L)
        slot_labels = np.empty(D, np.int64)  # [D] a_s
        cumulative = np.empty(D)  # [D] running slot masses
        for p in range(cells.shape[0]):
            r = rows[p]
            for s in range(D):
                slot_labels[s] = labels[neighbours[p, s]]
            mass = 0.0  # slot s: B_{a_s} expm1(gamma n_{a_s}) / n_{a_s}
            for s in range(D):
                agree = 0
                for t in range(D):
                    agree += slot_labels[t] == slot_labels[s]
                mass += background[r, slot_labels[s]] * tilt[agree]
                cumulative[s] = mass
            u = uniform(state) * (totals[r] + mass)
            label = slot_labels[D - 1]
            for s in range(D - 2, -1, -1):
                label = slot_labels[s] if u < cumulative[s] else label
            if u >= mass:  # the background part: B_l / totals[r]
                label = _background_label(background, totals, pi_cdf, r, state)
            labels[cells[p]] = label

    return sample_labels


@njit(cache=True)
def _count_cells(labels: np.ndarray, cells_per_concept: np.ndarray) -> None:
    """Add 1 to the zeroed cells_per_concept [1, L] for every label (eq. 14's m_l)."""
    for i in range(labels.shape[0]):
        cells_per_concept[0, labels[i]] += 1.0


@njit(cache=True)
def _modality_statistics(
    labels: np.ndarray, obs_cells: np.ndarray, counts: np.ndarray, out: np.ndarray
) -> None:
    """Add each observed cell's counts [M, K_m] to its concept's row of the zeroed out [L, K_m]
    (eqs. 16-17)."""
    for m in range(obs_cells.shape[0]):
        c = labels[obs_cells[m]]
        for k in range(counts.shape[1]):
            out[c, k] += counts[m, k]


# ----------------------------------------------------------------------------- python side


def _as_array(tensor: torch.Tensor, dtype: type) -> np.ndarray:
    """A C-contiguous numpy view of a CPU tensor (a copy only if dtype or layout differ)."""
    return np.ascontiguousarray(tensor.detach().cpu().numpy(), dtype=dtype)


def _check_data(data: ModelData) -> None:
    """What the compiled kernels index without bounds checks: obs_cells [M] in [0, N), one row
    of counts per observed cell. Raises ValueError naming the mismatch."""
    N, M = data.num_free, data.obs_cells.shape[0]
    if data.obs_cells.dim() != 1 or (
        M and (int(data.obs_cells.min()) < 0 or int(data.obs_cells.max()) >= N)
    ):
        raise ValueError(f"ModelData.obs_cells must be [M] free indices in [0, {N})")
    for modality in data.modalities:
        shape = tuple(modality.counts.shape)
        if len(shape) != 2 or shape[0] != M:
            raise ValueError(
                f"the counts of modality {modality.name!r} have shape {shape}, expected ({M}, ...)"
            )


def _check_state(state: GibbsState, data: ModelData, config: SpCoConfig) -> None:
    """Shapes of the state against data and config; raises ValueError naming the mismatch."""
    _check_data(data)
    L = config.num_concepts
    expected = {"labels": (data.num_free,), "log_pi": (L,)}
    for name, shape in expected.items():
        actual = tuple(getattr(state, name).shape)
        if actual != shape:
            raise ValueError(f"GibbsState.{name} has shape {actual}, expected {shape}")
    if len(state.log_emissions) != len(data.modalities):
        raise ValueError(
            f"GibbsState.log_emissions has {len(state.log_emissions)} tables for "
            f"{len(data.modalities)} modalities"
        )
    for modality, table in zip(data.modalities, state.log_emissions, strict=True):
        shape = (L, modality.counts.shape[1])
        if tuple(table.shape) != shape:
            raise ValueError(
                f"GibbsState.log_emissions of {modality.name!r} has shape "
                f"{tuple(table.shape)}, expected {shape}"
            )


def _extended_labels(labels: torch.Tensor, num_neighbours: int, config: SpCoConfig) -> np.ndarray:
    """[N + D] int64 copy of the labels followed by the sentinels L + s; checks 0 <= label < L."""
    source = _as_array(labels, np.int64)  # [N]
    out = np.empty(source.shape[0] + num_neighbours, dtype=np.int64)
    bad = _prepare_labels(source, out, config.num_concepts)
    if bad >= 0:
        raise ValueError(
            f"labels[{bad}] = {int(source[bad])} lies outside [0, {config.num_concepts}) "
            "(config.num_concepts)"
        )
    return out


def _neighbour_tilt(config: SpCoConfig, num_neighbours: int) -> np.ndarray:
    """[D + 1] expm1(gamma k) / k for k = 0..D (0 at k = 0); finite because SpCoConfig keeps
    gamma * D <= 700."""
    k = np.arange(num_neighbours + 1, dtype=np.float64)  # [D + 1]
    return np.expm1(config.gamma * k) / np.maximum(k, 1.0)


def _background_table(state: GibbsState, data: ModelData, config: SpCoConfig) -> np.ndarray:
    """[M + 1, L + D] the per-cell backgrounds B (module doc), the D last columns 0.

    Row m < M: exp(log pi + loglik[m] - max), loglik [M, L] = f_m . log theta_l + S_m . log w_l
    (+ any further modality; eqs. 5, 7; :func:`spcopyro.likelihood.observation_log_likelihood`);
    row M: exp(log pi - max).
    The zero columns are the sentinel labels of missing neighbours.
    """
    L, D, M = config.num_concepts, data.neighbours.shape[1], data.obs_cells.shape[0]
    # The products run in torch (MKL): numpy's OpenBLAS threads fight torch's OpenMP threads.
    logits_t = torch.zeros(M + 1, L, dtype=torch.float64)  # [M + 1, L]
    for index, (modality, table) in enumerate(
        zip(data.modalities, state.log_emissions, strict=True)
    ):
        if not config.uses(modality.name):
            continue
        log_phi = table.detach().to(torch.float64)  # [L, K_m]
        counts = modality.counts.to(torch.float64)  # [M, K_m]
        if index == 0:
            torch.matmul(counts, log_phi.T, out=logits_t[:M])  # [M, K] @ [K, L]
        else:
            logits_t[:M].addmm_(counts, log_phi.T)  # [M, K_m] @ [K_m, L]
    logits = logits_t.numpy()
    logits[M] = 0.0
    logits += _as_array(state.log_pi, np.float64)
    top = logits.max(axis=1, keepdims=True)  # [M + 1, 1]; NaN or +inf anywhere shows here
    if not np.isfinite(top).all():
        row = int(np.flatnonzero(~np.isfinite(top[:, 0]))[0])
        where = f"the observed cell in row {row} of data.obs_cells" if row < M else "pi"
        raise ValueError(
            f"log pi + observation log-likelihood is not finite for {where}: NaN or infinite "
            "values in GibbsState.log_pi / log_emissions or in the data's counts"
        )
    logits -= top
    table = np.zeros((M + 1, L + D))  # [M + 1, L + D]
    np.exp(logits, out=table[:, :L])
    return table


def _sample_labels_array(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    plan: SweepPlan | None,
    rng: np.ndarray,
) -> np.ndarray:
    """[N + D] int64 new labels (then the sentinels), drawn with the RNG state ``rng``."""
    _check_state(state, data, config)
    D = data.neighbours.shape[1]
    flat = flat_plan(plan, data)
    tilt = _neighbour_tilt(config, D)
    labels = _extended_labels(state.labels, D, config)
    background = _background_table(state, data, config)
    label_kernel(D)(
        labels, flat.cells, flat.neighbours, flat.background_rows, background, tilt, rng
    )
    return labels


def _statistics(
    labels: np.ndarray, obs_cells: np.ndarray, data: ModelData, config: SpCoConfig
) -> tuple[np.ndarray, list[np.ndarray]]:
    """cells_per_concept [1, L] and, per modality, the counts per concept [L, K_m] (zeros for a
    switched-off modality)."""
    L = config.num_concepts
    cells_per_concept = np.zeros((1, L))
    _count_cells(labels, cells_per_concept)
    per_modality = []
    for modality in data.modalities:
        out = np.zeros((L, modality.counts.shape[1]))
        if config.uses(modality.name):
            _modality_statistics(labels, obs_cells, _as_array(modality.counts, np.float64), out)
        per_modality.append(out)
    return cells_per_concept, per_modality


def _bad_concentration(name: str, statistics: np.ndarray, base: float, index: int) -> ValueError:
    row, column = divmod(index, statistics.shape[1])
    value = float(base + statistics.ravel()[index])
    return ValueError(
        f"the Dirichlet concentration of {name}[{row}, {column}] is {value!r}, not finite and "
        "positive: negative or non-finite values in the data's counts?"
    )


def _sample_globals_arrays(
    labels: np.ndarray,
    data: ModelData,
    config: SpCoConfig,
    rng: np.ndarray,
    previous: tuple[torch.Tensor, ...] | None = None,
    unobserved_refresh: float = 1.0,
) -> tuple[torch.Tensor, tuple[torch.Tensor, ...]]:
    """(log pi, per-modality log distributions) given valid int64 labels [N] (or longer), drawn
    with ``rng``: pi first, then each modality in ``data.modalities`` order.

    With ``previous`` (the state's log distributions) and ``unobserved_refresh`` < 1, a sweep
    keeps, with probability 1 - unobserved_refresh, the rows of concepts holding no observed cell
    (the reference's :func:`~spcopyro.gibbs.sweep.concepts_to_refresh`; here the coin is the
    first draw of the global step).
    """
    labels = labels[: data.num_free]
    obs_cells = _as_array(data.obs_cells, np.int64)
    partial = (
        previous is not None and unobserved_refresh < 1.0 and uniform(rng) >= unobserved_refresh
    )
    cells_per_concept, statistics = _statistics(labels, obs_cells, data, config)
    rows = np.unique(labels[obs_cells]) if partial else None  # [G] concepts with observed cells
    log_pi = np.empty((1, config.num_concepts))
    bad = fill_log_gamma(float(config.pi_concentration), cells_per_concept, log_pi, rng)
    if bad >= 0:
        raise _bad_concentration("pi", cells_per_concept, config.pi_concentration, bad)
    tables = []
    for modality, per_concept in zip(data.modalities, statistics, strict=True):
        base = config.concentration(modality.name)
        if rows is not None:
            per_concept = np.ascontiguousarray(per_concept[rows])  # [G, K_m]
        draw = np.empty(per_concept.shape)
        bad = fill_log_gamma(float(base), per_concept, draw, rng)
        if bad >= 0:
            raise _bad_concentration(modality.parameter, per_concept, base, bad)
        tables.append(draw)
    log_pi_t = torch.from_numpy(normalise_log_rows(log_pi)[0])
    if rows is None:
        return log_pi_t, tuple(torch.from_numpy(normalise_log_rows(t)) for t in tables)
    log_emissions = []
    for kept, draw in zip(previous, tables, strict=True):
        table = kept.clone()
        table[torch.from_numpy(rows)] = torch.from_numpy(normalise_log_rows(draw))
        log_emissions.append(table)
    return log_pi_t, tuple(log_emissions)


def sample_labels_numba(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    plan: SweepPlan | None = None,
) -> torch.Tensor:
    """[N] int64 new labels, every free cell drawn from eq. (13), one colour block at a time.

    Same distribution as :func:`~spcopyro.gibbs.sweep.sample_labels`; draws one seed from
    ``generator``.

    Raises:
        ValueError: as :func:`gibbs_sweep_numba`.
    """
    labels = _sample_labels_array(state, data, config, plan, rng_state(draw_seed(generator)))
    return torch.from_numpy(labels[: data.num_free])


def sample_globals_numba(
    labels: torch.Tensor, data: ModelData, config: SpCoConfig, generator: torch.Generator
) -> tuple[torch.Tensor, tuple[torch.Tensor, ...]]:
    """(log pi [L], per-modality log distributions [L, K_m]) from their conjugate conditionals
    (eqs. 14-17).

    Same distribution as :func:`~spcopyro.gibbs.sweep.sample_globals`; draws one seed from
    ``generator``.

    Raises:
        ValueError: ``labels`` is not [N] or holds a label outside [0, L), or ``data`` is
            inconsistent (observed cells outside the map, count rows != observed cells).
    """
    _check_data(data)
    if tuple(labels.shape) != (data.num_free,):
        raise ValueError(f"labels have shape {tuple(labels.shape)}, expected ({data.num_free},)")
    checked = _extended_labels(labels, 0, config)
    return _sample_globals_arrays(checked, data, config, rng_state(draw_seed(generator)))


def gibbs_sweep_numba(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    plan: SweepPlan | None = None,
    unobserved_refresh: float = 1.0,
) -> GibbsState:
    """One iteration of Algorithm 1, compiled: every cell label, then pi and the emission
    distributions.

    A drop-in for :func:`~spcopyro.gibbs.sweep.gibbs_sweep` with the same distribution. Draws one
    seed from ``generator`` per call, so a seeded run is reproducible bit for bit.

    Raises:
        ValueError: the state's shapes do not match ``data`` / ``config``, a label lies outside
            [0, L), ``plan`` was made for other data, or gamma * D > 700 (overflow).
    """
    rng = rng_state(draw_seed(generator))
    labels = _sample_labels_array(state, data, config, plan, rng)  # [N + D]
    return GibbsState(
        torch.from_numpy(labels[: data.num_free]),
        *_sample_globals_arrays(labels, data, config, rng, state.log_emissions, unobserved_refresh),
    )


@njit(cache=True)
def _potts_agreements_kernel(labels: np.ndarray, pairs: np.ndarray) -> int:
    total = 0
    for p in range(pairs.shape[0]):
        total += labels[pairs[p, 0]] == labels[pairs[p, 1]]
    return total


def potts_agreements_numba(labels: torch.Tensor, pairs: torch.Tensor) -> torch.Tensor:
    """E(C) of :func:`spcopyro.model.potts_agreements` (float64 scalar), compiled."""
    total = _potts_agreements_kernel(_as_array(labels, np.int64), _as_array(pairs, np.int64))
    return torch.tensor(float(total), dtype=torch.float64)
