"""Many Gibbs chains at once in forked processes: :func:`advance_in_processes`.

Threads (:mod:`spcopyro.gibbs.chains`) share one interpreter: the compiled kernels and torch's
operations release the GIL, but each sweep's Python part (the calls, numpy's small steps, the
records) holds it, and on a 2-core machine four chains on two threads took 0.60-0.85 of their
time one after another where two processes took 0.53-0.68 (``benchmarks/gibbs.py``, the chains
rows; docs/speed.md). Here each worker is a child process *forked* from this one after the chains
were started, so it has the house, the model data, the chains and the compiled kernels without
importing or compiling anything, and runs its chains one after another (chain i on worker
i mod W). When a chain ends (or stops), its worker sends back what the chain changed -- its
state, generator, records, best visited state, kept label maps -- and this process writes it
into the chain object the caller holds, so afterwards the chains are exactly those that
:func:`~spcopyro.gibbs.run.advance` gives in this process (tested bit for bit).

Progress: each worker counts its chains' sweeps in shared memory; this process reads the counts
a few times a second for the progress bar. Ctrl-C: the workers ignore SIGINT and SIGTERM (and
end if this process is killed); this process, on SIGINT (or SIGTERM, where a handler turns it
into an interrupt, as ``spcopyro fit``'s does), raises a shared stop flag, and every chain stops
after the sweep it is in (the one in progress finishes and is kept), as the threads do. The
chains' records come back, each read and written whole, and then :class:`KeyboardInterrupt` is
raised; a second Ctrl-C while waiting for them ends the workers at once and leaves the chains
that had not come back where they started (a consistent state, if an earlier one). A chain's
error (e.g. a non-finite log joint) stops the others the same way and is raised here, with the
worker's traceback in its notes.

Warnings: a chain's Python warnings and the ``spcopyro`` logger's records in a worker are not
shown there but sent to this process (:func:`_relay_warnings`), which gives them again in the
thread that waits for the chains (:func:`_warn_again`): a warning goes through this process's
filters and the registry of the module that warned, so one that two workers met under the
"default" action is shown once, as on threads, and both land where this thread's warnings go
(``spcopyro fit``'s ``config.json``, a study cell's record).

Only where forking is safe (:func:`processes_usable`): Linux, torch at one intra-op thread (an
OpenMP team is not usable after a fork), and no other Python thread running (a thread could hold
a lock that the child would inherit held).
"""

from __future__ import annotations

import copy
import logging
import multiprocessing
import os
import pickle
import signal
import sys
import threading
import traceback
import warnings
from collections.abc import Callable, Sequence
from dataclasses import fields
from multiprocessing.connection import Connection, wait

from spcopyro._util.forking import fork_refusal, fresh_tqdm_lock, start_forked
from spcopyro._util.interrupts import signals_deferred
from spcopyro.gibbs.run import ChainsStopped, GibbsChain, advance

LOGGER = "spcopyro"
"""The logger whose records a worker sends to this process (its children's included)."""
POLL_SECONDS = 0.1
"""How often the progress counts are read while the workers run."""

_FIXED_FIELDS = ("data", "config", "options", "backend", "plan")
"""The fields of a :class:`~spcopyro.gibbs.run.GibbsChain` that a sweep never changes: not sent
back. Every other field is (the generator as its state)."""


class ChainProcessError(RuntimeError):
    """A chain's worker process ended without sending its chain back (killed, or out of
    memory)."""


def processes_usable() -> str | None:
    """None if chains may run in forked processes here, else the reason they may not
    (:func:`spcopyro._util.forking.fork_refusal`: Linux, one torch thread, no other thread)."""
    return fork_refusal(uses_torch=True)


def chain_changes(chain: GibbsChain) -> dict[str, object]:
    """What a sweep changes in ``chain``: every field but :data:`_FIXED_FIELDS`, the generator
    as its state."""
    changes = {f.name: getattr(chain, f.name) for f in fields(chain) if f.name not in _FIXED_FIELDS}
    changes["generator"] = chain.generator.get_state()
    return changes


def apply_changes(chain: GibbsChain, changes: dict[str, object]) -> None:
    """Write :func:`chain_changes` of a chain (advanced elsewhere) into ``chain``."""
    for name, value in changes.items():
        if name == "generator":
            chain.generator.set_state(value)
        else:
            setattr(chain, name, value)


def _send(connection: Connection, message: tuple[str, int, object]) -> None:
    # plain pickle, not multiprocessing's: torch registers reductions there that move tensors
    # into shared memory; the records are sent once, by value
    connection.send_bytes(pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL))


def _portable_error(error: BaseException) -> BaseException:
    """``error`` with the worker's traceback as a note, or a RuntimeError with its text where the
    error does not survive pickling."""
    text = "".join(traceback.format_exception(error))
    try:
        error.add_note(f"in the chain's worker process:\n{text}")
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:  # noqa: BLE001  (any error of pickling)
        return RuntimeError(f"a chain failed in its worker process:\n{text}")


def _portable_warning(message: Warning | str, category: type[Warning]) -> tuple[object, type]:
    """``(message, category)`` as they survive pickling: the message's text where the warning
    object does not, :class:`UserWarning` where its class does not."""
    try:
        pickle.loads(pickle.dumps((message, category)))
        return message, category
    except Exception:  # noqa: BLE001  (any error of pickling)
        try:
            pickle.loads(pickle.dumps(category))
        except Exception:  # noqa: BLE001
            return f"{category.__name__}: {message}", UserWarning
        return str(message), category


class _LogRelay(logging.Handler):
    """In a worker: the ``spcopyro`` logger's only handler, sending each record to the parent."""

    def __init__(self, connection: Connection) -> None:
        super().__init__(logging.NOTSET)
        self.connection = connection

    def emit(self, record: logging.LogRecord) -> None:  # noqa: D102
        try:
            record = copy.copy(record)  # its message formatted here: arguments may not pickle
            record.msg, record.args = record.getMessage(), None
            if record.exc_info:
                record.exc_text = record.exc_text or logging.Formatter().formatException(
                    record.exc_info
                )
                record.exc_info = None
            _send(self.connection, ("log", -1, record))
        except Exception:  # noqa: BLE001  (logging's rule: report, never raise)
            self.handleError(record)


def _relay_warnings(connection: Connection) -> None:
    """In a worker: its Python warnings that pass the filters, and the ``spcopyro`` logger's
    records, go to the parent instead of this process's stderr (module docstring)."""

    def show(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
        _send(connection, ("warning", -1, (*_portable_warning(message, category), filename,
                                           lineno)))  # fmt: skip

    warnings.showwarning = show
    logger = logging.getLogger(LOGGER)
    logger.handlers = [_LogRelay(connection)]
    logger.propagate = False


def _module_named_by(filename: str) -> dict[str, object] | None:
    """The globals of the imported module whose file is ``filename``, if any."""
    for module in list(sys.modules.values()):
        if getattr(module, "__file__", None) == filename:
            return vars(module)
    return None


def _warn_again(kind: str, body: object, registries: dict[str, dict]) -> None:
    """Give here, in this thread, a warning (``kind`` "warning") or log record ("log") a worker
    sent: a warning as :func:`warnings.warn` gave it in the module that warned (its filters,
    its registry: once under "default"); ``registries``: for a file no module was loaded from."""
    if kind == "log":
        record: logging.LogRecord = body  # type: ignore[assignment]
        record.thread, record.threadName = threading.get_ident(), threading.current_thread().name
        logging.getLogger(record.name).handle(record)
        return
    message, category, filename, lineno = body  # type: ignore[misc]
    module = _module_named_by(filename)
    if module is None:
        registry, name = registries.setdefault(filename, {}), None
    else:
        registry, name = module.setdefault("__warningregistry__", {}), module.get("__name__")
    warnings.warn_explicit(message, category, filename, lineno, module=name,  # type: ignore[arg-type]
                           registry=registry, module_globals=module)  # fmt: skip


def _worker(runs, indices, thin, advance_chain, connection, sweeps_done, stop) -> None:  # noqa: ANN001
    """A worker's life: its chains one after another, each sent back when it ends or stops."""
    # the parent decides when the chains stop (its Ctrl-C, or `spcopyro fit`'s SIGTERM)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    parent = os.getppid()
    fresh_tqdm_lock()
    _relay_warnings(connection)

    def after_sweep(index: int) -> Callable[..., None]:
        def callback(*_: object) -> None:
            sweeps_done[index] += 1
            if stop.value:
                raise ChainsStopped
            if os.getppid() != parent:  # the parent was killed: nobody waits for the chains
                os._exit(1)

        return callback

    try:
        for index in indices:
            if stop.value:
                break
            chain, num_sweeps = runs[index]
            try:
                advance_chain(chain, num_sweeps, thin=thin, progress=False,
                              callback=after_sweep(index))  # fmt: skip
            except KeyboardInterrupt:  # the chain holds its completed sweeps
                _send(connection, ("chain", index, chain_changes(chain)))
                if stop.value:  # ChainsStopped
                    continue
                # raised by the chain itself (never SIGINT, ignored here): as on a thread
                _send(connection, ("error", index, KeyboardInterrupt()))
                break
            except BaseException as error:  # noqa: BLE001  (sent to the parent, raised there)
                _send(connection, ("error", index, _portable_error(error)))
                break
            _send(connection, ("chain", index, chain_changes(chain)))
        _send(connection, ("end", -1, None))
    finally:
        connection.close()


def advance_in_processes(
    runs: Sequence[tuple[GibbsChain, int]],
    workers: int,
    *,
    thin: int = 0,
    on_sweeps: Callable[[int], None] | None = None,
    on_started: Callable[[], None] | None = None,
    advance_chain: Callable[..., object] = advance,
) -> None:
    """Advance each ``(chain, num_sweeps)`` of ``runs`` in ``workers`` forked processes, in
    place (see the module docstring). ``on_sweeps(n)``: called in this process with the number
    of sweeps completed since its last call, a few times a second; ``on_started()``: called
    once every worker is forked (threads may start from then on); ``advance_chain``: what
    advances a chain in a worker (:func:`~spcopyro.gibbs.run.advance`, or a caller's wrapper).

    Raises:
        KeyboardInterrupt: Ctrl-C; every chain holds its completed sweeps.
        ChainProcessError: a worker ended without sending its chains back.
        Whatever a chain raised, after the others stopped.
    """
    context = multiprocessing.get_context("fork")
    sweeps_done = context.RawArray("q", len(runs))  # [chains] written by the chain's worker
    stop = context.RawValue("b", 0)
    receivers: dict[Connection, tuple[multiprocessing.process.BaseProcess, list[int]]] = {}
    returned: set[int] = set()
    errors: list[BaseException] = []
    registries: dict[str, dict] = {}  # of the warnings from files that are no module's
    reported = 0

    def report() -> None:
        nonlocal reported
        total = sum(sweeps_done)
        if total > reported and on_sweeps is not None:
            on_sweeps(total - reported)
        reported = total

    def lost(receive: Connection) -> None:  # the worker ended without its "end"
        process, indices = receivers.pop(receive)
        process.join()
        missing = [i for i in indices if i not in returned]
        errors.append(ChainProcessError(
            f"the worker process of chains {missing} ended (exit code {process.exitcode}) "
            "without sending them back"
        ))  # fmt: skip
        stop.value = 1

    def handle(receive: Connection) -> None:
        try:
            kind, index, body = pickle.loads(receive.recv_bytes())
        except EOFError:
            lost(receive)
            return
        if kind == "chain":
            apply_changes(runs[index][0], body)
            returned.add(index)
        elif kind == "error":
            errors.append(body)
            stop.value = 1
        elif kind in ("warning", "log"):
            try:
                _warn_again(kind, body, registries)
            except Exception as error:  # noqa: BLE001  (e.g. a filter made it an error here)
                errors.append(error)
                stop.value = 1
        else:  # "end"
            process, _ = receivers.pop(receive)
            process.join()

    signals = 0  # Ctrl-C (or SIGTERM) received while the workers run

    def on_signal(signum: int, frame: object) -> None:
        nonlocal signals
        signals += 1
        stop.value = 1  # every chain ends its sweep and comes back

    def collect() -> None:
        while receivers:
            for receive in wait(list(receivers), timeout=POLL_SECONDS):
                handle(receive)  # read and applied whole: no signal raises in here
                if signals > 1:
                    break
            report()
            if signals > 1:  # a second Ctrl-C: stop waiting for the chains
                raise KeyboardInterrupt

    with signals_deferred(on_signal):
        try:
            for w in range(workers):
                indices = list(range(w, len(runs), workers))
                receive, send = context.Pipe(duplex=False)
                process = context.Process(
                    target=_worker,
                    args=(runs, indices, thin, advance_chain, send, sweeps_done, stop),
                    name=f"spcopyro-chains-{w}", daemon=True,
                )  # fmt: skip
                start_forked(process)
                send.close()
                receivers[receive] = (process, indices)
            if on_started is not None:
                on_started()
            collect()
        finally:
            for process, _ in receivers.values():  # a second Ctrl-C, or an error here
                process.kill()
                process.join()
            report()
    if signals:
        raise KeyboardInterrupt
    if errors:
        raise errors[0]
