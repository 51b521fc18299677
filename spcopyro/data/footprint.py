r"""The observation footprint: each observation informs the free cells around it, not one cell.

In the paper every observation touches exactly one cell, ``convert(x_t)`` (eq. 11). A camera
image shows the room around the robot and "here is the kitchen" names the place around the
speaker, so on a real house (about 80 observed cells among 25,000 free ones) the data reach 0.3%
of the map. With a footprint of radius R, observation t informs every free cell c within
geodesic distance R of its cell s_t, with weights that sum to one observation:

.. math::

    w_{tc} \propto k(d(s_t, c)) \quad (d \le R,\; c \text{ in the field of view}),
    \qquad \sum_c w_{tc} = 1,

k the kernel: ``uniform`` (k = 1) or ``gaussian`` (k(d) = exp(-d^2 / (2 sigma^2)), sigma = R/2,
cut at R). Its likelihood is the **tempered product** of the observation's likelihood over its
footprint,

.. math::

    p(x_t \mid C, \phi) = \prod_c \mathrm{Mult}(x_t \mid \phi_{C_c})^{w_{tc}}
    \;\propto\; \prod_c \prod_k \phi_{C_c k}^{\,w_{tc} x_{tk}},

so that an observation still weighs one observation in total. Summed over observations, the
data term of cell c is :math:`\tilde x_c \cdot \log\phi_{C_c}` with the weighted counts
:math:`\tilde x_c = \sum_t w_{tc} x_t` (:func:`spread_counts`): the model of
:func:`~spcopyro.model.spcomapping_model` on the counts :math:`\tilde x` has, up to a term
constant in every label and parameter (the multinomial coefficients), the same density, so
every full conditional (eq. 13), every Dirichlet posterior (eqs. 14-17: its counts are the
weighted sums :math:`\sum_{c: C_c = l} \tilde x_c`), and every variational update is that of the
tempered model. This is why the footprint is a :class:`~spcopyro.config.preparation.DataPreparation`
switch (how observations become per-cell counts): the Pyro model, both Gibbs backends, CAVI and the
likelihood read the same weighted counts with no change of their code.

**Reach.** Distances are geodesic over free cells, so a footprint never crosses a wall: a
shortest path over the free cells' 8-neighbourhood (steps of one resolution, diagonal steps of
sqrt(2) resolutions), where a diagonal step needs both cells beside it free (no squeezing
through a wall's corner or a one-cell diagonal wall). The octile distance overestimates the
Euclidean one by at most 8%. Unknown and occupied cells are never reached.

**Field of view** (images only, where the data hold each image's yaw): a cell is in an image's
footprint only if its bearing from the image's cell lies within +-fov/2 of the yaw (the cell
itself always is). Words have no direction and use the full disc.

**The words' own radius** (``DataPreparation.word_footprint_radius``; None: the images'): each
observation's tempered product is over its own footprint, so the utterances may use another
radius than the images, 0 counting each whole at its own cell (the paper's words) while the
images keep their footprint.

**Factored counts.** The weighted counts :math:`\tilde x = A X` as a product of the footprints'
weights and the distinct footprints' counts: :mod:`spcopyro.data.factored_counts`
(:func:`spread_counts`, :class:`SpreadSources`, :func:`spread_sources`, re-exported here).

**Reaching the Voronoi border** (``DataPreparation.footprint_reach_share`` e, 0 <= e < 1; 0, the
field's default, is the footprint above exactly; the default preset ``coarse`` takes 0.2, cut at 1 m
doorways as below, in its first stage since 2026-12-06). Each observation's weight 1 is split: 1 - e
over its footprint as above, and e spread uniformly over its **geodesic Voronoi cell**, the free
cells whose nearest observed cell of the same modality (geodesic over the same free-cell graph, no
distance limit) is its own cell s_t:

.. math::

    w^e_{tc} = (1 - e)\, w_{tc} + e\, v_{s_t c}, \qquad
    v_{sc} = \frac{z_{sc}}{\sum_{c'} z_{sc'}}, \qquad
    z_{sc} = \frac{[\, d(s, c) = d^*(c) \,]}{\#\{s' \in S : d(s', c) = d^*(c)\}},

S the modality's observed (source) cells and :math:`d^*(c) = \min_{s \in S} d(s, c)`: a cell
equidistant from several sources is split equally between them, a cell no source reaches
(another component of the free space) gets none. Observations sharing a cell share its Voronoi
cell, as they share a footprint. The sources are where observations were placed, whatever they
hold: a placed observation whose counts are all zero (an utterance without words, an image
scaled to nothing) still claims its Voronoi cell, shrinking its neighbours', and brings no
evidence to it (its counts times any weight are zero). The field of view (images) shapes only
the footprint's part. Each row still sums to 1 (:math:`(1 - e) + e`), so the likelihood is the
same tempered product over :math:`w^e` and everything above -- the weighted counts, the factored
counts, the model, the samplers and the variational updates -- holds unchanged. Why: the
footprint reaches a radius, and on an open plan the borders between places lie in space no
footprint reaches, where the Potts prior alone draws them (the shortest border that keeps the
footprints apart); the reach share puts a little of each place's evidence up to the border
half-way to the next observation (:func:`voronoi_weights`).

**Bounding the reach** (``DataPreparation.footprint_reach_radius`` rho metres, > 0; None, the
default: no limit, the cells above exactly). The Voronoi cell is cut at geodesic distance rho
from its source:

.. math::

    z^\rho_{sc} = z_{sc}\, [\, d^*(c) \le \rho \,],

so a cell farther than rho from every source gets no Voronoi weight and the rest keep theirs
(a cell within rho of its nearest sources has the same nearest sources and ties as without the
cut). :math:`v_{sc}` normalises :math:`z^\rho_{sc}` as before; the source's own cell
(:math:`d = 0`) is always in, so each row still sums to 1. Why: on a sparse house a spot's
Voronoi cell reaches through a doorway into the next, unobserved room, carrying its place's
evidence there; the cut keeps it within rho of where it was observed. The Dijkstra pass takes rho
as its ``limit``: every cell on a shortest path to a cell within rho is within rho too, so the
ties below are found as without it.

**Voronoi cells within rooms** (``DataPreparation.footprint_reach_door_width`` M metres, > 0; None,
the field's default: no cut, the cells above exactly; preset ``coarse``'s is 1 m). The free cells
are cut into room segments at doorways up to M wide (:func:`~spcopyro.maps.rooms.room_segments` on
the grid the counts are on, the model grid in a ``coarse`` fit's first stage: the segmentation of
the rooms start and of baseline (F), whose M is ``DEFAULT_DOOR_WIDTH`` = 1 m), seg(c) >= 0 the
segment of every free cell c, and the free-cell graph loses its edges between cells of different
segments. The distances, nearest sources and ties above are those of that graph: with :math:`d_M`
the geodesic distance through the free cells of one segment (infinite between segments),

.. math::

    z^M_{sc} = [\, \mathrm{seg}(c) = \mathrm{seg}(s) \,]\;
    \frac{[\, d_M(s, c) = d^*_M(c) \,]}{\#\{s' \in S : d_M(s', c) = d^*_M(c)\}},
    \qquad d^*_M(c) = \min_{s \in S} d_M(s, c),

so a source's Voronoi cell is drawn among the sources of its own room only, within that room,
and a room where no observation of the modality lies gets none of its Voronoi weight. A walled
space no doorway cuts (an open plan: one segment) keeps its cells exactly; the radius rho, if
set, cuts :math:`d^*_M` as it cuts :math:`d^*`. The source's own cell is in its own segment, so
each row still sums to 1. Why: on a sparse house a spot's Voronoi cell reaches through a doorway
into the next, unobserved room, and a radius cannot tell a doorway from open space (the open
plans' gain lies within the same 2 m); the door cut keeps each spot's share in its room. Cost:
one segmentation of the grid, kept for every modality within :func:`shared_footprints` (about
1 ms on the public houses' 0.25 m model grids of 700-1,044 cells, 0.03-0.04 s on their map grids
of 18,622-27,746 cells: too little to share with the rooms start's own), and one pass over the
graph's edges. At 1 m every public house's model grid is one segment (as for the rooms start),
so there the cut changes nothing.

How :math:`d^*` and the ties are found: one multi-source Dijkstra pass (``min_only``) gives
:math:`d^*(c)` and one nearest source per cell; an edge p -> c of length l is *tight* where
:math:`d^*(p) + l = d^*(c)` (to a relative 1e-9), and a source s attains the minimum at c exactly
when it attains it at a tight predecessor of c (s's shortest path to c runs through one), so the
tie sets are the least fixed point of
:math:`Z(c) = \{\mathrm{nearest}(c)\} \cup \bigcup_{p \to c \text{ tight}} Z(p)`, found by
sparse products until nothing is added (2-5 on the synthetic and public houses). Cost: one
Dijkstra over the free cells and a few sparse products, against the footprint's per-source
searches (0.01-0.05 s on room2ldk4's 1,044 model cells and 27,746 map cells).

``footprint_radius = 0`` (and no reach share) is the paper's model exactly
(:func:`~spcopyro.data.cell_counts` does not call this module then).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from typing import TYPE_CHECKING, Literal, TypeVar

import numpy as np

from spcopyro._util.context import set_within
from spcopyro._util.number_checks import is_finite_number, is_positive_number
from spcopyro.data.factored_counts import SpreadSources, spread_counts, spread_sources
from spcopyro.maps.grid import OccupancyGrid

if TYPE_CHECKING:  # scipy.sparse is imported where a footprint is built (0.3 s of every fit else)
    from scipy import sparse

__all__ = [
    "FOOTPRINT_KERNELS",
    "FootprintKernel",
    "SpreadSources",
    "disc_weights",
    "footprint_weights",
    "free_cell_graph",
    "spread_counts",
    "release_shared_footprints",
    "room_of_free_cells",
    "shared_footprints",
    "spread_sources",
    "voronoi_weights",
]

FootprintKernel = Literal["uniform", "gaussian"]
FOOTPRINT_KERNELS = ("uniform", "gaussian")
_CHUNK = 64  # source cells per Dijkstra call: [64, N] float64 distances at a time
_WINDOW_SHARE = 0.5  # a chunk's Dijkstra runs on its window's cells if at most this share of N
_T = TypeVar("_T")
_SHARED: ContextVar[dict[tuple, tuple] | None] = ContextVar("shared_footprints", default=None)


@contextlib.contextmanager
def shared_footprints() -> Iterator[None]:
    """Within it, :func:`~spcopyro.data.cell_counts` spreads the same observations over the same
    footprints once: a second call with the same grid and observations (the same objects) and
    the same preparation returns the first's spread counts (``spcopyro fit``'s summary and its
    model data, each 24 s on a map of 10^6 cells). Its warnings are still given by each call.
    Outside it nothing is kept."""
    with set_within(_SHARED, {}):
        yield


def release_shared_footprints() -> None:
    """Forget what :func:`shared_footprints` kept so far (the fit that read it is done: its spread
    counts, 1.7 GB at 10^6 cells, are not held through the fit's outputs)."""
    cache = _SHARED.get()
    if cache is not None:
        cache.clear()


def shared(held: tuple[object, ...], key: tuple[object, ...], compute: Callable[[], _T]) -> _T:
    """``compute()``, or within :func:`shared_footprints` the value it gave for the same
    ``held`` objects (by identity, kept alive while the value is) and ``key`` (by equality)."""
    cache = _SHARED.get()
    if cache is None:
        return compute()
    index = (tuple(id(x) for x in held), key)
    try:
        found = cache.get(index)
    except TypeError:  # an unhashable key: nothing to share
        return compute()
    if found is not None and all(a is b for a, b in zip(found[0], held, strict=True)):
        return found[1]
    value = compute()
    cache[index] = (held, value)
    return value


def free_cell_graph(grid: OccupancyGrid) -> sparse.csr_matrix:
    """[N, N] symmetric sparse graph of the free cells (free-index order), edge weights in
    metres: 4-neighbours at one resolution, diagonal neighbours at sqrt(2) resolutions where
    both cells beside the diagonal step are free (no corner cutting)."""
    from scipy import sparse

    free = np.asarray(grid.free, dtype=bool)  # [H, W]
    index = np.asarray(grid.free_index, dtype=np.int64)  # [H, W], -1 off free
    height, width = free.shape
    rows, cols, weights = [], [], []

    def add(dr: int, dc: int, length: float, beside_free: np.ndarray | None = None) -> None:
        # pairs (r, c) -> (r + dr, c + dc) with both free; dr >= 0 so each pair once
        r0, r1 = 0, height - dr
        c0, c1 = max(0, -dc), width - max(0, dc)
        a = free[r0:r1, c0:c1] & free[r0 + dr : r1 + dr, c0 + dc : c1 + dc]  # [h, w] bool
        if beside_free is not None:
            a &= beside_free
        ra, ca = np.nonzero(a)
        rows.append(index[ra + r0, ca + c0])
        cols.append(index[ra + r0 + dr, ca + c0 + dc])
        weights.append(np.full(ra.size, length))

    res = float(grid.resolution)
    add(0, 1, res)
    add(1, 0, res)
    # down-right: cells (r, c+1) and (r+1, c) beside it; down-left: (r, c-1) and (r+1, c)
    add(1, 1, res * math.sqrt(2), free[:-1, 1:] & free[1:, :-1])
    add(1, -1, res * math.sqrt(2), free[:-1, :-1] & free[1:, 1:])
    i = np.concatenate(rows)
    j = np.concatenate(cols)
    w = np.concatenate(weights)
    n = int(grid.num_free)
    graph = sparse.coo_matrix((w, (i, j)), shape=(n, n)).tocsr()
    return (graph + graph.T).tocsr()


def _check_share(share: float) -> None:
    if not (is_finite_number(share) and 0 <= share < 1):
        raise ValueError(f"footprint_reach_share={share!r}: must be a number in [0, 1) "
                         "(each observation's share over its Voronoi cell; 0: off)")  # fmt: skip


def _limit(radius: float) -> float:
    """Dijkstra's ``limit`` for a radius in metres: a hair above it, so that a cell at exactly
    the radius (up to the sums' rounding) is reached."""
    return float(radius) * (1 + 1e-9) + 1e-12


def _check_optional_metres(name: str, value: float | None, none: str, metres: str) -> None:
    """ValueError naming ``name`` and ``value`` unless it is None (what ``none`` says) or a
    finite number of metres > 0 (what ``metres`` says they are)."""
    if value is not None and not is_positive_number(value):
        raise ValueError(f"{name}={value!r}: must be None ({none}) or a finite number of "
                         f"metres > 0 ({metres})")  # fmt: skip


def _check_reach_radius(radius: float | None) -> None:
    _check_optional_metres("footprint_reach_radius", radius, "no limit", "the Voronoi cells' cut")


def _check_door_width(width: float | None) -> None:
    _check_optional_metres("footprint_reach_door_width", width, "no cut", "the rooms' doorways")


def _check(radius: float, kernel: str, fov: float | None) -> None:
    if not (is_finite_number(radius) and radius >= 0):
        raise ValueError(f"footprint_radius={radius!r}: must be a finite number of metres >= 0")
    if kernel not in FOOTPRINT_KERNELS:
        raise ValueError(f"footprint_kernel={kernel!r}: must be one of {FOOTPRINT_KERNELS}")
    if fov is not None and not (is_finite_number(fov) and 0 < fov <= 360):
        raise ValueError(f"footprint_fov={fov!r}: must be None or degrees in (0, 360]")


def footprint_weights(
    grid: OccupancyGrid,
    cells: np.ndarray,
    radius: float,
    kernel: FootprintKernel = "uniform",
    *,
    yaw: np.ndarray | None = None,
    fov: float | None = None,
    graph: sparse.csr_matrix | None = None,
    advance: Callable[[int], None] | None = None,
    reach_share: float = 0.0,
    reach_radius: float | None = None,
    reach_door_width: float | None = None,
) -> sparse.csr_matrix:
    """[T, N] sparse weights w_tc of each observation over the free cells (module docstring):
    the footprint's, or with ``reach_share`` e > 0 the mixture (1 - e) w_tc + e v_{s_t c} with
    the observation's Voronoi cell among ``cells`` (:func:`voronoi_weights`), cut at
    ``reach_radius`` metres from its source (None: no limit) and, given ``reach_door_width``
    (metres; None: no cut), drawn within the room segments at doorways up to that wide. The
    other arguments are :func:`disc_weights`'; e = 0 returns its weights as they are (the
    radius and door width unread)."""
    _check_share(reach_share)
    _check_reach_radius(reach_radius)
    _check_door_width(reach_door_width)
    if reach_share and graph is None:  # built once, for the disc's searches and the Voronoi's
        graph = free_cell_graph(grid)
    weights = disc_weights(grid, cells, radius, kernel, yaw=yaw, fov=fov, graph=graph,
                           advance=advance)  # fmt: skip  # [T, N]
    if not reach_share:
        return weights
    cut = voronoi_weights(grid, cells, graph, reach_radius, reach_door_width)  # [T, N]
    mixed = (1.0 - reach_share) * weights + reach_share * cut
    mixed = mixed.tocsr()  # [T, N]
    mixed.eliminate_zeros()
    mixed.sort_indices()
    return mixed


def disc_weights(
    grid: OccupancyGrid,
    cells: np.ndarray,
    radius: float,
    kernel: FootprintKernel = "uniform",
    *,
    yaw: np.ndarray | None = None,
    fov: float | None = None,
    graph: sparse.csr_matrix | None = None,
    advance: Callable[[int], None] | None = None,
) -> sparse.csr_matrix:
    """[T, N] sparse weights w_tc of each observation over its footprint (module docstring).

    Args:
        grid: the occupancy grid.
        cells: ``[T]`` int64 free index of each observation's cell
            (:func:`~spcopyro.data.place_observations`), -1 where unplaced (its row stays zero).
        radius: R in metres, >= 0 (0: the observation's own cell, weight 1, without the
            graph or a Dijkstra call).
        kernel: ``"uniform"`` or ``"gaussian"`` (sigma = R / 2, cut at R).
        yaw: ``[T]`` radians, the heading of each observation (images), used with ``fov``.
        fov: field of view in degrees (None: the whole disc); needs ``yaw``.
        graph: :func:`free_cell_graph` of ``grid`` (computed if None).
        advance: called with the number of distinct observed cells (sources) done, after each
            chunk of them (a progress bar's ``update``).

    Returns:
        csr ``[T, N]`` float64, every placed observation's row summing to 1 (its own cell always
        has positive weight), unplaced rows empty.
    """
    from scipy import sparse

    _check(radius, kernel, fov)
    cells, placed = _placed(grid, cells)  # [T], [T']
    num_obs, n = cells.size, int(grid.num_free)
    if fov is not None and yaw is None:
        raise ValueError("footprint_fov needs each observation's yaw (the data hold none)")
    if yaw is not None:
        yaw = np.asarray(yaw, dtype=np.float64).reshape(-1)  # [T]
        if yaw.size != num_obs:
            raise ValueError(f"yaw has {yaw.size} entries for {num_obs} observations")
    if radius == 0:  # each observation whole at its own cell: no graph, no Dijkstra
        if advance is not None and placed.size:
            advance(int(np.unique(cells[placed]).size))
        ones = np.ones(placed.size)  # [T'] the weight 1 / 1 of the own cell, kernel and fov alike
        return sparse.csr_matrix((ones, (placed, cells[placed])), shape=(num_obs, n))
    from scipy.sparse.csgraph import dijkstra

    graph = free_cell_graph(grid) if graph is None else graph
    centres = np.asarray(grid.cell_to_world(grid.free_cells), dtype=np.float64)  # [N, 2]
    sources = np.unique(cells[placed])  # [S]
    # the observations at each source, in increasing t: one stable sort, not a scan of all T
    # observations per source (quadratic in the map's size)
    by_cell = placed[np.argsort(cells[placed], kind="stable")]  # [T']
    bounds = np.searchsorted(cells[by_cell], sources, side="left")  # [S]
    ends = np.searchsorted(cells[by_cell], sources, side="right")  # [S]
    out_rows, out_cols, out_vals = [], [], []
    limit = _limit(radius)
    for chunk, window in _source_windows(grid, sources, limit):
        # Dijkstra on the free cells of a window around the chunk's sources only: a path of at
        # most `limit` metres moves at most that far in each axis, so it stays in the window;
        # the window keeps the free-index order, so the distances are the whole graph's
        local = graph[window][:, window] if window is not None else graph
        dist = dijkstra(local, directed=False, indices=_local(chunk, window), limit=limit)
        for k, source in enumerate(chunk):
            found = np.flatnonzero(np.isfinite(dist[k]))  # [r] includes source (d = 0)
            reach = found if window is None else window[found]  # [r] free indices
            d = dist[k, found]  # [r] metres
            if kernel == "uniform":
                base = np.ones(d.size)
            else:
                sigma = radius / 2.0
                base = np.exp(-0.5 * (d / sigma) ** 2)  # [r]
            at = int(np.searchsorted(sources, source))
            for t in by_cell[bounds[at] : ends[at]]:
                w = base
                if fov is not None:
                    offset = centres[reach] - centres[source]  # [r, 2]
                    bearing = np.arctan2(offset[:, 1], offset[:, 0])  # [r]
                    diff = np.angle(np.exp(1j * (bearing - yaw[t])))  # [r] in (-pi, pi]
                    seen = (np.abs(diff) <= math.radians(fov) / 2 + 1e-12) | (reach == source)
                    w = np.where(seen, base, 0.0)
                keep = w > 0
                out_rows.append(np.full(int(keep.sum()), t, dtype=np.int64))
                out_cols.append(reach[keep])
                out_vals.append(w[keep] / w[keep].sum())
        if advance is not None:
            advance(len(chunk))
    if out_rows:
        r, c, v = np.concatenate(out_rows), np.concatenate(out_cols), np.concatenate(out_vals)
    else:
        r = c = np.zeros(0, dtype=np.int64)
        v = np.zeros(0)
    return sparse.csr_matrix((v, (r, c)), shape=(num_obs, n))


def voronoi_weights(
    grid: OccupancyGrid,
    cells: np.ndarray,
    graph: sparse.csr_matrix | None = None,
    radius: float | None = None,
    door_width: float | None = None,
) -> sparse.csr_matrix:
    """[T, N] sparse weights v_{s_t c} of each observation uniform over its geodesic Voronoi
    cell among the distinct placed ``cells`` (module docstring, "Reaching the Voronoi border"):
    the free cells whose nearest source over ``graph`` (:func:`free_cell_graph`, computed if
    None) is its cell, a cell tied between k sources counting 1/k to each; with ``radius``
    (metres, None: no limit) only the cells within that geodesic distance of it ("Bounding the
    reach"); with ``door_width`` (metres, None: no cut) over ``graph`` without its edges between
    room segments at doorways up to that wide ("Voronoi cells within rooms"). ``cells`` [T] free
    indices, -1 unplaced (its row stays empty). Every placed row sums to 1."""
    from scipy import sparse
    from scipy.sparse.csgraph import dijkstra

    _check_reach_radius(radius)
    _check_door_width(door_width)
    limit = np.inf if radius is None else _limit(radius)
    cells, placed = _placed(grid, cells)  # [T], [T']
    num_obs, n = cells.size, int(grid.num_free)
    if not placed.size:
        return sparse.csr_matrix((num_obs, n))
    graph = free_cell_graph(grid) if graph is None else graph
    if door_width is not None:
        graph = _within_rooms(grid, graph, door_width)  # [N, N]
    sources = np.unique(cells[placed])  # [S] sorted
    dist, _, nearest = dijkstra(graph, directed=False, indices=sources, min_only=True,
                                return_predecessors=True, limit=limit)  # fmt: skip  # [N] x3
    reached = np.flatnonzero(np.isfinite(dist))  # [r] cells some source reaches (within limit)
    first = sparse.csr_matrix(  # [N, S] the one nearest source Dijkstra names
        (np.ones(reached.size), (reached, np.searchsorted(sources, nearest[reached]))),
        shape=(n, sources.size),
    )
    edges = graph.tocoo()  # both directions (the graph is symmetric)
    p, c, length = edges.row, edges.col, edges.data  # [E] x3
    both = np.flatnonzero(np.isfinite(dist[p]) & np.isfinite(dist[c]))  # [E'] reached edges
    p, c, length = p[both], c[both], length[both]  # [E'] x3
    slack = np.abs(dist[p] + length - dist[c])  # [E'] metres
    tight = slack <= 1e-9 * np.maximum(dist[c], float(grid.resolution))  # [E']
    before = sparse.csr_matrix(  # [N, N] row c: its tight predecessors p
        (np.ones(int(tight.sum())), (c[tight], p[tight])), shape=(n, n)
    )
    ties = first  # [N, S] 0/1: the sources attaining d*(c), grown to the least fixed point
    while True:  # ties holds first from the start, so first need not be added again
        grown = (ties + before @ ties).tocsr()  # [N, S]
        grown.data[:] = 1.0
        if grown.nnz == ties.nnz:  # grown holds ties: nothing added, the fixed point
            break
        ties = grown
    share = sparse.diags(1.0 / np.maximum(np.asarray(ties.sum(axis=1)).ravel(), 1.0)) @ ties
    size = np.asarray(share.sum(axis=0)).ravel()  # [S] >= 1: a source holds its own cell
    cell_of = (share @ sparse.diags(1.0 / size)).T.tocsr()  # [S, N] each row sums to 1
    pick = sparse.csr_matrix(  # [T, S] observation t at source s_t
        (np.ones(placed.size), (placed, np.searchsorted(sources, cells[placed]))),
        shape=(num_obs, sources.size),
    )
    out = (pick @ cell_of).tocsr()  # [T, N]
    out.sort_indices()
    return out


def _placed(grid: OccupancyGrid, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``cells`` as [T] int64 free indices (-1: unplaced) and [T'] the positions of the placed
    observations in it, checked against the grid's free cells (ValueError naming the index)."""
    cells = np.asarray(cells, dtype=np.int64).reshape(-1)  # [T]
    placed = np.flatnonzero(cells >= 0)  # [T']
    n = int(grid.num_free)
    if placed.size and cells[placed].max() >= n:
        raise ValueError(f"cells holds free index {cells[placed].max()}, the map has {n}")
    return cells, placed


def room_of_free_cells(grid: OccupancyGrid, door_width: float) -> np.ndarray:
    """[N] int64 room segment (>= 0) of every free cell, in free-index order
    (:func:`~spcopyro.maps.rooms.free_cell_rooms` at doorways up to ``door_width`` metres, no
    bar), computed once per grid and width within :func:`shared_footprints`."""
    from spcopyro.maps.rooms import free_cell_rooms

    key = ("room segments", float(door_width))
    return shared((grid,), key, lambda: free_cell_rooms(grid, door_width, progress=False))


def _within_rooms(
    grid: OccupancyGrid, graph: sparse.csr_matrix, door_width: float
) -> sparse.csr_matrix:
    """[N, N] ``graph`` without its edges between free cells of different room segments at
    ``door_width`` metres (:func:`room_of_free_cells`): every path stays in one room. ``graph``
    itself where no edge joins two rooms (one walled space); computed once per grid, graph and
    width within :func:`shared_footprints`."""

    def cut() -> sparse.csr_matrix:
        from scipy import sparse

        room = room_of_free_cells(grid, door_width)  # [N]
        edges = graph.tocoo()  # [E] both directions
        keep = room[edges.row] == room[edges.col]  # [E] bool
        if keep.all():
            return graph
        kept = (edges.data[keep], (edges.row[keep], edges.col[keep]))
        return sparse.coo_matrix(kept, shape=graph.shape).tocsr()

    return shared((grid, graph), ("graph within rooms", float(door_width)), cut)


def _source_windows(
    grid: OccupancyGrid, sources: np.ndarray, limit: float
) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """``sources`` [S] (sorted free indices) in chunks of at most :data:`_CHUNK`, each with the
    sorted free indices of the window around it that holds every cell within ``limit`` metres of
    its sources (None: the whole map, where the window would hold more than
    :data:`_WINDOW_SHARE` of its free cells). A chunk's window is
    its sources' bounding box grown by ``limit`` in cells; a chunk ends where its rows would span
    more than one window's height, so a large map's Dijkstra calls stay local (one call over all
    N cells for each 64 sources made a 10^6-cell map's footprints take minutes)."""
    free_cells = np.asarray(grid.free_cells, dtype=np.int64)  # [N, 2] (row, col)
    index = np.asarray(grid.free_index, dtype=np.int64)  # [H, W]
    height, width = index.shape
    margin = int(math.floor(limit / float(grid.resolution))) + 1  # cells each side
    out: list[tuple[np.ndarray, np.ndarray | None]] = []
    start = 0
    while start < sources.size:
        stop = min(start + _CHUNK, sources.size)
        rows = free_cells[sources[start:stop], 0]  # [s], non-decreasing (raster order)
        stop = start + int(np.searchsorted(rows, rows[0] + 2 * margin, side="right"))
        chunk = sources[start:stop]
        r, c = free_cells[chunk, 0], free_cells[chunk, 1]
        r0, r1 = max(int(r.min()) - margin, 0), min(int(r.max()) + margin + 1, height)
        c0, c1 = max(int(c.min()) - margin, 0), min(int(c.max()) + margin + 1, width)
        box = index[r0:r1, c0:c1]  # [h, w]
        window = np.sort(box[box >= 0])  # [n] free indices, increasing
        out.append((chunk, None if window.size > _WINDOW_SHARE * grid.num_free else window))
        start = stop
    return out


def _local(chunk: np.ndarray, window: np.ndarray | None) -> np.ndarray:
    """The positions of ``chunk``'s free indices in ``window`` (the indices themselves if None)."""
    return chunk if window is None else np.searchsorted(window, chunk)
