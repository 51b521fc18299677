"""Progress bars (spcopyro._util.progress): a bar whose first iterations compile code shows no
time left extrapolated from them."""

from __future__ import annotations

import io
import re
import sys
import time

from tqdm import tqdm

from spcopyro._util import progress
from spcopyro._util.progress import COMPILE_ITERATIONS, noted_updates


def _seconds_left(text: str) -> list[float]:
    """The times left ('<MM:SS' or '<H:MM:SS') of every line of a bar's output."""
    found = []
    for match in re.finditer(r"<((?:\d+:)?\d+:\d+)", text):
        parts = [int(p) for p in match.group(1).split(":")]
        found.append(float(sum(p * 60**i for i, p in enumerate(reversed(parts)))))
    return found


def test_a_compiling_first_iteration_gives_no_time_left_from_its_pace():
    """spcopyro fit's first sweep compiled for 9.3 s, then ran at 5 ms a sweep: the bar said
    12:55:58 left (9.3 s x 4999) for seconds. Here 0.3 s, then 2 ms an iteration over 200: the
    bar may say no time left while the note is up, then about the 0.4 s it takes."""
    out = io.StringIO()
    bar = tqdm(total=200, desc="Gibbs sweeps (compiling)", unit="sweep", file=out, mininterval=0)
    update = noted_updates(bar, "Gibbs sweeps", "compiling")
    time.sleep(0.3)  # the compiling iteration
    update(1)
    for _ in range(199):
        time.sleep(0.002)
        update(1)
    bar.close()
    text = out.getvalue()
    lines = text.split("\r")
    noted = [line for line in lines if "(compiling)" in line]
    assert len(noted) >= COMPILE_ITERATIONS and not _seconds_left("".join(noted))
    left = _seconds_left(text)
    assert left and max(left) <= 5, text  # extrapolated from the first: 199 x 0.3 s = 59 s
    assert lines[-1].startswith("Gibbs sweeps: 100%") and "200/200" in lines[-1]


def test_without_a_note_the_bar_is_tqdms_own():
    bar = tqdm(total=3, file=io.StringIO())
    assert noted_updates(bar, "Gibbs sweeps", None) == bar.update
    bar.close()


def test_noted_bar_makes_the_bar_with_its_note_and_drops_it_after_the_compiling_iterations(
    monkeypatch,
):
    import spcopyro._util.progress as progress

    made = []

    def quiet(*args, **kwargs):
        made.append(tqdm(*args, file=io.StringIO(), mininterval=0, **kwargs))
        return made[-1]

    monkeypatch.setattr("tqdm.auto.tqdm", quiet)
    bar, update = progress.noted_bar(30, "Gibbs sweeps (model grid)", "compiling", "sweep", False)
    assert made == [bar] and bar.unit == "sweep" and bar.total == 30
    assert bar.desc == "Gibbs sweeps (model grid) (compiling)"
    for _ in range(COMPILE_ITERATIONS):
        update(1)
    assert bar.desc == "Gibbs sweeps (model grid)" and bar.n == COMPILE_ITERATIONS
    bar.close()
    plain, update = progress.noted_bar(3, "CAVI", None, "it", False)
    assert plain.desc == "CAVI" and update == plain.update
    plain.close()


def test_a_bar_gone_once_done_leaves_no_line_of_spaces_in_a_log(capsys):
    """`spcopyro fit 2> log.txt`: the point estimate's bar (tqdm's leave=False) cleared its line
    when done, which in a file is a carriage return, a line of spaces and a carriage return. Off
    a terminal it now keeps its last state on a line of its own."""
    import numpy as np

    from spcopyro.results.point_estimate import point_estimate

    samples = np.random.default_rng(0).integers(0, 3, size=(4, 30))  # [S, N]
    point_estimate(samples, progress=True)
    written = capsys.readouterr().err  # not a terminal, as a log file is not
    assert "point estimate (variation of information)" in written
    pieces = re.split(r"[\r\n]", written)
    assert not [p for p in pieces if p and not p.strip()], repr(written)
    assert written.endswith("\n")  # the next line of the log starts on a line of its own


class _Stream:
    """A stderr that is no terminal (a log file's, or a notebook's as its module says)."""

    def __init__(self, tty: bool = False) -> None:
        self.tty = tty

    def isatty(self) -> bool:
        return self.tty

    def write(self, text: str) -> int:
        return len(text)

    def flush(self) -> None:
        pass


def test_a_bar_is_cleared_when_done_on_a_terminal_and_in_a_notebook_only(monkeypatch):
    """1a72b9f kept finished bars off a terminal, and ipykernel's OutStream.isatty() is False:
    in Jupyter the point estimate's bar stayed where it used to vanish. A notebook's stderr
    (its type from ipykernel, told without importing it) clears as a terminal does."""
    notebook = type("OutStream", (_Stream,), {"__module__": "ipykernel.iostream"})
    for stream, clears in ((_Stream(tty=True), True), (notebook(), True), (_Stream(), False)):
        monkeypatch.setattr(sys, "stderr", stream)
        assert progress.clears_when_done() is clears, type(stream).__module__
    monkeypatch.setattr(sys, "stderr", None)  # pythonw: no stream
    assert progress.clears_when_done() is False
