"""The names of the point estimates, without numpy: what ``spcopyro fit --point-estimate`` offers.

The parser (:mod:`spcopyro.cli.fit_parser`) reads them from here, so ``spcopyro --help`` does not
import :mod:`spcopyro.results.point_estimate` (``tests/test_cli_startup.py``), which re-exports
them under the same names.
"""

from __future__ import annotations

__all__ = ["LOSSES", "LOSS_LABELS", "POINT_ESTIMATES"]

LOSSES = ("binder", "vi")
"""The expected losses :func:`~spcopyro.results.point_estimate.point_estimate` minimises."""
LOSS_LABELS = {"binder": "Binder loss", "vi": "variation of information"}
"""What the progress bar calls each loss (its label read 'vi' as variational inference)."""
POINT_ESTIMATES = ("map-visited", *LOSSES)
"""What a fit may report as its map: the highest-log-joint state visited, or a loss's minimiser."""
