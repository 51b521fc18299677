"""Hyperparameters and variant switches of SpCoMapping, validated once, with named presets.

Every variant of the model (DP or Dirichlet prior, 4- or 8-neighbourhood, modalities on or off,
image-feature scaling, word weighting) is a field of :class:`SpCoConfig`, never a copy of the model.

Presets (:func:`preset`):

``paper-dp``
    The paper's Section 4.1 values for the weak-limit Dirichlet-process prior:
    alpha 1e8, beta 500, chi 1e4, gamma 4.0, L 120.
``paper-dirichlet``
    The paper's values for the finite Dirichlet prior: alpha 5e7, beta 100, chi 1e4, gamma 3.0,
    L = the known number of categories (pass ``num_concepts``).
``original-code``
    The released implementation's values: alpha 1e7, beta 0.1, chi 1.0, gamma 2.1, L 120,
    image features as floor(100 f).

A note on gamma. The Potts prior over L labels on a square lattice has its critical coupling at
``ln(1 + sqrt(L))`` (2.48 for L = 120). Below it the MRF alone does not form regions: measured with
a port of the released code, ``original-code`` (gamma 2.1) keeps all 120 labels in patches of about
one cell after 1000 sweeps, while gamma 3.0 grows regions that stop at walls. Above it, regions
appear by *coarsening*, slowly, over thousands of sweeps -- which is why sweep speed matters.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal

from spcopyro.data import FeatureScaling, WordWeighting

PRESETS: dict[str, dict[str, object]] = {
    "paper-dp": dict(
        prior="dp", alpha=1e8, beta=500.0, chi=1e4, gamma=4.0, num_concepts=120,
        feature_scaling="probability",
    ),
    "paper-dirichlet": dict(
        prior="dirichlet", alpha=5e7, beta=100.0, chi=1e4, gamma=3.0, num_concepts=None,
        feature_scaling="probability",
    ),
    "original-code": dict(
        prior="dp", alpha=1e7, beta=0.1, chi=1.0, gamma=2.1, num_concepts=120,
        feature_scaling="floor100",
    ),
}  # fmt: skip
DEFAULT_PRESET = "paper-dp"


@dataclass(frozen=True)
class SpCoConfig:
    """Hyperparameters of SpCoMapping (paper eqs. 1-10) and the switches selecting a variant.

    Attributes:
        num_concepts: L, the number of concepts (the weak-limit upper bound for ``prior="dp"``).
        prior: ``"dp"``: pi ~ Dir(alpha/L, ..., alpha/L) (weak-limit DP, eq. 2);
            ``"dirichlet"``: pi ~ Dir(alpha, ..., alpha) (number of concepts known).
        alpha: concentration of the prior over pi.
        beta: symmetric Dirichlet concentration of each word distribution w_l (eq. 6).
        chi: symmetric Dirichlet concentration of each image-feature distribution theta_l (eq. 4).
        gamma: Potts MRF coupling between 4- (or 8-) neighbouring cells (eq. 3), >= 0.
        connectivity: 4 (the paper) or 8.
        use_images, use_words: switch an emission modality on or off.
        feature_scaling: how image histograms become counts: ``"probability"`` (as they are),
            ``"floor100"`` (floor(100 f), the released code) or a float s (s * f).
        word_weighting: ``"count"`` or ``"tfidf"`` (paper eq. 20, for sentences).
        unobserved_refresh: the probability that a sweep redraws theta_l and w_l of the concepts
            that hold no observed cell (for them the conditional is the prior). 1.0 (default)
            redraws every concept every sweep, as Algorithm 1 does; any value in (0, 1] leaves
            the posterior invariant (a random choice of which conditionally independent blocks
            to update, made independently of the state), and a small one makes the sweep's
            cost nearly flat in L, since the [L, K] and [L, V] draws dominate for large L.
        cluster_moves: the probability that a sweep starts with a Swendsen-Wang cluster move of
            the labels (:mod:`spcopyro.gibbs.cluster`: whole regions change concept at once).
            0 (default): Algorithm 1's single-site sweeps only. Any value in [0, 1] leaves the
            posterior invariant (the choice is made independently of the state).
    """

    num_concepts: int = 120
    prior: Literal["dp", "dirichlet"] = "dp"
    alpha: float = 1e8
    beta: float = 500.0
    chi: float = 1e4
    gamma: float = 4.0
    connectivity: Literal[4, 8] = 4
    use_images: bool = True
    use_words: bool = True
    feature_scaling: FeatureScaling = "probability"
    word_weighting: WordWeighting = "count"
    unobserved_refresh: float = 1.0
    cluster_moves: float = 0.0

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"SpCoConfig.{name}={getattr(self, name)!r}: {why}")

        if not isinstance(self.num_concepts, int) or self.num_concepts < 1:
            raise bad("num_concepts", "must be a positive integer")
        if self.prior not in ("dp", "dirichlet"):
            raise bad("prior", "must be 'dp' or 'dirichlet'")
        for name in ("alpha", "beta", "chi"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise bad(name, "must be a finite positive number")
        if not (isinstance(self.gamma, (int, float)) and math.isfinite(self.gamma)):
            raise bad("gamma", "must be a finite number")
        if self.gamma < 0:
            # The sampler's fast path writes exp(gamma n) = 1 + expm1(gamma n) as a mixture of
            # positive parts; an anti-ferromagnetic MRF is outside SpCoMapping's model anyway.
            raise bad("gamma", "must be >= 0 (neighbouring cells attract, never repel)")
        if self.connectivity in (4, 8) and self.gamma * self.connectivity > 700:
            # exp(gamma * n) for n up to D neighbours must stay finite in float64.
            raise bad("gamma", f"gamma * connectivity must be <= 700, got {self.gamma}")
        if self.connectivity not in (4, 8):
            raise bad("connectivity", "must be 4 or 8")
        fs = self.feature_scaling
        is_scale = isinstance(fs, (int, float)) and not isinstance(fs, bool)
        if not (fs in ("probability", "floor100") or (is_scale and math.isfinite(fs) and fs > 0)):
            raise bad("feature_scaling", "must be 'probability', 'floor100' or a positive float")
        refresh = self.unobserved_refresh
        if not (isinstance(refresh, (int, float)) and 0.0 < refresh <= 1.0):
            raise bad("unobserved_refresh", "must be a probability in (0, 1]")
        moves = self.cluster_moves
        if not (isinstance(moves, (int, float)) and 0.0 <= moves <= 1.0):
            raise bad("cluster_moves", "must be a probability in [0, 1]")
        if self.word_weighting not in ("count", "tfidf"):
            raise bad("word_weighting", "must be 'count' or 'tfidf'")

    @property
    def pi_concentration(self) -> float:
        """Each component of pi's Dirichlet concentration: alpha / L (DP) or alpha (Dirichlet)."""
        return self.alpha / self.num_concepts if self.prior == "dp" else self.alpha

    @property
    def critical_gamma(self) -> float:
        """The Potts model's critical coupling ln(1 + sqrt(L)) on the square lattice."""
        return math.log1p(math.sqrt(self.num_concepts))

    def replace(self, **changes: object) -> SpCoConfig:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


def preset(name: str = DEFAULT_PRESET, **overrides: object) -> SpCoConfig:
    """The named preset (see the module docstring) with ``overrides`` applied.

    ``paper-dirichlet`` needs ``num_concepts`` (the known number of categories).
    Overrides whose value is ``None`` are ignored, so CLI options can be passed straight through.
    """
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose one of {sorted(PRESETS)}")
    values = dict(PRESETS[name])
    values.update({k: v for k, v in overrides.items() if v is not None})
    if values.get("num_concepts") is None:
        raise ValueError(
            f"preset {name!r} needs num_concepts (the known number of place categories)"
        )
    unknown = set(values) - {f.name for f in dataclasses.fields(SpCoConfig)}
    if unknown:
        raise ValueError(f"unknown SpCoConfig fields {sorted(unknown)}")
    return SpCoConfig(**values)  # type: ignore[arg-type]
