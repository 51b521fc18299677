"""The AlexNet backbone and where its weights come from.

SpCoMapping's image modality is a place-class histogram from AlexNet (the paper: trained on
Places205, run in Caffe). Here the network is torchvision's :class:`~torchvision.models.AlexNet`;
its weights come from one of three sources (:func:`parse_weights`):

* ``"imagenet"``: torchvision's weights API, ``AlexNet_Weights.IMAGENET1K_V1``. torchvision keeps
  the file ``alexnet-owt-7be5be79.pth`` in its cache, ``$TORCH_HOME/hub/checkpoints/``
  (``$TORCH_HOME`` defaults to ``~/.cache/torch``; :func:`torchvision_cache_file`). It is read from
  there; it is downloaded (233 MB) only with ``download=True`` on a machine with internet. Without
  the file and without ``download`` a :class:`WeightsNotFoundError` says how to get it.
* a path: a local checkpoint holding a state dict of torchvision's AlexNet (for example the
  Places365 project's ``alexnet_places365.pth.tar``, 365 classes, or a state dict saved with
  ``torch.save(model.state_dict(), path)``). The number of classes is read from the final layer.
  The original Caffe AlexNet (the paper's Places205 model: 96 conv1 filters, grouped
  convolutions) is another architecture and does not fit; nor does its BGR, mean-only
  preprocessing.
* ``"random"``: torchvision's random initialisation from a seed. For tests, timing and plumbing
  only: features from random weights carry no information about places.

Nothing is downloaded unless asked: the cache file is looked up *before* torchvision's weights API
is called, because that API would otherwise try to download it.
"""

from __future__ import annotations

import os
import pickle
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import torch
from torch import nn
from torchvision.models import AlexNet, AlexNet_Weights, alexnet

from spcopyro._util.digests import file_sha256
from spcopyro._util.messages import ECHO_LIMIT, setting
from spcopyro._util.progress import progress_enabled

__all__ = [
    "FEATURE_DIM",
    "IMAGENET_WEIGHTS",
    "CheckpointError",
    "WeightsNotFoundError",
    "WeightsSource",
    "load_alexnet",
    "load_state_dict_file",
    "parse_weights",
    "torchvision_cache_file",
]

IMAGENET_WEIGHTS = AlexNet_Weights.IMAGENET1K_V1
FEATURE_DIM = 4096  # width of AlexNet's fc7, the input of the place head
FINAL_LAYER = "classifier.6"  # fc8: Linear(4096, num_classes), the layer a place head replaces

WeightsKind = Literal["imagenet", "random", "file"]


class WeightsNotFoundError(FileNotFoundError):
    """The requested backbone weights are not on this machine; the message says how to get them."""


class CheckpointError(ValueError):
    """A checkpoint file is unreadable or does not fit AlexNet; the message names the file."""


@dataclass(frozen=True)
class WeightsSource:
    """Where backbone weights come from: ``kind`` is "imagenet", "random" or "file" (``path``)."""

    kind: WeightsKind
    path: Path | None = None
    seed: int = 0  # only for kind "random"

    @property
    def pretrained(self) -> bool:
        """False for random weights: their features mean nothing about places."""
        return self.kind != "random"

    def fingerprint(self) -> str:
        """What identifies these weights wherever the file lies: ``"imagenet"``, ``"random
        seed S"``, or for a checkpoint the SHA-256 of its bytes (the same file under another
        path, relative or absolute, is the same backbone; another file at the same path is not).
        """
        if self.kind == "imagenet":
            return "imagenet"
        if self.kind == "random":
            return f"random seed {self.seed}"
        assert self.path is not None
        return f"sha256 {file_sha256(self.path)}"

    def describe(self) -> str:
        if self.kind == "imagenet":
            return f"torchvision {IMAGENET_WEIGHTS!r} (ImageNet-1k, 1000 classes)"
        if self.kind == "random":
            return f"random initialisation (seed {self.seed}; NOT pretrained)"
        return f"checkpoint {self.path}"


def parse_weights(spec: str | os.PathLike[str] | WeightsSource, *, seed: int = 0) -> WeightsSource:
    """``"imagenet"``, ``"random"`` or a checkpoint path -> :class:`WeightsSource`.

    A path must exist (else :class:`WeightsNotFoundError` naming it).
    """
    if isinstance(spec, WeightsSource):
        return spec
    if isinstance(spec, str) and spec in ("imagenet", "random"):
        return WeightsSource(kind=spec, seed=int(seed))  # type: ignore[arg-type]
    path = Path(spec)
    if not path.is_file():
        weights = setting("weights", "--weights", "features")
        raise WeightsNotFoundError(
            f"{path}: backbone weights file not found ({weights} takes 'imagenet', 'random' or "
            "the path of an AlexNet state-dict checkpoint)"
        )
    return WeightsSource(kind="file", path=path)


def torchvision_cache_file() -> Path:
    """Where torchvision keeps ``AlexNet_Weights.IMAGENET1K_V1``:
    ``torch.hub.get_dir()/checkpoints/alexnet-owt-7be5be79.pth`` (``$TORCH_HOME/hub/...``)."""
    return Path(torch.hub.get_dir()) / "checkpoints" / Path(IMAGENET_WEIGHTS.url).name


LOCAL_WEIGHTS = setting("weights=PATH", "--weights PATH", "features")
"""How a message names a local state-dict checkpoint as the backbone, for a library caller
(``PlaceClassifier.load``; ``extract_features`` takes the model it built) and ``spcopyro features``;
``features-head`` names its own flags (its command rewrites the name, ``spcopyro.features.cli``)."""


def _missing_imagenet_message(cache_file: Path) -> str:
    download = setting("download=True", "--download", "features")
    random = setting("weights='random'", "--weights random", "features")
    return (
        f"AlexNet ImageNet weights not found: torchvision caches them as {cache_file} "
        f"(file {cache_file.name}; the folder is $TORCH_HOME/hub/checkpoints, $TORCH_HOME "
        f"defaulting to ~/.cache/torch). Get them on a machine with internet with "
        f"`python -c \"import torchvision; torchvision.models.alexnet(weights='IMAGENET1K_V1')\"` "
        f"(or pass {download}), or download {IMAGENET_WEIGHTS.url} and put it there; or give a "
        f"local state-dict checkpoint with {LOCAL_WEIGHTS}; or {random} (features then mean "
        "nothing)."
    )


def torch_load(path: Path, what: str) -> object:
    """``torch.load(path, weights_only=True)`` on the CPU; CheckpointError naming ``path`` when
    it fails. torch's own message advises ``weights_only=False`` ("will likely succeed"), which
    no option here sets; instead the message says what the file holds: a pickled object (a
    whole model saved with ``torch.save(model)``) or no torch file at all."""
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # torch raises many types for a bad file
        text = str(error)
        pickled = re.search(r"Unsupported global: GLOBAL ([\w.]+)", text)
        if pickled:
            reason = (
                f"it holds a pickled Python object ({pickled.group(1)}), not only tensors (a "
                "whole model saved with torch.save(model)?); files are read without running "
                "their code: where you trust it, load it and save its state dict, "
                "torch.save(model.state_dict(), path)"
            )
        elif isinstance(error, pickle.UnpicklingError):
            reason = "not a torch file: its bytes are no pickled tensors"
        else:
            first = next((line.strip() for line in text.splitlines() if line.strip()), "")
            cut = first if len(first) <= ECHO_LIMIT else f"{first[:ECHO_LIMIT]}..."
            reason = f"{type(error).__name__}: {cut}"
        raise CheckpointError(f"{path}: not a readable {what} ({reason})") from None


def load_state_dict_file(path: str | os.PathLike[str]) -> dict[str, torch.Tensor]:
    """Read a checkpoint file into a state dict (on the CPU, ``weights_only``: no code runs).

    Accepts a plain state dict, or a dict holding one under ``"state_dict"`` or ``"model"``;
    every ``module`` part of a key (left by ``nn.DataParallel``: ``module.features.0.weight``,
    or ``features.module.0.weight`` from PyTorch's ImageNet example and the Places365 models,
    which wrap only ``features``) is removed.

    Raises:
        WeightsNotFoundError: no such file.
        CheckpointError: not a torch file, or not a mapping of names to tensors.
    """
    path = Path(path)
    if not path.is_file():
        raise WeightsNotFoundError(f"{path}: checkpoint file not found")
    raw = torch_load(path, "torch checkpoint")
    if isinstance(raw, Mapping):
        for key in ("state_dict", "model"):
            if isinstance(raw.get(key), Mapping):
                raw = raw[key]
                break
    if not isinstance(raw, Mapping) or not raw:
        raise CheckpointError(
            f"{path}: expected a state dict (a mapping of parameter names to tensors), "
            f"got {type(raw).__name__}"
        )
    bad = [k for k, v in raw.items() if not isinstance(k, str) or not torch.is_tensor(v)]
    if bad:
        raise CheckpointError(f"{path}: entry {bad[0]!r} is not a named tensor")
    state = dict(raw)
    if any("module" in k.split(".") for k in state):
        state = {".".join(p for p in k.split(".") if p != "module"): v for k, v in state.items()}
    return state


def _alexnet_from_state_dict(state: Mapping[str, torch.Tensor], path: Path) -> AlexNet:
    """An AlexNet whose final layer has as many classes as the checkpoint's."""
    final_weight = state.get(f"{FINAL_LAYER}.weight")
    if final_weight is None or final_weight.ndim != 2:
        raise CheckpointError(
            f"{path}: not an AlexNet state dict: no 2-d {FINAL_LAYER}.weight (keys: "
            f"{', '.join(list(state)[:8])}{', ...' if len(state) > 8 else ''})"
        )
    model = alexnet(weights=None, num_classes=int(final_weight.shape[0]))
    expected = model.state_dict()
    missing = [k for k in expected if k not in state]
    unexpected = [k for k in state if k not in expected]
    if missing or unexpected:
        raise CheckpointError(
            f"{path}: does not fit torchvision's AlexNet: missing keys {missing}, "
            f"unexpected keys {unexpected}"
        )
    for key, tensor in expected.items():
        if state[key].shape != tensor.shape:
            caffe = key == "features.0.weight" and state[key].shape[0] == 96
            raise CheckpointError(
                f"{path}: {key} has shape {tuple(state[key].shape)}, AlexNet needs "
                f"{tuple(tensor.shape)}"
                + (
                    " (96 conv1 filters: the original Caffe AlexNet, another architecture "
                    "than torchvision's)"
                    if caffe
                    else ""
                )
            )
        if tensor.is_floating_point() and not torch.isfinite(state[key]).all():
            bad = int((~torch.isfinite(state[key])).sum())
            raise CheckpointError(
                f"{path}: {key} holds {bad} non-finite value(s) (NaN or inf) of "
                f"{state[key].numel()}: the weights are damaged (a diverged training run?)"
            )
    model.load_state_dict(state)
    return model


def _load_cached_imagenet(cache_file: Path) -> AlexNet:
    """torchvision's cached ImageNet file (torchvision itself would raise a bare unpickling
    error for a damaged one); CheckpointError naming it, and how to replace it."""
    try:
        model = _alexnet_from_state_dict(load_state_dict_file(cache_file), cache_file)
        if final_layer(model).out_features != 1000:
            raise CheckpointError(
                f"{cache_file}: {final_layer(model).out_features} classes, not 1000"
            )
    except CheckpointError as error:
        raise CheckpointError(
            f"{error} (the cached ImageNet weights are damaged: delete the file and get it "
            f"again from {IMAGENET_WEIGHTS.url})"
        ) from None
    return model


def load_alexnet(
    weights: str | os.PathLike[str] | WeightsSource = "imagenet",
    *,
    download: bool = False,
    seed: int = 0,
) -> AlexNet:
    """torchvision's AlexNet with the requested weights (module docstring), in eval mode, on CPU.

    Args:
        weights: ``"imagenet"``, ``"random"``, a checkpoint path, or a :class:`WeightsSource`.
        download: with ``"imagenet"``, let torchvision download the file when it is not cached
            (needs internet). Off by default: a missing file raises instead.
        seed: the seed of ``"random"`` weights (the global RNG is left untouched).

    Raises:
        WeightsNotFoundError: the ImageNet file is not cached (and no ``download``), or the
            checkpoint path does not exist; the message says how to get the weights.
        CheckpointError: a checkpoint (or the cached ImageNet file) that is unreadable or does
            not fit AlexNet.
    """
    source = parse_weights(weights, seed=seed)
    if source.kind == "imagenet":
        cache_file = torchvision_cache_file()
        if cache_file.is_file():  # read as torchvision would, with errors naming the file
            model = _load_cached_imagenet(cache_file)
        elif not download:
            raise WeightsNotFoundError(_missing_imagenet_message(cache_file))
        else:  # 233 MB: torch.hub's progress bar
            try:
                model = alexnet(weights=IMAGENET_WEIGHTS, progress=progress_enabled(None))
            except OSError as error:  # URLError: "<urlopen error [Errno -2] Name or service..."
                raise WeightsNotFoundError(
                    f"downloading {IMAGENET_WEIGHTS.url} into {cache_file} failed ({error}); "
                    "is there internet here? Otherwise download it elsewhere and put it there, "
                    f"or give a local state-dict checkpoint with {LOCAL_WEIGHTS}"
                ) from None
    elif source.kind == "random":
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(source.seed)
            model = alexnet(weights=None)
    else:
        assert source.path is not None
        model = _alexnet_from_state_dict(load_state_dict_file(source.path), source.path)
    return model.eval()


def final_layer(model: AlexNet) -> nn.Linear:
    """fc8, ``model.classifier[6]``: ``Linear(4096, num_classes)``."""
    layer = model.classifier[6]
    assert isinstance(layer, nn.Linear) and layer.in_features == FEATURE_DIM
    return layer
