"""A fit stopped while its figure thread (:class:`spcopyro.cli.fit_figures.FigurePrefetch`) works.

A Ctrl-C or SIGTERM that lands in the main thread while Python's import machinery holds a module
lock for it can leave that lock held for good (the handler raises between the lock's acquisition
and the ``with`` that releases it). The figure thread, importing matplotlib meanwhile, then waits
on that lock forever; ``fit`` joined it without bound and never exited (seen once in the full
suite: ``test_a_real_ctrl_c_in_a_fit_process[SIGTERM]`` timed out after 120 s, the bar closed
and no "interrupted" line). The thread is now abandoned after a bounded wait, and draws nothing
into the staging folder once abandoned."""

from __future__ import annotations

import threading

from fit_interrupts import interrupt_fit_at

import spcopyro.cli.fit_figures as fit_figures
from spcopyro._util.outputs import checkpoint_path
from spcopyro.cli.fit_figures import FigurePrefetch
from spcopyro.cli.main import main


def test_an_interrupted_fit_does_not_wait_for_a_stuck_figure_thread(
    home, tmp_path, capsys, monkeypatch
):
    release = threading.Event()
    stuck: list[threading.Thread] = []

    def stuck_on_a_lock(self, house, out):  # as on an import lock an interrupt left held
        stuck.append(threading.current_thread())
        release.wait(20)

    monkeypatch.setattr(FigurePrefetch, "_run", stuck_on_a_lock)
    monkeypatch.setattr(fit_figures, "ABANDON_TIMEOUT", 0.05, raising=False)
    interrupt_fit_at(monkeypatch, chain=0, sweep=2)
    out = tmp_path / "out"
    try:
        assert main(["fit", str(home), "--out", str(out), "--sweeps", "50", "--concepts", "4",
                     "--refine", "never"]) == 130  # fmt: skip
        assert stuck and stuck[0].is_alive()  # fit returned without waiting for it
    finally:
        release.set()
    assert "continue with: spcopyro" in capsys.readouterr().err
    assert checkpoint_path(out).is_file() and not out.exists()


def test_an_abandoned_figure_thread_draws_nothing(tmp_path, monkeypatch):
    imported, go_on = threading.Event(), threading.Event()
    drawn: list[object] = []

    def slow_timed(name):  # the imports take until the fit has stopped
        import contextlib

        if name == "prefetch imports":
            imported.set()
            go_on.wait(60)
        return contextlib.nullcontext()

    monkeypatch.setattr(fit_figures, "timed", slow_timed)
    monkeypatch.setattr("spcopyro.figures.plotting.plot_house", lambda *a: drawn.append(a))
    prefetch = FigurePrefetch(house=object(), out=tmp_path)
    assert imported.wait(60)
    assert not prefetch.abandon(timeout=0.01)  # still importing: not waited for
    go_on.set()
    prefetch._thread.join(60)
    assert not prefetch._thread.is_alive() and drawn == [] and not prefetch.house_drawn
    assert not prefetch.join() and list(tmp_path.iterdir()) == []
