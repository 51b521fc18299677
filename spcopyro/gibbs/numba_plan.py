"""A :class:`~spcopyro.gibbs.state.SweepPlan` as flat numpy arrays, checked, for the compiled
sweep (which indexes without bounds checks), and cached per plan object."""

from __future__ import annotations

import threading
from typing import NamedTuple

import numpy as np
import torch

from spcopyro.gibbs.state import SweepPlan, make_sweep_plan
from spcopyro.model import ModelData

_PLAN_CACHE_SIZE = 8


class FlatPlan(NamedTuple):
    """A :class:`SweepPlan` as numpy arrays, its blocks laid end to end (the visiting order)."""

    cells: np.ndarray
    """[N] int64 free index of the cell at each position of the sweep (block after block)."""
    neighbours: np.ndarray
    """[N, D] int64 free indices of that cell's neighbours; a missing one in slot s is N + s."""
    background_rows: np.ndarray
    """[N] int64 the cell's row of the background table: its row in ``data.obs_cells``, or M."""
    num_observed: int
    """M, the number of observed cells of the data the plan was checked against."""


# id(plan) -> (plan, its FlatPlan). The plan itself is held so that its id cannot be reused while
# it is cached (SweepPlan is a NamedTuple: no weak references); at most _PLAN_CACHE_SIZE entries.
_plan_cache: dict[int, tuple[SweepPlan, FlatPlan]] = {}
_plan_cache_lock = threading.Lock()  # chains may sweep in threads (spcopyro.gibbs.chains)


def flatten_plan(plan: SweepPlan, data: ModelData) -> FlatPlan:
    """The plan's blocks concatenated into numpy arrays, checked against ``data``.

    The compiled sweep does no bounds checking, so every index is validated here: the cells must
    be each free cell exactly once, neighbours must lie in [0, N + D), and the observed positions
    and rows must agree with ``data.obs_cells``.

    Raises:
        ValueError: the plan does not belong to ``data``.
    """
    N, D = data.num_free, data.neighbours.shape[1]
    M = data.obs_cells.shape[0]
    empty = torch.zeros(0, dtype=torch.int64)
    cells = torch.cat([b.cells for b in plan.blocks]).to(torch.int64) if plan.blocks else empty
    in_range = cells.numel() == 0 or (int(cells.min()) >= 0 and int(cells.max()) < N)
    if (
        cells.shape != (N,)
        or not in_range
        or not bool((torch.bincount(cells, minlength=N) == 1).all())
    ):
        raise ValueError(
            f"sweep plan does not match the data: its blocks hold {cells.numel()} cells, which "
            f"must be each of the map's {N} free cells exactly once"
        )
    neighbours = torch.cat([b.neighbours for b in plan.blocks]).to(torch.int64)  # [N, D]
    if neighbours.shape != (N, D):
        raise ValueError(
            f"sweep plan neighbours have shape {tuple(neighbours.shape)}, expected ({N}, {D})"
        )
    if N and (int(neighbours.min()) < 0 or int(neighbours.max()) >= N + D):
        raise ValueError(
            f"sweep plan neighbours must lie in [0, {N + D}) (N + slot where none), got values "
            f"in [{int(neighbours.min())}, {int(neighbours.max())}]"
        )
    rows = torch.full((N,), M, dtype=torch.int64)  # [N]
    offset = 0
    for block in plan.blocks:
        rows[offset + block.observed_positions] = block.observed_rows
        offset += block.cells.shape[0]
    expected = data.observation_rows()[cells]  # [N], -1 where unobserved
    expected = torch.where(expected >= 0, expected, M)
    if not torch.equal(rows, expected):
        bad = int((rows != expected).nonzero()[0, 0])
        raise ValueError(
            f"sweep plan observed rows do not match data.obs_cells: free cell {int(cells[bad])} "
            f"has row {int(rows[bad])} in the plan and {int(expected[bad])} in the data "
            f"({M} = none)"
        )
    return FlatPlan(
        cells=np.ascontiguousarray(cells.numpy()),
        neighbours=np.ascontiguousarray(neighbours.numpy()),
        background_rows=np.ascontiguousarray(rows.numpy()),
        num_observed=M,
    )


def flat_plan(plan: SweepPlan | None, data: ModelData) -> FlatPlan:
    """The FlatPlan of ``plan`` (cached per plan object), or of a fresh plan if None."""
    if plan is None:
        return flatten_plan(make_sweep_plan(data), data)
    entry = _plan_cache.get(id(plan))
    if entry is None or entry[0] is not plan:
        flat = flatten_plan(plan, data)
        with _plan_cache_lock:
            while len(_plan_cache) >= _PLAN_CACHE_SIZE:
                del _plan_cache[next(iter(_plan_cache))]  # oldest first
            _plan_cache[id(plan)] = (plan, flat)
        return flat
    flat = entry[1]
    N, D, M = data.num_free, data.neighbours.shape[1], data.obs_cells.shape[0]
    if flat.neighbours.shape != (N, D) or flat.num_observed != M:
        raise ValueError(
            f"sweep plan was made for {flat.neighbours.shape[0]} free cells, "
            f"{flat.neighbours.shape[1]} neighbours and {flat.num_observed} observed cells; "
            f"the data have {N}, {D} and {M}"
        )
    return flat
