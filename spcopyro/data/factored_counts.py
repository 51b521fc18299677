r"""The footprints' counts: the observations' weighted per-cell counts, and their factored form.

Each observation t spreads its counts :math:`x_t` over the free cells with weights
:math:`w_{tc}` (:func:`~spcopyro.data.footprint.footprint_weights`): the data term of cell c is
:math:`\tilde x_c \cdot \log\phi_{C_c}` with :math:`\tilde x_c = \sum_t w_{tc} x_t`
(:func:`spread_counts`). Moved from :mod:`spcopyro.data.footprint`, which re-exports every name.

**Factored counts.** The weighted counts are a product, :math:`\tilde x = A X`: ``A`` [M, S]
the footprints' weights on the observed cells and ``X`` [S, K] the counts of the S distinct
footprints (observations sharing a cell share one, unless a field of view tells them apart).
A public house (room2ldk4) at 0.25 m has M = 561 observed cells under the default's 0.75 m
footprints (686 under 1 m) and S = 75 footprints, so a sampler's per-sweep product
:math:`\tilde x \log\phi^\top`, computed as :math:`A (X \log\phi^\top)`, costs about
S / M = 1 / 7.5 of the direct one (:class:`SpreadSources`, kept beside the counts by
:func:`~spcopyro.data.cell_counts`; :mod:`spcopyro.gibbs.numba_background` uses it). Both give
the same numbers to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from spcopyro.data.identical_rows import identical_rows

if TYPE_CHECKING:
    from scipy import sparse

__all__ = ["SpreadSources", "spread_counts", "spread_sources"]


def spread_counts(weights: sparse.csr_matrix, counts: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """[M, K] weighted per-cell counts x~_c = sum_t w_tc x_t at the free indices ``cells`` [M]
    (``weights`` [T, N] from :func:`footprint_weights`, ``counts`` [T, K] per observation)."""
    counts = np.asarray(counts, dtype=np.float64)  # [T, K]
    selected = weights.tocsc()[:, np.asarray(cells, dtype=np.int64)]  # [T, M]
    return np.asarray(selected.T @ counts, dtype=np.float64).reshape(len(cells), counts.shape[1])


@dataclass(frozen=True, eq=False)
class SpreadSources:
    """Weighted per-cell counts [M, K] as the product ``weights [M, S] @ sources [S, K]`` (module
    docstring, "Factored counts"): S distinct footprints, the weights a CSR matrix."""

    indptr: np.ndarray  # [M + 1] int64: row m's weights are entries indptr[m]:indptr[m + 1]
    indices: np.ndarray  # [nnz] int64: the footprint of each weight, in [0, S)
    weights: np.ndarray  # [nnz] float64: w_sc, footprint s's weight on the row's cell
    sources: np.ndarray  # [S, K] float64: the summed counts of the observations of footprint s

    @property
    def shape(self) -> tuple[int, int]:
        """(M, K): the shape of the counts this product equals."""
        return self.indptr.size - 1, self.sources.shape[1]

    def dense(self) -> np.ndarray:
        """[M, K] the product, as :func:`spread_counts` gives it (to rounding)."""
        rows = np.repeat(np.arange(self.shape[0]), np.diff(self.indptr))  # [nnz]
        out = np.zeros(self.shape)  # [M, K]
        np.add.at(out, rows, self.weights[:, None] * self.sources[self.indices])
        return out

    def pays(self) -> bool:
        """Whether a product with it costs less than with the dense counts: S K + nnz < M K
        multiply-adds a column of the other factor."""
        num_rows, num_items = self.shape
        return self.sources.size + self.weights.size < num_rows * num_items


def spread_sources(
    weights: sparse.csr_matrix, counts: np.ndarray, cells: np.ndarray
) -> SpreadSources:
    """The factored form of :func:`spread_counts`'s result for the same arguments: observations
    whose rows of ``weights`` [T, N] are identical, bit for bit (one footprint,
    :func:`~spcopyro.data.identical_rows.identical_rows`), are summed into one source row, the
    footprints numbered by their first observation; unplaced observations (empty rows) are left
    out."""
    counts = np.asarray(counts, dtype=np.float64)  # [T, K]
    weights = weights.tocsr()
    member = np.flatnonzero(np.diff(weights.indptr))  # [T'] the observations with a footprint
    # [T' + 1] their rows' bounds: an empty row holds no entry, so row t' ends where t' + 1 starts
    bounds = np.append(weights.indptr[:-1][member], weights.indptr[-1])
    group, first = identical_rows((bounds, weights.indices, weights.data))  # [T'], [S]
    first = member[first]  # [S] each footprint's first observation
    sources = np.zeros((first.size, counts.shape[1]))  # [S, K]
    np.add.at(sources, group, counts[member])
    on_cells = weights[first].tocsc()[:, np.asarray(cells, dtype=np.int64)].T.tocsr()  # [M, S]
    on_cells.sort_indices()
    return SpreadSources(
        indptr=on_cells.indptr.astype(np.int64),
        indices=on_cells.indices.astype(np.int64),
        weights=on_cells.data.astype(np.float64),
        sources=sources,
    )
