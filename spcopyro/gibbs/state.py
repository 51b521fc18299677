"""The Gibbs sampler's state and the per-map plan of a sweep (built once, reused every sweep)."""

from __future__ import annotations

from typing import NamedTuple

import torch

from spcopyro.model import ModelData


class GibbsState(NamedTuple):
    """One point of the Markov chain. Globals are kept as log probabilities
    (see :mod:`spcopyro._util.random_draws`)."""

    labels: torch.Tensor
    """[N] int64: the concept C of every free cell (free-index order), in [0, L)."""
    log_pi: torch.Tensor
    """[L] float64: log concept weights."""
    log_emissions: tuple[torch.Tensor, ...]
    """Per modality of ``data.modalities``, [L, K_m] float64: each concept's log distribution
    (log theta for images, log w for words, then any further modality)."""

    @property
    def log_theta(self) -> torch.Tensor:
        """[L, K] log image-feature distributions (the first modality, ``images``)."""
        return self.log_emissions[0]

    @property
    def log_w(self) -> torch.Tensor:
        """[L, V] log word distributions (the second modality, ``words``)."""
        return self.log_emissions[1]


class ColourBlock(NamedTuple):
    """One colour class of the neighbour graph: its cells are conditionally independent."""

    cells: torch.Tensor
    """[Nc] int64 free indices of this colour."""
    neighbours: torch.Tensor
    """[Nc, D] int64 free indices of their neighbours, with a missing neighbour in slot s pointing
    at N + s: the sweep gathers from labels extended by D distinct negative sentinels, so missing
    neighbours never agree with anything and need no mask."""
    observed_positions: torch.Tensor
    """[Mc] int64 positions within ``cells`` of the cells that hold observations."""
    observed_rows: torch.Tensor
    """[Mc] int64 the rows of ``data.obs_cells`` / the count tensors for those cells."""


class SweepPlan(NamedTuple):
    """Index bookkeeping of a label sweep, derived from :class:`~spcopyro.model.ModelData`."""

    blocks: tuple[ColourBlock, ...]


def make_sweep_plan(data: ModelData) -> SweepPlan:
    """Split the free cells by colour and locate the observed cells of each colour."""
    obs_row_of_cell = data.observation_rows()  # [N]
    blocks = []
    for cells in data.colours:
        rows = obs_row_of_cell[cells]  # [Nc]
        nb = data.neighbours[cells]  # [Nc, D]
        slots = torch.arange(nb.shape[1])  # [D]
        positions = (rows >= 0).nonzero(as_tuple=True)[0]  # [Mc]
        blocks.append(
            ColourBlock(
                cells=cells,
                neighbours=torch.where(nb >= 0, nb, data.num_free + slots),
                observed_positions=positions,
                observed_rows=rows[positions],
            )
        )
    covered = sum(int(b.cells.numel()) for b in blocks)
    if covered != data.num_free:
        raise ValueError(f"colour classes cover {covered} cells, the map has {data.num_free}")
    return SweepPlan(blocks=tuple(blocks))
