r"""The region relabel move's region, grown from its seed cell alone (compiled).

:mod:`spcopyro.gibbs.region_move` steps 1-2 draw a bond on every agreeing neighbour pair of the
map, take the connected components and keep the one of a uniformly drawn seed cell: O(P) work
(and a scipy graph) for one region. The region's distribution depends only on the bonds the
seed's component reaches, so :func:`grow_region` draws the seed first and then grows its
cluster breadth-first, drawing each pair's bond when the growth first reaches it: a pair from a
cell of the region to an outside cell of the same concept is bonded with probability q, and
joins that cell if so. Every pair is drawn at most once (a pair whose outer cell joins later
through another pair is inside the region, and its bond no longer matters), and the bonds are
independent, so the region has the distribution of the seed's component under bonds drawn on
every pair (Wolff's single-cluster growth). The work is O(region x D).

The draws come from the compiled sampler's own stream (:mod:`spcopyro.gibbs.numba_random`,
seeded from the move's generator), so a chain on the numba backend makes other regions than one
on torch, from the same distribution: the move's tests run both.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spcopyro.gibbs.numba_random import bits_to_uniform, next_bits

__all__ = ["grow_region"]


@njit(cache=True, nogil=True)
def grow_region(
    labels: np.ndarray, neighbours: np.ndarray, bond_probability: float, state: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(``[N]`` bool: the region, ``[B]`` int64: the outside label of every neighbour pair
    across its border) of a seed cell drawn uniformly from the ``labels`` [N] and the cells its
    bonds reach (module doc); ``neighbours`` [N, D] free indices, -1 for none. Advances the RNG
    ``state`` [4] in place."""
    n, num_neighbours = neighbours.shape
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
    seed = min(int(bits_to_uniform(bits) * n), n - 1)
    concept = labels[seed]
    inside = np.zeros(n, np.bool_)
    queue = np.empty(n, np.int64)  # the region's cells in the order they joined
    inside[seed] = True
    queue[0] = seed
    head, tail = 0, 1
    while head < tail:
        k = queue[head]
        head += 1
        for t in range(num_neighbours):
            m = neighbours[k, t]
            if m < 0 or inside[m] or labels[m] != concept:
                continue
            bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
            if bits_to_uniform(bits) < bond_probability:
                inside[m] = True
                queue[tail] = m
                tail += 1
    state[0], state[1], state[2], state[3] = s0, s1, s2, s3
    border = np.empty(tail * num_neighbours, np.int64)
    count = 0
    for p in range(tail):
        k = queue[p]
        for t in range(num_neighbours):
            m = neighbours[k, t]
            if m >= 0 and not inside[m]:
                border[count] = labels[m]
                count += 1
    return inside, border[:count]
