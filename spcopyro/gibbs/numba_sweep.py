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
[M + 1, L] table computed per sweep (:mod:`spcopyro.gibbs.numba_background`: the loglik [M, L]
of :func:`~spcopyro.gibbs.sweep.observation_log_likelihood` as one matrix product per modality,
through the footprints' factored counts where they have one; row M holds pi; where every
modality has them, one row per footprint pattern, which the cells of that pattern share:
:func:`~spcopyro.gibbs.numba_background.row_classes`, the same draws to the bit).
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
sum(B) / (sum(B) + neighbour mass) the label comes from B (pi's alias table for a cell without
observations, a scan of its row for one with), else from the slots. The loop itself, its layout
and what it counts on the way (E(C) and the concept sizes, for the run loop's log joint) are
:mod:`spcopyro.gibbs.numba_labels`'s.

**Globals (eqs. 14-17).** pi ~ Dir(pi_concentration + m), theta_l ~ Dir(chi + image counts of
the cells labelled l), w_l ~ Dir(beta + word counts of those cells), from normalised gamma
variates (:func:`~spcopyro.gibbs.numba_random.dirichlet_log_rows`: Marsaglia & Tsang, 2000, drawn
linearly and logged in one vectorised pass; log G(a) = log G(a + 1) + log(U) / a for a < 1, in
log space, so concentrations far below 1 (alpha / L) never underflow). A switched-off modality
contributes zero statistics (its distributions are drawn from the prior), as in the reference.
Optionally (:func:`~spcopyro.gibbs.numba_globals.prior_thread`, ``SPCOPYRO_PRIOR_THREAD``; off
by default: it did not pay reliably on a shared 2-core machine) the sweep draws them in two parts
(:mod:`spcopyro.gibbs.numba_globals`): the Gamma(b) variates of every entry, whose shape does
not depend on the labels, from streams of their own started before the label loop (on a worker
thread while the loop runs), then the entries with nonzero statistics after it; exact, and the
same numbers whichever thread draws. With ``unobserved_refresh`` < 1 the one-pass draw is used.

**Randomness** (:mod:`spcopyro.gibbs.numba_random`): each call draws one seed from the given
:class:`torch.Generator` and runs its own xoshiro256++ stream from it (and a second seed for
the prior part of the globals in the two-part modes). A seeded run is
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

import numpy as np
import torch
from numba import njit

from spcopyro.config import SpCoConfig
from spcopyro.gibbs.numba_background import background_table, row_classes
from spcopyro.gibbs.numba_globals import (
    PriorDraws,
    abandon_prior_draws,
    finish_globals,
    start_prior_draws,
    two_part,
)
from spcopyro.gibbs.numba_labels import (
    compact_label_dtype,
    compact_labels,
    count_cells,
    label_plan,
    label_sweep_kernel,
)
from spcopyro.gibbs.numba_log_joint import (
    label_counts_numba,
    potts_agreements_numba,
    remember_sweep,
    trace_numba,
)
from spcopyro.gibbs.numba_random import (
    dirichlet_log_rows,
    draw_seed,
    rng_state,
    sample_log_gamma_numba,
    sample_standard_normal_numba,
    uniform,
)
from spcopyro.gibbs.state import GibbsState, SweepPlan
from spcopyro.model import ModelData

__all__ = [
    "gibbs_sweep_numba",
    "label_counts_numba",
    "potts_agreements_numba",
    "trace_numba",
    "sample_globals_numba",
    "sample_labels_numba",
    "sample_log_gamma_numba",
    "sample_standard_normal_numba",
]

# ------------------------------------------------------------------------------ statistics


@njit(cache=True, nogil=True)
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
    """[N + D] compact copy (:func:`~spcopyro.gibbs.numba_labels.compact_label_dtype`) of the
    labels followed by the sentinels L + s; checks 0 <= label < L."""
    source = _as_array(labels, np.int64)  # [N]
    dtype = compact_label_dtype(config.num_concepts, num_neighbours)
    out = np.empty(source.shape[0] + num_neighbours, dtype=dtype)
    bad = compact_labels(source, out, config.num_concepts)
    if bad >= 0:
        raise ValueError(
            f"labels[{bad}] = {int(source[bad])} lies outside [0, {config.num_concepts}) "
            "(config.num_concepts)"
        )
    return out


def _neighbour_tilt(config: SpCoConfig, num_neighbours: int) -> np.ndarray:
    """[D + 1] expm1(gamma k) / k for k = 0..D (0 at k = 0); finite because SpCoConfig keeps
    gamma * D <= 700. Read-only, cached per (gamma, D)."""
    return _tilt(float(config.gamma), int(num_neighbours))


@functools.lru_cache(maxsize=64)
def _tilt(gamma: float, num_neighbours: int) -> np.ndarray:
    k = np.arange(num_neighbours + 1, dtype=np.float64)  # [D + 1]
    tilt = np.expm1(gamma * k) / np.maximum(k, 1.0)
    tilt.flags.writeable = False
    return tilt


def _sample_labels_array(
    state: GibbsState,
    data: ModelData,
    config: SpCoConfig,
    plan: SweepPlan | None,
    rng: np.ndarray,
) -> tuple[np.ndarray, int]:
    """([N + D] compact new labels (then the sentinels), E(C) of those labels), drawn with the
    RNG state ``rng`` (:mod:`spcopyro.gibbs.numba_labels`)."""
    _check_state(state, data, config)
    D = data.neighbours.shape[1]
    layout = label_plan(plan, data)
    tilt = _neighbour_tilt(config, D)
    labels = _extended_labels(state.labels, D, config)
    classes = row_classes(data)  # one row per footprint pattern, where the rows repeat
    background = background_table(state, data, config, classes)  # [M + 1 or U + 1, L + D]
    rows = layout.rows if classes is None else classes.of[layout.rows]  # [N] int32
    agreements = label_sweep_kernel(D)(
        labels, layout.order, layout.neighbours, rows, layout.segments, layout.modes,
        layout.earlier,
        background, tilt, rng,
    )  # fmt: skip
    return labels, int(agreements)


def _statistics(
    labels: np.ndarray, obs_cells: np.ndarray, data: ModelData, config: SpCoConfig
) -> tuple[np.ndarray, list[np.ndarray]]:
    """cells_per_concept [1, L] and, per modality, the counts per concept [L, K_m] (zeros for a
    switched-off modality), from integer labels [N] (or longer: the first N count)."""
    L = config.num_concepts
    cells_per_concept = np.zeros((1, L))
    count_cells(labels, data.num_free, cells_per_concept[0])
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
    cell_counts: np.ndarray | None = None,
) -> tuple[torch.Tensor, tuple[torch.Tensor, ...]]:
    """(log pi, per-modality log distributions) given valid int64 labels [N] (or longer), drawn
    with ``rng``: pi first, then each modality in ``data.modalities`` order.

    With ``previous`` (the state's log distributions) and ``unobserved_refresh`` < 1, a sweep
    keeps, with probability 1 - unobserved_refresh, the rows of concepts holding no observed cell
    (the reference's :func:`~spcopyro.gibbs.sweep.concepts_to_refresh`; here the coin is the
    first draw of the global step). ``cell_counts`` [L], if given, receives the concept sizes.
    """
    obs_cells = _as_array(data.obs_cells, np.int64)
    partial = (
        previous is not None and unobserved_refresh < 1.0 and uniform(rng) >= unobserved_refresh
    )
    cells_per_concept, statistics = _statistics(labels, obs_cells, data, config)
    if cell_counts is not None:
        cell_counts[:] = cells_per_concept[0]
    rows = np.unique(labels[obs_cells]).astype(np.int64) if partial else None  # [G] concepts
    log_pi, bad = dirichlet_log_rows(float(config.pi_concentration), cells_per_concept, rng)
    if bad >= 0:
        raise _bad_concentration("pi", cells_per_concept, config.pi_concentration, bad)
    tables = []
    for modality, per_concept in zip(data.modalities, statistics, strict=True):
        base = config.concentration(modality.name)
        if rows is not None:
            per_concept = np.ascontiguousarray(per_concept[rows])  # [G, K_m]
        draw, bad = dirichlet_log_rows(float(base), per_concept, rng)
        if bad >= 0:
            raise _bad_concentration(modality.parameter, per_concept, base, bad)
        tables.append(draw)
    log_pi_t = torch.from_numpy(log_pi[0])
    if rows is None:
        return log_pi_t, tuple(torch.from_numpy(t) for t in tables)
    log_emissions = []
    for kept, draw in zip(previous, tables, strict=True):
        table = kept.clone()
        table[torch.from_numpy(rows)] = torch.from_numpy(draw)
        log_emissions.append(table)
    return log_pi_t, tuple(log_emissions)


def _start_globals(
    data: ModelData,
    config: SpCoConfig,
    generator: torch.Generator,
    labels: torch.Tensor | None = None,
) -> PriorDraws | None:
    """Start the prior part of the globals' draw (:mod:`~spcopyro.gibbs.numba_globals`: pi
    [1, L], then each modality's [L, K_m]) from a seed drawn from ``generator``; None (nothing
    drawn) in the one-pass mode (:func:`~spcopyro.gibbs.numba_globals.prior_thread`, the
    default) or where a concentration is not finite and positive (the one-pass draw names it).
    ``labels`` [N] (the labels before the sweep, left unchanged by it) give the worker its guess
    of the rows the sweep will redraw whole: those whose every statistic is nonzero now."""
    if not two_part():
        return None
    L = config.num_concepts
    bases = [float(config.pi_concentration)]
    bases += [float(config.concentration(modality.name)) for modality in data.modalities]
    if not all(0.0 < base < np.inf for base in bases):
        return None
    shapes = [(1, L)] + [(L, modality.counts.shape[1]) for modality in data.modalities]
    hint = None
    if labels is not None:

        def hint() -> list[np.ndarray]:
            current = _as_array(labels, np.int64)  # [N]
            _check_data(data)  # the compiled statistics index without bounds checks
            if current.shape != (data.num_free,) or (
                current.size and (current.min() < 0 or current.max() >= L)
            ):
                return [np.zeros(shape[0], dtype=np.bool_) for shape in shapes]  # no guess
            cells, statistics = _statistics(current, _as_array(data.obs_cells, np.int64), data,
                                            config)  # fmt: skip
            return [(table != 0.0).all(axis=1) for table in (cells, *statistics)]

    return start_prior_draws(bases, shapes, draw_seed(generator), hint)


def _finish_globals_arrays(
    started: PriorDraws,
    labels: np.ndarray,
    data: ModelData,
    config: SpCoConfig,
    rng: np.ndarray,
    cell_counts: np.ndarray | None = None,
) -> tuple[torch.Tensor, tuple[torch.Tensor, ...]]:
    """(log pi, per-modality log distributions) given valid labels [N] (or longer) and the
    prior draw ``started`` (:func:`_start_globals`): the entries with nonzero statistics drawn
    with ``rng`` (:func:`~spcopyro.gibbs.numba_globals.finish_globals`). ``cell_counts`` [L], if
    given, receives the concept sizes."""
    try:
        obs_cells = _as_array(data.obs_cells, np.int64)
        cells_per_concept, statistics = _statistics(labels, obs_cells, data, config)
    except BaseException:
        abandon_prior_draws(started)
        raise
    if cell_counts is not None:
        cell_counts[:] = cells_per_concept[0]
    tables, table, bad = finish_globals(started, [cells_per_concept, *statistics], rng)
    if bad >= 0:
        if table == 0:
            raise _bad_concentration("pi", cells_per_concept, config.pi_concentration, bad)
        modality = data.modalities[table - 1]
        base = config.concentration(modality.name)
        raise _bad_concentration(modality.parameter, statistics[table - 1], base, bad)
    log_pi, *log_emissions = tables
    return torch.from_numpy(log_pi[0]), tuple(torch.from_numpy(t) for t in log_emissions)


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
    rng = rng_state(draw_seed(generator))
    labels, _ = _sample_labels_array(state, data, config, plan, rng)  # [N + D]
    return torch.from_numpy(labels[: data.num_free].astype(np.int64))


def sample_globals_numba(
    labels: torch.Tensor, data: ModelData, config: SpCoConfig, generator: torch.Generator
) -> tuple[torch.Tensor, tuple[torch.Tensor, ...]]:
    """(log pi [L], per-modality log distributions [L, K_m]) from their conjugate conditionals
    (eqs. 14-17).

    Same distribution as :func:`~spcopyro.gibbs.sweep.sample_globals`; draws one seed from
    ``generator`` (two in the two-part modes of :mod:`~spcopyro.gibbs.numba_globals`).

    Raises:
        ValueError: ``labels`` is not [N] or holds a label outside [0, L), or ``data`` is
            inconsistent (observed cells outside the map, count rows != observed cells).
    """
    _check_data(data)
    if tuple(labels.shape) != (data.num_free,):
        raise ValueError(f"labels have shape {tuple(labels.shape)}, expected ({data.num_free},)")
    checked = _extended_labels(labels, 0, config)
    rng = rng_state(draw_seed(generator))
    started = _start_globals(data, config, generator)
    if started is None:
        return _sample_globals_arrays(checked, data, config, rng)
    return _finish_globals_arrays(started, checked, data, config, rng)


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
    seed from ``generator`` per call (two in the two-part modes of
    :mod:`~spcopyro.gibbs.numba_globals`), so a seeded run is reproducible bit for bit, with or
    without the prior draw's worker thread. The sweep
    remembers E(C) and the concept sizes of the labels it returns (:func:`potts_agreements_numba`
    and :func:`label_counts_numba` then cost nothing).

    Raises:
        ValueError: the state's shapes do not match ``data`` / ``config``, a label lies outside
            [0, L), ``plan`` was made for other data, or gamma * D > 700 (overflow).
    """
    rng = rng_state(draw_seed(generator))
    counts = np.empty(config.num_concepts)  # [L]
    started = None
    if unobserved_refresh >= 1.0:
        started = _start_globals(data, config, generator, state.labels)
    if started is None:
        compact, agreements = _sample_labels_array(state, data, config, plan, rng)  # [N + D]
        log_pi, log_emissions = _sample_globals_arrays(
            compact, data, config, rng, state.log_emissions, unobserved_refresh, counts
        )
    else:  # the prior part of the globals is drawn while the labels are (numba_globals)
        try:
            compact, agreements = _sample_labels_array(state, data, config, plan, rng)
        except BaseException:
            abandon_prior_draws(started)
            raise
        log_pi, log_emissions = _finish_globals_arrays(started, compact, data, config, rng, counts)
    labels = torch.from_numpy(compact[: data.num_free].astype(np.int64))  # [N]
    state = GibbsState(labels, log_pi, log_emissions)
    obs_cells = _as_array(data.obs_cells, np.int64)
    counts_m = tuple(_as_array(modality.counts, np.float64) for modality in data.modalities)
    remember_sweep(state, data, config, agreements, counts, obs_cells, counts_m, compact)
    return state
