"""What a resumed ``fit`` prints of its time: the trace's seconds, and so the paces per sweep, go
on from the checkpoint's, while the wall clock is this process's alone. Before, the line read
e.g. "300 sweeps ... (8.60 ms per sweep), then 300 ... (3.49 ms per sweep) in 3.2 s wall
clock", paces that add up to more than the wall clock, without a word of the resume."""

from __future__ import annotations

import re
import shlex

from fit_interrupts import interrupt_fit_at

from spcopyro.cli.main import main

FIT = ["--sweeps", "12", "--preset", "original-code", "--gamma", "3", "--concepts", "8",
       "--no-figures", "--refine", "never"]  # fmt: skip


def test_a_resumed_fit_says_its_wall_clock_is_this_runs(home, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    with monkeypatch.context() as patch:
        interrupt_fit_at(patch, 0, 5)
        assert main(["fit", str(home), "--out", str(out), *FIT]) == 130
    again = shlex.split(capsys.readouterr().err.split("continue with: ")[1])
    assert main(again[1:]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("fitted "))
    said = (r"12 sweeps in [\d.]+ s wall clock this run \(resumed: the paces include the "
            r"sweeps run before the interruption\) \([\d.]+ ms per sweep\)")  # fmt: skip
    assert re.search(said, line), line
    assert main(["fit", str(home), "--out", str(tmp_path / "whole"), *FIT]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("fitted "))
    assert "this run" not in line and "resumed" not in line
