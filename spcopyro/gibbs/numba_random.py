r"""The compiled sampler's own random numbers (numba cannot draw from a torch.Generator).

numba's ``np.random`` costs ~9 ns a uniform (a thread-local state lookup per call). Each call of
the compiled sweep therefore draws one seed from the given :class:`torch.Generator`
(:func:`draw_seed`) and expands it with SplitMix64 (:func:`rng_state`) into the state of an
inlined xoshiro256++ generator (Blackman & Vigna, 2018; ~1.5 ns a uniform, doubles from its top
53 bits); normals come from Doornik's (2005) ziggurat (~4 ns), gamma variates from Marsaglia &
Tsang (2000) in log space, with log G(a) = log G(a + 1) + log(U) / a for a < 1, so
concentrations far below 1 (alpha / L) never underflow. A seeded run is reproducible bit for
bit, but its numbers differ from the torch backend's: only the distributions agree (what the
tests check). Importing this module raises :class:`ImportError` when numba is missing.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from numba import njit

SEED_BOUND = 2**62
"""Seeds drawn from the torch generator lie in [0, SEED_BOUND)."""

_U11, _U17, _U23, _U41, _U45, _U19 = (np.uint64(k) for k in (11, 17, 23, 41, 45, 19))
_U127 = np.uint64(127)
_TWO_TO_MINUS_53 = 1.0 / 9007199254740992.0
_MASK64 = (1 << 64) - 1


def rng_state(seed: int) -> np.ndarray:
    """[4] uint64 xoshiro256++ state from an integer seed, expanded by SplitMix64."""
    words = []
    x = seed & _MASK64
    for _ in range(4):
        x = (x + 0x9E3779B97F4A7C15) & _MASK64
        z = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
        words.append(z ^ (z >> 31))
    return np.array(words, dtype=np.uint64)


def draw_seed(generator: torch.Generator) -> int:
    """One seed in [0, SEED_BOUND) for the compiled sampler's RNG, from the torch generator."""
    return int(torch.randint(SEED_BOUND, (), generator=generator))


@njit(cache=True, inline="always")
def next_bits(
    s0: np.uint64, s1: np.uint64, s2: np.uint64, s3: np.uint64
) -> tuple[np.uint64, np.uint64, np.uint64, np.uint64, np.uint64]:
    """xoshiro256++ (Blackman & Vigna, 2018) on a state held in four local variables:
    (64 random bits, the next state). The hot loops keep the state in registers this way and
    write it back to the [4] array once (an array state costs a store and a reload per draw)."""
    total = s0 + s3
    result = ((total << _U23) | (total >> _U41)) + s0
    t = s1 << _U17
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    s3 = (s3 << _U45) | (s3 >> _U19)
    return result, s0, s1, s2, s3


@njit(cache=True, inline="always")
def bits_to_uniform(bits: np.uint64) -> float:
    """A uniform double in [0, 1) from the top 53 of 64 random bits."""
    return float(bits >> _U11) * _TWO_TO_MINUS_53


@njit(cache=True, inline="always")
def _next_bits(state: np.ndarray) -> np.uint64:
    """64 random bits from xoshiro256++; advances the array ``state`` [4]."""
    bits, state[0], state[1], state[2], state[3] = next_bits(state[0], state[1], state[2], state[3])
    return bits


@njit(cache=True, inline="always")
def uniform(state: np.ndarray) -> float:
    """A uniform double in [0, 1) (the top 53 of 64 random bits)."""
    return float(_next_bits(state) >> _U11) * _TWO_TO_MINUS_53


def _ziggurat_tables(layers: int = 128) -> tuple[np.ndarray, np.ndarray, float]:
    """Doornik's (2005) ZIGNOR tables: layer edges x [C + 1], ratios x[i+1] / x[i] [C], and R.

    The C layers of equal area V under exp(-x^2 / 2) start at R = 3.442619855899 (C = 128).
    """
    tail_start, area = 3.442619855899, 9.91256303526217e-3
    x = np.zeros(layers + 1)  # [C + 1]
    f = math.exp(-0.5 * tail_start**2)
    x[0], x[1] = area / f, tail_start
    for i in range(2, layers):
        x[i] = math.sqrt(-2.0 * math.log(area / x[i - 1] + f))
        f = math.exp(-0.5 * x[i] ** 2)
    return x, x[1:] / x[:-1], tail_start


_ZIG_X, _ZIG_RATIO, _ZIG_TAIL = _ziggurat_tables()


@njit(cache=True, nogil=True)
def _normal_slow_path(bits: np.uint64, state: np.ndarray) -> float:
    """The rest of Doornik's ziggurat after its first 64 bits missed the layer's rectangle
    (~1% of draws): the tail or the wedge, NaN where the wedge rejects (then start afresh).
    Out of line, so that the fast path stays small where it is inlined."""
    i = np.int64(bits & _U127)
    u = 2.0 * (float(bits >> _U11) * _TWO_TO_MINUS_53) - 1.0
    if i == 0:  # the tail beyond R (Marsaglia, 1964)
        while True:
            x = math.log(1.0 - uniform(state)) / _ZIG_TAIL
            y = math.log(1.0 - uniform(state))
            if -2.0 * y >= x * x:
                return x - _ZIG_TAIL if u < 0.0 else _ZIG_TAIL - x
    x = u * _ZIG_X[i]
    f0 = math.exp(-0.5 * (_ZIG_X[i] * _ZIG_X[i] - x * x))
    f1 = math.exp(-0.5 * (_ZIG_X[i + 1] * _ZIG_X[i + 1] - x * x))
    if f1 + uniform(state) * (f0 - f1) < 1.0:
        return x
    return math.nan


@njit(cache=True, inline="always")
def _normal(state: np.ndarray) -> float:
    """A standard normal by Doornik's ziggurat (ZIGNOR; layer and uniform from separate bits)."""
    while True:
        bits = _next_bits(state)
        i = np.int64(bits & _U127)  # layer: the low 7 bits
        u = 2.0 * (float(bits >> _U11) * _TWO_TO_MINUS_53) - 1.0  # (-1, 1): the top 53 bits
        if abs(u) < _ZIG_RATIO[i]:
            return u * _ZIG_X[i]  # inside the layer's rectangle (~99%)
        x = _normal_slow_path(bits, state)
        if not math.isnan(x):
            return x


@njit(cache=True, inline="always")
def marsaglia_tsang(
    d: float,
    scale: float,
    s0: np.uint64,
    s1: np.uint64,
    s2: np.uint64,
    s3: np.uint64,
    state: np.ndarray,
) -> tuple[float, np.uint64, np.uint64, np.uint64, np.uint64]:
    """(G ~ Gamma(a, 1) for a > 1, the next RNG state) by Marsaglia & Tsang (2000) with its
    squeeze, d = a - 1/3 and scale = 1 / sqrt(9 d) given. The RNG state travels in four
    registers (:func:`next_bits`); ``state`` [4] is only the scratch of the ziggurat's slow path
    (~1% of normals), whose fast path is inlined here."""
    while True:
        bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
        layer = np.int64(bits & _U127)
        z = 2.0 * (float(bits >> _U11) * _TWO_TO_MINUS_53) - 1.0
        if abs(z) < _ZIG_RATIO[layer]:
            x = z * _ZIG_X[layer]  # the ziggurat's rectangle (~99%)
        else:
            state[0], state[1], state[2], state[3] = s0, s1, s2, s3
            x = _normal_slow_path(bits, state)
            s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
            if math.isnan(x):  # the wedge rejected: a fresh normal
                continue
        t = 1.0 + scale * x
        if t <= 0.0:
            continue
        v = t * t * t
        bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
        u = 1.0 - bits_to_uniform(bits)
        x2 = x * x
        if u < 1.0 - 0.0331 * x2 * x2 or math.log(u) < 0.5 * x2 + d * (1.0 - v + math.log(v)):
            return d * v, s0, s1, s2, s3


@njit(cache=True, nogil=True)
def _fill_normal(out: np.ndarray, state: np.ndarray) -> None:
    """out [n] = standard normals."""
    for i in range(out.shape[0]):
        out[i] = _normal(state)


@njit(cache=True, nogil=True)
def _fill_gamma_linear(
    base: float,
    statistics: np.ndarray,
    out: np.ndarray,
    boost: np.ndarray,
    row_sums: np.ndarray,
    row_boosted: np.ndarray,
    state: np.ndarray,
) -> int:
    """The rejection part of :func:`fill_log_gamma`: out[r, c] = G(a') (linear) with
    a' = a + 1 where a = base + statistics[r, c] < 1 (then boost[r, c] = log(U) / a, else 0),
    row_sums[r] = sum_c out[r, c], row_boosted[r] = whether row r has a shape below 1.
    Returns -1 or the flat index of the first a that is not finite and positive. The RNG state
    stays in registers; the ziggurat's fast path is inlined.
    """
    R, C = statistics.shape
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    shape, d, scale = -1.0, 0.0, 0.0  # Marsaglia-Tsang's constants of the last shape seen
    for r in range(R):
        total = 0.0
        row_boosted[r] = False
        for c in range(C):
            a = base + statistics[r, c]
            extra = 0.0
            # Shape 1 first (chi = 1's empty concepts: most of theta): this order keeps the
            # one loop as fast as a separate loop for rows without statistics was; the range
            # check first costs 5% (Marsaglia-Tsang rows) to 25% (shape 1) a fill.
            if a != 1.0:
                if not 0.0 < a < np.inf:
                    state[0], state[1], state[2], state[3] = s0, s1, s2, s3
                    return r * C + c
                if a < 1.0:
                    bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                    extra = math.log(1.0 - bits_to_uniform(bits)) / a  # 1 - U lies in (0, 1]
                    a += 1.0
                    row_boosted[r] = True
            boost[r, c] = extra
            if a == 1.0:  # Gamma(1) is Exp(1): -log(1 - U), exactly (chi = 1, empty concepts)
                bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                draw = -math.log(1.0 - bits_to_uniform(bits))
                while draw == 0.0:  # U = 0 exactly (p = 2^-53): log G would be -inf
                    bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                    draw = -math.log(1.0 - bits_to_uniform(bits))
                out[r, c] = draw
                total += draw
                continue
            if a != shape:  # most concepts hold no observations: their shapes repeat
                shape, d = a, a - 1.0 / 3.0
                scale = 1.0 / math.sqrt(9.0 * d)
            draw, s0, s1, s2, s3 = marsaglia_tsang(d, scale, s0, s1, s2, s3, state)
            out[r, c] = draw
            total += draw
        row_sums[r] = total
    state[0], state[1], state[2], state[3] = s0, s1, s2, s3
    return -1


def fill_log_gamma(base: float, statistics: np.ndarray, out: np.ndarray, state: np.ndarray) -> int:
    """out[r, c] = log G, G ~ Gamma(base + statistics[r, c], 1), for [R, C] float64 arrays.

    Shape exactly 1 (chi = 1 with no counts: most rows of the released code's theta) is an
    exponential, -log(1 - U); other shapes Marsaglia-Tsang with its squeeze (a >= 1); for a < 1,
    log G(a) = log G(a + 1) + log(U) / a, finite however small a is. Returns -1, or the flat
    index r * C + c of the first shape that is not finite and positive (and stops there: the
    rejection loop would never end).
    """
    log_rows, bad = _log_gamma_rows(base, statistics, state, normalise=False)
    if bad < 0:
        out[...] = log_rows
    return bad


def _log_gamma_rows(
    base: float, statistics: np.ndarray, state: np.ndarray, normalise: bool
) -> tuple[np.ndarray, int]:
    """([R, C] log G, or log(G / sum_c G) with ``normalise``; the bad index or -1).

    The rejection loop draws G linearly (:func:`_fill_gamma_linear`), then one vectorised log
    pass; a row whose shapes are all >= 1 normalises as log G - log(sum G) (its sum is finite:
    no underflow above shape 1), one with shapes below 1 in log space (G(a) = G(a+1) U^(1/a)
    underflows for small a).
    """
    R, C = statistics.shape
    if C == 0:  # over no items (the words of a house where none was heard): [R, 0]
        return np.empty((R, 0)), -1
    out = np.empty((R, C))
    boost = np.empty((R, C))
    row_sums = np.empty(R)
    boosted = np.empty(R, dtype=np.bool_)  # [R] rows with a shape below 1
    bad = _fill_gamma_linear(float(base), statistics, out, boost, row_sums, boosted, state)
    if bad >= 0:
        return out, bad
    np.log(out, out=out)
    if not boosted.any():  # every shape >= 1: the linear sums are safe
        if normalise:
            out -= np.log(row_sums)[:, None]
        return out, -1
    out[boosted] += boost[boosted]
    if normalise:
        plain = ~boosted
        out[plain] -= np.log(row_sums[plain])[:, None]
        out[boosted] = normalise_log_rows(out[boosted])
    return out, -1


def dirichlet_log_rows(
    base: float, statistics: np.ndarray, state: np.ndarray
) -> tuple[np.ndarray, int]:
    """([R, C] log of R Dirichlet(base + statistics[r]) draws, -1), or (garbage, the flat index
    of the first concentration that is not finite and positive): normalised Gamma variates
    (:func:`fill_log_gamma`'s), in log space where a shape is below 1."""
    return _log_gamma_rows(base, statistics, state, normalise=True)


def normalise_log_rows(log_g: np.ndarray) -> np.ndarray:
    """log g - logsumexp(log g) over the last axis, in place (vectorised numpy exp)."""
    log_g -= log_g.max(axis=-1, keepdims=True)
    log_g -= np.log(np.exp(log_g).sum(axis=-1, keepdims=True))
    return log_g


def sample_log_gamma_numba(concentration: np.ndarray, seed: int) -> np.ndarray:
    """[n] log G_i, G_i ~ Gamma(concentration_i, 1): the compiled sampler's own log-gamma draws.

    Exposed to test them against scipy.

    Raises:
        ValueError: a concentration is not finite and positive.
    """
    a = np.ascontiguousarray(concentration, dtype=np.float64).reshape(1, -1)  # [1, n]
    invalid = ~(np.isfinite(a) & (a > 0))
    if invalid.any():
        raise ValueError(f"gamma concentration must be finite and positive, got {a[invalid][0]}")
    out = np.empty_like(a)
    fill_log_gamma(0.0, a, out, rng_state(seed))
    return out[0]  # [n]


def sample_standard_normal_numba(size: int, seed: int) -> np.ndarray:
    """[size] standard normals from the compiled sampler's ziggurat (exposed for testing)."""
    out = np.empty(size)
    _fill_normal(out, rng_state(seed))
    return out
