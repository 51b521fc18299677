"""Moved to :mod:`spcopyro.random_draws` (the baselines draw from it too); re-exported here."""

from spcopyro.random_draws import sample_categorical_logits, sample_log_dirichlet, sample_log_gamma

__all__ = ["sample_categorical_logits", "sample_log_dirichlet", "sample_log_gamma"]
