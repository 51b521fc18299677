"""The figures of ``spcopyro fit``: its PNGs, and what of them can be done while the chains run.

A default fit's sweeps run in compiled kernels that release the GIL, one chain on one core.
:class:`FigurePrefetch` uses that time: on a thread of its own it imports what the figures and
the point estimate import (matplotlib, scipy's image and assignment modules: about a second of a
fresh process) and draws ``house.png``, which needs the house only (again, of the map's own
cells, while a refinement's chains run: :meth:`FigurePrefetch.redraw`). After the fit,
:func:`figures_drawn` draws the figures that need the result, in a child forked for them where
forking is safe, while the fit saves its result, then shares what is left with the child (two
CPUs draw them in about half the time). While the thread works the interpreter's switch
interval is shortened, so a sweep that ends waits at most that long for the GIL. The figures
are those drawn without either, file for file (issue 25 item 1).
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from spcopyro._util.collector import import_frozen
from spcopyro._util.timings import timed

if TYPE_CHECKING:
    from multiprocessing.process import BaseProcess

    from spcopyro.data import House
    from spcopyro.results.result import SpCoResult

__all__ = ["FigurePrefetch", "figures_drawn"]

PREFETCH_SWITCH_INTERVAL = 0.0005
"""Seconds: :func:`sys.setswitchinterval` while :class:`FigurePrefetch` works (Python's default
is 0.005, a sweep's length on a public house)."""
ABANDON_TIMEOUT = 10.0
"""Seconds a stopped fit waits for :class:`FigurePrefetch`'s thread (its ``abandon``)."""


class FigurePrefetch:
    """Import the figures' modules, choose the semantic map's palette for up to ``concepts``
    concepts (:func:`~spcopyro.maps.palette.concept_palette`, kept for the figures: 0.02 s of
    the map's drawing on room2ldk4) and draw ``house.png`` into ``out`` on a daemon thread, started
    at once, or by :meth:`start` when ``start`` is False (a fit whose chains run in forked
    processes starts it once they are forked: :func:`spcopyro.gibbs.chains.when_chains_start`).
    :meth:`join` waits for it; an error there is not raised but left to the figures drawn after
    the fit (which draw ``house.png`` again, as they do if it never started). A fit that stops
    (Ctrl-C, SIGTERM, an error) calls :meth:`abandon` instead."""

    def __init__(self, house: House, out: Path, start: bool = True, concepts: int = 0) -> None:
        self.house_drawn = False
        self._concepts = concepts
        self._abandoned = threading.Event()
        self._lock = threading.Lock()  # guards _newer and _running
        self._newer: House | None = None  # a house asked for by redraw, not yet taken
        self._running = False  # a thread is working or about to (it takes _newer before it ends)
        self._previous = sys.getswitchinterval()
        self._out = Path(out)
        self._thread = self._new_thread(house)
        self._started = False
        if start:
            self.start()

    def _new_thread(self, house: House | None) -> threading.Thread:
        return threading.Thread(
            target=self._run, args=(house, self._out), name="spcopyro-figures", daemon=True
        )

    def redraw(self, house: House) -> None:
        """Draw ``house.png`` again, of ``house``: the fit went on on another grid (``--refine``:
        the map's own cells), whose chains run meanwhile. Without waiting: a thread still at
        work takes ``house`` next, in place of a house it has not begun to draw (a short fit's
        first stage ends before the figures' imports do: the model grid's house, which this
        drawing replaces, is then never drawn; before, the fit waited here for it, 0.3-0.8 s);
        else a new thread draws it. :meth:`join` then tells of this drawing."""
        with self._lock:
            self._newer = house
            self.house_drawn = False
            if self._running:  # the thread at work takes it
                return
            if self._started:  # its thread has ended: another
                self._thread = self._new_thread(None)
            else:  # never started: its thread draws this house in place of the first
                self._started = True
                self._previous = sys.getswitchinterval()
            self._launch()

    def start(self) -> None:
        """Start the thread (once; later calls do nothing)."""
        with self._lock:
            if self._started:
                return
            self._started = True
            self._previous = sys.getswitchinterval()
            self._launch()

    def _launch(self) -> None:
        """Start ``_thread`` with the short switch interval (the lock held)."""
        self._running = True
        sys.setswitchinterval(min(self._previous, PREFETCH_SWITCH_INTERVAL))
        self._thread.start()

    def _take(self, house: House | None) -> House | None:
        """The house to draw next: one :meth:`redraw` asked for since, else ``house``; None
        (nothing left to draw, or abandoned) ends the thread's work, the switch interval
        restored, before a redraw may start another (the lock held throughout)."""
        with self._lock:
            if self._newer is not None:
                house, self._newer = self._newer, None
            if house is None or self._abandoned.is_set():
                self._end()
                return None
            self.house_drawn = False
            return house

    def _end(self) -> None:
        """The thread's work ended (the lock held): a later :meth:`redraw` starts another."""
        self._running = False
        sys.setswitchinterval(self._previous)

    def _run(self, house: House | None, out: Path) -> None:
        try:
            with timed("prefetch imports"):  # frozen after, as the fit's (_util.collector)
                import_frozen("scipy.optimize")  # the point estimate's matching
                plot_house = import_frozen("spcopyro.figures.plotting").plot_house
            if self._concepts:
                with timed("prefetch palette"):
                    import_frozen("spcopyro.maps.palette").concept_palette(self._concepts)
            # _take: None once abandoned (the fit stopped: nothing more into its folder)
            while (house := self._take(house)) is not None:
                with timed("prefetch house"):
                    plot_house(house, out / "house.png")
                self.house_drawn, house = True, None  # a redraw meanwhile: False, taken next
        except Exception:  # drawn again, with its error, after the fit
            with self._lock:
                self._newer, self.house_drawn = None, False
                self._end()

    def working(self) -> bool:
        """Whether its thread is at work now (started, not ended, not abandoned)."""
        return self._started and self._thread.is_alive() and not self._abandoned.is_set()

    def join(self) -> bool:
        """Wait for the thread (not once abandoned); whether ``house.png`` was drawn."""
        if self._started and self._thread.is_alive() and not self._abandoned.is_set():
            with timed("prefetch wait"):
                self._thread.join()
        return self.house_drawn

    def abandon(self, timeout: float | None = None) -> bool:
        """The fit stopped: tell the thread to draw nothing more and wait at most ``timeout``
        seconds (None: :data:`ABANDON_TIMEOUT`) for it; whether it ended.

        Not an unbounded :meth:`join`: an interrupt raised in the main thread while it took an
        import's module lock (Python's import machinery is Python code, where a signal handler
        can raise between the lock's acquisition and the ``with`` that would release it) leaves
        that lock held for good, and this thread, importing the same module, would wait for it
        forever, and the fit with it. The thread is a daemon: one still running does not keep
        the process from exiting."""
        self._abandoned.set()
        if self._started and self._thread.is_alive():
            self._thread.join(ABANDON_TIMEOUT if timeout is None else timeout)
        return not self._thread.is_alive()


@contextlib.contextmanager
def figures_drawn(
    result: SpCoResult,
    house: House,
    out: Path,
    uncertainty: bool,
    prefetch: FigurePrefetch | None = None,
    fork: bool | None = None,
    kept: tuple[int, int] | None = None,
    said: list[str] | None = None,
) -> Iterator[None]:
    """The fit's PNGs, drawn while the block writes the fit's other outputs: semantic map,
    trace, house (unless ``prefetch`` drew it), and the uncertainty and agreement maps of a
    result that has them (:mod:`spcopyro.figures.plotting`, matplotlib's Agg canvas).

    ``fork`` (None: where :func:`~spcopyro._util.forking.fork_refusal` allows it, without torch):
    a child forked at the block's start draws them, the semantic map first (the largest:
    0.3-0.6 s against 0.1-0.3 s each), while this process runs the block (``spcopyro fit``
    saves its result there, 0.1 s of room2ldk4's fit); then both take what is left, one figure
    at a time (:class:`_Claims`), so the two CPUs share the work however the figures' sizes
    fall; the same files, byte for byte. Where ``prefetch``'s thread is still at work (a short
    fit), the block runs first, while it finishes, and the child is forked after it (else the
    block would wait for the thread: a fit of one sweep on room2ldk4 took 0.07 s longer). The
    figures a failed child took are drawn here again (their error, if any, raised). An
    interrupt or error here, in the block or after it, ends the child before it is raised
    (:meth:`_Child.stop`): ``spcopyro fit`` then discards the folder it draws into. Without a
    fork, the figures are drawn here after the block. ``kept`` = (k, K): ``result`` is chain k
    of K, the one kept (``trace.png`` says so: it draws that chain's trace only).

    ``said``: the list that a :func:`~spcopyro.cli.fit_warnings.recorded_warnings` block in
    effect fills (the fit's, for ``config.json``). What the block says comes first; the
    warnings of the figures drawn here go into it as they are given; those of the child's
    (printed there) come back when it ends, and the figures' warnings are then put in the
    figures' order (semantic map, trace, house, uncertainty, agreement), as drawn in one
    process, whichever process drew which."""
    # a prefetch thread still at work (a short fit: its imports, house.png): the block runs while
    # it finishes; else the child is forked first (no other thread may run at a fork)
    late = prefetch is not None and prefetch.working()
    if late:
        yield
    house_drawn = prefetch is not None and prefetch.join()
    figures = _figures(result, house, out, uncertainty, kept, house_drawn)
    if not _may_fork(fork):
        if not late:
            yield
        _draw(figures)  # in order
        return
    claims = _Claims(len(figures))
    try:
        child = _draw_in_child(figures, claims)
        mine: list[int] = []  # the figures drawn here
        try:
            if not late:
                yield  # the fit's other outputs, while the child draws
            heard = _Heard(said)  # after what the block said
            _draw(claims.figures(figures, mine), heard)
            with timed("figure child wait"):
                told = child.wait()
        except BaseException:  # Ctrl-C, SIGTERM, an error: nothing more drawn into the folder
            child.stop()
            raise
    finally:
        claims.close()
    if child.exitcode != 0:  # the child's figures drawn here, so that none is lost
        _draw([figure for k, figure in enumerate(figures) if k not in mine], heard)
    else:
        heard.by_figure.update(json.loads(told))
    heard.in_figure_order([name for name, _ in figures])


def _figures(
    result: SpCoResult,
    house: House,
    out: Path,
    uncertainty: bool,
    kept: tuple[int, int] | None,
    house_drawn: bool,
) -> list[Figure]:
    """The figures :func:`figures_drawn` draws, in their order."""
    with timed("figure imports"):
        from spcopyro.figures.plotting import (
            plot_agreement,
            plot_house,
            plot_semantic_map,
            plot_trace,
            plot_uncertainty,
        )

    observations = house.observations
    figures: list[Figure] = [
        ("semantic_map",
         lambda: plot_semantic_map(result, out / "semantic_map.png", observations=observations)),
        ("trace", lambda: plot_trace(result, out / "trace.png", kept)),
    ]  # fmt: skip
    if not house_drawn:
        figures.append(("house", lambda: plot_house(house, out / "house.png")))
    if uncertainty:
        figures.append(("uncertainty", lambda: plot_uncertainty(result, out / "uncertainty.png")))
    if result.agreement is not None:
        figures.append(("agreement", lambda: plot_agreement(result, out / "agreement.png")))
    return figures


Figure = tuple[str, Callable[[], None]]
"""A figure to draw: its name (for the timings) and the call that writes its PNG."""

STOP_TIMEOUT = 5.0
"""Seconds a stopped fit waits for the figures' child to end on SIGTERM before it kills it."""


class _Claims:
    """Which of n figures shared by this process and its forked child are taken: n one-byte
    tokens in a pipe both hold, each read by exactly one (a pipe's read of one byte is atomic;
    no lock that a dying child could keep)."""

    def __init__(self, count: int) -> None:
        if count > 255:
            raise ValueError(f"{count} figures to share: at most 255")
        read, write = os.pipe()
        os.write(write, bytes(range(count)))
        os.close(write)
        os.set_blocking(read, False)
        self._read = read

    def take(self) -> int | None:
        """The index of a figure nobody has taken, now taken; None when all are."""
        try:
            token = os.read(self._read, 1)
        except BlockingIOError:
            return None
        return token[0] if token else None

    def figures(self, shared: Sequence[Figure], taken: list[int]) -> Iterator[Figure]:
        """The figures of ``shared`` this process takes, one at a time as it asks for the next;
        their indices appended to ``taken``."""
        while (index := self.take()) is not None:
            taken.append(index)
            yield shared[index]

    def close(self) -> None:
        os.close(self._read)


class _Heard:
    """The warnings each figure gave, to be put into ``said`` (None: nothing kept) in the
    figures' order (:meth:`in_figure_order`). Those of a figure drawn here are the messages the
    recording block in effect appended to ``said`` while it was drawn (:meth:`drawing`); the
    child's come from it (``by_figure`` updated)."""

    def __init__(self, said: list[str] | None) -> None:
        self.said = said
        self.by_figure: dict[str, list[str]] = {}
        self._start = 0 if said is None else len(said)
        self._spans: list[tuple[int, int]] = []  # the slices of said given by figures drawn here

    @contextlib.contextmanager
    def drawing(self, name: str) -> Iterator[None]:
        """Around the drawing of figure ``name`` here: what it adds to ``said`` is its own."""
        before = 0 if self.said is None else len(self.said)
        try:
            yield
        finally:
            if self.said is not None:
                self.by_figure[name] = self.said[before:]
                self._spans.append((before, len(self.said)))

    def in_figure_order(self, names: Sequence[str]) -> None:
        """``said`` from where the figures began: the warnings of the figures ``names`` in that
        order, then what else was said meanwhile (a PNG compressed on its thread), in order."""
        said = self.said
        if said is None:
            return
        theirs = {k for begin, end in self._spans for k in range(begin, end)}
        rest = [said[k] for k in range(self._start, len(said)) if k not in theirs]
        said[self._start :] = [text for name in names for text in self.by_figure.get(name, [])]
        said.extend(rest)


def _may_fork(fork: bool | None) -> bool:
    from spcopyro._util.forking import fork_refusal

    return fork is not False and fork_refusal(uses_torch=False) is None


def _draw(figures: Iterable[Figure], heard: _Heard | None = None) -> None:
    from spcopyro.figures.png import background_writes

    with background_writes():  # each PNG compressed on a thread while the next is drawn
        for name, draw in figures:
            drawing = contextlib.nullcontext() if heard is None else heard.drawing(name)
            with timed(f"figure {name}"), drawing:
                draw()


class _Child:
    """A forked child drawing figures (:func:`_draw_in_child`), and the read end of the pipe on
    which it sends, as it ends, the warnings its figures gave (JSON: figure name -> messages)."""

    def __init__(self, process: BaseProcess, told: int) -> None:
        self.process = process
        self._told: int | None = told

    @property
    def exitcode(self) -> int | None:
        return self.process.exitcode

    def wait(self) -> bytes:
        """What it sent, once it ended. The pipe is read to its end before the join: a child
        whose warnings outgrow the pipe's buffer waits for them to be read."""
        assert self._told is not None, "waited for twice"
        chunks: list[bytes] = []
        while chunk := os.read(self._told, 1 << 16):
            chunks.append(chunk)
        self._close()
        self.process.join()
        return b"".join(chunks)

    def stop(self) -> None:
        """End it now: the pipe closed first (a write there then fails instead of waiting for a
        reader), SIGTERM (its default action: the child does not keep ``fit``'s handler, which
        raises KeyboardInterrupt), then a join of at most :data:`STOP_TIMEOUT` s, SIGKILL
        after."""
        self._close()
        self.process.terminate()
        self.process.join(STOP_TIMEOUT)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()

    def _close(self) -> None:
        if self._told is not None:
            told, self._told = self._told, None
            os.close(told)


def _draw_in_child(figures: list[Figure], claims: _Claims) -> _Child:
    """A child forked to draw the ``figures`` it takes from ``claims`` (no torch there: the
    plots are numpy and matplotlib), started; it exits with 0 once they are written, 1 if one
    failed.

    Forked with SIGINT and SIGTERM held back: blocked (the child unblocks them once its own
    handlers are in place) and, here, recorded rather than raised, then given to their handlers
    once the child is a :class:`_Child`, stopped if one raises. Before, a KeyboardInterrupt of
    fit's handlers could be raised in the child before its own were set (a fit stopped just
    after the fork sends it SIGTERM at once), outside what multiprocessing's bootstrap catches
    (just after the fork returns): the child then went on in its copy of the fit, unwinding as
    an interrupted fit does, and whatever called the fit carried on in it (a test went on to
    write OUT from there). A signal raised here after the fork, before the child was recorded,
    left it drawing unstopped into the folder being discarded."""
    import multiprocessing
    import signal

    from spcopyro._util.forking import start_forked
    from spcopyro._util.interrupts import signals_blocked, signals_deferred

    told, tell = os.pipe()
    wait, go = os.pipe()  # the child draws once a byte comes here, never if the pipe just ends
    held: list[int] = []  # the signals that came while the child was forked
    try:
        with signals_deferred(lambda signum, frame: held.append(signum)), signals_blocked() as mask:
            process = multiprocessing.get_context("fork").Process(
                target=_child_draws, args=(figures, claims, tell, told, mask, wait, go),
                name="spcopyro-figures", daemon=True,
            )  # fmt: skip
            start_forked(process)
    except BaseException:
        os.close(told)
        os.close(go)
        raise
    finally:
        os.close(tell)  # the child's end: the pipe ends when the child does
        os.close(wait)
    child = _Child(process, told)
    try:
        for signum in held:  # to their handlers now (fit's raise KeyboardInterrupt)
            signal.raise_signal(signum)
        os.write(go, b"1")  # no signal stopped the fit: the child draws
    except BaseException:
        child.stop()  # it drew nothing: no byte came
        raise
    finally:
        os.close(go)
    return child


def _child_draws(
    figures: list[Figure],
    claims: _Claims,
    tell: int,
    told: int,
    mask: set[int] | None,
    wait: int,
    go: int,
) -> None:
    """In the child (:func:`_draw_in_child`), SIGINT and SIGTERM blocked since the fork:
    ``mask`` (the parent's before it blocked them; None: nothing blocked) restored once its
    handlers are set (a SIGTERM that came since ends it there). It draws only once the parent
    sends a byte on ``wait`` (no signal stopped the fit while it forked); the pipe's end without
    one ends the child, having drawn nothing."""
    import gc
    import signal

    from spcopyro.cli.fit_warnings import recorded_warnings

    # what the fork copied into the collector's permanent generation (O(1)): the child's
    # collections scan its figures' objects only, not the fit's (a scan writes to each object it
    # visits, copying its page from the parent): in two embedded fits (--sweeps 300) each way, the
    # child's collections took 21-37 ms without this, 2-10 ms with it (of its 0.4-0.5 s CPU)
    gc.freeze()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides (and redraws on failure)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # _Child.stop ends it (not fit's handler)
    if mask is not None:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    os.close(told)  # the parent's end: once the parent closes its own, a write here fails
    os.close(go)  # the parent's end: the pipe ends when the parent closes its own
    if not os.read(wait, 1):  # the fit stopped as it forked this child: nothing to draw
        os._exit(1)
    os.close(wait)
    heard: dict[str, list[str]] = {}  # figure name -> the warnings it gave (printed as well)
    code = 0
    try:
        for name, draw in claims.figures(figures, []):
            with recorded_warnings() as said:
                heard[name] = said
                draw()
    except BaseException:  # noqa: BLE001  (the parent draws them again and reports the error)
        code = 1
    with contextlib.suppress(OSError), os.fdopen(tell, "wb") as pipe:  # OSError: parent stopped
        pipe.write(json.dumps(heard).encode())
    if code:
        os._exit(code)
