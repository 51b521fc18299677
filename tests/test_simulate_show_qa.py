"""``spcopyro simulate`` and ``show`` as a user meets them: their summaries and messages (issues
found by running the commands on small and hand-drawn houses)."""

from __future__ import annotations

from spcopyro.cli.main import main
from spcopyro.synthetic import HouseSpec, write_synthetic


def test_show_counts_one_category_trial_and_word_in_the_singular(tmp_path, capsys):
    """A one-room house's summary said "ground truth 1 categories: kitchen" (and would say
    "vocabulary of 1 words", "in 1 trial(s)"): each count now agrees with its noun."""
    spec = HouseSpec(height=30, width=30, num_rooms=1, num_open_plan=0, min_room_size=8)
    room = write_synthetic(tmp_path / "data", seed=0, spec=spec, name="one")
    assert main(["show", str(room), "--out", str(tmp_path / "one.png")]) == 0
    out = capsys.readouterr().out
    assert "ground truth     1 category: kitchen" in out
    assert "in 3 trials" in out and "trial(s)" not in out
    assert "vocabulary of 3 words" in out
