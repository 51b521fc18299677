"""`spcopyro fit` keeps the warnings it printed in its config.json ("warnings"), and `show` on
the fit's folder points to them (spcopyro.cli.fit_warnings)."""

from __future__ import annotations

import json
import logging
import sys
import warnings

import pytest

from spcopyro.cli.fit_warnings import recorded_warnings, write_config
from spcopyro.cli.main import main
from spcopyro.synthetic import HouseSpec, write_synthetic

LOW_GAMMA = "is below the Potts critical coupling"


@pytest.fixture
def small_house(tmp_path):
    return write_synthetic(
        tmp_path / "data", seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3)
    )


def _fit(house, out, gamma: str, *more: str) -> dict:
    argv = ["fit", str(house), "--out", str(out), "--sweeps", "2", "--no-figures",
            "--preset", "original-code", "--gamma", gamma, "--concepts", "10", *more]  # fmt: skip
    assert main(argv) == 0
    return json.loads((out / "config.json").read_text())


def test_a_fits_warnings_are_printed_and_kept_in_config_json(small_house, tmp_path, capsys):
    settings = _fit(small_house, tmp_path / "low", "0.5")
    assert LOW_GAMMA in capsys.readouterr().err  # still printed
    said = settings["warnings"]
    assert isinstance(said, list) and all(isinstance(m, str) for m in said)
    assert sum(LOW_GAMMA in m for m in said) == 1, said
    assert len(said) == len(set(said)), said
    # show on a fit's folder: an error that points to them
    assert main(["show", str(tmp_path / "low"), "--out", str(tmp_path / "h.png")]) == 2
    err = capsys.readouterr().err
    assert "its fit gave 1 warning" in err and LOW_GAMMA in err, err

    settings = _fit(small_house, tmp_path / "fine", "3.5")
    assert settings["warnings"] == [], settings["warnings"]
    assert main(["show", str(tmp_path / "fine"), "--out", str(tmp_path / "h.png")]) == 2
    err = capsys.readouterr().err
    assert "not a house folder" in err and "its fit gave" not in err, err


def test_a_fit_writes_its_config_json_once_with_its_warnings(small_house, tmp_path, monkeypatch):
    """config.json is written once, at the end (it was written by the result's save, then read
    and written again with the warnings); a fit interrupted before is discarded whole."""
    from pathlib import Path

    written: list[str] = []
    real = Path.write_text

    def write_text(self, *args, **kwargs):
        written.append(self.name)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", write_text)
    settings = _fit(small_house, tmp_path / "low", "0.5")
    assert written.count("config.json") == 1, written
    assert written.index("config.json") > written.index("scores.json"), written  # at the end
    assert any(LOW_GAMMA in m for m in settings["warnings"]), settings
    assert list(settings)[-1] == "warnings" and settings["method"] == "gibbs", settings


def _print_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"{filename}:{lineno}: {category.__name__}: {message}", file=sys.stderr)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forked chains: Linux only")
def test_a_warning_in_a_chains_worker_process_is_kept_as_on_threads(
    small_house, tmp_path, monkeypatch, capfd
):
    """--chains 2 on two workers: a warning a chain gives in its forked process lands in
    config.json as one given on a thread does (spcopyro.gibbs.chain_processes)."""
    import spcopyro.gibbs.run as run_module

    real = run_module.step

    def step(*args, **kwargs):
        warnings.warn("a sweep's own warning", RuntimeWarning, stacklevel=1)
        return real(*args, **kwargs)

    monkeypatch.setattr(run_module, "step", step)
    kept = {}
    for mode in ("off", "on"):  # threads, processes
        monkeypatch.setenv("SPCOPYRO_CHAIN_PROCESSES", mode)
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.showwarning = _print_warning  # pytest's keeps them off stderr
            kept[mode] = _fit(small_house, tmp_path / mode, "0.5",
                              "--chains", "2", "--chain-workers", "2")["warnings"]  # fmt: skip
        assert capfd.readouterr().err.count("a sweep's own warning") == 1
    assert "RuntimeWarning: a sweep's own warning" in kept["off"], kept
    assert any(LOW_GAMMA in m for m in kept["off"]), kept
    assert kept["on"] == kept["off"], kept


def test_recorded_warnings_keeps_log_records_and_python_warnings_in_order(tmp_path):
    logger = logging.getLogger("spcopyro.somewhere")
    handlers = list(logging.getLogger("spcopyro").handlers)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda *args, **kwargs: None  # restored by catch_warnings
        with recorded_warnings() as said:
            logger.warning("first %s", 1)
            logger.info("not a warning")
            warnings.warn("second", UserWarning, stacklevel=1)
            logger.warning("first %s", 1)
    assert said == ["first 1", "UserWarning: second", "first 1"]
    assert logging.getLogger("spcopyro").handlers == handlers  # its handler removed
    config = tmp_path / "config.json"
    write_config(config, {"method": "gibbs"}, said)
    kept = json.loads(config.read_text())
    assert kept == {"method": "gibbs", "warnings": ["first 1", "UserWarning: second"]}
