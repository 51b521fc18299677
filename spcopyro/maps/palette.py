r"""Colours a reader can tell apart on a semantic map.

:func:`label_colours` (in :mod:`~spcopyro.maps.render`) only promises *different* RGB triples:
beyond its 18 tab20 colours, golden-ratio hues come close to earlier ones, so two concepts, even
touching ones, look alike (its 20 colours hold two reds 9 apart in Delta E, its 120 two greens
1.7 apart, under a just noticeable difference of about 2.3). This module picks colours by how
different they *look*, measured as Delta E CIE94 (:func:`delta_e94`; colours 20 or more apart are
told apart at a glance). CIE94 weighs a difference of chroma less in saturated colours, as the
eye does: the Euclidean CIELAB distance (CIE76, :func:`delta_e`) that the palette used before
put pure green and a light yellow-green 52.6 apart (12.3 in CIE94), so two concepts of one map
could look alike; the smallest CIE94 difference of 12 palette colours went from 12.3 to 26.5,
of 40 from 6.8 to 15.2.

* :func:`distinct_colours` -- ``n`` colours by farthest-point sampling in CIE94 from a grid of
  candidate RGB colours, none close to black (walls), white (unlabelled free space), the unknown
  grey, nor so dark or so light (L* outside 40-90) that they pass for walls or free space, nor
  grey or near-grey (chroma C* under 15): a concept drawn in (120, 120, 120) or (165, 165, 165),
  which palettes of 40 colours and more held, read as unexplored space or wall. Each
  new colour maximises its smallest Delta E to the ones chosen before (and to those reserved
  colours), so the first colours are the most different and every colour is distinct from
  every other.
* :func:`region_adjacency` -- which concepts touch (4-neighbourhood) in a label image.
* :func:`concept_colours` -- one colour per concept, all distinct, given largest region first;
  each concept takes, of a palette of twice as many colours as concepts, the unused one farthest
  from the colours of the concepts it touches that are already coloured, so neighbours differ
  most. (With exactly one colour per concept the last concepts must take what is left: on
  room1dk5's 114 concepts, fitted with the released code's values and gamma 3, touching concepts
  then came as close as Delta E 41, against 55 with the doubled palette and 18 with the palette
  in order of concept size, in CIE76; on a 10 x 10 chessboard of concepts 20, 94 and 27 in
  CIE76, and with the CIE94 palette 47 against 12 in CIE94.)
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from spcopyro._util.number_checks import is_integer
from spcopyro.maps.regions import region_contacts

__all__ = [
    "concept_colours",
    "concept_palette",
    "delta_e",
    "delta_e94",
    "distinct_colours",
    "region_adjacency",
    "srgb_to_lab",
]

_RESERVED = np.array([[0, 0, 0], [255, 255, 255], [205, 205, 205]], dtype=np.uint8)
"""Black walls, white unlabelled free space, unknown grey (render.RGB_*)."""
_MIN_LIGHTNESS, _MAX_LIGHTNESS = 40.0, 90.0  # CIELAB L*: not near-black, not near-white
_MIN_CHROMA = 15.0  # CIELAB C*: no grey, which reads as unknown space or a wall
_LEVELS = 18  # candidate grid: 18 levels per channel (5832 colours)


def srgb_to_lab(rgb: Any) -> np.ndarray:
    r"""``[..., 3]`` sRGB (uint8 0-255) -> ``[..., 3]`` CIELAB (D65 white), float64.

    .. math::

        c_{lin} = \begin{cases} c/12.92 & c \le 0.04045 \\ ((c + 0.055)/1.055)^{2.4}
        & \text{else} \end{cases}, \quad XYZ = M\,c_{lin}, \quad
        L^* = 116 f(Y/Y_n) - 16, \; a^* = 500 (f(X/X_n) - f(Y/Y_n)), \;
        b^* = 200 (f(Y/Y_n) - f(Z/Z_n)).
    """
    c = np.asarray(rgb, dtype=np.float64) / 255.0  # [..., 3]
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    m = np.array(
        [[0.4124564, 0.3575761, 0.1804375],
         [0.2126729, 0.7151522, 0.0721750],
         [0.0193339, 0.1191920, 0.9503041]]
    )  # fmt: skip
    xyz = linear @ m.T / np.array([0.95047, 1.0, 1.08883])  # [..., 3] relative to D65 white
    delta = 6.0 / 29.0
    f = np.where(xyz > delta**3, np.cbrt(xyz), xyz / (3 * delta**2) + 4.0 / 29.0)
    return np.stack(
        [
            116.0 * f[..., 1] - 16.0,
            500.0 * (f[..., 0] - f[..., 1]),
            200.0 * (f[..., 1] - f[..., 2]),
        ],
        axis=-1,
    )


def delta_e(a: Any, b: Any) -> np.ndarray:
    """Delta E (CIE76: the Euclidean CIELAB distance) between sRGB colours ``[..., 3]`` and
    ``[..., 3]`` (broadcast). It overstates differences of chroma in saturated colours; the
    palette is chosen by :func:`delta_e94`."""
    return np.linalg.norm(srgb_to_lab(a) - srgb_to_lab(b), axis=-1)


def _lab_delta_e94(lab_a: np.ndarray, lab_b: np.ndarray) -> np.ndarray:
    r"""Delta E CIE94 (graphic arts: k_L = 1, K_1 = 0.045, K_2 = 0.015) between CIELAB colours
    ``[..., 3]`` and ``[..., 3]`` (broadcast), made symmetric by taking the chroma that weighs
    the differences as the geometric mean of the two:

    .. math::

        \Delta E_{94} = \sqrt{\Delta L^2 + \left(\frac{\Delta C}{1 + K_1 C}\right)^2
        + \left(\frac{\Delta H}{1 + K_2 C}\right)^2}, \quad C = \sqrt{C_a C_b}, \;
        \Delta H^2 = \Delta a^2 + \Delta b^2 - \Delta C^2.
    """
    chroma_a = np.hypot(lab_a[..., 1], lab_a[..., 2])
    chroma_b = np.hypot(lab_b[..., 1], lab_b[..., 2])
    d_lightness = lab_a[..., 0] - lab_b[..., 0]
    d_chroma = chroma_a - chroma_b
    d_ab2 = (lab_a[..., 1] - lab_b[..., 1]) ** 2 + (lab_a[..., 2] - lab_b[..., 2]) ** 2
    d_hue2 = np.maximum(d_ab2 - d_chroma**2, 0.0)  # rounding can leave it a hair below 0
    chroma = np.sqrt(chroma_a * chroma_b)
    return np.sqrt(
        d_lightness**2 + (d_chroma / (1 + 0.045 * chroma)) ** 2 + d_hue2 / (1 + 0.015 * chroma) ** 2
    )


def delta_e94(a: Any, b: Any) -> np.ndarray:
    """Delta E CIE94 between sRGB colours ``[..., 3]`` and ``[..., 3]`` (broadcast; symmetric:
    see :func:`_lab_delta_e94`). The measure the palette is chosen by."""
    return _lab_delta_e94(srgb_to_lab(a), srgb_to_lab(b))


@functools.cache
def _candidates() -> tuple[np.ndarray, np.ndarray]:
    """The candidate colours ``[M, 3]`` uint8 and their CIELAB ``[M, 3]``: an 18-level grid per
    channel, lightness within [_MIN_LIGHTNESS, _MAX_LIGHTNESS], chroma at least _MIN_CHROMA.
    Computed once (read-only arrays)."""
    levels = np.round(np.linspace(0, 255, _LEVELS)).astype(np.uint8)
    grid = np.stack(np.meshgrid(levels, levels, levels, indexing="ij"), axis=-1).reshape(-1, 3)
    lab = srgb_to_lab(grid)  # [M, 3]
    keep = (lab[:, 0] >= _MIN_LIGHTNESS) & (lab[:, 0] <= _MAX_LIGHTNESS)
    keep &= np.hypot(lab[:, 1], lab[:, 2]) >= _MIN_CHROMA  # no grey
    grid, lab = grid[keep], lab[keep]
    grid.flags.writeable = lab.flags.writeable = False
    return grid, lab


def _num_candidates() -> int:
    return len(_candidates()[0])


_PICKS: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
"""The candidates :func:`distinct_colours` picked for the largest ``n`` asked for so far, in
order. The k-th pick does not depend on ``n``, so the colours of a smaller ``n`` are the first
``n`` of these (``spcopyro fit`` asks for the semantic map's palette on its figures' thread while
the chains run: :class:`~spcopyro.cli.fit_figures.FigurePrefetch`)."""


def distinct_colours(n: int) -> np.ndarray:
    """``[n, 3]`` uint8 sRGB colours, pairwise distinct, deterministic, each as far (in Delta E
    CIE94) from the earlier ones and from black, white and the unknown grey as the candidates
    allow.

    The smallest pairwise Delta E CIE94 falls as ``n`` grows (29 for 10 colours, 15 for 40, 9.3
    for 120); ``n`` is limited to the candidates (18 levels per channel, lightness L* 40-90,
    chroma C* at least 15).
    """
    if not is_integer(n) or n < 0:
        raise ValueError(f"n must be a non-negative integer, got {n!r}")
    grid, lab = _candidates()  # [M, 3] uint8, [M, 3] Lab
    if n > len(grid):
        raise ValueError(f"at most {len(grid)} distinct colours are available, asked for {n}")
    if n > len(_PICKS[0]):
        # distance of every candidate to the nearest colour taken so far (reserved ones included)
        nearest = np.min(_lab_delta_e94(lab[:, None, :], srgb_to_lab(_RESERVED)[None]), axis=1)
        chosen = np.empty(n, dtype=np.int64)  # [n]
        for k in range(n):
            pick = int(np.argmax(nearest))  # first maximum: deterministic
            chosen[k] = pick
            nearest = np.minimum(nearest, _lab_delta_e94(lab, lab[pick]))  # [M]
            nearest[pick] = -1.0  # never twice
        _PICKS[0] = chosen
    return grid[_PICKS[0][:n]]  # [n, 3], a copy


def concept_palette(count: int) -> np.ndarray:
    """``[P, 3]`` uint8: the palette :func:`concept_colours` chooses from for ``count`` concepts,
    the first ``P = 2 count`` :func:`distinct_colours` (all candidates where there are fewer)."""
    return distinct_colours(min(2 * count, _num_candidates()))


def region_adjacency(labels: Any) -> set[tuple[int, int]]:
    """Pairs ``(a, b)``, ``a < b``, of labels >= 0 that touch across a 4-neighbour edge of the
    ``[H, W]`` label image (-1 cells touch nothing): :func:`~spcopyro.maps.regions.region_contacts`
    as a set."""
    a, b, _ = region_contacts(labels)
    return set(zip(a.tolist(), b.tolist(), strict=True))


def concept_colours(labels: Any, concepts: Any) -> np.ndarray:
    """``[K, 3]`` uint8: a colour for each of ``concepts`` (``[K]`` ids, largest region first),
    all distinct; concepts that touch in ``labels`` (``[H, W]``) get colours far apart.

    The palette is :func:`distinct_colours` ``(2 K)``; concept k (in the given order) takes the
    unused palette colour that maximises the smallest Delta E (CIE94) to its already coloured
    neighbours (the palette's first unused colour when it has none), ties to the earlier colour.
    """
    order = [int(c) for c in np.asarray(concepts).ravel()]
    if len(set(order)) != len(order):
        raise ValueError("concepts must be distinct")
    palette = concept_palette(len(order))  # [P, 3]
    lab = srgb_to_lab(palette)  # [P, 3]
    apart: dict[int, np.ndarray] = {}  # palette index j -> [P] Delta E to j, computed once

    def to(j: int) -> np.ndarray:
        if j not in apart:
            apart[j] = _lab_delta_e94(lab, lab[j])  # [P]
        return apart[j]

    position = {c: k for k, c in enumerate(order)}
    neighbours: dict[int, list[int]] = {k: [] for k in range(len(order))}
    for a, b in region_adjacency(labels):
        if a in position and b in position:
            neighbours[position[a]].append(position[b])
            neighbours[position[b]].append(position[a])
    given = np.full(len(order), -1, dtype=np.int64)  # palette index of each concept
    free = np.ones(len(palette), dtype=bool)  # [P]
    for k in range(len(order)):
        coloured = [given[j] for j in neighbours[k] if given[j] >= 0]
        if coloured:
            distance = np.stack([to(int(j)) for j in coloured], axis=1)  # [P, n]
            score = np.where(free, distance.min(axis=1), -1.0)  # [P]
            pick = int(np.argmax(score))
        else:
            pick = int(np.argmax(free))
        given[k] = pick
        free[pick] = False
    return palette[given]
