r"""Distillation report: how closely a place head on this backbone reproduces the paper's features.

The public dataset pairs every camera image with the paper's Places205 histogram (its Ft.csv
rows, in the images' order). :func:`distillation_report` trains a 205-class head on the images of
some trials with those histograms as targets (mode "distill" of
:func:`~spcopyro.features.head.train_head`) and measures, on a held-out trial,

* the mean Kullback-Leibler divergence :math:`\frac1N \sum_n KL(p_n \| f_n)` in nats between the
  paper's histogram p_n and the head's f_n (:func:`kl_divergence`; 0 is a perfect copy), and
* the top-1 agreement: the share of held-out images whose most probable class is the same in
  both (:func:`top1_agreement`).

Two image-blind baselines frame the numbers: the uniform histogram (KL = log K - H(p_n)) and the
mean training histogram (the best constant prediction).

**What the numbers mean.** With random backbone weights (``--weights random``; no pretrained
file on this machine) the backbone's activations are random functions of the pixels (colour and
texture statistics at best), not learnt place features: the head then does little better than
the mean-histogram baseline, and the numbers say nothing about how well the paper's features
can be reproduced. With torchvision's ImageNet AlexNet the head is a linear probe on ImageNet
fc7 activations; only a converted Places205 AlexNet can reproduce the paper's features closely.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from spcopyro.data import House
from spcopyro.features.backbone import WeightsSource
from spcopyro.features.extract import DEFAULT_BATCH_SIZE, frozen_inputs
from spcopyro.features.head import PlaceClassifier, TrainingResult, train_head
from spcopyro.features.images import list_images

__all__ = ["DistillationReport", "distillation_report", "kl_divergence", "top1_agreement"]

RANDOM_WEIGHTS_NOTE = (
    "The backbone has RANDOM weights (not pretrained): its activations are random functions of "
    "the pixels, not learnt place features, so these numbers mean little; compare them with the "
    "image-blind baselines. "
    "Use pretrained weights (--weights imagenet, or a converted Places205 AlexNet checkpoint) "
    "for a meaningful report."
)
PRETRAINED_NOTE = (
    "The head is a linear map on the backbone's fc7 activations{tuned}; how close it gets "
    "depends on how much place information those activations hold (ImageNet weights: some; a "
    "converted Places205 AlexNet: the paper's own network)."
)


def kl_divergence(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``[N]`` KL(p_n || q_n) = sum_k p_nk (log p_nk - log q_nk) in nats, for ``[N, K]``
    histograms (each row normalised to sum 1 first; 0 log 0 = 0; inf where q = 0 < p)."""
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if p.shape != q.shape or p.ndim != 2:
        raise ValueError(f"p and q must be [N, K] of one shape, got {p.shape} and {q.shape}")
    p = p / p.sum(axis=1, keepdims=True)
    q = q / q.sum(axis=1, keepdims=True)
    support = p > 0  # [N, K] bool
    with np.errstate(divide="ignore"):  # log 0 = -inf where q = 0 < p: KL = inf
        log_ratio = np.log(np.where(support, p, 1.0)) - np.log(np.where(support, q, 1.0))
    terms = np.where(support, p * log_ratio, 0.0)  # [N, K]
    return terms.sum(axis=1)


def top1_agreement(p: np.ndarray, q: np.ndarray) -> float:
    """Share of rows whose argmax (first one on ties) is the same in ``p`` and ``q`` ``[N, K]``."""
    p, q = np.asarray(p), np.asarray(q)
    if p.shape != q.shape or p.ndim != 2 or p.shape[0] == 0:
        raise ValueError(f"p and q must be non-empty [N, K] of one shape: {p.shape}, {q.shape}")
    return float(np.mean(p.argmax(axis=1) == q.argmax(axis=1)))


@dataclass
class DistillationReport:
    """The held-out scores of a distilled head (module docstring); ``model`` is the trained one."""

    house: str
    weights: str
    pretrained: bool
    train_trials: tuple[int, ...]
    held_out_trial: int
    num_train: int
    num_test: int
    num_classes: int
    tune_layers: int
    kl: float  # mean KL(paper || head) over held-out images, nats
    top1: float  # top-1 agreement on held-out images
    uniform_kl: float
    mean_kl: float  # mean training histogram as the prediction
    mean_top1: float
    training: TrainingResult
    model: PlaceClassifier = field(repr=False)

    def text(self) -> str:
        """A plain-text report, with what the numbers mean."""
        tuned = {0: "", 1: " (fc7 tuned too)", 2: " (fc6 and fc7 tuned too)"}[self.tune_layers]
        note = RANDOM_WEIGHTS_NOTE if not self.pretrained else PRETRAINED_NOTE.format(tuned=tuned)
        lines = [
            f"distillation of house {self.house}'s Ft.csv ({self.num_classes} classes)",
            f"backbone         {self.weights}",
            f"training         trials {list(self.train_trials)}: {self.num_train} images; "
            f"loss {self.training.initial_loss:.4f} -> {self.training.final_loss:.4f} "
            f"(KL, nats, {len(self.training.epoch_losses)} epochs)",
            f"held out         trial {self.held_out_trial}: {self.num_test} images",
            f"                 {'KL (nats)':>10} {'top-1 agreement':>16}",
            f"  head           {self.kl:>10.4f} {self.top1:>16.3f}",
            f"  mean histogram {self.mean_kl:>10.4f} {self.mean_top1:>16.3f}   (image-blind)",
            f"  uniform        {self.uniform_kl:>10.4f} {'-':>16}   (image-blind)",
            f"note: {note}",
        ]
        return "\n".join(lines)


def _first_per_trial(trial: np.ndarray, wanted: Sequence[int], limit: int | None) -> np.ndarray:
    """Indices of the images of the ``wanted`` trials, at most ``limit`` (the first) per trial."""
    picked = []
    for k in wanted:
        rows = np.flatnonzero(trial == k)  # [n_k]
        picked.append(rows if limit is None else rows[:limit])
    return np.concatenate(picked) if picked else np.zeros(0, dtype=np.int64)


def _why_no_images(house: House) -> str:
    """Why load_house paired no images with the rows (it only logs it): list_images' error
    on the house folder names the folder and the image or trial that does not fit."""
    if house.source is None or not Path(house.source).is_dir():
        return "the house was not loaded from a folder with img_K/ folders"
    try:
        list_images(house.source)
    except (OSError, ValueError) as error:
        return str(error)
    return "its img_K/ folders do not hold one image per Ft.csv row of their trial"


def distillation_report(
    house: House,
    *,
    weights: str | os.PathLike[str] | WeightsSource = "imagenet",
    model: PlaceClassifier | None = None,
    held_out_trial: int | None = None,
    train_trials: Sequence[int] | None = None,
    tune_layers: int = 0,
    epochs: int = 100,
    lr: float = 1e-3,
    batch_size: int = DEFAULT_BATCH_SIZE,
    device: str | torch.device = "cpu",
    download: bool = False,
    seed: int = 0,
    max_images_per_trial: int | None = None,
    progress: bool | None = None,
) -> DistillationReport:
    """Train a head on ``train_trials`` (default: all but the held-out one) to reproduce the
    house's Ft.csv histograms from its images, and score it on ``held_out_trial`` (default: the
    last trial).

    **With random backbone weights the numbers mean little** (module docstring): the report's
    text says so, and shows image-blind baselines to compare with.

    Args:
        house: a house with camera images (``observations.image_paths``), e.g. from
            :func:`spcopyro.data.load_house` on a dataset folder.
        weights: backbone weights (``"imagenet"``, ``"random"``, a checkpoint path), unless
            ``model`` is given (its head is replaced).
        max_images_per_trial: use only the first images of each trial (a quick run).

    Raises:
        ValueError: the house has no image paths, or fewer than two trials / bad trial ids, or
            ``max_images_per_trial`` < 1.
        UnreadableImagesError, WeightsNotFoundError: as in extraction.
    """
    if max_images_per_trial is not None and max_images_per_trial < 1:  # -2 dropped the last 2
        raise ValueError(f"max_images_per_trial must be >= 1 (or None), got {max_images_per_trial}")
    obs = house.observations
    if obs.image_paths is None:
        raise ValueError(
            f"house {house.name!r} ({house.source}): no camera images paired with its Ft.csv "
            f"rows to distil: {_why_no_images(house)}"
        )
    trials = sorted({int(t) for t in obs.image_trial})
    if len(trials) < 2 and held_out_trial is None and train_trials is None:
        raise ValueError(
            f"house {house.name!r}: its images are one trial ({trials[0]}), and distillation "
            "trains on some trials and holds out another to report on: record two trials (a "
            "pose_K.csv, word_K.csv and img_K/ each), or train a head on IMAGE,PLACE labels "
            "(spcopyro features-head labels.csv)"
        )
    held_out = trials[-1] if held_out_trial is None else int(held_out_trial)
    train = [t for t in trials if t != held_out] if train_trials is None else list(train_trials)
    unknown = sorted(({held_out} | set(train)) - set(trials))
    if unknown or held_out in train or not train:
        raise ValueError(
            f"house {house.name!r}: held-out trial {held_out} and training trials {train} must "
            f"be distinct trials among {trials}"
        )
    train_rows = _first_per_trial(obs.image_trial, train, max_images_per_trial)  # [N_train]
    test_rows = _first_per_trial(obs.image_trial, [held_out], max_images_per_trial)  # [N_test]
    targets = obs.image_features  # [T, K] float64
    paths = obs.image_paths
    empty = targets.sum(axis=1) <= 0  # [T] bool: rows with no histogram to imitate
    picked = np.concatenate([train_rows, test_rows])  # [N_train + N_test]
    left_out = picked[empty[picked]]
    if left_out.size:  # train_head refused them after all the activations, by a subset index
        logging.getLogger("spcopyro").warning(
            "house %r: %d image(s) left out of the distillation: their Ft.csv rows are all zero "
            "(lines %s), no histogram to imitate",
            house.name, left_out.size,
            ", ".join(str(i + 1) for i in left_out[:5]) + (", ..." if left_out.size > 5 else ""),
        )  # fmt: skip
        train_rows, test_rows = train_rows[~empty[train_rows]], test_rows[~empty[test_rows]]
        if not train_rows.size or not test_rows.size:
            raise ValueError(
                f"house {house.name!r}: every {'training' if not train_rows.size else 'held-out'} "
                "image's Ft.csv row is all zero: nothing to distil"
            )

    if model is None:
        model = PlaceClassifier.load(weights, download=download, seed=seed)
    model.replace_head(obs.num_feature_classes)
    all_rows = np.concatenate([train_rows, test_rows])
    inputs = frozen_inputs(
        model,
        [paths[i] for i in all_rows],
        tune_layers=tune_layers,
        batch_size=batch_size,
        device=device,
        progress=progress,
    )  # [N_train + N_test, D]
    train_inputs, test_inputs = inputs[: len(train_rows)], inputs[len(train_rows) :]
    training = train_head(
        model,
        train_inputs,
        torch.as_tensor(targets[train_rows], dtype=torch.float32),
        mode="distill",
        tune_layers=tune_layers,
        epochs=epochs,
        lr=lr,
        batch_size=batch_size,
        seed=seed,
        progress=progress,
    )
    model.eval()
    with torch.no_grad():
        logits = model.suffix(test_inputs.to(model.head.weight.device), tune_layers)
        predicted = torch.softmax(logits.double(), dim=1).cpu().numpy()  # [N_test, K]
    truth = targets[test_rows]  # [N_test, K]
    mean_hist = targets[train_rows].mean(axis=0, keepdims=True)  # [1, K]
    mean_pred = np.repeat(mean_hist, len(test_rows), axis=0)  # [N_test, K]
    uniform = np.full_like(truth, 1.0 / truth.shape[1])  # [N_test, K]
    return DistillationReport(
        house=house.name,
        weights=model.weights.describe(),
        pretrained=model.weights.pretrained,
        train_trials=tuple(train),
        held_out_trial=held_out,
        num_train=len(train_rows),
        num_test=len(test_rows),
        num_classes=obs.num_feature_classes,
        tune_layers=tune_layers,
        kl=float(kl_divergence(truth, predicted).mean()),
        top1=top1_agreement(truth, predicted),
        uniform_kl=float(kl_divergence(truth, uniform).mean()),
        mean_kl=float(kl_divergence(truth, mean_pred).mean()),
        mean_top1=top1_agreement(truth, mean_pred),
        training=training,
        model=model,
    )
