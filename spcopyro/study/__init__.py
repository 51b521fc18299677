"""Studies of model variants (issue 26): a declared grid of variants x data x methods x seeds,
run in-process or on a Dask cluster, cached by each cell's input, results as one tidy table.

* :mod:`~spcopyro.study.spec`: the study file (TOML) or the same in Python;
* :mod:`~spcopyro.study.sources`: the data sources (synthetic, public, a tour on a map);
* :mod:`~spcopyro.study.cells`: the grid and each cell's key (the hash of its full input);
* :mod:`~spcopyro.study.evaluate`: one cell: fit and score (what a worker runs);
* :mod:`~spcopyro.study.run`: in-process and Dask execution, the resumable cache;
* :mod:`~spcopyro.study.table`: the cache on disk and ``results.csv``;
* :mod:`~spcopyro.study.report`: markdown mean +- sd tables from the table only.

``spcopyro study STUDY.toml --out OUT`` runs one (:mod:`spcopyro.cli.study`; docs/studies.md).
"""

from __future__ import annotations

from pathlib import Path

STUDIES = Path(__file__).resolve().parent / "studies"
"""The study files shipped with the package (``spcopyro study NAME`` finds them by name)."""

__all__ = ["STUDIES"]
