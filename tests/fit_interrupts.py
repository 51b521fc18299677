"""Interrupting a fit at a chosen sweep or CAVI step, or in whatever function is patched with
:func:`interrupted`, as Ctrl-C would: for the ``fit`` command's tests (test_checkpoint,
test_refine, test_fit_resume_gaps, test_fit_interrupt_setup, test_resumed_fit_report,
test_interrupt_with_figure_thread) and ``compare-inference``'s (test_inference_comparison)."""

from __future__ import annotations

from typing import NoReturn

import spcopyro.gibbs.chains
import spcopyro.guides.cavi as cavi
from spcopyro.gibbs.run import advance


def interrupted(*args, **kwargs) -> NoReturn:
    """A stand-in for any function (patched over it) that is stopped by Ctrl-C as it starts."""
    raise KeyboardInterrupt


def interrupt_fit_at(monkeypatch, chain: int, sweep: int) -> None:
    """Make ``fit``'s run loop raise KeyboardInterrupt (through its callback) after ``sweep`` of
    the ``chain``-th chain advanced (0: the first; the chains of every stage of the fit count,
    one after another)."""
    calls: list[int] = []

    def interrupting_advance(gibbs_chain, num_sweeps, callback=None, **kwargs):
        calls.append(1)

        def stop(s, state):
            if callback is not None:
                callback(s, state)
            if len(calls) - 1 == chain and s == sweep:
                raise KeyboardInterrupt

        return advance(gibbs_chain, num_sweeps, callback=stop, **kwargs)

    monkeypatch.setattr(spcopyro.gibbs.chains, "advance", interrupting_advance)


def interrupt_cavi_at(monkeypatch, call: int) -> None:
    """Make CAVI's torch step raise KeyboardInterrupt at its ``call``-th call (1: the first)."""
    real, calls = cavi.step, []

    def interrupting(*args, **kwargs):
        calls.append(1)
        if len(calls) == call:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(cavi, "step", interrupting)
