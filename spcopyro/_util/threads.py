r"""How many threads a fit uses: chosen on purpose, not left to torch's default.

torch runs each operation on a tensor with up to ``torch.get_num_threads()`` intra-op threads
(OpenMP; the default is one per core). A Gibbs sweep is a few hundred *small* operations -- tensors
of the N free cells or fewer (N ~ 2e4 on the public houses), the L x K emission tables, an
M x K by K x L product over the M observed cells -- so a second thread saves little per
operation and costs a fork/join at each of them. On a machine doing anything else it costs far
more: the OpenMP team waits at every join for whichever thread the scheduler has set aside.

**The policy** (``threads="auto"``, the default of :func:`spcopyro.fit.house.fit_house` and
``spcopyro fit``): a map of fewer than :data:`MIN_CELLS_FOR_MORE_THREADS` free cells runs with
one intra-op thread; a larger one keeps torch's own setting. With T threads, a sweep of N cells
costs about

.. math::

    t(T) \approx \frac{a N}{T} + b N_\text{ops} (T - 1) + \text{(waits for descheduled threads)},

and the threshold is the N from which the first term's saving beats the rest on an idle 2-core
machine: the smallest map size from which two threads were at least 1.2x faster than one on both
backends (``python benchmarks/threads.py``; its measurements are in ``docs/speed.md``, "Threads").
Next to a busy neighbour the second thread makes a fit several times *slower*, labels identical;
above the threshold, a fit on a busy machine still gains from ``threads=1`` (``--threads 1``): the
policy cannot see the machine's load.

:func:`torch_threads` sets the count around a fit and restores the previous one afterwards, even
when the fit fails. What it does not touch:

- **numba**: the compiled sweep's kernels (:mod:`spcopyro.gibbs.numba_sweep`) are
  single-threaded ``@njit`` functions (no ``parallel=True``, no ``prange``), so
  ``NUMBA_NUM_THREADS`` plays no part; the torch operations around them (the background table's
  product, the conjugate draws, the log joint) follow the torch setting.
- **numpy's BLAS (OpenBLAS)**: the sweep makes no numpy BLAS call -- the one matrix product of the
  compiled backend runs in torch for that reason -- so numpy's thread pool stays idle during a
  fit; it is sized by ``OPENBLAS_NUM_THREADS`` when numpy is imported and left alone here.
- **torch's inter-op pool** (``torch.set_num_interop_threads``): only TorchScript's ``fork``
  uses it; nothing here does.

The thread count changes no label: torch's random draws on the CPU are serial, whatever the
setting, and ``tests/test_threads.py`` checks that a seeded fit gives the same labels with one
thread and with two. Only the last bits of a float reduction (a sum split across threads) may
differ, which is why the pinned outputs hash float tables at 12 significant digits; on room1dk5
and the synthetic house (200 sweeps, both backends) the floats were bit-identical too.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from numbers import Integral

from spcopyro._util.messages import plural

AUTO = "auto"
"""``threads`` value that applies :func:`policy_threads`."""

MIN_CELLS_FOR_MORE_THREADS = 50_000
"""Free cells from which a map keeps torch's own thread count (``threads="auto"``); below it, one
thread. Measured with ``python benchmarks/threads.py`` (``docs/speed.md``)."""


def policy_threads(num_cells: int) -> int | None:
    """The policy's intra-op thread count for a map of ``num_cells`` free cells: 1 below
    :data:`MIN_CELLS_FOR_MORE_THREADS`, else None (torch's own setting)."""
    return 1 if num_cells < MIN_CELLS_FOR_MORE_THREADS else None


def resolve_threads(threads: int | str | None, num_cells: int) -> int | None:
    """The intra-op thread count to run a map of ``num_cells`` free cells with.

    Args:
        threads: ``"auto"`` (:func:`policy_threads`), ``None`` or 0 (leave torch's setting as it
            is), or a positive integer (that many threads).

    Returns:
        A positive count, or None for "leave torch's setting".
    """
    if threads == AUTO:
        return policy_threads(num_cells)
    if threads is None:
        return None
    if isinstance(threads, Integral) and not isinstance(threads, bool) and threads >= 0:
        return int(threads) or None
    raise ValueError(
        f"threads must be 'auto', 0 or None (torch's own setting) or a positive integer, "
        f"got {threads!r}"
    )


def describe_threads(threads: int | str | None, num_cells: int) -> str:
    """One line on the thread count a fit of ``num_cells`` free cells will use, and why."""
    import torch  # here, not at the top: the commands that only parse need no torch

    count = resolve_threads(threads, num_cells)
    current = torch.get_num_threads()
    if threads == AUTO:
        if count is None:
            why = f"policy: {num_cells} free cells >= {MIN_CELLS_FOR_MORE_THREADS}"
        else:
            why = f"policy: {num_cells} free cells < {MIN_CELLS_FOR_MORE_THREADS}"
    elif count is None:
        why = "torch's own setting, as asked"
    else:
        why = "as asked"
    used = current if count is None else count
    return f"{plural(used, 'torch intra-op thread')} ({why})"


@contextmanager
def torch_threads(count: int | None) -> Iterator[int]:
    """Run the block with ``count`` torch intra-op threads (None: leave the setting alone), then
    restore the previous count -- also when the block raises. Yields the count in effect."""
    import torch

    integer = isinstance(count, Integral) and not isinstance(count, bool)
    if count is not None and not (integer and count >= 1):
        raise ValueError(f"count must be a positive integer or None, got {count!r}")
    previous = torch.get_num_threads()
    if count is not None and count != previous:
        torch.set_num_threads(int(count))
    try:
        yield torch.get_num_threads()
    finally:
        if torch.get_num_threads() != previous:
            torch.set_num_threads(previous)
