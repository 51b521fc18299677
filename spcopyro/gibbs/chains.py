"""Many Gibbs chains at once: :func:`advance_chains`.

``--chains K`` used to run its chains one after another. Here they share what a process sets up
once (the imports, the house, the model data, the sweep plan, the compiled kernels) and advance
side by side, up to ``workers`` at a time: in processes forked from this one where that is safe
(:mod:`spcopyro.gibbs.chain_processes`: no GIL shared; :func:`uses_processes`), else on threads
(the compiled sweep releases the GIL -- its kernels are ``nogil``, torch's operations release it
too -- but each sweep's Python part holds it), so on a 2-core machine two chains run at once.

Each chain keeps its own generator and advances exactly as :func:`~spcopyro.gibbs.run.advance`
would advance it alone, so chain k of a parallel run is the chain of seed k run by itself, bit for
bit (tested). There is no barrier between chains: a chain whose thread the scheduler sets aside
delays itself only, which keeps a busy machine from costing more than its share (a lock-step
batched sweep would wait for the slowest chain at every sweep; and on the CPU it saves nothing,
the per-cell work being the same scalar loop).

Ctrl-C stops every chain at its last *completed* sweep (the one in progress finishes), then the
:class:`KeyboardInterrupt` is raised again, as :func:`~spcopyro.gibbs.run.advance` does for one
chain: a checkpoint saved then resumes to the uninterrupted result.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait
from contextlib import contextmanager
from typing import Any

from spcopyro._util.progress import noted_bar, progress_enabled, staged
from spcopyro._util.threads import usable_cpus
from spcopyro.gibbs.run import ChainsStopped, GibbsChain, advance, compile_note

AUTO = "auto"


def resolve_workers(workers: int | str | None, num_chains: int) -> int:
    """Threads for ``num_chains`` chains: ``"auto"`` / None -> one per usable CPU, at most one per
    chain; a count -> that many (at most one per chain).

    Raises:
        ValueError: a count below 1, or neither a count nor ``"auto"``.
    """
    if workers is None or workers == AUTO:
        count = usable_cpus()
    elif isinstance(workers, int) and not isinstance(workers, bool) and workers >= 1:
        count = workers
    else:
        raise ValueError(f"chain workers must be a positive integer or 'auto', got {workers!r}")
    return max(1, min(count, num_chains))


PROCESSES_ENV = "SPCOPYRO_CHAIN_PROCESSES"
"""Environment variable: ``auto`` (default), ``on`` or ``off``, the default of
:func:`advance_chains`' ``processes``."""

_PROCESS_MODES = (AUTO, "on", "off")


def chain_processes(mode: str | None = None) -> str:
    """The mode of running chains in processes: ``mode``, else ``$SPCOPYRO_CHAIN_PROCESSES``,
    else ``"auto"``.

    Raises:
        ValueError: a mode other than auto / on / off.
    """
    source = "processes" if mode is not None else f"${PROCESSES_ENV}"
    value = mode if mode is not None else os.environ.get(PROCESSES_ENV, AUTO)
    if value not in _PROCESS_MODES:
        raise ValueError(f"{source} must be one of {', '.join(_PROCESS_MODES)}, got {value!r}")
    return value


def uses_processes(workers: int, mode: str | None = None) -> bool:
    """Whether :func:`advance_chains` with ``workers`` (resolved) runs its chains in forked
    processes (:mod:`spcopyro.gibbs.chain_processes`): with more than one worker, under mode
    ``"auto"`` where forking is safe, under ``"on"`` always (ValueError where it is not safe).
    """
    mode = chain_processes(mode)
    if workers < 2 or mode == "off":
        return False
    from spcopyro.gibbs.chain_processes import processes_usable

    reason = processes_usable()
    if reason is not None and mode == "on":
        raise ValueError(f"chains cannot run in processes here: {reason}")
    return reason is None


_when_started: list[Callable[[], None]] = []


@contextmanager
def when_chains_start(action: Callable[[], None]) -> Iterator[None]:
    """Within the block, call ``action`` once, when the first :func:`advance_chains` has its
    chains running: after their worker processes were forked, or as it starts them on threads.

    For work that a thread should do while the chains run (``spcopyro fit``'s figure
    prefetch): a thread running at the fork would keep the chains on threads
    (:func:`uses_processes`). Not called if no chains run in the block.
    """
    _when_started.append(action)
    try:
        yield
    finally:
        if action in _when_started:
            _when_started.remove(action)


def _chains_started() -> None:
    while _when_started:
        _when_started.pop(0)()


def advance_chains(
    runs: Sequence[tuple[GibbsChain, int]],
    *,
    workers: int | str | None = AUTO,
    thin: int = 0,
    progress: bool | None = None,
    on_sweep: Callable[[], None] | None = None,
    processes: str | None = None,
) -> None:
    """Advance each ``(chain, num_sweeps)`` of ``runs`` by its number of sweeps, up to
    ``workers`` chains at a time (:func:`resolve_workers`), in place.

    One progress bar counts the sweeps of all chains; ``on_sweep`` is called after every sweep
    of any chain (under a lock; in processes, by this thread when it reads the counts). With one
    worker the chains run one after another in this thread (what
    :func:`~spcopyro.gibbs.run.advance` in a loop did); with more, on threads or, where
    :func:`uses_processes` says so (``processes``: auto / on / off, default
    ``$SPCOPYRO_CHAIN_PROCESSES`` or auto), in forked processes. The chains are the same either
    way.
    """
    runs = [(chain, int(n)) for chain, n in runs if int(n) > 0]
    if not runs:
        return
    count = resolve_workers(workers, len(runs))
    total = sum(n for _, n in runs)
    note = compile_note([chain for chain, _ in runs]) if progress_enabled(progress) else None

    label = staged("Gibbs sweeps")  # a refined fit's stage, read in this thread

    def bar_of() -> Callable[[int], None]:  # the compile note stays over the first sweeps
        bar, update = noted_bar(total, label, note, "sweep", not progress_enabled(progress))
        bars.append(bar)
        return update

    bars: list[Any] = []  # tqdm bars
    updates: list[Callable[[int], None]] = []

    if uses_processes(count, processes):
        from spcopyro.gibbs.chain_processes import advance_in_processes

        def started() -> None:  # the workers are forked: threads may start now
            updates.append(bar_of())
            _chains_started()

        def on_sweeps(done: int) -> None:
            for update in updates:
                update(done)
            for _ in range(done if on_sweep is not None else 0):
                on_sweep()

        try:
            advance_in_processes(runs, count, thin=thin, on_sweeps=on_sweeps, on_started=started,
                                 advance_chain=advance)  # fmt: skip
        finally:
            for bar in bars:
                bar.close()
        return
    _chains_started()
    stop = threading.Event()
    update = bar_of()
    (bar,) = bars
    lock = threading.Lock()

    def after_sweep(*_: object) -> None:
        with lock:
            update(1)
            if on_sweep is not None:
                on_sweep()
        if stop.is_set():
            raise ChainsStopped

    def run_one(chain: GibbsChain, num_sweeps: int) -> None:
        try:
            advance(chain, num_sweeps, thin=thin, progress=False, callback=after_sweep)
        except KeyboardInterrupt:  # ChainsStopped, as the driver raises it again
            if not stop.is_set():
                raise

    try:
        if count == 1:
            for chain, num_sweeps in runs:
                advance(chain, num_sweeps, thin=thin, progress=False, callback=after_sweep)
            return
        with ThreadPoolExecutor(max_workers=count, thread_name_prefix="gibbs-chain") as pool:
            futures = [pool.submit(run_one, chain, n) for chain, n in runs]
            try:
                # the first chain to fail stops the others now, not when those before it end
                finished, _ = wait(futures, return_when=FIRST_EXCEPTION)
                for future in [*finished, *futures]:
                    future.result()
            except BaseException:  # Ctrl-C here, or a chain's error
                stop.set()  # every running chain stops after its sweep; queued ones never start
                for future in futures:
                    future.cancel()
                pool.shutdown(wait=True)
                raise
    finally:
        bar.close()
