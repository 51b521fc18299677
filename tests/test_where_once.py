"""`spcopyro where FIT WORD --out PNG` computes the word's [N] p(cell in its place) once
(:func:`~spcopyro.results.uncertainty.where_probability`), for its printed line and both
figures: not three times, and not kept on the result (one [N] per word for its lifetime)."""

from __future__ import annotations

import numpy as np

from spcopyro.cli.main import main
from spcopyro.data import load_house
from spcopyro.figures import plotting
from spcopyro.results import uncertainty
from spcopyro.results.result import SpCoResult
from spcopyro.synthetic import HouseSpec, write_synthetic


def test_where_with_figures_computes_the_place_probability_once(tmp_path, monkeypatch, capsys):
    data = write_synthetic(tmp_path / "data", seed=1, spec=HouseSpec(height=40, width=50,
                                                                     num_rooms=3))  # fmt: skip
    fit = tmp_path / "fit"
    assert main(["fit", str(data), "--out", str(fit), "--sweeps", "20"]) == 0
    assert SpCoResult.load(fit).marginals is not None  # where_figure's colour scale reads it too
    word = load_house(data).observations.vocabulary[0]
    calls: list[str] = []
    original = uncertainty.where_probability

    def counted(result: SpCoResult, word: str, prior: str = "area") -> np.ndarray:
        calls.append(word)
        return original(result, word, prior)

    monkeypatch.setattr(uncertainty, "where_probability", counted)  # main imports it when run
    monkeypatch.setattr(plotting, "where_probability", counted)  # the figures' own import
    capsys.readouterr()
    assert main(["where", str(fit), word, "--out", str(tmp_path / "where.png")]) == 0
    assert "wrote" in capsys.readouterr().out
    assert (tmp_path / "where.png").stat().st_size > 0
    assert (tmp_path / "where_probability.png").stat().st_size > 0
    assert calls == [word]
