"""Mean field, loopy BP and exact label marginals side by side on tiny maps (the teaching
notebook "Gibbs versus VI" shows them), and the measurement behind docs/variational.md's
statement of how far each approximation is from exact.

All three describe the same label field, the one a variational label update sees: with the
global factors q(pi), q(phi) held fixed, node terms E[log pi_l] + the observed cell's expected
log-likelihood and the model's Potts coupling gamma. The exact marginals are enumerated by
:func:`spcopyro.guides.testing.exact_marginals` at the factors' expected logs.
"""

from __future__ import annotations

import types
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import torch

from spcopyro.config import SpCoConfig
from spcopyro.guides.cavi import one_hot, update_labels
from spcopyro.guides.factors import (
    GlobalFactors,
    expected_log_emissions,
    expected_log_pi,
    update_factors,
)
from spcopyro.guides.lbp import LoopyBP, node_log_potentials
from spcopyro.guides.testing import exact_marginals
from spcopyro.likelihood import concept_statistics
from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
from spcopyro.model import DTYPE, ModelData, make_model_data

SQUARE = ("...", "...", "...")
"""3 x 3 free cells: the tiny map of the tests and of docs/variational.md's numbers."""


class TinyMapComparison(NamedTuple):
    """Mean field, loopy BP and exact label marginals of one tiny map, globals fixed."""

    exact: torch.Tensor
    """[N, L] p(C_i = l | x, pi, phi) by enumeration, at pi, phi's expected logs."""
    mean_field: torch.Tensor
    """[N, L] CAVI's q(C) (colour-block updates from uniform q, factors fixed)."""
    lbp: torch.Tensor
    """[N, L] loopy BP's beliefs (uniform messages at the start, factors fixed)."""

    def errors(self) -> dict[str, float]:
        """Largest absolute error of each method's marginals, and its mean."""
        out = {}
        for name in ("mean_field", "lbp"):
            error = (getattr(self, name) - self.exact).abs()
            out[f"{name} max"] = float(error.max())
            out[f"{name} mean"] = float(error.mean())
        return out

    def entropies(self) -> dict[str, torch.Tensor]:
        """[N] each cell's entropy (nats) under each: mean field's lower than the exact one is
        its over-confidence."""
        return {
            name: -torch.special.xlogy(p, p).sum(-1)
            for name, p in (("exact", self.exact), ("mean_field", self.mean_field),
                            ("lbp", self.lbp))
        }  # fmt: skip


def compare_on_tiny_map(
    data: ModelData,
    config: SpCoConfig,
    factors: GlobalFactors,
    iterations: int = 500,
    damping: float = 0.5,
) -> TinyMapComparison:
    """Mean-field, loopy-BP and exact marginals side by side for a tiny map with the global
    factors fixed: all three describe the label field with node terms E[log pi] + the observed
    cells' E-log-likelihood (``factors``' expectations) and the model's Potts coupling.
    ``iterations`` mean-field sweeps and as many BP message passes (``damping`` for BP)."""
    N, L = data.num_free, config.num_concepts
    exact = exact_marginals(data, config, expected_log_pi(factors), expected_log_emissions(factors))
    q = torch.full((N, L), 1.0 / L, dtype=DTYPE)
    for _ in range(iterations):
        q = update_labels(q, factors, data, config)
    bp = LoopyBP(data, config, damping=damping)
    beliefs = bp.run(node_log_potentials(factors, data, config), config.gamma, iterations)
    return TinyMapComparison(exact, q, beliefs)


def tiny_map(
    seed: int,
    rows: Sequence[str] = SQUARE,
    num_observed: int = 3,
    feature_classes: int = 3,
    vocabulary_size: int = 4,
) -> ModelData:
    """A tiny map (``rows``: '.' free, '#' wall) with ``num_observed`` observed cells holding
    random real-valued image counts (Gamma(1, 2)) and word counts (Poisson(1) + U(0, 0.5))."""
    occupancy = np.array([[FREE if c == "." else OCCUPIED for c in row] for row in rows])
    grid = OccupancyGrid(occupancy.astype(np.int8), 0.1, (0.0, 0.0, 0.0))
    rng = np.random.default_rng(seed)
    cells = np.sort(rng.choice(grid.num_free, num_observed, replace=False))
    images = rng.gamma(1.0, 2.0, (num_observed, feature_classes))
    words = rng.poisson(1.0, (num_observed, vocabulary_size)) + rng.uniform(
        0, 0.5, (1, vocabulary_size)
    )
    counts = types.SimpleNamespace(
        num_free=grid.num_free, cells=cells, image_counts=images, word_counts=words
    )
    return make_model_data(grid, counts)


def labelled_factors(data: ModelData, config: SpCoConfig, seed: int) -> GlobalFactors:
    """Global factors as a variational run holds them: the Dirichlet update from one-hot
    uniformly random labels (informative node fields, not extreme ones)."""
    rng = np.random.default_rng(seed)
    labels = torch.as_tensor(rng.integers(0, config.num_concepts, data.num_free))
    q = one_hot(labels, config.num_concepts)
    return update_factors(concept_statistics(q, data, config), data, config)


def marginal_error_study(
    gammas: Sequence[float] = (0.5, 1.0, 1.5, 2.0, 3.0),
    concepts: Sequence[int] = (2, 3),
    seeds: int = 10,
    iterations: int = 300,
) -> list[dict[str, float]]:
    """For every (L, gamma), ``seeds`` random 3 x 3 maps (:func:`tiny_map`, factors from
    :func:`labelled_factors`): the largest and mean absolute marginal errors of mean field and
    LBP, and their mean entropy minus the exact one per cell (negative: over-confident)."""
    rows = []
    for L in concepts:
        for gamma in gammas:
            config = SpCoConfig(num_concepts=L, prior="dp", alpha=3.0, beta=1.0, chi=1.0,
                                gamma=gamma)  # fmt: skip
            found = []
            for seed in range(seeds):
                data = tiny_map(seed)
                comparison = compare_on_tiny_map(
                    data, config, labelled_factors(data, config, seed + 100), iterations
                )
                entropy = comparison.entropies()
                gaps = {
                    f"{name} entropy gap": float((entropy[name] - entropy["exact"]).mean())
                    for name in ("mean_field", "lbp")
                }
                found.append({**comparison.errors(), **gaps})
            row = {"L": L, "gamma": gamma}
            for key in found[0]:
                values = [f[key] for f in found]
                row[key] = max(values) if key.endswith("max") else float(np.mean(values))
            rows.append(row)
    return rows
