"""Batch extraction of image features: a folder of images -> Ft.csv rows.

Each image becomes one row, the place head's class histogram ``softmax(logits)`` (``[K]``), in
the order of :func:`~spcopyro.features.images.list_images` (for a house folder, the order
:func:`spcopyro.data.load_house` pairs Ft.csv rows with ``img_K/`` images). The file is the
dataset's layout: K comma-separated numbers per line, written with ``repr`` (full precision,
they read back exactly), so ``spcopyro fit`` reads it like the dataset's own Ft.csv.

The model runs in eval mode under ``torch.inference_mode``: on the CPU the same images give the
same numbers, bit for bit, on every run with the same batch size (other batch sizes agree to
float32 rounding). Unreadable images are collected and reported all together, with their paths
(:class:`~spcopyro.features.images.UnreadableImagesError`); nothing is written then.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from spcopyro._util.messages import setting
from spcopyro._util.outputs import check_folder_path, replace_text
from spcopyro._util.progress import progress_enabled
from spcopyro.features.backbone import WeightsSource
from spcopyro.features.head import PlaceClassifier
from spcopyro.features.images import UnreadableImagesError, iter_image_batches, list_images

__all__ = [
    "ExtractionResult",
    "check_out_file",
    "extract_features",
    "extract_to_csv",
    "frozen_inputs",
    "resolve_device",
    "write_features_csv",
]

DEFAULT_BATCH_SIZE = 32


def resolve_device(device: str | torch.device) -> torch.device:
    """``"cpu"``, ``"cuda"`` or ``"cuda:N"`` -> a device; ValueError if CUDA is not available."""
    try:
        resolved = torch.device(device)
    except RuntimeError as error:
        raise ValueError(f"unknown device {device!r}: {error}") from None
    if resolved.type not in ("cpu", "cuda"):
        raise ValueError(f"device must be cpu or cuda, got {device!r}")
    if resolved.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device {device!r} requested but CUDA is not available here; use cpu")
    return resolved


def _map_batches(
    model: PlaceClassifier,
    paths: Sequence[Path],
    compute: Callable[[torch.Tensor], torch.Tensor],
    *,
    batch_size: int,
    device: str | torch.device,
    progress: bool | None,
    desc: str,
) -> torch.Tensor:
    """``compute`` on every batch of preprocessed images -> concatenated ``[N, ...]`` on CPU.

    After a first unreadable image the model is not run any more, but every remaining image is
    still decoded, so that the error lists all of them.
    """
    if not paths:
        raise ValueError("no images given")
    device = resolve_device(device)
    model.to(device).eval()
    outputs: list[torch.Tensor] = []
    failures: list[tuple[Path, str]] = []
    bar = tqdm(total=len(paths), desc=desc, unit="img", disable=not progress_enabled(progress))
    with bar, torch.inference_mode():
        for batch in iter_image_batches(paths, batch_size):
            failures.extend(batch.failures)
            if not failures:
                assert batch.pixels is not None
                outputs.append(compute(batch.pixels.to(device)).float().cpu())
            bar.update(len(batch.paths))
    if failures:
        raise UnreadableImagesError(failures, len(paths))
    return torch.cat(outputs)


def extract_features(
    model: PlaceClassifier,
    paths: Sequence[str | os.PathLike[str]],
    *,
    batch_size: int = DEFAULT_BATCH_SIZE,
    device: str | torch.device = "cpu",
    progress: bool | None = None,
) -> np.ndarray:
    """``[T, K]`` float64 class histograms ``softmax(logits)`` of the images ``paths``, in order.

    Raises:
        UnreadableImagesError: listing every image that could not be read (missing, not an
            image, truncated), with its path.
        ValueError: no paths, a bad device or batch size, or an output that is not finite
            (naming the image; damaged weights).
    """
    paths = [Path(p) for p in paths]
    probabilities = _map_batches(
        model,
        paths,
        model.probabilities,
        batch_size=batch_size,
        device=device,
        progress=progress,
        desc="image features",
    )  # [T, K] float32
    finite = torch.isfinite(probabilities).all(dim=1)  # [T] bool
    if not finite.all():
        first = int((~finite).nonzero()[0])
        raise ValueError(
            f"{paths[first]}: the network's output is not finite (NaN or inf) for this image "
            f"and {int((~finite).sum()) - 1} other(s): the backbone weights or the head are "
            "damaged (nothing was written)"
        )
    return probabilities.double().numpy()


def frozen_inputs(
    model: PlaceClassifier,
    paths: Sequence[str | os.PathLike[str]],
    *,
    tune_layers: int = 0,
    batch_size: int = DEFAULT_BATCH_SIZE,
    device: str | torch.device = "cpu",
    progress: bool | None = None,
) -> torch.Tensor:
    """``[N, D]`` float32 outputs of the frozen part (:meth:`PlaceClassifier.prefix`), computed
    once per image for :func:`~spcopyro.features.head.train_head`."""
    paths = [Path(p) for p in paths]
    return _map_batches(
        model,
        paths,
        lambda pixels: model.prefix(pixels, tune_layers),
        batch_size=batch_size,
        device=device,
        progress=progress,
        desc="backbone activations",
    )


def check_out_file(
    path: str | os.PathLike[str], *, overwrite: bool = False, command: str = "features"
) -> Path:
    """Check, before any work, that a file may be written at ``path``; writes nothing.

    ``command``: the ``spcopyro`` command whose ``--overwrite`` the refusal names beside the
    keyword (``"features-head"`` for a head file).

    Raises:
        IsADirectoryError: ``path`` is a folder (the file to write goes inside it).
        NotADirectoryError: a part of ``path``'s folder is a file.
        PermissionError: the folder (or its nearest existing parent) is not writable.
        FileExistsError: ``path`` exists and ``overwrite`` is False.
    """
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"{path}: a folder, not a file: give the file to write in it")
    existing = check_folder_path(path.parent, str(path))
    if not os.access(existing, os.W_OK | os.X_OK):
        raise PermissionError(f"{path}: cannot write in {existing}")
    if path.exists() and not overwrite:
        given = setting("overwrite=True", "--overwrite", command)
        raise FileExistsError(f"{path} already exists; pass {given} to replace it")
    return path


def write_features_csv(
    path: str | os.PathLike[str], features: np.ndarray, *, overwrite: bool = False
) -> Path:
    """Write ``[T, K]`` features as Ft.csv: one comma-separated row per image, ``repr`` floats.

    The file is written whole or not at all (an interrupted write leaves the old file).

    Raises:
        FileExistsError, IsADirectoryError, ...: as :func:`check_out_file`.
        ValueError: not a non-empty 2-d array of finite values >= 0.
    """
    path = Path(path)
    features = np.asarray(features, dtype=np.float64)  # [T, K]
    if features.ndim != 2 or features.shape[0] == 0 or features.shape[1] == 0:
        raise ValueError(f"{path}: features must be a non-empty [T, K] array, got {features.shape}")
    if not np.isfinite(features).all() or (features < 0).any():
        row, col = np.argwhere(~np.isfinite(features) | (features < 0))[0]
        raise ValueError(f"{path}: feature [{row}, {col}] is not finite or negative")
    check_out_file(path, overwrite=overwrite)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = "\n".join(",".join(map(repr, row)) for row in features.tolist()) + "\n"
    replace_text(path, text)  # whole or not at all
    return path


@dataclass(frozen=True)
class ExtractionResult:
    """What :func:`extract_to_csv` wrote: ``features`` ``[T, K]`` for ``paths`` ``[T]``."""

    out: Path
    paths: tuple[Path, ...]
    features: np.ndarray  # [T, K] float64
    class_names: tuple[str, ...]
    weights: WeightsSource


def extract_to_csv(
    images: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    weights: str | os.PathLike[str] | WeightsSource = "imagenet",
    head: str | os.PathLike[str] | None = None,
    batch_size: int = DEFAULT_BATCH_SIZE,
    device: str | torch.device = "cpu",
    download: bool = False,
    overwrite: bool = False,
    progress: bool | None = None,
    model: PlaceClassifier | None = None,
    seed: int = 0,
) -> ExtractionResult:
    """What ``spcopyro features IMAGES --out Ft.csv`` does: list the images of a folder
    (:func:`~spcopyro.features.images.list_images`), run the network, write Ft.csv.

    Without ``head`` the rows are the backbone's own final layer: 1000 ImageNet classes for
    ``"imagenet"``, 365 for the Places365 AlexNet checkpoint. ``seed``: that of ``"random"``
    weights. ``model`` (already built) replaces ``weights`` / ``head`` / ``download`` / ``seed``.
    """
    paths = list_images(images)
    resolve_device(device)  # a bad device fails before the weights are loaded
    out = check_out_file(out, overwrite=overwrite)  # fail before the work, not after
    if model is None:
        model = PlaceClassifier.load(weights, head, download=download, seed=seed)
    features = extract_features(
        model, paths, batch_size=batch_size, device=device, progress=progress
    )
    write_features_csv(out, features, overwrite=overwrite)
    return ExtractionResult(
        out=out,
        paths=tuple(paths),
        features=features,
        class_names=model.names,
        weights=model.weights,
    )
