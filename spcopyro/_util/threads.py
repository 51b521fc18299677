r"""How many threads a fit uses: chosen on purpose, not left to torch's default.

torch runs each operation on a tensor with up to ``torch.get_num_threads()`` intra-op threads
(OpenMP; the default is one per core). A Gibbs sweep is a few hundred *small* operations -- tensors
of the N free cells or fewer (N ~ 2e4 on the public houses), the L x K emission tables, an
M x K by K x L product over the M observed cells -- so a second thread saves little per
operation and costs a fork/join at each of them. On a machine doing anything else it costs far
more: the OpenMP team waits at every join for whichever thread the scheduler has set aside.

**The policy** (``threads="auto"``, the default of :func:`spcopyro.fit.house.fit_house` and
``spcopyro fit``): a map of fewer than :data:`MIN_CELLS_FOR_MORE_THREADS` free cells runs with
one intra-op thread; a larger one keeps torch's own setting, unless the other processes leave
fewer cores free than that many threads (:func:`other_load`, read as the fit starts, a reading
reused for :data:`LOAD_REUSE_S` s): then it runs with the cores they leave free, at least one.
With T threads, a sweep of N cells costs about

.. math::

    t(T) \approx \frac{a N}{T} + b N_\text{ops} (T - 1) + \text{(waits for descheduled threads)},

and the threshold is the N from which the first term's saving beats the rest on an idle 2-core
machine: the smallest map size from which two threads were at least 1.2x faster than one on both
backends (``python benchmarks/threads.py``; its measurements are in ``docs/speed.md``, "Threads").
The last term is why the load counts: next to a busy neighbour the second thread makes a fit
several times *slower* (memoized VI on 92,328 cells beside a load of about 4: 94 s against 20 s),
with bit-identical outputs, so the load may choose the count without changing a result (a label;
``svi``'s floats change in their last bits, below).
``config.json`` records the count that ran (``"threads"``).

:func:`torch_threads` sets the count around a fit and restores the previous one afterwards, even
when the fit fails. What it does not touch:

- **numba**: the compiled sweep's kernels (:mod:`spcopyro.gibbs.numba_sweep`) are
  single-threaded ``@njit`` functions (no ``parallel=True``, no ``prange``), so
  ``NUMBA_NUM_THREADS`` plays no part; the torch operations around them (the conjugate draws,
  the log joint) follow the torch setting, and the background table's products run on one
  thread whatever it is (:func:`one_blas_thread`), so that their bits do not depend on it.
- **numpy's BLAS (OpenBLAS)**: the sweep makes no numpy BLAS call -- the one matrix product of the
  compiled backend runs in torch for that reason -- so numpy's thread pool stays idle during a
  fit; it is sized by ``OPENBLAS_NUM_THREADS`` when numpy is imported and left alone here.
- **torch's inter-op pool** (``torch.set_num_interop_threads``): only TorchScript's ``fork``
  uses it; nothing here does.

The thread count changes no label: torch's random draws on the CPU are serial, whatever the
setting, and ``tests/test_threads.py`` checks that a seeded fit gives the same labels with one
thread and with two. Only the last bits of a float reduction (a sum split across threads) may
differ, which is why the pinned outputs hash float tables at 12 significant digits; on room1dk5
and the synthetic house (200 sweeps, both backends) the floats were bit-identical too, and on a
simulated map of 92,328 free cells every output of ``spcopyro fit`` but the timings (Gibbs with
its refinement and ``vi`` point estimate, memoized VI, CAVI, loopy BP; ``docs/speed.md``), and
``vi-gibbs`` on a small house. ``svi`` is the exception: MKL splits the inner dimension of the
float64 image product ``counts @ log_phi.T`` (205 classes, a transposed operand) across threads
from 86 observed cells on, whatever the map's size, and SVI differentiates through it, so its
pi, tables and ELBO differ in their last bits between one thread and two (labels the same in
every run measured; ``docs/speed.md``, "Threads").
"""

from __future__ import annotations

import ctypes
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from numbers import Integral

from spcopyro._util.messages import plural

AUTO = "auto"
"""``threads`` value that applies :func:`policy_threads`."""

MIN_CELLS_FOR_MORE_THREADS = 50_000
"""Free cells from which a map keeps torch's own thread count (``threads="auto"``); below it, one
thread. Measured with ``python benchmarks/threads.py`` (``docs/speed.md``)."""


LOAD_WINDOW_S = 0.25
"""Seconds over which :func:`other_load` watches the machine."""

LOAD_REUSE_S = 30.0
"""A reading of :func:`other_load` younger than this is reused: the line a fit prints and the
count it runs with come from one reading, and a fit's stages do not wait for it again."""

_last_load: tuple[float, float | None] | None = None  # (time.monotonic() read, the load)


def _cpu_ticks() -> tuple[int, int] | None:
    """(busy, total) CPU ticks of the whole machine since boot (Linux ``/proc/stat``), else
    None."""
    try:
        with open("/proc/stat") as stat:
            ticks = [int(v) for v in stat.readline().split()[1:]]  # user nice system idle iowait
    except (OSError, ValueError):
        return None
    if len(ticks) < 4:
        return None
    idle = ticks[3] + (ticks[4] if len(ticks) > 4 else 0)
    return sum(ticks) - idle, sum(ticks)


def _own_cpu_seconds() -> float:
    times = os.times()
    return times.user + times.system


def _measure_other_load() -> float | None:
    before, own_before = _cpu_ticks(), _own_cpu_seconds()
    if before is None:
        return None
    time.sleep(LOAD_WINDOW_S)
    after, own_after = _cpu_ticks(), _own_cpu_seconds()
    if after is None or after[1] <= before[1]:
        return None
    cpus = os.cpu_count() or 1  # /proc/stat's first line sums every CPU of the machine
    busy = (after[0] - before[0]) / (after[1] - before[1]) * cpus  # cores in use
    own = (own_after - own_before) / LOAD_WINDOW_S  # this process's threads (figures, ...)
    return max(0.0, busy - own)


def other_load() -> float | None:
    """Cores the *other* processes keep busy now: the machine's CPU use over
    :data:`LOAD_WINDOW_S` seconds (``/proc/stat``) less this process's own; None where the
    machine does not say (not Linux). A reading is reused for :data:`LOAD_REUSE_S` seconds."""
    global _last_load
    now = time.monotonic()
    if _last_load is None or now - _last_load[0] > LOAD_REUSE_S:
        _last_load = (now, _measure_other_load())
    return _last_load[1]


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def policy_threads(
    num_cells: int, load: float | None = None, cpus: int | None = None, default: int = 0
) -> int | None:
    """The policy's intra-op thread count for a map of ``num_cells`` free cells: 1 below
    :data:`MIN_CELLS_FOR_MORE_THREADS`; from there torch's own setting (None), unless the other
    processes' ``load`` (busy cores, :func:`other_load`; None: unknown) leaves fewer of the
    ``cpus`` usable cores free than torch's ``default`` thread count: then as many threads as
    cores are free, rounded, at least 1 (on 2 cores: one thread beside a load of 0.5 or more).
    ``cpus``/``default`` 0 or None: :func:`usable_cpus` / ``torch.get_num_threads()``."""
    if num_cells < MIN_CELLS_FOR_MORE_THREADS:
        return 1
    if load is None:
        return None
    if not default:
        import torch

        default = torch.get_num_threads()
    free = int((cpus or usable_cpus()) - load + 0.5)
    return None if free >= default else max(1, free)


def resolve_threads(threads: int | str | None, num_cells: int) -> int | None:
    """The intra-op thread count to run a map of ``num_cells`` free cells with.

    Args:
        threads: ``"auto"`` (:func:`policy_threads` under the :func:`other_load` read now, or
            less than :data:`LOAD_REUSE_S` seconds ago), ``None`` or 0 (leave torch's setting
            as it is), or a positive integer (that many threads).

    Returns:
        A positive count, or None for "leave torch's setting".
    """
    if threads == AUTO:
        if num_cells < MIN_CELLS_FOR_MORE_THREADS:
            return 1
        return policy_threads(num_cells, other_load())
    if threads is None:
        return None
    if isinstance(threads, Integral) and not isinstance(threads, bool) and threads >= 0:
        return int(threads) or None
    raise ValueError(
        f"threads must be 'auto', 0 or None (torch's own setting) or a positive integer, "
        f"got {threads!r}"
    )


def chain_threads(threads: int | str | None, num_cells: int, workers: int = 1) -> int | None:
    """:func:`resolve_threads` for each of ``workers`` Gibbs chains advancing at once: with
    more than one, ``"auto"`` runs each on one intra-op thread (the chains are the
    parallelism); a count asked, or torch's own setting, is kept."""
    if threads == AUTO and workers > 1:
        return 1
    return resolve_threads(threads, num_cells)


def describe_threads(threads: int | str | None, num_cells: int, workers: int = 1) -> str:
    """One line on the thread count a fit of ``num_cells`` free cells will use, and why;
    ``workers``: the chains that advance at once (:func:`chain_threads`)."""
    import torch  # here, not at the top: the commands that only parse need no torch

    if threads == AUTO and workers > 1:
        return (f"1 torch intra-op thread per chain, {workers} chains side by side (policy: "
                "one each when chains run at once)")  # fmt: skip
    count = resolve_threads(threads, num_cells)
    current = torch.get_num_threads()
    if threads == AUTO:
        if num_cells < MIN_CELLS_FOR_MORE_THREADS:
            why = f"policy: {num_cells} free cells < {MIN_CELLS_FOR_MORE_THREADS}"
        else:
            why = f"policy: {num_cells} free cells >= {MIN_CELLS_FOR_MORE_THREADS}"
            load = other_load()  # the reading resolve_threads used
            if load is not None:
                why += f", other processes busy on {load:.1f} of {usable_cpus()} cores"
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


_mkl_local_setter: Callable[[int], int] | None | bool = False  # False: not looked up yet


def _mkl_set_num_threads_local() -> Callable[[int], int] | None:
    """MKL's ``MKL_Set_Num_Threads_Local`` (its C interface: sets the calling thread's count, 0
    for the global one, and returns the previous) from the MKL that torch links, else None
    (torch without MKL, or a build that does not export it)."""
    global _mkl_local_setter
    if _mkl_local_setter is False:
        import torch

        _mkl_local_setter = None
        folder = os.path.join(os.path.dirname(torch.__file__), "lib")
        names = ("libtorch_cpu.so", "libtorch_cpu.dylib", "torch_cpu.dll")
        for path in (os.path.join(folder, name) for name in names):
            if not torch.backends.mkl.is_available() or not os.path.exists(path):
                continue
            try:
                setter = ctypes.CDLL(path).MKL_Set_Num_Threads_Local
            except (OSError, AttributeError):
                continue
            setter.restype, setter.argtypes = ctypes.c_int, [ctypes.c_int]
            _mkl_local_setter = setter
            break
    return _mkl_local_setter or None


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block's torch matrix products on one BLAS thread, then restore the setting --
    also when the block raises. With MKL (torch's BLAS on x86) only the calling thread's MKL
    count changes, so chains sweeping on other threads (:mod:`spcopyro.gibbs.chains`), and
    threads that start meanwhile, keep theirs; without it, :func:`torch_threads` (1): the
    process's torch count for the block, which a thread starting during it would take up."""
    setter = _mkl_set_num_threads_local()
    if setter is None:
        with torch_threads(1):
            yield
        return
    # torch sets a thread's MKL count lazily, at its first parallel op, to torch's count: were
    # that op inside the block (a fresh chain thread's first sweep), it would overwrite the 1
    # and leave MKL's global default (0) behind. get_num_threads runs that setup first.
    import torch

    torch.get_num_threads()
    previous = setter(1)
    try:
        yield
    finally:
        setter(previous)
