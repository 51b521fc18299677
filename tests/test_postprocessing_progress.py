"""A large map's post-processing steps show a progress bar, not a silent terminal.

On a 100 m x 100 m warehouse map at 0.05 m (2.9 million free cells, ``spcopyro fit --sweeps
50``, 25 kept samples) renaming the samples to the map's concepts and counting their label
frequencies took 6.7 s after the point estimate's bar closed, with nothing on the terminal.
"""

from __future__ import annotations

from spcopyro._util import progress
from spcopyro.config import preset
from spcopyro.fit.house import fit_house
from spcopyro.synthetic import HouseSpec, make_house


def test_label_frequencies_have_a_bar_on_a_large_map(monkeypatch, capsys):
    monkeypatch.setattr(progress, "SETUP_PROGRESS_CELLS", 0)  # this small house counts as large
    house = make_house(seed=1, spec=HouseSpec(height=30, width=40, num_rooms=2, num_trials=2))
    settings = preset("original-code", gamma=3.0, num_concepts=6)
    result = fit_house(house, settings, sweeps=20, progress=True, marginal_samples=5)
    assert result.marginals is not None
    err = capsys.readouterr().err
    assert "label frequencies" in err
    assert "6/6" in err.split("label frequencies")[-1]  # one step per kept sample, then the count


def test_fit_shows_a_bar_while_it_writes_a_large_maps_outputs(monkeypatch, capsys, tmp_path):
    """Saving result.npz (it compresses the [N, L] marginals), the uncertainty and agreement
    maps and the figures were 16 s of a silent terminal on the warehouse map."""
    from spcopyro.cli.main import main

    monkeypatch.setattr(progress, "SETUP_PROGRESS_CELLS", 0)  # the embedded house counts as large
    monkeypatch.delenv("CI", raising=False)  # CI switches bars off when no --progress is given
    assert main(["fit", "--out", str(tmp_path / "out"), "--sweeps", "20", "--no-figures"]) == 0
    err = capsys.readouterr().err
    assert "writing the outputs" in err
    assert "3/3" in err.split("writing the outputs")[-1]
