r"""The numbers of the inference comparison (:mod:`spcopyro.experiments.inference_comparison`)
that do not depend on how a method works: time to reach a share of the final quality, effective
sample size per second, the Potts agreement count along a chain, and how confident a method is
on the cells it labels wrong.

All functions take plain arrays and are checked on constructed inputs
(``tests/test_inference_comparison.py``).
"""

from __future__ import annotations

import math

import numpy as np
import torch

from spcopyro.model import potts_agreements

CONFIDENT = 0.99
"""A cell counts as confidently labelled when its method gives its label at least this
probability (variational: q(C_i = label); sampler: the share of kept samples with that label)."""


def time_to_fraction(
    seconds: np.ndarray,
    values: np.ndarray,
    final: float,
    fraction: float = 0.95,
    *,
    higher_is_better: bool = True,
) -> float:
    r"""The first time at which a quality curve reaches ``fraction`` of its own final value.

    ``seconds`` ``[S]`` (ascending) and ``values`` ``[S]`` are the curve; ``final`` the method's
    final quality. For a score where higher is better the target is ``fraction * final`` when
    ``final > 0`` (and ``final`` itself otherwise: "95% of" a non-positive ARI means nothing);
    for one where lower is better (a distance, a rank) it is ``final / fraction`` when
    ``final > 0``. Returns NaN when the curve never reaches the target (or ``final`` is NaN).
    """
    seconds = np.asarray(seconds, dtype=np.float64)  # [S]
    values = np.asarray(values, dtype=np.float64)  # [S]
    if seconds.shape != values.shape or seconds.ndim != 1:
        raise ValueError(f"seconds {seconds.shape} and values {values.shape} must be equal [S]")
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must lie in (0, 1], got {fraction}")
    if not math.isfinite(final) or seconds.size == 0:
        return math.nan
    if higher_is_better:
        target = fraction * final if final > 0 else final
        reached = values >= target - 1e-12
    else:
        target = final / fraction if final > 0 else final
        reached = values <= target + 1e-12
    reached &= np.isfinite(values)
    hits = np.flatnonzero(reached)
    return float(seconds[hits[0]]) if hits.size else math.nan


def effective_sample_size(series: np.ndarray) -> float:
    r"""The effective sample size of one chain's scalar ``series`` ``[S]``.

    Geyer's (1992) initial monotone sequence estimator, as Stan and Pyro
    (:func:`pyro.ops.stats.effective_sample_size`) use it, in numpy (Pyro's running minimum is
    a Python loop, minutes on a long chain): with :math:`\rho_t` the autocorrelation at lag t
    (FFT, the 1/S autocovariance) and :math:`\Gamma_k = \rho_{2k} + \rho_{2k+1}`,

    .. math::

        \mathrm{ESS} = \frac{S}{-1 + 2\Gamma_0 + 2\sum_{k \ge 1} \min_{j \le k}
        \max(\Gamma_j, 0)} .

    For an AR(1) series with coefficient :math:`\rho` this tends to
    :math:`S (1 - \rho) / (1 + \rho)`. NaN for fewer than 4 values or a constant series (no
    variance, nothing to estimate).
    """
    x = np.asarray(series, dtype=np.float64)  # [S]
    if x.ndim != 1:
        raise ValueError(f"series must be one-dimensional, got shape {x.shape}")
    if x.size < 4 or not np.all(np.isfinite(x)) or np.ptp(x) == 0:
        return math.nan
    n = x.size
    size = 1 << int(2 * n - 1).bit_length()  # >= 2n: no circular wrap-around
    spectrum = np.fft.rfft(x - x.mean(), n=size)
    autocovariance = np.fft.irfft(spectrum * spectrum.conj(), n=size)[:n] / n  # [S]
    rho = autocovariance / autocovariance[0]  # [S]
    pairs = rho[: 2 * (n // 2)].reshape(-1, 2).sum(1)  # [S // 2] Gamma_k
    tail = np.minimum.accumulate(np.clip(pairs[1:], 0.0, None))  # initial monotone sequence
    tau = -1.0 + 2.0 * pairs[0] + 2.0 * tail.sum()
    return float(n / tau) if tau > 0 else math.nan


def ess_per_second(series: np.ndarray, seconds: np.ndarray, burn_in: float = 0.5) -> float:
    """ESS per second of the draws after the first ``burn_in`` share of ``series`` ``[S]``;
    ``seconds`` ``[S]`` is the cumulative wall-clock time at each draw, so the window's cost is
    ``seconds[-1] - seconds[start - 1]`` (or ``seconds[-1]`` when nothing is discarded)."""
    x = np.asarray(series, dtype=np.float64)  # [S]
    t = np.asarray(seconds, dtype=np.float64)  # [S]
    if x.shape != t.shape:
        raise ValueError(f"series {x.shape} and seconds {t.shape} differ")
    if not 0 <= burn_in < 1:
        raise ValueError(f"burn_in must lie in [0, 1), got {burn_in}")
    start = int(math.floor(burn_in * x.size))
    elapsed = t[-1] - (t[start - 1] if start > 0 else 0.0) if x.size else 0.0
    ess = effective_sample_size(x[start:])
    return ess / elapsed if elapsed > 0 and math.isfinite(ess) else math.nan


def agreement_counts(label_samples: np.ndarray, pairs: torch.Tensor) -> np.ndarray:
    """[S] the Potts statistic E(C) = sum over neighbour pairs of [C_a = C_b] of each kept label
    map ``[S, N]`` (:func:`spcopyro.model.potts_agreements`)."""
    labels = torch.as_tensor(np.asarray(label_samples, dtype=np.int64))  # [S, N]
    return potts_agreements(labels, pairs).numpy()


def sample_confidence(label_samples: np.ndarray, labels: np.ndarray, burn_in: float = 0.5):
    """[N] the share of a sampler's kept label maps after burn-in that give each cell its label
    in ``labels`` ``[N]`` (the sampler's counterpart of q(C_i = label)); concept numbers are
    stable along one chain, so no relabelling is needed."""
    samples = np.asarray(label_samples)  # [S, N]
    kept = samples[int(math.floor(burn_in * samples.shape[0])) :]  # [S', N]
    return (kept == np.asarray(labels)[None, :]).mean(0)


def wrong_cells(labels: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """[N] bool: cells whose concept's majority ground-truth category differs from their own.

    Each concept is read as the category most of its cells belong to (a merged concept is then
    wrong on the smaller categories it covers; a split category is not penalised).
    ``labels`` and ``truth`` are ``[N]`` non-negative ints over the same cells.
    """
    labels = np.asarray(labels, dtype=np.int64)  # [N]
    truth = np.asarray(truth, dtype=np.int64)  # [N]
    if labels.shape != truth.shape or (labels < 0).any() or (truth < 0).any():
        raise ValueError("labels and truth must be equal-shaped arrays of non-negative ints")
    table = np.zeros((labels.max() + 1, truth.max() + 1), dtype=np.int64)  # [L, T]
    np.add.at(table, (labels, truth), 1)
    majority = table.argmax(1)  # [L]
    return majority[labels] != truth


def overconfidence(confidence: np.ndarray, wrong: np.ndarray) -> dict[str, float]:
    """How sure a method is where it is wrong: the share of wrong cells, the mean confidence on
    wrong and on right cells, and the share of wrong cells labelled with confidence
    >= :data:`CONFIDENT` (``confidence`` ``[N]`` in [0, 1], ``wrong`` ``[N]`` bool)."""
    confidence = np.asarray(confidence, dtype=np.float64)  # [N]
    wrong = np.asarray(wrong, dtype=bool)  # [N]

    def mean(x: np.ndarray) -> float:
        return float(x.mean()) if x.size else math.nan

    return {
        "wrong_share": float(wrong.mean()),
        "confidence_wrong": mean(confidence[wrong]),
        "confidence_right": mean(confidence[~wrong]),
        "confident_wrong_share": mean(confidence[wrong] >= CONFIDENT),
    }


def geometric_indices(count: int, points: int) -> np.ndarray:
    """Up to ``points`` distinct indices into ``count`` items, spaced evenly on a log scale and
    always holding the last one (the points of a curve drawn on a log time axis)."""
    if count < 1:
        return np.empty(0, dtype=np.int64)
    raw = np.geomspace(1, count, num=max(2, points))
    return np.unique(np.clip(np.rint(raw).astype(np.int64) - 1, 0, count - 1))


def geometric_budgets(iterations: int, points: int) -> list[int]:
    """Iteration budgets ``iterations, iterations // 2, iterations // 4, ...`` (at most
    ``points``, each >= 1), ascending: the reruns of a method that keeps no label maps."""
    budgets = sorted({max(1, iterations >> k) for k in range(max(1, points))})
    return budgets
