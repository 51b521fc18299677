r"""The compiled label sweep (eq. 13): the hot loop of :mod:`spcopyro.gibbs.numba_sweep`.

Every free cell is drawn from

.. math::

    p(C_i = l \mid \text{rest}) \propto B_l(i) \, e^{\gamma n_l(i)}
        = B_l(i) + \sum_{s=1}^{D} \delta_{l a_s} \, B_{a_s}
          \frac{\mathrm{expm1}(\gamma n_{a_s}(i))}{n_{a_s}(i)},

B(i) being the cell's background (pi, or pi times the likelihood of its observations, scaled:
the [M + 1, L + D] table of :mod:`~spcopyro.gibbs.numba_sweep`) and a_s the label in neighbour
slot s (a missing neighbour reads a sentinel label L + s of background 0). With probability
sum(B) / (sum(B) + neighbour mass) the label comes from B, else from the slots.

What makes this loop lean (issue 15; each kept because it paid on room2ldk4 and the
distribution tests still pass):

- **Layout** (:class:`LabelPlan`, built once per sweep plan): the cells of each colour block in
  the plan's order, its cells without observations first, then those with; int32 neighbour
  indices; labels as uint8 when L + D <= 256 (uint16, int32 above), so the whole label map of a
  house (28k cells) sits in the L1 cache. Cells of one block are conditionally independent, so
  their order inside the block does not change the distribution.
- **Two loops per block**: cells without observations never look up a background row (theirs
  is pi's, row M), and draw from pi by Walker's alias method (Vose, 1991: one uniform, O(1);
  the table is built per sweep in O(L)) instead of a binary search; cells with observations
  scan their row. A cell without observations so costs O(D^2) (O(D) on the short path below),
  against O(D^2 + log L) in the reference (:mod:`spcopyro.gibbs.sweep`); one with
  observations O(D^2 + L).
- **The RNG state in registers** (:func:`~spcopyro.gibbs.numba_random.next_bits`).
- **A short path inside regions**: a cell without observations whose D neighbours all hold one
  label a (most cells of a settled map) is a from p(a) = B_a e^{gamma D} / (sum(B) +
  B_a expm1(gamma D)), else a draw from pi: the same conditional, without the D^2 comparisons
  (a third faster on room2ldk4 once regions have formed).
- **The Potts statistic for free**: when a cell is drawn, its neighbours in *earlier* blocks
  already hold their final labels for this sweep, so counting its agreements with them counts
  every neighbouring pair exactly once (a pair's two cells lie in different blocks): the sweep
  returns E(C) of the labels it leaves, which the run loop's log joint needs. Where all of a
  segment's neighbours are earlier (the second block of the 4-neighbourhood's two) the count is
  n_l(i) of the drawn label, which the draw has at hand already.

D is a compile-time constant of each kernel (a closure variable), so the slot loops unroll.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit

from spcopyro.gibbs.numba_plan import FlatPlan, flat_plan, flatten_plan
from spcopyro.gibbs.numba_random import bits_to_uniform, next_bits
from spcopyro.gibbs.state import SweepPlan, make_sweep_plan
from spcopyro.model import ModelData

_LABEL_PLAN_CACHE_SIZE = 8


class LabelPlan(NamedTuple):
    """A :class:`~spcopyro.gibbs.state.SweepPlan` laid out for the lean label loop."""

    order: np.ndarray
    """[N] int32 free index of the cell at each position: block after block, each block's cells
    without observations first, then those with."""
    neighbours: np.ndarray
    """[N, D] int32 free indices of that cell's neighbours (N + s for a missing one in slot s)."""
    rows: np.ndarray
    """[N] int32 the cell's background row (its row in ``data.obs_cells``; M where none)."""
    segments: np.ndarray
    """[2B + 1] int64: block b's cells without observations lie at positions
    segments[2b]:segments[2b + 1], those with at segments[2b + 1]:segments[2b + 2]."""
    modes: np.ndarray
    """[2B] int64 per segment: 0 when none of its cells' neighbours lies in an earlier block,
    1 when all of them do (missing neighbours aside), 2 otherwise (then ``earlier`` says which)."""
    earlier: np.ndarray
    """[N] uint8, bit s set where neighbour slot s is a cell of an earlier block."""


# id(plan) -> (plan, its LabelPlan), as numba_plan's cache (the plan is held so that its id is
# not reused while cached); changes hold the lock (chains may sweep in threads).
_label_plans: dict[int, tuple[SweepPlan, LabelPlan]] = {}
_label_plans_lock = threading.Lock()


def label_plan(plan: SweepPlan | None, data: ModelData) -> LabelPlan:
    """The :class:`LabelPlan` of ``plan`` (checked against ``data`` by
    :func:`~spcopyro.gibbs.numba_plan.flat_plan`; cached per plan object), or of a fresh plan of
    ``data`` if None (not cached: that plan dies with the call)."""
    if plan is None:
        plan = make_sweep_plan(data)
        return _layout(plan, flatten_plan(plan, data), data)
    flat = flat_plan(plan, data)  # validates (and caches) the plan for these data
    entry = _label_plans.get(id(plan))
    if entry is not None and entry[0] is plan:
        return entry[1]
    result = _layout(plan, flat, data)
    with _label_plans_lock:
        while len(_label_plans) >= _LABEL_PLAN_CACHE_SIZE:
            del _label_plans[next(iter(_label_plans))]  # oldest first
        _label_plans[id(plan)] = (plan, result)
    return result


def _layout(plan: SweepPlan, flat: FlatPlan, data: ModelData) -> LabelPlan:
    """The :class:`LabelPlan` of a plan already checked and flattened (``flat``)."""
    N, D, M = data.num_free, data.neighbours.shape[1], flat.num_observed
    block_of = np.empty(N + D, dtype=np.int64)  # [N + D] block of each free cell; D sentinels
    block_of[N:] = len(plan.blocks)  # never "earlier"
    sizes = [int(block.cells.shape[0]) for block in plan.blocks]
    starts = np.cumsum([0, *sizes])  # [B + 1]
    for b in range(len(sizes)):
        block_of[flat.cells[starts[b] : starts[b + 1]]] = b
    order, segments = [], [0]
    for b in range(len(sizes)):
        positions = np.arange(starts[b], starts[b + 1])
        observed = flat.background_rows[positions] < M
        for part in (positions[~observed], positions[observed]):
            order.append(part)
            segments.append(segments[-1] + part.shape[0])
    positions = np.concatenate(order) if order else np.zeros(0, dtype=np.int64)  # [N]
    neighbours = flat.neighbours[positions]  # [N, D]
    own_block = block_of[flat.cells[positions]]  # [N]
    earlier_slots = block_of[neighbours] < own_block[:, None]  # [N, D]
    earlier = (earlier_slots * (1 << np.arange(D))).sum(axis=1).astype(np.uint8)  # [N]
    real = neighbours < N  # [N, D] slots holding a cell
    modes = np.empty(len(segments) - 1, dtype=np.int64)  # [2B]
    for g in range(len(segments) - 1):
        part = slice(segments[g], segments[g + 1])
        if not earlier_slots[part].any():
            modes[g] = 0
        elif np.array_equal(earlier_slots[part], real[part]):
            modes[g] = 1
        else:
            modes[g] = 2
    return LabelPlan(
        order=np.ascontiguousarray(flat.cells[positions], dtype=np.int32),
        neighbours=np.ascontiguousarray(neighbours, dtype=np.int32),
        rows=np.ascontiguousarray(flat.background_rows[positions], dtype=np.int32),
        segments=np.asarray(segments, dtype=np.int64),
        modes=modes,
        earlier=earlier,
    )


def compact_label_dtype(num_concepts: int, num_neighbours: int) -> type:
    """The narrowest integer type holding labels 0..L-1 and the sentinels L..L+D-1."""
    top = num_concepts + num_neighbours - 1
    return np.uint8 if top <= 255 else np.uint16 if top <= 65535 else np.int32


@njit(cache=True, nogil=True)
def compact_labels(labels: np.ndarray, out: np.ndarray, num_concepts: int) -> int:
    """Copy int64 labels [N] into the narrower out [N + D], sentinels L + s at N + s; returns
    the first position whose label lies outside [0, L), or -1."""
    N = labels.shape[0]
    for i in range(N):
        value = labels[i]
        if value < 0 or value >= num_concepts:
            return i
        out[i] = value
    for s in range(out.shape[0] - N):
        out[N + s] = num_concepts + s
    return -1


@njit(cache=True, nogil=True)
def alias_table(weights: np.ndarray, probability: np.ndarray, alias: np.ndarray) -> None:
    """Walker's alias table of the non-negative weights [L] (not all 0), by Vose's (1991) method:
    draw i uniform in [0, L), keep it with probability[i], else take alias[i]."""
    L = weights.shape[0]
    total = 0.0
    for l in range(L):
        total += weights[l]
    scaled = np.empty(L)  # [L] weights * L / total
    small = np.empty(L, np.int64)  # stack of indices below 1
    large = np.empty(L, np.int64)  # stack of indices at or above 1
    num_small = num_large = 0
    for l in range(L):
        scaled[l] = weights[l] * L / total
        if scaled[l] < 1.0:
            small[num_small] = l
            num_small += 1
        else:
            large[num_large] = l
            num_large += 1
    while num_small > 0 and num_large > 0:
        num_small -= 1
        num_large -= 1
        low, high = small[num_small], large[num_large]
        probability[low], alias[low] = scaled[low], high
        scaled[high] = (scaled[high] + scaled[low]) - 1.0
        if scaled[high] < 1.0:
            small[num_small] = high
            num_small += 1
        else:
            large[num_large] = high
            num_large += 1
    for k in range(num_large):  # what rounding leaves over is (numerically) exactly 1
        probability[large[k]], alias[large[k]] = 1.0, large[k]
    for k in range(num_small):
        probability[small[k]], alias[small[k]] = 1.0, small[k]


@functools.cache
def label_sweep_kernel(num_neighbours: int) -> Callable[..., int]:
    """The compiled label sweep for D = ``num_neighbours`` (one compilation per D and label
    dtype).

    Arguments: labels [N + D] (compact dtype, sentinels L + s at N + s), redrawn in place; the
    :class:`LabelPlan`'s order, neighbours, rows, segments, modes, earlier; background
    [M + 1, L + D] (zero columns L..L+D-1; row M is pi's); tilt [D + 1] expm1(gamma k) / k;
    state [4] the RNG.
    Returns E(C), the number of agreeing neighbour pairs of the labels it leaves.
    """
    D = num_neighbours

    @njit(cache=True, nogil=True)
    def sweep_labels(
        labels: np.ndarray,
        order: np.ndarray,
        neighbours: np.ndarray,
        rows: np.ndarray,
        segments: np.ndarray,
        modes: np.ndarray,
        earlier: np.ndarray,
        background: np.ndarray,
        tilt: np.ndarray,
        state: np.ndarray,
    ) -> int:
        L = background.shape[1] - D
        M = background.shape[0] - 1
        totals = np.empty(M + 1)  # [M + 1] row sums, in the order the scans add them up
        for r in range(M + 1):
            running = 0.0
            for l in range(L):
                running += background[r, l]
            totals[r] = running
        keep = np.empty(L)  # [L] pi's alias table
        alias = np.empty(L, np.int64)
        alias_table(background[M, :L], keep, alias)
        pi_total = totals[M]
        whole_tilt = tilt[D] * D  # expm1(gamma D)
        slots = np.empty(D, np.int64)  # [D] a_s
        agree = np.empty(D, np.int64)  # [D] n_{a_s}(i): the slots holding a_s
        cumulative = np.empty(D)  # [D] running slot masses
        s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
        agreements = 0
        for segment in range(segments.shape[0] - 1):
            observed = segment % 2 == 1
            counting = modes[segment]  # 0: no earlier neighbours, 1: all are, 2: per the mask
            # Unsigned positions and cell indices: numba wraps a negative signed index around,
            # a compare and a select per access that LLVM cannot drop for a position loaded
            # from memory; unsigned ones skip it (the same cells; ~a quarter of the loop).
            for p in range(np.uint64(segments[segment]), np.uint64(segments[segment + 1])):
                r = rows[p] if observed else M
                for s in range(D):
                    slots[s] = labels[np.uint32(neighbours[p, s])]
                first = slots[0]
                alike = first < L
                for s in range(1, D):
                    alike = alike and slots[s] == first
                if alike and not observed:  # inside a region: p(a) = B_a e^{gamma D} / Z
                    mass = background[M, first] * whole_tilt  # B_a expm1(gamma D)
                    bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                    label = first
                    if bits_to_uniform(bits) * (pi_total + mass) >= mass:  # from pi
                        bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                        y = bits_to_uniform(bits) * L
                        i = min(int(y), L - 1)
                        label = i if y - i < keep[i] else alias[i]
                    labels[np.uint32(order[p])] = label
                    if label == first and counting == 1:
                        agreements += D
                    elif label == first and counting == 2:
                        mask = earlier[p]
                        for s in range(D):
                            agreements += (mask >> s) & 1
                    continue
                mass = 0.0  # slot s: B_{a_s} expm1(gamma n_{a_s}) / n_{a_s}
                for s in range(D):
                    same = 0
                    for t in range(D):
                        same += slots[t] == slots[s]
                    agree[s] = same
                    mass += background[r, slots[s]] * tilt[same]
                    cumulative[s] = mass
                total = totals[r] if observed else pi_total
                bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                u = bits_to_uniform(bits) * (total + mass)
                label = slots[D - 1]
                matches = agree[D - 1]  # neighbours holding the drawn label
                for s in range(D - 2, -1, -1):
                    chosen = u < cumulative[s]
                    label = slots[s] if chosen else label
                    matches = agree[s] if chosen else matches
                if u >= mass:  # the background part, with a fresh uniform
                    bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                    if not observed:  # pi: alias method
                        y = bits_to_uniform(bits) * L
                        i = min(int(y), L - 1)
                        label = i if y - i < keep[i] else alias[i]
                    else:  # B_r / totals[r]: a linear scan
                        x = bits_to_uniform(bits) * total
                        while x >= total:  # U * total rounded up to total (p ~ 1e-16): redraw
                            bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                            x = bits_to_uniform(bits) * total
                        running = 0.0
                        label = 0
                        while label < L - 1:
                            running += background[r, label]
                            if running > x:
                                break
                            label += 1
                    matches = 0
                    for s in range(D):
                        matches += slots[s] == label
                labels[np.uint32(order[p])] = label
                if counting == 1:
                    agreements += matches
                elif counting == 2:
                    mask = earlier[p]
                    for s in range(D):
                        agreements += ((mask >> s) & 1) * (slots[s] == label)
        state[0], state[1], state[2], state[3] = s0, s1, s2, s3
        return agreements

    return sweep_labels


@njit(cache=True, nogil=True)
def count_cells(labels: np.ndarray, num_free: int, out: np.ndarray) -> None:
    """out [L] (zeroed) += 1 for the label of each of the first ``num_free`` cells (eq. 14's
    m_l). Four interleaved integer tallies: runs of one label do not wait on one counter."""
    L = out.shape[0]
    tallies = np.zeros((4, L), np.int64)
    head = num_free - num_free % 4
    for i in range(0, head, 4):
        tallies[0, labels[i]] += 1
        tallies[1, labels[i + 1]] += 1
        tallies[2, labels[i + 2]] += 1
        tallies[3, labels[i + 3]] += 1
    for i in range(head, num_free):
        tallies[0, labels[i]] += 1
    for l in range(L):
        out[l] += tallies[0, l] + tallies[1, l] + tallies[2, l] + tallies[3, l]


@njit(cache=True, nogil=True)
def agreements_of(labels: np.ndarray, pairs: np.ndarray) -> int:
    """E(C): the number of pairs [P, 2] whose two cells hold the same label."""
    total = 0
    for p in range(pairs.shape[0]):
        total += labels[pairs[p, 0]] == labels[pairs[p, 1]]
    return total
