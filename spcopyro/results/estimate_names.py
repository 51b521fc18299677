"""The names of the point estimates, without numpy: what ``spcopyro fit --point-estimate`` offers.

The parser (:mod:`spcopyro.cli.fit_parser`) reads them from here, so ``spcopyro --help`` does not
import :mod:`spcopyro.results.point_estimate` (``tests/test_cli_startup.py``), which re-exports
them under the same names.
"""

from __future__ import annotations

__all__ = ["KEEPS_SPECKS", "LOSSES", "LOSS_LABELS", "POINT_ESTIMATES", "estimate_loss"]

LOSSES = ("binder", "vi")
"""The expected losses :func:`~spcopyro.results.point_estimate.point_estimate` minimises."""
LOSS_LABELS = {"binder": "Binder loss", "vi": "variation of information"}
"""What the progress bar calls each loss (its label read 'vi' as variational inference)."""
KEEPS_SPECKS = "-specks"
"""The suffix of a loss's estimate that keeps its speck clusters (``vi-specks``): the plain
``vi`` and ``binder`` join each speck's cells to other concepts
(:mod:`spcopyro.results.speck_join`); ``vi-specks`` is the unconstrained minimiser, as ``vi``
was until 2026-12-06."""
POINT_ESTIMATES = ("map-visited", *LOSSES, *(f"{loss}{KEEPS_SPECKS}" for loss in LOSSES))
"""What a fit may report as its map: the highest-log-joint state visited, a loss's minimiser
among the partitions without specks, or its unconstrained minimiser (specks kept)."""


def estimate_loss(name: str) -> tuple[str, bool]:
    """(the loss, whether speck clusters are joined) of the point estimate ``name``, one of
    :data:`POINT_ESTIMATES` but ``map-visited``: ``"vi"`` -> ``("vi", True)``, ``"vi-specks"``
    -> ``("vi", False)``; ValueError for any other name."""
    loss = name.removesuffix(KEEPS_SPECKS)
    if name == "map-visited" or loss not in LOSSES:
        named = ", ".join(n for n in POINT_ESTIMATES if n != "map-visited")
        raise ValueError(f"point estimate {name!r} minimises no loss: choose one of {named}")
    return loss, loss == name
