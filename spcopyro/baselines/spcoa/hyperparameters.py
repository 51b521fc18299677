"""The SpCoA baseline's hyperparameters (priors of its concepts' Gaussians and distributions)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from spcopyro._util.number_checks import is_finite_number, is_positive_number
from spcopyro.baselines.spcoa.niw import DIM


@dataclass(frozen=True)
class SpCoAHyperparameters:
    """Priors (C1)-(C3) of the package docstring; validated on construction.

    Attributes:
        num_concepts: L, the weak-limit upper bound on the number of concepts.
        alpha: DP concentration; pi ~ Dir(alpha / L).
        beta: symmetric Dirichlet concentration of each word distribution w_l.
        chi: symmetric Dirichlet concentration of each image-class distribution theta_l.
        kappa0: NIW prior strength on the mean (mu ~ N(m_0, Sigma / kappa_0)).
        nu0: NIW degrees of freedom, > d + 1 = 3 so that E[Sigma] exists.
        psi0: Psi_0 = psi0 * I (m^2); the prior mean of Sigma is Psi_0 / (nu0 - 3).
        mu0: m_0, world (x, y); None: the mean of the event positions.
    """

    num_concepts: int = 20
    alpha: float = 1.0
    beta: float = 0.1
    chi: float = 0.1
    kappa0: float = 0.01
    nu0: float = 4.0
    psi0: float = 1.0
    mu0: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"SpCoA {name}={getattr(self, name)!r}: {why}")

        if isinstance(self.num_concepts, bool) or not isinstance(self.num_concepts, int):
            raise bad("num_concepts", "must be a positive integer")
        if self.num_concepts < 1:
            raise bad("num_concepts", "must be a positive integer")
        for name in ("alpha", "beta", "chi", "kappa0", "psi0"):
            value = getattr(self, name)
            if not is_positive_number(value):
                raise bad(name, "must be a finite positive number")
        nu0 = self.nu0
        if not is_finite_number(nu0):
            raise bad("nu0", f"must be a finite number > {DIM + 1}")
        if nu0 <= DIM + 1:
            raise bad("nu0", f"must be > d + 1 = {DIM + 1} (so that E[Sigma] exists)")
        if self.mu0 is not None:
            try:
                mu0 = tuple(float(v) for v in self.mu0)
            except (TypeError, ValueError):
                raise bad("mu0", "must be None or two numbers (x, y)") from None
            if len(mu0) != DIM or not all(math.isfinite(v) for v in mu0):
                raise bad("mu0", "must be None or two finite numbers (x, y)")
            object.__setattr__(self, "mu0", mu0)
