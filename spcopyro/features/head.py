r"""The place head: AlexNet's final layer replaced by a classifier over K place classes, and its
fine-tuning with the backbone frozen (optionally its last fully connected layers too).

The network (torchvision's AlexNet) is split at fc7::

    image -> conv1..conv5 -> avgpool -> [Dropout, fc6, ReLU, Dropout, fc7, ReLU] -> head -> logits
             '-------------- frozen ------------'  '-- tunable: tune_layers 2 / 1 --'   fc8: K

``tune_layers`` = 0 trains only the head (a linear probe on the 4096 fc7 activations), 1 also
fc7, 2 also fc6. The frozen part runs once per image (:func:`frozen_inputs`); training then
touches only the tunable part, in train mode (its dropout active), on those cached activations.

The image feature of an image is the head's class histogram ``f = softmax(logits)`` (``[K]``,
sums to 1): what the paper's Ft.csv holds, with K = 205 Places205 classes.

Two training modes (:func:`train_head`):

* ``"labels"``: images labelled with place names (class indices y), cross-entropy
  ``-(1/N) sum_n log f_n[y_n]``;
* ``"distill"``: images paired with target histograms p_n (such as the dataset's Ft.csv rows),
  the mean Kullback-Leibler divergence ``(1/N) sum_n KL(p_n || f_n)
  = (1/N) sum_n sum_k p_nk (log p_nk - log f_nk)`` (0 log 0 = 0).

A new head starts at zero weights and biases, i.e. at the uniform histogram (loss log K for
balanced labels): no random draw is involved.

A trained head is saved on its own (:func:`save_head`, a small ``torch.save`` file of tensors
and strings, readable with ``weights_only=True``), with the tuned backbone layers when
``tune_layers`` > 0, and applied to a backbone with :func:`load_head`.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import torch
import torch.nn.functional as F
from torch import nn
from torchvision.models import AlexNet
from tqdm.auto import tqdm

from spcopyro._util.messages import setting
from spcopyro._util.outputs import replace_file
from spcopyro._util.progress import progress_enabled
from spcopyro.features.backbone import (
    FEATURE_DIM,
    LOCAL_WEIGHTS,
    CheckpointError,
    WeightsSource,
    final_layer,
    load_alexnet,
    parse_weights,
    torch_load,
)
from spcopyro.features.images import SPELT_TWICE, spelt_twice

__all__ = [
    "HEAD_FORMAT",
    "HeadFile",
    "PlaceClassifier",
    "TrainingResult",
    "encode_labels",
    "load_head",
    "save_head",
    "train_head",
]

HEAD_FORMAT = "spcopyro-place-head"
HEAD_VERSION = 1
TrainingMode = Literal["labels", "distill"]

# Where the tunable part of AlexNet's classifier starts, by tune_layers: index into
# classifier = [Dropout, fc6, ReLU, Dropout, fc7, ReLU, fc8].
_TUNABLE_START = {0: 6, 1: 3, 2: 0}
_TUNED_LAYER_NAMES = {0: (), 1: ("classifier.4",), 2: ("classifier.1", "classifier.4")}


class PlaceClassifier(nn.Module):
    """AlexNet with its final layer as a head over K classes: ``[N, 3, 224, 224] -> [N, K]``.

    Built from an AlexNet (:func:`~spcopyro.features.backbone.load_alexnet`); the head is its
    own final layer (fc8: 1000 ImageNet classes, or a checkpoint's own, such as the 365 of
    Places365) until :meth:`replace_head` or :func:`load_head` puts a place head there.

    Attributes:
        network: the AlexNet; ``network.classifier[6]`` is the head.
        class_names: ``[K]`` names of the head's classes, or None (then ``class_0``, ...).
        weights: where the backbone weights came from.
    """

    def __init__(
        self,
        network: AlexNet,
        *,
        weights: WeightsSource,
        class_names: Sequence[str] | None = None,
    ) -> None:
        super().__init__()
        self.network = network
        self.weights = weights
        self.class_names = None if class_names is None else tuple(class_names)
        self._check_names()
        self.tune_layers = 0

    @classmethod
    def load(
        cls,
        weights: str | os.PathLike[str] | WeightsSource = "imagenet",
        head: str | os.PathLike[str] | None = None,
        *,
        download: bool = False,
        seed: int = 0,
    ) -> PlaceClassifier:
        """The backbone from ``weights`` (see :func:`~spcopyro.features.backbone.load_alexnet`)
        with the head file ``head`` applied (:func:`load_head`), in eval mode."""
        source = parse_weights(weights, seed=seed)
        model = cls(load_alexnet(source, download=download), weights=source)
        if head is not None:
            load_head(model, head)
        return model.eval()

    @property
    def head(self) -> nn.Linear:
        return final_layer(self.network)

    @property
    def num_classes(self) -> int:
        """K."""
        return int(self.head.out_features)

    @property
    def names(self) -> tuple[str, ...]:
        """``[K]`` class names (``class_k`` where none are known)."""
        return self.class_names or tuple(f"class_{k}" for k in range(self.num_classes))

    def _check_names(self) -> None:
        if self.class_names is not None and len(self.class_names) != self.num_classes:
            raise ValueError(
                f"{len(self.class_names)} class names for a head of {self.num_classes} classes"
            )

    def replace_head(self, num_classes: int, class_names: Sequence[str] | None = None) -> None:
        """A new head ``Linear(4096, num_classes)``, zero weights and biases (uniform output)."""
        if num_classes < 1:
            raise ValueError(f"num_classes must be >= 1, got {num_classes}")
        old = self.head
        new = nn.Linear(FEATURE_DIM, num_classes, device=old.weight.device, dtype=old.weight.dtype)
        nn.init.zeros_(new.weight)
        nn.init.zeros_(new.bias)
        self.network.classifier[6] = new
        self.class_names = None if class_names is None else tuple(class_names)
        self._check_names()

    def prefix(self, pixels: torch.Tensor, tune_layers: int = 0) -> torch.Tensor:
        """The frozen part's output: ``[N, 3, 224, 224] -> [N, D]``, D = 4096 (tune_layers 0
        or 1: fc7 or fc6 activations) or 9216 (tune_layers 2: pooled conv5)."""
        net = self.network
        x = torch.flatten(net.avgpool(net.features(pixels)), 1)  # [N, 9216]
        return net.classifier[: _TUNABLE_START[tune_layers]](x)

    def suffix(self, inputs: torch.Tensor, tune_layers: int = 0) -> torch.Tensor:
        """The tunable part: :meth:`prefix` output ``[N, D]`` -> logits ``[N, K]``."""
        return self.network.classifier[_TUNABLE_START[tune_layers] :](inputs)

    def embed(self, pixels: torch.Tensor) -> torch.Tensor:
        """fc7 activations ``[N, 4096]`` (the head's input)."""
        return self.prefix(pixels, 0)

    def forward(self, pixels: torch.Tensor) -> torch.Tensor:
        """Logits ``[N, K]``."""
        return self.network(pixels)

    def probabilities(self, pixels: torch.Tensor) -> torch.Tensor:
        """Class histograms ``[N, K]``, ``softmax(logits)``: the image features."""
        return torch.softmax(self.forward(pixels), dim=1)


def encode_labels(place_names: Sequence[str]) -> tuple[tuple[str, ...], torch.Tensor]:
    """Place names -> (class names sorted, ``[N]`` int64 class index of each image).

    ValueError for an empty name, and for two spellings of one name (``Kitchen`` and
    ``kitchen``, ``living room`` and ``living  room``, full-width ``ＴＶ`` and ``TV``: equal
    under :func:`~spcopyro.data.text.fold_word` with their spaces collapsed), which would split
    one place into two classes.
    """
    names = [str(n).strip() for n in place_names]
    empty = [i for i, n in enumerate(names) if not n]
    if empty:
        raise ValueError(f"place name of image {empty[0]} is empty")
    classes = tuple(sorted(set(names)))
    twice = spelt_twice(names)
    if twice is not None:
        i, j = twice
        raise ValueError(
            f"one place written {names[i]!r} (image {i}) and {names[j]!r} (image {j}): "
            f"{SPELT_TWICE}"
        )
    index = {c: k for k, c in enumerate(classes)}
    return classes, torch.tensor([index[n] for n in names], dtype=torch.int64)


@dataclass
class TrainingResult:
    """What :func:`train_head` did.

    ``initial_loss`` / ``final_loss``: the loss over all training inputs in eval mode (dropout
    off) before and after training; ``epoch_losses``: the mean minibatch loss (train mode) of
    each epoch.
    """

    mode: TrainingMode
    tune_layers: int
    initial_loss: float
    final_loss: float
    epoch_losses: list[float] = field(default_factory=list)


def _check_targets(targets: torch.Tensor, mode: str, n: int, k: int) -> torch.Tensor:
    if mode == "labels":
        if targets.dtype != torch.int64 or targets.shape != (n,):
            raise ValueError(
                f"labels mode needs [N] = [{n}] int64 class indices, got "
                f"{tuple(targets.shape)} {targets.dtype}"
            )
        if n and (targets.min() < 0 or targets.max() >= k):
            raise ValueError(f"class index out of range 0..{k - 1}: {targets.tolist()}")
        return targets
    if mode != "distill":
        raise ValueError(f"mode must be 'labels' or 'distill', got {mode!r}")
    if targets.shape != (n, k):
        raise ValueError(
            f"distill mode needs [N, K] = [{n}, {k}] target histograms, got {tuple(targets.shape)}"
        )
    targets = targets.to(torch.float32)
    if not torch.isfinite(targets).all() or (targets < 0).any():
        raise ValueError("target histograms must be finite and >= 0")
    sums = targets.sum(dim=1, keepdim=True)  # [N, 1]
    if (sums <= 0).any():
        raise ValueError(f"target histogram {int((sums[:, 0] <= 0).nonzero()[0])} sums to 0")
    return targets / sums


def _loss(logits: torch.Tensor, targets: torch.Tensor, mode: str) -> torch.Tensor:
    if mode == "labels":
        return F.cross_entropy(logits, targets)
    return F.kl_div(torch.log_softmax(logits, dim=1), targets, reduction="batchmean")


def train_head(
    model: PlaceClassifier,
    inputs: torch.Tensor,
    targets: torch.Tensor,
    *,
    mode: TrainingMode,
    tune_layers: int = 0,
    epochs: int = 100,
    lr: float = 1e-3,
    batch_size: int = 32,
    weight_decay: float = 0.0,
    seed: int = 0,
    progress: bool | None = None,
) -> TrainingResult:
    """Fine-tune the head (and ``tune_layers`` last fc layers) on the frozen part's outputs.

    Args:
        model: its head must already have the wanted K classes (:meth:`replace_head`).
        inputs: ``[N, D]`` :meth:`PlaceClassifier.prefix` outputs for the same ``tune_layers``
            (:func:`spcopyro.features.extract.frozen_inputs` computes them from image files).
        targets: ``[N]`` int64 class indices (mode "labels") or ``[N, K]`` histograms (mode
            "distill"; each row is normalised to sum 1).
        epochs, lr, batch_size, weight_decay: Adam, minibatches reshuffled every epoch from
            ``seed`` (the global RNG is left untouched).
        progress: a progress bar over the epochs (default: on unless ``$CI`` is set); with
            fc6 tuned (``tune_layers`` 2) training takes minutes on a CPU.

    The model is left in eval mode; ``model.tune_layers`` records ``tune_layers``.
    """
    if tune_layers not in _TUNABLE_START:
        raise ValueError(f"tune_layers must be 0, 1 or 2, got {tune_layers}")
    if epochs < 0 or batch_size < 1:
        raise ValueError(f"epochs must be >= 0 and batch_size >= 1, got {epochs}, {batch_size}")
    n = int(inputs.shape[0])
    if n == 0:
        raise ValueError("no training inputs")
    targets = _check_targets(targets, mode, n, model.num_classes)
    device = model.head.weight.device
    inputs, targets = inputs.to(device), targets.to(device)
    params = list(model.network.classifier[_TUNABLE_START[tune_layers] :].parameters())
    for p in model.parameters():
        p.requires_grad_(False)
    for p in params:
        p.requires_grad_(True)

    def full_loss() -> float:
        model.eval()
        with torch.no_grad():
            return float(_loss(model.suffix(inputs, tune_layers), targets, mode))

    initial = full_loss()
    optimizer = torch.optim.Adam(params, lr=lr, weight_decay=weight_decay)
    generator = torch.Generator().manual_seed(int(seed))
    epoch_losses = []
    bar = tqdm(
        total=epochs, desc="training head", unit="epoch", disable=not progress_enabled(progress)
    )
    with bar, torch.random.fork_rng(devices=[device] if device.type == "cuda" else []):
        torch.manual_seed(int(seed))  # dropout masks of the tunable layers
        for _ in range(epochs):
            model.train()
            order = torch.randperm(n, generator=generator).to(device)  # [N]
            total = 0.0
            for start in range(0, n, batch_size):
                batch = order[start : start + batch_size]
                loss = _loss(model.suffix(inputs[batch], tune_layers), targets[batch], mode)
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                total += float(loss.detach()) * len(batch)
            epoch_losses.append(total / n)
            bar.set_postfix(loss=f"{total / n:.4f}", refresh=False)
            bar.update()
    for p in model.parameters():
        p.requires_grad_(False)
    model.tune_layers = tune_layers
    final = full_loss()
    return TrainingResult(mode, tune_layers, initial, final, epoch_losses)


@dataclass(frozen=True)
class HeadFile:
    """What a head file holds besides the tensors: its classes and how it was trained."""

    path: Path
    class_names: tuple[str, ...]
    tune_layers: int
    backbone: str  # description of the backbone weights it was trained on
    mode: str
    note: str


def save_head(
    model: PlaceClassifier,
    path: str | os.PathLike[str],
    *,
    mode: str = "",
    note: str = "",
) -> Path:
    """Write the head (and the layers tuned with it, ``model.tune_layers``) to ``path``."""
    path = Path(path)
    state = model.network.state_dict()
    layers = ("classifier.6", *_TUNED_LAYER_NAMES[model.tune_layers])
    tensors = {
        k: v.detach().cpu().clone()
        for k, v in state.items()
        if any(k.startswith(f"{layer}.") for layer in layers)
    }
    payload = {
        "format": HEAD_FORMAT,
        "version": HEAD_VERSION,
        "class_names": list(model.names),
        "tune_layers": model.tune_layers,
        "backbone": model.weights.describe(),
        "backbone_fingerprint": model.weights.fingerprint(),
        "mode": mode,
        "note": note,
        "state_dict": tensors,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    replace_file(path, lambda file: torch.save(payload, file))  # whole or not at all
    return path


def load_head(model: PlaceClassifier, path: str | os.PathLike[str]) -> HeadFile:
    """Put the head saved in ``path`` (:func:`save_head`) onto ``model``'s backbone.

    Warns (logger ``"spcopyro"``) when the head was trained on another backbone than
    ``model``'s (:meth:`~spcopyro.features.backbone.WeightsSource.fingerprint`: a checkpoint's
    bytes, not its path): its classes would read features it never saw.

    Raises:
        FileNotFoundError: no such file.
        CheckpointError: not a head file (wrong format tag or version, bad shapes); the
            message names the file.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: head file not found")
    payload = torch_load(path, "head file")
    if not isinstance(payload, dict) or payload.get("format") != HEAD_FORMAT:
        raise CheckpointError(
            f"{path}: not an spcopyro place-head file (written by save_head / "
            f"`spcopyro features-head`); for backbone weights use {LOCAL_WEIGHTS}"
        )
    if payload.get("version") != HEAD_VERSION:
        raise CheckpointError(f"{path}: head file version {payload.get('version')!r} unsupported")
    tune_layers = payload.get("tune_layers")
    state = payload.get("state_dict")
    names = payload.get("class_names")
    if tune_layers not in _TUNED_LAYER_NAMES or not isinstance(state, dict):
        raise CheckpointError(
            f"{path}: malformed head file (tune_layers {tune_layers!r}, state_dict "
            f"{type(state).__name__})"
        )
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise CheckpointError(
            f"{path}: class_names must be a list of strings",
        )
    names = tuple(names)
    weight = state.get("classifier.6.weight")
    if weight is None or tuple(weight.shape) != (len(names), FEATURE_DIM):
        raise CheckpointError(
            f"{path}: classifier.6.weight must be [{len(names)}, {FEATURE_DIM}], got "
            f"{None if weight is None else tuple(weight.shape)}"
        )
    device = model.head.weight.device
    model.replace_head(len(names), names)
    current = model.network.state_dict()
    expected = {
        k for k in current if any(k.startswith(f"{layer}.") for layer in _TUNED_LAYER_NAMES[2])
    }
    for key, tensor in state.items():
        if key not in current or current[key].shape != tensor.shape:
            raise CheckpointError(
                f"{path}: {key} {tuple(tensor.shape)} does not fit AlexNet "
                f"({tuple(current[key].shape) if key in current else 'no such layer'})"
            )
        if not torch.isfinite(tensor).all():
            raise CheckpointError(
                f"{path}: {key} holds non-finite values (NaN or inf): the head's training "
                "diverged (retrain it with a smaller --lr)"
            )
    tuned = {k for k in state if not k.startswith("classifier.6.")}
    wanted = {
        k for k in expected if any(k.startswith(f"{n}.") for n in _TUNED_LAYER_NAMES[tune_layers])
    }
    if tuned != wanted:
        raise CheckpointError(
            f"{path}: tune_layers {tune_layers} needs tuned tensors {sorted(wanted)}, the file "
            f"holds {sorted(tuned)}"
        )
    model.network.load_state_dict(state, strict=False)
    model.network.to(device)
    model.tune_layers = tune_layers
    trained_on, backbone = str(payload.get("backbone", "")), model.weights.describe()
    fingerprint = payload.get("backbone_fingerprint")  # absent from older head files
    if fingerprint is None:  # compare the descriptions, paths as given
        other = bool(trained_on) and trained_on != backbone
    else:
        other = fingerprint != model.weights.fingerprint()
    if other:
        same_name = " (same name, other contents)" if trained_on == backbone else ""
        given = setting("weights", "--weights", "features")  # load_head runs under `features`
        if trained_on.startswith("random"):  # random weights are their seed's
            given += f" and its seed as {setting('seed', '--seed', 'features')}"
        logging.getLogger("spcopyro").warning(
            "head file %s was trained on the backbone %s; this model's is %s%s: unless they "
            "are the same weights, its place classes read features it was not trained on; "
            "pass the head's backbone as %s",
            path, trained_on, backbone, same_name, given,
        )  # fmt: skip
    return HeadFile(
        path=path,
        class_names=names,
        tune_layers=tune_layers,
        backbone=str(payload.get("backbone", "")),
        mode=str(payload.get("mode", "")),
        note=str(payload.get("note", "")),
    )
