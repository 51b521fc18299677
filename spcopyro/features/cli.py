"""The ``spcopyro features`` and ``spcopyro features-head`` commands.

:func:`add_parser` registers both on the main parser's subparsers; torch and torchvision are
imported only when one of them runs, so other commands start as fast as before.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from spcopyro._util.arguments import integer_at_least, positive_number, seed

__all__ = ["add_parser", "features_command", "imagenet_cache_file"]

IMAGENET_FILE = "alexnet-owt-7be5be79.pth"
"""The file of torchvision's ``AlexNet_Weights.IMAGENET1K_V1`` in its cache
(:func:`spcopyro.features.backbone.torchvision_cache_file`)."""

WEIGHTS_HELP = (
    "backbone weights: 'imagenet' (torchvision's AlexNet_Weights.IMAGENET1K_V1, read from "
    "$TORCH_HOME/hub/checkpoints; see --download), 'random' (no pretrained weights: features "
    "mean nothing), or the path of a state-dict checkpoint of torchvision's AlexNet (e.g. "
    "alexnet_places365.pth.tar; the original Caffe AlexNet does not fit). Default: imagenet"
)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--weights", default="imagenet", help=WEIGHTS_HELP)
    p.add_argument(
        "--batch", type=integer_at_least(1), default=32, help="images per batch (default 32)"
    )
    p.add_argument("--device", default="cpu", help="cpu or cuda (default cpu)")
    p.add_argument(
        "--download",
        action="store_true",
        help="let torchvision download the ImageNet weights when not cached (needs internet)",
    )


def imagenet_cache_file() -> Path:
    """Where torchvision keeps the ImageNet weights ``features`` reads by default, without
    importing torch (:func:`spcopyro.features.backbone.torchvision_cache_file`, ``torch.hub``'s
    rule: ``$TORCH_HOME``, else ``$XDG_CACHE_HOME/torch``, else ``~/.cache/torch``, then
    ``hub/checkpoints``)."""
    import os

    cache = os.getenv("XDG_CACHE_HOME", "~/.cache")
    home = Path(os.getenv("TORCH_HOME", os.path.join(cache, "torch"))).expanduser()
    return home / "hub" / "checkpoints" / IMAGENET_FILE


def features_command(images: Path, out: Path) -> tuple[str, str | None]:
    """The ``spcopyro features`` command that writes ``out`` from the image folder ``images``
    as printed, and a note on its weights (None when there is nothing to say): the ImageNet
    weights where torchvision has them cached (:func:`imagenet_cache_file`); else ``--weights
    random`` (``features`` stops offline without the file), with how to get them."""
    command = f"spcopyro features {shlex.quote(str(images))} --out {shlex.quote(str(out))}"
    cached = imagenet_cache_file()
    if cached.is_file():
        return f"{command} --weights imagenet", None
    return f"{command} --weights random", (
        f"no ImageNet weights in {cached.parent}: random weights try the pipeline only (the "
        "features mean nothing); --weights imagenet --download fetches them (233 MB, needs "
        "internet) for learnt place features"
    )


def _random_warning(weights: str) -> None:
    if weights == "random":
        print(
            "warning: --weights random: the backbone is not pretrained, its features are not "
            "learnt place features (fine for testing the pipeline only)",
            file=sys.stderr,
        )


def floor100_note(features, out: str | Path) -> str | None:
    """A note on what ``floor100`` (floor(100 f): presets ``auto`` and ``original-code``, and
    the refinement of the default preset ``coarse`` on the map's cells) would leave of the
    histograms ``features`` ``[T, K]`` written to ``out``, and what to fit with: None when it
    empties no row and keeps at least half of a row's mass in median. A histogram over 1000
    ImageNet classes often has every entry below 0.01 (``--weights random``: all of them),
    which floor(100 f) makes an all-zero row. The default fit reads them as probabilities, and
    its ``--refine auto`` does not refine where more than
    :data:`~spcopyro.data.count_checks.KEEPS` of the rows would be emptied: nothing to do there;
    else the refinement, where it runs, counts them as floor(100 f), and ``--refine never``
    keeps them as probabilities."""
    import numpy as np

    from spcopyro.data.counts import KEEPS, scale_features, scaled_away

    f = np.asarray(features, dtype=np.float64)  # [T, K]
    if f.size == 0:
        return None
    total = f.sum(axis=1)  # [T]
    scaled = scale_features(f, "floor100")  # [T, K]
    kept = scaled.sum(axis=1) / 100.0  # [T] mass left by floor(100 f)
    share = np.divide(kept, total, out=np.ones_like(total), where=total > 0)  # [T]
    empty = scaled_away(f, scaled)  # [n] rows floor(100 f) empties
    median = float(np.median(share))
    if not empty.size and median >= 0.5:
        return None
    lines = ", ".join(str(i + 1) for i in empty[:5].tolist()) + (", ..." if empty.size > 5 else "")
    emptied = (
        f"leaves nothing of {empty.size} of {f.shape[0]} rows (every value below 0.01: "
        f"line{'s' if empty.size > 1 else ''} {lines} of {out}) and "
        if empty.size
        else ""
    )
    counted = (f"floor(100 f), the counting of --preset auto and original-code and of the "
               f"default fit's refinement on the map's cells, {emptied}keeps {100 * median:.0f}% "
               "of a row's mass in median")  # fmt: skip
    others = ("with --preset auto or original-code add --feature-scaling probability (or a "
              "number s, counting s * f)")  # fmt: skip
    if empty.size > KEEPS * f.shape[0]:
        return (f"{counted}. The default fit needs nothing: preset coarse reads these "
                f"{f.shape[1]}-class rows as probabilities, and --refine auto does not refine "
                "where floor(100 f) would leave out more than half of them (its 'not refined' "
                f"line says so); {others}")  # fmt: skip
    return (f"{counted}. The default fit (preset coarse) reads these {f.shape[1]}-class rows as "
            "probabilities, but where --refine auto refines on the map's cells (where the "
            "images tell the places apart) the refinement counts them as floor(100 f): "
            "--refine never keeps them as probabilities, on the model grid; "
            f"{others}")  # fmt: skip


def _features(args: argparse.Namespace) -> int:
    from spcopyro.features.extract import extract_to_csv

    if args.seed != 0 and args.weights != "random":  # nothing else draws from it
        raise ValueError(f"--seed {args.seed}: the seed of --weights random, not of {args.weights}")
    _random_warning(args.weights)
    result = extract_to_csv(
        args.images,
        args.out,
        weights=args.weights,
        head=args.head,
        batch_size=args.batch,
        device=args.device,
        download=args.download,
        overwrite=args.overwrite,
        seed=args.seed,
    )
    rows, classes = result.features.shape
    print(f"backbone         {result.weights.describe()}")
    print(f"head             {args.head or 'the backbone final layer'} ({classes} classes)")
    print(f"wrote {result.out}: {rows} rows x {classes} columns, one per image of {args.images}")
    note = floor100_note(result.features, result.out)
    if note:
        print(f"counting         {note}")
    return 0


def _features_head(args: argparse.Namespace) -> int:
    from spcopyro.features.backbone import WeightsNotFoundError

    try:
        return _train_head(args)
    except WeightsNotFoundError as error:  # the backbone's message names features' flags
        raise WeightsNotFoundError(
            str(error).replace("(features's --", "(features-head's --")
        ) from None


def _train_head(args: argparse.Namespace) -> int:
    from spcopyro.features.head import PlaceClassifier, encode_labels, save_head, train_head

    _random_warning(args.weights)
    from spcopyro.features.extract import check_out_file

    # before the training, not after
    out = check_out_file(args.out, overwrite=args.overwrite, command="features-head")
    source = Path(args.source)
    if source.is_dir():
        from spcopyro.data import load_house
        from spcopyro.features.distill import distillation_report

        report = distillation_report(
            load_house(source),
            weights=args.weights,
            held_out_trial=args.held_out_trial,
            train_trials=args.train_trials,
            tune_layers=args.tune_layers,
            epochs=args.epochs,
            lr=args.lr,
            batch_size=args.batch,
            device=args.device,
            download=args.download,
            seed=args.seed,
            max_images_per_trial=args.max_images_per_trial,
        )
        print(report.text())
        save_head(report.model, out, mode="distill", note=f"distilled from {source}")
    else:
        from spcopyro.features.extract import frozen_inputs
        from spcopyro.features.images import read_labelled_images

        given = [
            option
            for option, value in (
                ("--held-out-trial", args.held_out_trial),
                ("--train-trials", args.train_trials),
                ("--max-images-per-trial", args.max_images_per_trial),
            )
            if value is not None
        ]
        if given:  # they were silently ignored
            raise ValueError(
                f"{source}: {', '.join(given)} choose(s) the images of a house folder's trials "
                "(distillation); a labels file trains on all the images it lists"
            )
        paths, names = read_labelled_images(source)
        class_names, labels = encode_labels(names)
        if len(class_names) < 2:
            raise ValueError(
                f"{source}: every image is labelled {class_names[0]!r}: a head over one place "
                "gives every image the feature 1.0; label images of at least two places"
            )
        model = PlaceClassifier.load(args.weights, download=args.download, seed=args.seed)
        model.replace_head(len(class_names), class_names)
        inputs = frozen_inputs(
            model, paths, tune_layers=args.tune_layers, batch_size=args.batch, device=args.device
        )
        result = train_head(
            model,
            inputs,
            labels,
            mode="labels",
            tune_layers=args.tune_layers,
            epochs=args.epochs,
            lr=args.lr,
            batch_size=args.batch,
            seed=args.seed,
        )
        print(f"backbone         {model.weights.describe()}")
        print(f"trained          {len(paths)} images, {len(class_names)} places "
              f"({', '.join(class_names)}); cross-entropy {result.initial_loss:.4f} -> "
              f"{result.final_loss:.4f}")  # fmt: skip
        save_head(model, out, mode="labels", note=f"labels from {source}")
    print(f"wrote {out} (use it with: {_features_command(out, args)})")
    return 0


def _features_command(head: Path, args: argparse.Namespace) -> str:
    """The ``spcopyro features`` command line that runs ``head`` on the backbone it was trained
    on: ``--weights`` (and ``--seed`` for random weights) as given to ``features-head``."""
    words = ["spcopyro", "features", "IMAGES", "--out", "Ft.csv", "--head", str(head)]
    if args.weights != "imagenet":
        words += ["--weights", str(args.weights)]
    if args.weights == "random" and args.seed != 0:
        words += ["--seed", str(args.seed)]
    return shlex.join(words)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``features`` (extract Ft.csv) and ``features-head`` (train a place head)."""
    p = subparsers.add_parser(
        "features",
        help="image features (Ft.csv) from a folder of images with torchvision's AlexNet",
        description=(
            "Write one place-class histogram per image (softmax of the head) as Ft.csv rows. "
            "IMAGES is a folder of images (sorted by name) or a house folder with img_K/ folders "
            "(rows in the order load_house pairs with them). Without --head the rows are the "
            "backbone's own classes (1000 for ImageNet weights)."
        ),
    )
    p.add_argument("images", help="folder of images, or a house folder with img_K/ folders")
    p.add_argument("--out", required=True, help="Ft.csv file to write")
    p.add_argument("--head", help="a place head file from `spcopyro features-head` (default: "
                   "none, the backbone's own classes)")  # fmt: skip
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    p.add_argument("--seed", type=seed, default=0, help="seed of --weights random (a head "
                   "trained on random weights needs the seed it was trained with)")  # fmt: skip
    _common(p)
    p.set_defaults(func=_features)

    p = subparsers.add_parser(
        "features-head",
        help="train a place head on the frozen AlexNet (distil a house's Ft.csv, or labels)",
        description=(
            "SOURCE a house folder: distil its Ft.csv (the paper's Places205 histograms) from "
            "its images, training on some trials and reporting KL divergence and top-1 agreement "
            "on a held-out one. SOURCE a file of IMAGE,PLACE lines: train on place names."
        ),
    )
    p.add_argument("source", help="house folder (distillation) or IMAGE,PLACE labels file")
    p.add_argument("--out", required=True, help="head file to write")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    p.add_argument(
        "--tune-layers",
        type=int,
        choices=(0, 1, 2),
        default=0,
        help="also fine-tune fc7 (1) or fc6 and fc7 (2); default: head only",
    )
    p.add_argument("--epochs", type=integer_at_least(0), default=100, help="training epochs")
    p.add_argument("--lr", type=positive_number("learning rate is"), default=1e-3,
                   help="Adam learning rate")  # fmt: skip
    p.add_argument("--seed", type=seed, default=0,
                   help="seed of random weights, batch order and dropout")  # fmt: skip
    p.add_argument("--held-out-trial", type=int, help="distillation: default the last trial")
    p.add_argument("--train-trials", type=int, nargs="+", help="distillation: default the rest")
    p.add_argument("--max-images-per-trial", type=integer_at_least(1),
                   help="distillation: a quick run (default: all images)")  # fmt: skip
    _common(p)
    p.set_defaults(func=_features_head)
