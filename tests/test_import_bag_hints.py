"""``spcopyro import-bag``'s closing 'next:' and 'then:' commands run as printed: ``features``
names the weights it can run with (without ``--weights`` it stopped offline, the ImageNet file
missing), and ``fit`` writes outside the data folder (it suggested ``--out data/fit``)."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from spcopyro.cli.main import main

pytest.importorskip("rosbags")


def _printed_commands(printed: str) -> dict[str, list[str]]:
    """The argv of each printed ``  next: spcopyro ...`` / ``  then: spcopyro ...`` line."""
    commands = {}
    for line in printed.splitlines():
        for word in ("next", "then"):
            prefix = f"  {word}: spcopyro "
            if line.startswith(prefix):
                commands[word] = shlex.split(line[len(prefix) :])
    return commands


def _import(out: str, capsys) -> tuple[dict[str, list[str]], str]:
    bags = sorted(str(p) for p in Path("bags").glob("trial_*.bag"))
    assert main(["import-bag", *bags, "--map", "bags/map.yaml", "--image-topic",
                 "/camera/image/compressed", "--out", out]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    return _printed_commands(printed), printed


def test_the_printed_next_commands_run_as_printed(tmp_path, monkeypatch, capsys):
    pytest.importorskip("torchvision")
    monkeypatch.chdir(tmp_path)
    torch_home = tmp_path / "torch"
    monkeypatch.setenv("TORCH_HOME", str(torch_home))  # no ImageNet weights cached: offline
    assert main(["simulate-bag", "--out", "bags", "--ros", "1", "--image-size", "16", "20",
                 "--trials", "0"]) == 0  # fmt: skip
    capsys.readouterr()
    commands, printed = _import("data/house", capsys)
    features, fit = commands["next"], commands["then"]
    assert features[features.index("--weights") + 1] == "random"
    assert f"no ImageNet weights in {torch_home / 'hub' / 'checkpoints'}" in printed
    assert "--weights imagenet --download fetches them" in printed
    assert main(features) == 0  # as printed
    capsys.readouterr()
    assert (tmp_path / "data" / "house" / "Ft.csv").is_file()
    out = Path(fit[fit.index("--out") + 1])
    assert out == Path("out/house")  # the README's walk: data/house -> out/house
    assert (tmp_path / "data").resolve() not in out.resolve().parents
    assert main([*fit, "--sweeps", "2", "--no-figures", "--chain-workers", "1"]) == 0
    assert (out / "labels.npy").is_file()

    cached = torch_home / "hub" / "checkpoints" / "alexnet-owt-7be5be79.pth"
    cached.parent.mkdir(parents=True)
    cached.write_bytes(b"")  # where torchvision keeps the ImageNet weights
    commands, printed = _import("out/rooms", capsys)
    features = commands["next"]
    assert features[features.index("--weights") + 1] == "imagenet"
    assert "no ImageNet weights" not in printed
    # a house folder where out/NAME would be: the fit goes beside it, not into it
    assert commands["then"][commands["then"].index("--out") + 1] == "rooms-fit"


def test_imagenet_cache_file_is_torchvision_s(tmp_path, monkeypatch):
    """``features_command`` looks for the ImageNet file where torchvision does, without torch."""
    pytest.importorskip("torchvision")
    from spcopyro.features.backbone import torchvision_cache_file
    from spcopyro.features.cli import imagenet_cache_file

    monkeypatch.delenv("TORCH_HOME", raising=False)
    for xdg in (None, str(tmp_path / "xdg")):
        if xdg is None:
            monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
        else:
            monkeypatch.setenv("XDG_CACHE_HOME", xdg)
        assert imagenet_cache_file() == torchvision_cache_file()
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "th"))
    assert imagenet_cache_file() == torchvision_cache_file()
