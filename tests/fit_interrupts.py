"""Interrupting a fit at a chosen sweep, as Ctrl-C would: for the ``fit`` command's tests
(test_checkpoint, test_refine)."""

from __future__ import annotations

import spcopyro.gibbs.chains
from spcopyro.gibbs.run import advance


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
