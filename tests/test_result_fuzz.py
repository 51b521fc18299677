"""A seeded fuzz of the saved-result and checkpoint readers (issue 22 item 9): a truncated or
corrupted ``result.npz``, ``config.json`` or checkpoint is one clear error that names the file
(exit 2 on the command line), never a traceback."""

from __future__ import annotations

import random
import shutil
from pathlib import Path

import pytest

from spcopyro.cli.main import main
from spcopyro.gibbs.checkpoint import read_record
from spcopyro.results.result import SpCoResult
from spcopyro.synthetic import HouseSpec, write_synthetic

CASES = 40
FIT = ["--sweeps", "6", "--preset", "original-code", "--gamma", "3", "--concepts", "6",
       "--no-figures"]  # fmt: skip


@pytest.fixture(scope="module")
def fitted(tmp_path_factory) -> tuple[Path, Path]:
    """(a small fit's output folder, the room folder it was fitted to)."""
    root = tmp_path_factory.mktemp("fuzz")
    room = write_synthetic(root / "data", seed=3, spec=HouseSpec(height=30, width=36, num_rooms=2))
    out = root / "fit"
    assert main(["fit", str(room), "--out", str(out), *FIT]) == 0
    return out, room


def _corrupt(rng: random.Random, data: bytes) -> bytes:
    """Truncate, flip bytes in, or replace ``data`` (one of them, drawn)."""
    kind = rng.choice(["truncate", "flip", "garbage", "empty"])
    if kind == "truncate":
        return data[: rng.randrange(0, max(1, len(data)))]
    if kind == "flip":
        data = bytearray(data)
        for _ in range(rng.randint(1, 20)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        return bytes(data)
    if kind == "garbage":
        return bytes(rng.randrange(256) for _ in range(rng.randint(1, 300)))
    return b""


def test_damaged_results_are_one_clear_error(fitted, tmp_path, capsys):
    out, _ = fitted
    rng = random.Random(20261202)
    outcomes = {"error": 0, "read": 0}
    for case in range(CASES):
        damaged = tmp_path / f"fit{case}"
        shutil.copytree(out, damaged)
        name = rng.choice(["result.npz", "config.json"])
        path = damaged / name
        path.write_bytes(_corrupt(rng, path.read_bytes()))
        try:
            SpCoResult.load(damaged)
        except (OSError, ValueError) as error:
            assert str(damaged) in str(error), (case, name, error)
            outcomes["error"] += 1
        except Exception as error:  # noqa: BLE001 - the point: nothing else may escape
            raise AssertionError(
                f"case {case} ({name}): {type(error).__name__}: {error}"
            ) from error
        else:
            outcomes["read"] += 1
        word = "kitchen"
        code = main(["where", str(damaged), word])  # never raises
        assert code in (0, 2), (case, name, code)
        capsys.readouterr()
    assert outcomes["error"] > CASES // 2, outcomes


def test_a_damaged_checkpoint_is_one_clear_error(fitted, tmp_path, capsys):
    out, room = fitted
    rng = random.Random(7)
    checkpoint = tmp_path / "pristine.checkpoint.npz"
    shutil.copy(out / "result.npz", checkpoint)  # a real npz that is no checkpoint
    with pytest.raises(ValueError, match="not a spcopyro checkpoint"):
        read_record(checkpoint)
    data = checkpoint.read_bytes()
    for case in range(CASES // 2):
        damaged = tmp_path / f"c{case}.npz"
        damaged.write_bytes(_corrupt(rng, data))
        with pytest.raises(ValueError, match=str(damaged)):
            read_record(damaged)
        code = main(["fit", str(room), "--out", str(tmp_path / f"o{case}"), *FIT,
                     "--resume", str(damaged)])  # fmt: skip
        assert code == 2, (case, capsys.readouterr().err)
        assert str(damaged) in capsys.readouterr().err


def test_a_fit_folder_without_its_config_says_so(fitted, tmp_path, capsys):
    """A result.npz copied without its config.json was a bare '[Errno 2] No such file or
    directory' (a helper's QA)."""
    out, _ = fitted
    copy = tmp_path / "copied"
    shutil.copytree(out, copy)
    (copy / "config.json").unlink()
    with pytest.raises(FileNotFoundError, match=r"config\.json: missing beside result\.npz"):
        SpCoResult.load(copy)
    assert main(["where", str(copy), "kitchen"]) == 2
    assert "config.json: missing beside result.npz" in capsys.readouterr().err
