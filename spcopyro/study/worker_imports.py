"""What a study's forkserver imports before it forks the LocalCluster's workers
(:data:`spcopyro.study.local_cluster.WORKER_PRELOAD`): dask's worker and a cell's code
(:data:`WORKER_IMPORTS`), each through :func:`spcopyro._util.collector.import_frozen`, as the
study's own process imports them: the cyclic garbage collector does not run during the import
(it ran about 600 collections, 0.7-0.8 s on a 2-core machine, in ``import spcopyro.study.run``)
and the objects imported are frozen, so the forked workers' collections skip them too. Then it
creates the file that ``SPCOPYRO_FORKSERVER_READY`` names, where set (the forkserver's
environment), which tells the study's process that the server is ready to fork workers.
"""

from __future__ import annotations

import os

from spcopyro._util.collector import import_frozen

__all__ = ["WORKER_IMPORTS"]

WORKER_IMPORTS = ("distributed", "spcopyro.study.evaluate")
"""The modules imported (dask's worker and a cell's code)."""

_ready = os.environ.pop("SPCOPYRO_FORKSERVER_READY", None)  # local_cluster.READY_FILE
try:
    for _name in WORKER_IMPORTS:
        import_frozen(_name)
finally:  # the study's process waits for it (local_cluster.wait_for_forkserver); not forked on
    if _ready:
        open(_ready, "w").close()  # noqa: SIM115
