"""The memo of memoized VI (:mod:`spcopyro.guides.memoized`): every block's expected sufficient
statistics S_b -- ``[L]`` expected concept sizes, per modality ``[L, K_m]`` expected counts of
the block's observed cells -- and their running sums over the blocks, which set the global
factors q(pi), q(phi) (eqs. 14-17 in expectation).

When a step has updated q(C) of a block's cells, :meth:`Memo.replace` swaps that block's S_b for
the statistic of its new q and updates the sums by the difference; :meth:`Memo.resum` re-adds
the sums from the memo after a pass (no rounding drift). So the sums always equal
:func:`spcopyro.likelihood.concept_statistics` of the whole current q.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import torch

from spcopyro.config import SpCoConfig
from spcopyro.guides.blocks import Blocks
from spcopyro.likelihood import ConceptStatistics
from spcopyro.model import DTYPE, ModelData


class _ObservedIndex(NamedTuple):
    """The observed cells grouped by block."""

    cells: torch.Tensor  # [M] int64 free indices, sorted by block
    rows: torch.Tensor  # [M] int64 their rows in the count matrices
    starts: torch.Tensor  # [B + 1] int64 slice bounds per block
    slot: torch.Tensor  # [B] int64 the block's row in the count memo, -1 if no observation


def _observed_index(data: ModelData, blocks: Blocks) -> _ObservedIndex:
    block = blocks.block_of[data.obs_cells]  # [M]
    perm = torch.argsort(block, stable=True)  # [M]
    starts = torch.searchsorted(block[perm], torch.arange(blocks.num_blocks + 1))  # [B + 1]
    has = starts[1:] > starts[:-1]  # [B]
    slot = torch.full((blocks.num_blocks,), -1, dtype=torch.long)
    slot[has] = torch.arange(int(has.sum()))
    return _ObservedIndex(data.obs_cells[perm], perm, starts, slot)


class Memo:
    """Every block's expected sufficient statistics S_b and their sums (module docstring).

    ``cells`` ``[B, L]`` are the blocks' expected concept sizes; ``counts[m]`` ``[B_obs, L, K_m]``
    the expected per-concept counts of modality m of each block holding observations (a block
    without one contributes zero counts). ``total_cells`` and ``total_counts`` are their sums
    over the blocks (without the prior), kept up to date by :meth:`replace`.
    """

    def __init__(
        self,
        q: torch.Tensor,
        data: ModelData,
        config: SpCoConfig,
        blocks: Blocks,
        advance: Callable[[int], None] | None = None,
    ) -> None:
        """``advance(1)`` is called after each block's statistic (a progress bar's update)."""
        self.data, self.config, self.blocks = data, config, blocks
        self.observed = _observed_index(data, blocks)
        B, L = blocks.num_blocks, q.shape[1]
        num_observed = int((self.observed.slot >= 0).sum())
        self.used = tuple(config.uses(m.name) for m in data.modalities)
        self.cells = torch.zeros(B, L, dtype=DTYPE)  # [B, L]
        self.counts = tuple(
            torch.zeros(num_observed if used else 0, L, m.counts.shape[-1], dtype=DTYPE)
            for m, used in zip(data.modalities, self.used, strict=True)
        )  # per modality [B_obs, L, K_m]
        for block in range(B):
            self._store(block, *self.block_statistics(q, block))
            if advance is not None:
                advance(1)
        self.resum()

    def block_statistics(
        self, q: torch.Tensor, block: int
    ) -> tuple[torch.Tensor, tuple[torch.Tensor | None, ...]]:
        """S_b from the current q: ``[L]`` concept sizes, per modality ``[L, K_m]`` counts
        (None for a switched-off modality or a block without observations)."""
        cells = q[self.blocks.cells(block)].to(DTYPE).sum(0)  # [L]
        lo, hi = int(self.observed.starts[block]), int(self.observed.starts[block + 1])
        if lo == hi:
            return cells, tuple(None for _ in self.used)
        observed_q = q[self.observed.cells[lo:hi]].to(DTYPE)  # [m, L]
        rows = self.observed.rows[lo:hi]  # [m]
        counts = tuple(
            observed_q.T @ modality.counts[rows] if used else None  # [L, m] @ [m, K_m]
            for modality, used in zip(self.data.modalities, self.used, strict=True)
        )
        return cells, counts

    def _store(
        self, block: int, cells: torch.Tensor, counts: tuple[torch.Tensor | None, ...]
    ) -> None:
        self.cells[block] = cells
        slot = int(self.observed.slot[block])
        for memo, value in zip(self.counts, counts, strict=True):
            if value is not None:
                memo[slot] = value

    def replace(self, q: torch.Tensor, block: int) -> None:
        """Swap block b's memo for the statistic of its current q, and the sums with it."""
        cells, counts = self.block_statistics(q, block)
        self.total_cells += cells - self.cells[block]
        slot = int(self.observed.slot[block])
        for total, memo, value in zip(self.total_counts, self.counts, counts, strict=True):
            if value is not None:
                total += value - memo[slot]
        self._store(block, cells, counts)

    def resum(self) -> None:
        """Re-add the sums from the memo (clears the rounding drift of the swaps)."""
        self.total_cells = self.cells.sum(0)  # [L]
        self.total_counts = [
            memo.sum(0) if used else torch.zeros(memo.shape[1], m.counts.shape[-1], dtype=DTYPE)
            for memo, m, used in zip(self.counts, self.data.modalities, self.used, strict=True)
        ]  # per modality [L, K_m]

    def statistics(self) -> ConceptStatistics:
        """The sums over all blocks, as :func:`spcopyro.likelihood.concept_statistics` gives
        them for the whole q."""
        return ConceptStatistics(self.total_cells, tuple(self.total_counts))

    def nbytes(self) -> int:
        return sum(t.element_size() * t.numel() for t in (self.cells, *self.counts))
