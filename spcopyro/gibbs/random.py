"""Moved to :mod:`spcopyro.random_draws` (the draws are not Gibbs-specific)."""

from spcopyro.random_draws import (  # noqa: F401
    sample_categorical_logits,
    sample_log_dirichlet,
    sample_log_gamma,
)
