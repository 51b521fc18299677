"""What ``spcopyro fit`` says of its time: the pace of a method's own iterations, apart from
what ran before them."""

from __future__ import annotations

import csv
import json
import re

from spcopyro.cli.common import pace
from spcopyro.cli.main import main


def test_vi_gibbs_pace_is_of_its_sweeps_and_its_cavi_start_says_its_time(tmp_path, capsys):
    """vi-gibbs's trace clock starts with its CAVI start's seconds, and the fitted line's pace
    took them in: "2.79 ms per sweep after a first of 0.6 s" where the first sweep took 0.08 s
    and CAVI 0.53 s (on a shorter start, total / sweeps, CAVI spread over the sweeps). The pace
    is of the sweeps; the CAVI start's line gives its seconds."""
    out = tmp_path / "fit"
    assert main(["fit", "--out", str(out), "--method", "vi-gibbs", "--sweeps", "20",
                 "--no-figures"]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    start = json.loads((out / "config.json").read_text())["inference"]["vi_seconds"]
    with (out / "trace.csv").open() as f:
        seconds = [float(row["seconds"]) for row in csv.DictReader(f)]  # cumulative, from 0
    assert start > 0 and len(seconds) == 20 and seconds[0] > start
    fitted = next(line for line in printed.splitlines() if line.startswith("fitted "))
    # the pace printed is of the sweeps: compared as numbers, since the printed one rounds the
    # run's own floats and a value at a rounding boundary (1.045) may print either way
    printed_ms = float(re.search(r"\((\d+\.\d+) ms per sweep", fitted).group(1))

    def ms(text: str) -> float:
        return float(text.split(" ms per sweep")[0])

    assert abs(printed_ms - ms(pace(seconds[0] - start, seconds[-1] - start, 20))) <= 0.011
    with_cavi = ms(pace(seconds[0], seconds[-1], 20))  # CAVI's time in it: what it printed
    assert abs(printed_ms - with_cavi) > 0.011 or with_cavi == ms(
        pace(seconds[0] - start, seconds[-1] - start, 20)
    ), fitted
    cavi = next(line for line in printed.splitlines() if line.startswith("CAVI start"))
    assert re.search(rf"\({start:.2f} s, not in the sweeps' pace above\)", cavi), cavi
