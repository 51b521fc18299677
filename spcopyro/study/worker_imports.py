"""What a study's forkserver imports before it forks the LocalCluster's workers
(:data:`spcopyro.study.local_cluster.WORKER_PRELOAD`): dask's worker and a cell's code
(:data:`WORKER_IMPORTS`), each through :func:`spcopyro._util.collector.import_frozen`, as the
study's own process imports them: the cyclic garbage collector does not run during the import
(it ran about 600 collections, 0.7-0.8 s on a 2-core machine, in ``import spcopyro.study.run``)
and the objects imported are frozen, so the forked workers' collections skip them too.
"""

from __future__ import annotations

from spcopyro._util.collector import import_frozen

__all__ = ["WORKER_IMPORTS"]

WORKER_IMPORTS = ("distributed", "spcopyro.study.evaluate")
"""The modules imported (dask's worker and a cell's code)."""

for _name in WORKER_IMPORTS:
    import_frozen(_name)
