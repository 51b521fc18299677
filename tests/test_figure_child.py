"""The child that ``spcopyro fit`` forks to draw some of its figures
(:func:`spcopyro.cli.fit_figures.figures_drawn`): its warnings reach the fit's list
(``config.json``'s) in the figures' order, as drawn in one process; a fit stopped while it waits
for the child ends the child before the staging folder is discarded; and a child's warnings
larger than a pipe holds do not hang the fit.

The fork is disabled as the tests of :mod:`test_fixed_cost` do it: ``fork=False``, or
``_may_fork`` (where :func:`spcopyro._util.forking.fork_refusal` allows one) answering False.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import signal
import sys
import time
import warnings
from pathlib import Path
from types import SimpleNamespace

import pytest

from spcopyro._util.outputs import STAGING_INFIX
from spcopyro.cli import fit_figures
from spcopyro.cli.fit_warnings import recorded_warnings
from spcopyro.cli.main import main

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="figures are drawn in a forked child on Linux only"
)

NAMES = ("semantic_map", "trace", "house", "uncertainty", "agreement")
PARENT = os.getpid()


class Hung(Exception):
    """Not an OSError (as TimeoutError is): multiprocessing's join swallows those."""


@contextlib.contextmanager
def _deadline(seconds: int):
    """:class:`Hung` raised in the main thread after ``seconds`` (no thread: a thread would keep
    figures_drawn from forking)."""

    def expire(signum, frame):
        raise Hung(f"not done in {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


class _Split(fit_figures._Claims):
    """The figures (semantic map, trace, house, uncertainty, agreement: 0-4, as ``NAMES``) taken
    as told: ``here`` by the test's process, the others by the child."""

    here: tuple[int, ...] = ()

    def __init__(self, count: int) -> None:
        super().__init__(count)
        self._mine = {True: iter(self.here), False: iter(sorted(set(range(count)) - {*self.here}))}

    def take(self) -> int | None:
        return next(self._mine[os.getpid() == PARENT], None)


def _split_figures(monkeypatch, here: tuple[int, ...]) -> None:
    """The fit's figures split by :class:`_Split`: ``here`` drawn by this process."""
    monkeypatch.setattr(_Split, "here", here)
    monkeypatch.setattr(fit_figures, "_Claims", _Split)


def _warning_figures(monkeypatch, extra: dict[str, int] | None = None) -> None:
    """Every figure of figures_drawn a stub that gives a logger warning and a Python warning
    (``extra[name]`` more logger warnings of 100 characters) and writes its pid as the PNG."""
    import spcopyro.figures.plotting as plotting

    def stub(name):
        def draw(*args, **kwargs):
            logger = logging.getLogger("spcopyro")
            logger.warning("%s: logged", name)
            warnings.warn(f"{name}: warned", UserWarning, stacklevel=1)
            for k in range((extra or {}).get(name, 0)):
                logger.warning("%s %06d %s", name, k, "x" * 80)
            path = next(a for a in args if isinstance(a, Path))
            path.write_text(str(os.getpid()))

        return draw

    for name in NAMES:
        monkeypatch.setattr(plotting, f"plot_{name}", stub(name))


def _said(out: Path, fork: bool | None) -> list[str]:
    """The warnings a fit's recording block keeps while figures_drawn draws the stubs."""
    result = SimpleNamespace(agreement=object())
    house = SimpleNamespace(observations=None)
    out.mkdir()
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # each figure's, in both processes
        warnings.showwarning = lambda *args, **kwargs: None  # kept below, not shown
        with recorded_warnings() as said:
            with fit_figures.figures_drawn(result, house, out, True, fork=fork, said=said):  # type: ignore[arg-type]
                pass
    return said


def test_the_childs_warnings_join_the_fits_in_the_figures_order(tmp_path, monkeypatch):
    """The child draws trace and uncertainty, this process the semantic map, house and agreement:
    the fit's list is the one drawn in one process (before: the child's two were printed only)."""
    _warning_figures(monkeypatch)
    expected = _said(tmp_path / "here", fork=False)
    given = [(f"{name}: logged", f"UserWarning: {name}: warned") for name in NAMES]
    assert expected == [text for pair in given for text in pair]
    _split_figures(monkeypatch, (0, 2, 4))
    assert _said(tmp_path / "forked", fork=None) == expected
    drawn_by = {name: int((tmp_path / "forked" / f"{name}.png").read_text()) for name in NAMES}
    assert {name for name, pid in drawn_by.items() if pid != PARENT} == {"trace", "uncertainty"}


def test_a_childs_warnings_larger_than_a_pipe_do_not_hang_the_figures(tmp_path, monkeypatch):
    """3000 warnings of 100 characters (about 370 kB of JSON, a pipe holds 64 kB) from the
    child's figure: read before the child is joined, else both would wait for ever."""
    _warning_figures(monkeypatch, extra={"uncertainty": 3000})
    expected = _said(tmp_path / "here", fork=False)
    _split_figures(monkeypatch, (0, 1, 2, 4))  # the child draws the uncertainty map
    with _deadline(20):
        said = _said(tmp_path / "forked", fork=None)
    assert len(said) == len(expected) == 2 * len(NAMES) + 3000 and said == expected


def _fit_with_trace_warning(out: Path, monkeypatch) -> list[str]:
    import spcopyro.figures.plotting as plotting

    plot_trace = plotting.plot_trace

    def warning_trace(*args, **kwargs):
        logging.getLogger("spcopyro").warning("the trace warns (pid %d)", PARENT)
        return plot_trace(*args, **kwargs)

    monkeypatch.setattr(plotting, "plot_trace", warning_trace)
    assert main(["fit", "--sweeps", "4", "--out", str(out)]) == 0
    return json.loads((out / "config.json").read_text())["warnings"]


def _recording_children(monkeypatch) -> list[fit_figures._Child]:
    """The figure children fit_figures forks from now on, in the list returned, as started."""
    children: list[fit_figures._Child] = []
    start = fit_figures._draw_in_child

    def recorded(figures, claims):
        children.append(start(figures, claims))
        return children[-1]

    monkeypatch.setattr(fit_figures, "_draw_in_child", recorded)
    return children


def test_a_figure_that_warns_in_the_child_is_in_config_json(tmp_path, monkeypatch):
    """``spcopyro fit``: trace.png drawn in the child (it takes every figure) warns; its
    warning is in config.json's list, the list of the same fit with the fork disabled."""
    drawn_there: list[int] = []
    start = fit_figures._draw_in_child

    def recorded(figures, claims):
        child = start(figures, claims)
        drawn_there.append(len(figures))
        return child

    monkeypatch.setattr(fit_figures, "_draw_in_child", recorded)
    _split_figures(monkeypatch, ())
    forked = _fit_with_trace_warning(tmp_path / "forked", monkeypatch)
    assert drawn_there  # the fork was used
    monkeypatch.setattr(fit_figures, "_may_fork", lambda fork: False)
    alone = _fit_with_trace_warning(tmp_path / "alone", monkeypatch)
    assert f"the trace warns (pid {PARENT})" in alone
    assert forked == alone


@pytest.mark.parametrize("working", [False, True], ids=["thread ended", "thread at work"])
def test_the_child_draws_the_semantic_map_while_the_fit_saves_its_result(
    tmp_path, monkeypatch, working
):
    """``spcopyro fit`` whose figures' thread has ended (FigurePrefetch.working, here as told)
    forks the figures' child before it saves its result, and the child starts with the
    semantic map: here the save waits until semantic_map.png is in the staging folder (the fit,
    waiting, takes no figure meanwhile). Before, the figures were drawn once the result was
    saved, so the save waited in vain (about 0.1 s of room2ldk4's fit that the figures now
    overlap). Where the thread is still at work (a short fit), the save runs first, while it
    finishes: no figure is drawn before it, and all are after."""
    from spcopyro.results.result import SpCoResult

    save = SpCoResult.save
    at_save: list[tuple[int, bool]] = []  # children forked, semantic_map.png there

    def save_once_the_map_is_drawn(self, out_dir, **kwargs):
        png = Path(out_dir) / "semantic_map.png"  # written whole or not at all (replace_file)
        deadline = time.monotonic() + (0 if working else 20)
        while not png.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        at_save.append((len(children), png.exists()))
        return save(self, out_dir, **kwargs)

    children = _recording_children(monkeypatch)
    monkeypatch.setattr(fit_figures.FigurePrefetch, "working", lambda self: working)
    monkeypatch.setattr(SpCoResult, "save", save_once_the_map_is_drawn)
    out = tmp_path / "fit"
    assert main(["fit", "--sweeps", "4", "--out", str(out)]) == 0
    assert at_save == [(0, False) if working else (1, True)]
    assert len(children) == 1
    assert {"semantic_map.png", "trace.png", "house.png", "uncertainty.png"} <= {
        path.name for path in out.iterdir()
    }


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_fit_stopped_while_it_waits_for_the_child_ends_the_child_first(
    tmp_path, monkeypatch, capsys, signum
):
    """The child (every figure its own but the semantic map, which the fit draws) signals the
    fit once the fit's semantic map is drawn, then sleeps: the fit, waiting for it, stops (130),
    and the child has been ended by SIGTERM (its default action: not fit's handler, which raised
    KeyboardInterrupt in the child) before the staging folder was discarded, none of which is
    left; in seconds, not 30."""
    import spcopyro.figures.plotting as plotting

    plot_semantic_map = plotting.plot_semantic_map
    drawn = tmp_path / "semantic map drawn"

    def semantic_map(*args, **kwargs):
        plot_semantic_map(*args, **kwargs)
        drawn.touch()

    def sleeping_trace(*args, **kwargs):
        while not drawn.exists():
            time.sleep(0.01)
        time.sleep(0.2)  # the fit is waiting for the child (or still writing its PNG)
        os.kill(os.getppid(), signum)
        time.sleep(30)

    children = _recording_children(monkeypatch)
    monkeypatch.setattr(plotting, "plot_semantic_map", semantic_map)
    monkeypatch.setattr(plotting, "plot_trace", sleeping_trace)
    _split_figures(monkeypatch, (0,))  # the fit draws the semantic map
    out = tmp_path / "fit"
    began = time.monotonic()
    try:
        with _deadline(25):
            assert main(["fit", "--sweeps", "4", "--out", str(out)]) == 130
        assert time.monotonic() - began < 20
        (child,) = children
        assert not child.process.is_alive() and child.exitcode == -signal.SIGTERM
    finally:
        for child in children:
            if child.process.is_alive():  # before the fix: still asleep
                child.process.kill()
                child.process.join()
    assert "interrupted" in capsys.readouterr().err
    assert not out.exists()
    assert not [path.name for path in tmp_path.iterdir() if STAGING_INFIX in path.name]


def test_the_child_scans_only_its_own_objects(tmp_path, monkeypatch):
    """The child freezes what the fork copied (gc.freeze, as the fit freezes its imports): its
    collections then scan the figures' objects only, not the fit's, each of whose pages a scan
    would copy from the parent. A figure drawn there counts the objects its collector tracks;
    the same child without its freeze tracks the parent's 50,000 lists too (its count drops by
    about as many once they are deleted), so the bar can fail."""
    import gc

    counted = tmp_path / "tracked.txt"

    def count() -> None:
        counted.write_text(str(len(gc.get_objects())))

    def tracked_in_child() -> int:
        claims = fit_figures._Claims(1)
        try:
            with _deadline(60):
                child = fit_figures._draw_in_child([("count", count)], claims)
                child.wait()
        finally:
            claims.close()
        assert child.exitcode == 0
        return int(counted.read_text())

    # the fit's state: 50,000 lists, each tracked by the collector (a bare object() is not)
    held = [[object()] for _ in range(50_000)]
    assert tracked_in_child() < 10_000  # the child's collector does not track them
    monkeypatch.setattr(gc, "freeze", lambda: None)  # the child as it was before its freeze
    with_held = tracked_in_child()  # pytest's own objects too: about 260,000 in all
    del held
    without = tracked_in_child()
    # it tracked the parent's lists: most of the 50,000 (a few other objects come and go
    # between the two children: 49,998 was seen once)
    assert with_held - without >= 45_000


SIGNALS = pytest.mark.parametrize(
    "signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"]
)


def _signal_at_fork(monkeypatch, signum: int, in_child: bool) -> list[int]:
    """``os.fork`` sends ``signum`` to the child (``in_child``) or to this process just after the
    fork, before multiprocessing's own code goes on; the children's pids, appended as forked."""
    fork = os.fork
    forked: list[int] = []

    def fork_then_signal() -> int:
        pid = fork()
        if pid != 0:
            forked.append(pid)
        if (pid == 0) == in_child:
            os.kill(os.getpid(), signum)
        return pid

    monkeypatch.setattr(os, "fork", fork_then_signal)
    return forked


@SIGNALS
def test_a_signal_to_the_child_at_the_fork_does_not_let_it_go_on_as_the_fit(
    tmp_path, monkeypatch, signum
):
    """A signal that reaches the child before its handlers are set (a fit stopped just after the
    fork sends it SIGTERM at once; a Ctrl-C reaches the whole process group): fit's handlers,
    inherited, raised KeyboardInterrupt in it just after multiprocessing's fork returned, outside
    what its bootstrap catches, and the child went on as the fit (test_checkpoint's
    ctrl_c_while_writing test failed 1 run in 6 under load: the child, back in the test, wrote
    OUT). Now it starts with them blocked: SIGTERM ends it once its handlers are set (the fit
    draws its figures), SIGINT is ignored there."""
    from spcopyro._util.interrupts import sigterm_as_interrupt

    _warning_figures(monkeypatch)
    expected = _said(tmp_path / "here", fork=False)
    _signal_at_fork(monkeypatch, signum, in_child=True)
    children = _recording_children(monkeypatch)
    _split_figures(monkeypatch, ())  # the child takes every figure
    here, escaped = os.getpid(), tmp_path / "escaped"
    try:
        with sigterm_as_interrupt(), _deadline(30):  # fit's handlers, as in a fit
            said = _said(tmp_path / "forked", fork=None)
    finally:
        if os.getpid() != here:  # the child, gone on as this test: tell, and end it here
            escaped.write_text(f"the child {os.getpid()} went on as the test")
            os._exit(1)
    assert not escaped.exists()
    (child,) = children
    assert child.exitcode == (-signal.SIGTERM if signum == signal.SIGTERM else 0)
    assert said == expected  # every figure drawn, by the child or here
    assert {path.name for path in (tmp_path / "forked").iterdir()} == {
        f"{name}.png" for name in NAMES
    }


@SIGNALS
def test_a_signal_to_the_fit_at_the_fork_stops_the_child(tmp_path, monkeypatch, signum):
    """A signal that reaches the fit while it forks the child raises once the child is known,
    which is stopped (reaped) before the interrupt leaves figures_drawn. Before, raised in the
    middle of multiprocessing's start, it left the child unstopped, drawing into the folder the
    fit then discards."""
    from spcopyro._util.interrupts import sigterm_as_interrupt

    _warning_figures(monkeypatch)
    forked = _signal_at_fork(monkeypatch, signum, in_child=False)
    try:
        with sigterm_as_interrupt(), _deadline(30), pytest.raises(KeyboardInterrupt):
            _said(tmp_path / "forked", fork=None)
        (pid,) = forked
        with pytest.raises(ChildProcessError):  # stopped and reaped
            os.waitpid(pid, os.WNOHANG)
        assert list((tmp_path / "forked").iterdir()) == []  # it drew nothing
    finally:
        for pid in forked:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)


def test_the_entropy_is_computed_before_the_figures_child_is_forked(tmp_path, monkeypatch):
    """The uncertainty map's [N, L] entropy pass (2 s at 2.9 million cells) is computed once,
    before the figures' child is forked, so the child's uncertainty.png inherits it. Since
    5ab0c44 forked the child before the save, the entropy was computed after the fork, and
    whichever process drew uncertainty.png computed it again."""
    import spcopyro.cli.fit_write as fit_write

    kept_at_fork: list[bool] = []
    drawn = fit_write.figures_drawn

    def recorded(result, *args, **kwargs):
        kept_at_fork.append(any("entropy" in str(key) for key in result._computed))
        return drawn(result, *args, **kwargs)

    monkeypatch.setattr(fit_write, "figures_drawn", recorded)
    assert main(["fit", "--sweeps", "4", "--out", str(tmp_path / "fit")]) == 0
    assert kept_at_fork == [True]
