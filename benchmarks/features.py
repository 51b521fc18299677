#!/usr/bin/env python
"""Speed of image-feature extraction (spcopyro.features): images per second with AlexNet.

Sections, for each device (``cpu``; ``cuda`` too when available, or as ``--devices`` says):

1. **network**: the AlexNet forward pass alone on preprocessed ``[B, 3, 224, 224]`` batches,
   B in the batch sizes (default 1, 8, 32): median seconds per batch -> images per second.
2. **end to end**: :func:`spcopyro.features.extract.extract_features` on real files -- read,
   OpenCV decode, torchvision preprocessing, forward, softmax -- for the same batch sizes. The
   images are the public dataset's room1dk5 camera images (640 x 480 JPEG) when the dataset is
   found, else synthetic 640 x 480 JPEGs written to a temporary folder.
3. **decode + preprocess** alone (CPU, no network): images per second.
4. **distillation** (skipped with ``--quick`` unless ``--distill``): the report of
   :func:`spcopyro.features.distill.distillation_report` on room1dk5 (trials 0, 1 -> 2), with
   whatever backbone weights are here. With random weights its numbers mean little.

The weights are torchvision's ImageNet AlexNet when its file is cached, else random weights
(``--weights`` overrides): the speed is the same either way.

Usage::

    python benchmarks/features.py                  # full run (1-2 minutes on 2 CPU cores)
    python benchmarks/features.py --quick          # smoke test, a few seconds
    python benchmarks/features.py --devices cpu,cuda --batch-sizes 1,8,32,128

It prints a plain-text table to stdout (progress goes to stderr) and writes every number, with
machine information, to a JSON file (``benchmarks/features_results.json``, or
``features_quick.json`` with ``--quick``, unless ``--out`` says otherwise).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
import torchvision
from bench_cli import COUNT, counts, dataset_root, fail, quick_or, run_main

from spcopyro.data import load_house
from spcopyro.features.backbone import (
    CheckpointError,
    WeightsNotFoundError,
    parse_weights,
    torchvision_cache_file,
)
from spcopyro.features.distill import distillation_report
from spcopyro.features.extract import extract_features
from spcopyro.features.head import PlaceClassifier
from spcopyro.features.images import make_transform, read_image

SCRIPT_DIR = Path(__file__).resolve().parent
HOUSE = "room1dk5"
IMAGE_SIZE = (480, 640)  # H, W of the dataset's camera images


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def machine_info(devices: list[str]) -> dict[str, Any]:
    info = {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "torch": torch.__version__,
        "torchvision": torchvision.__version__,
        "opencv": cv2.__version__,
        "cpu": cpu_name(),
        "cpu_count": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
    }
    if "cuda" in devices:
        info["gpu"] = torch.cuda.get_device_name(0)
    return info


def busy_seconds() -> float | None:
    """CPU seconds all processes have been busy since boot (/proc/stat), None if unknown."""
    try:
        fields = Path("/proc/stat").read_text().splitlines()[0].split()[1:]
    except (OSError, IndexError):
        return None
    user, nice, system, _idle, _iowait, irq, softirq, steal = (int(v) for v in fields[:8])
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


class Contention:
    """CPU seconds *other* processes used while the ``with`` block ran (0 on an idle machine)."""

    def __enter__(self) -> Contention:
        self.busy, self.own = busy_seconds(), sum(os.times()[:4])
        return self

    def __exit__(self, *exc: object) -> None:
        busy = busy_seconds()
        own = sum(os.times()[:4]) - self.own
        self.other = None if busy is None or self.busy is None else busy - self.busy - own

    def text(self) -> str:
        return "unknown" if self.other is None else f"{max(self.other, 0.0):.1f} s"


def time_calls(call: Callable[[], object], *, min_seconds: float, min_repeats: int, sync) -> float:
    """Median seconds of one ``call()`` after one warm-up call, repeated for ``min_seconds``."""
    call()
    sync()
    times: list[float] = []
    start = time.perf_counter()
    while len(times) < min_repeats or time.perf_counter() - start < min_seconds:
        t0 = time.perf_counter()
        call()
        sync()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def synchronizer(device: str) -> Callable[[], None]:
    return torch.cuda.synchronize if device == "cuda" else (lambda: None)


def bench_network(
    model: PlaceClassifier, device: str, batch_sizes: list[int], min_seconds: float
) -> list[dict[str, Any]]:
    model.to(device).eval()
    rows = []
    generator = torch.Generator().manual_seed(0)
    for batch in batch_sizes:
        pixels = torch.randn(batch, 3, 224, 224, generator=generator).to(device)

        def forward(pixels: torch.Tensor = pixels) -> torch.Tensor:
            with torch.inference_mode():
                return model.probabilities(pixels)

        seconds = time_calls(
            forward, min_seconds=min_seconds, min_repeats=3, sync=synchronizer(device)
        )
        rows.append({"batch": batch, "seconds_per_batch": seconds, "images_per_s": batch / seconds})
        log(f"  network   {device:>4} batch {batch:>3}: {batch / seconds:8.1f} img/s")
    return rows


def bench_end_to_end(
    model: PlaceClassifier,
    device: str,
    paths: list[Path],
    batch_sizes: list[int],
    repeats: int,
) -> list[dict[str, Any]]:
    rows = []
    for batch in batch_sizes:
        n = len(paths)
        extract_features(model, paths[: min(batch, n)], batch_size=batch, device=device,
                         progress=False)  # fmt: skip
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            extract_features(model, paths, batch_size=batch, device=device, progress=False)
            synchronizer(device)()
            times.append(time.perf_counter() - t0)
        seconds = statistics.median(times)
        rows.append({"batch": batch, "images": n, "seconds": seconds, "images_per_s": n / seconds})
        log(f"  end2end   {device:>4} batch {batch:>3}: {n / seconds:8.1f} img/s ({n} images)")
    return rows


def bench_decode(paths: list[Path], repeats: int) -> dict[str, Any]:
    transform = make_transform()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for path in paths:
            transform(read_image(path))
        times.append(time.perf_counter() - t0)
    seconds = statistics.median(times)
    log(f"  decode + preprocess: {len(paths) / seconds:8.1f} img/s")
    return {"images": len(paths), "seconds": seconds, "images_per_s": len(paths) / seconds}


def camera_images(dataset: Path | None, count: int, folder: Path) -> tuple[list[Path], str]:
    """``count`` 640 x 480 JPEGs: the dataset's (room1dk5) when present, else synthetic ones."""
    if dataset is not None:
        paths = load_house(dataset / HOUSE).observations.image_paths
        if paths is not None:
            return list(paths[:count]), f"{HOUSE} camera images (640 x 480 JPEG)"
    rng = np.random.default_rng(0)
    paths = []
    for i in range(count):
        # smooth random colour fields compress like photos, unlike white noise
        small = rng.integers(0, 256, size=(12, 16, 3), dtype=np.uint8)
        image = cv2.resize(small, IMAGE_SIZE[::-1], interpolation=cv2.INTER_CUBIC)
        path = folder / f"{i:05d}.jpg"
        cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, 90])
        paths.append(path)
    return paths, "synthetic 640 x 480 JPEGs (dataset not found)"


def default_weights() -> str:
    return "imagenet" if torchvision_cache_file().is_file() else "random"


def format_table(result: dict[str, Any]) -> str:
    lines = [
        f"AlexNet image features, weights: {result['weights']}",
        f"machine: {result['machine']['cpu']} ({result['machine']['cpu_count']} CPUs, "
        f"{result['machine']['torch_threads']} torch threads)"
        + (f", GPU {result['machine']['gpu']}" if "gpu" in result["machine"] else ""),
        f"images: {result['images']}",
        "",
        f"{'device':<6} {'batch':>5} {'network img/s':>14} {'end-to-end img/s':>17}",
    ]
    for device, sections in result["devices"].items():
        end_to_end = {row["batch"]: row for row in sections["end_to_end"]}
        for row in sections["network"]:
            e2e = end_to_end.get(row["batch"])
            e2e_text = f"{e2e['images_per_s']:17.1f}" if e2e else f"{'-':>17}"
            lines.append(f"{device:<6} {row['batch']:>5} {row['images_per_s']:14.1f} {e2e_text}")
    lines.append(
        f"decode + preprocess alone (CPU, one process): "
        f"{result['decode']['images_per_s']:.1f} img/s"
    )
    lines.append(result["contention_note"])
    if result.get("distillation"):
        lines += ["", result["distillation"]["text"]]
    elif result.get("distillation_note"):
        lines += ["", result["distillation_note"]]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke test: few images, short runs")
    parser.add_argument("--out", type=Path,
                        help="JSON output (default benchmarks/features_results.json, "
                             "features_quick.json with --quick)")  # fmt: skip
    parser.add_argument("--devices", help="comma separated: cpu,cuda (default: cpu, + cuda if any)")
    parser.add_argument("--batch-sizes", type=counts,
                        help="comma separated (default 1,8,32; quick: 1,8)")  # fmt: skip
    parser.add_argument("--weights", help="imagenet, random or a checkpoint (default: what's here)")
    parser.add_argument("--dataset", type=Path, help="dataset root (default: find_dataset_root())")
    parser.add_argument("--no-dataset", action="store_true", help="synthetic images only")
    parser.add_argument("--distill", action="store_true", help="run the distillation section")
    parser.add_argument("--no-distill", action="store_true", help="skip the distillation section")
    parser.add_argument("--torch-threads", type=COUNT, help="torch.set_num_threads")
    args = parser.parse_args(argv)

    if args.torch_threads:
        torch.set_num_threads(args.torch_threads)
    devices = (
        [d.strip() for d in args.devices.split(",") if d.strip()]
        if args.devices
        else ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    )
    for device in devices:  # a usage error, not torch's traceback after the model is loaded
        if device not in ("cpu", "cuda"):
            fail(f"--devices {args.devices}: {device!r} is not one of cpu, cuda")
        if device == "cuda" and not torch.cuda.is_available():
            fail(f"--devices {args.devices}: no CUDA device on this machine")
    if not devices:
        fail(f"--devices {args.devices!r}: no device named")
    batch_sizes = quick_or(args.batch_sizes, args.quick, [1, 8], [1, 8, 32])
    weights = args.weights or default_weights()
    try:
        parse_weights(weights)  # a missing checkpoint: one line, before anything is measured
    except WeightsNotFoundError as error:
        fail(f"--weights: {error}")
    without = "synthetic images are used and the distillation is skipped"
    dataset = None if args.no_dataset else dataset_root(args.dataset, without=without)
    num_images = 16 if args.quick else 64
    min_seconds = 0.3 if args.quick else 2.0
    repeats = 1 if args.quick else 3
    name = "features_quick.json" if args.quick else "features_results.json"
    out = args.out or SCRIPT_DIR / name

    try:
        model = PlaceClassifier.load(weights)
    except (WeightsNotFoundError, CheckpointError) as error:  # e.g. imagenet not cached
        fail(f"--weights {weights}: {error}")
    result: dict[str, Any] = {
        "weights": model.weights.describe(),
        "pretrained": model.weights.pretrained,
        "machine": machine_info(devices),
        "batch_sizes": batch_sizes,
        "devices": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        paths, images = camera_images(dataset, num_images, Path(tmp))
        result["images"] = f"{len(paths)} {images}"
        log(f"weights: {result['weights']}; images: {result['images']}")
        with Contention() as contention:
            result["decode"] = bench_decode(paths, repeats)
            for device in devices:
                result["devices"][device] = {
                    "network": bench_network(model, device, batch_sizes, min_seconds),
                    "end_to_end": bench_end_to_end(model, device, paths, batch_sizes, repeats),
                }
        result["other_processes_cpu_seconds"] = contention.other
        result["contention_note"] = (
            f"other processes used {contention.text()} of CPU time during the timings (/proc/stat "
            "busy time minus this process); well above 0 means the CPU numbers are inflated"
        )
        model.to("cpu")

    run_distill = args.distill or not (args.quick or args.no_distill)
    if run_distill and dataset is not None:
        log("distillation report ...")
        t0 = time.perf_counter()
        report = distillation_report(
            load_house(dataset / HOUSE),
            model=model,
            device=devices[-1],
            max_images_per_trial=4 if args.quick else None,
            epochs=10 if args.quick else 100,
            progress=False,
        )
        result["distillation"] = {
            "house": report.house,
            "train_trials": list(report.train_trials),
            "held_out_trial": report.held_out_trial,
            "num_train": report.num_train,
            "num_test": report.num_test,
            "kl": report.kl,
            "top1": report.top1,
            "uniform_kl": report.uniform_kl,
            "mean_kl": report.mean_kl,
            "mean_top1": report.mean_top1,
            "initial_loss": report.training.initial_loss,
            "final_loss": report.training.final_loss,
            "seconds": time.perf_counter() - t0,
            "text": report.text(),
        }
    elif run_distill:
        result["distillation_note"] = "distillation skipped: the public dataset was not found"

    print(format_table(result))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"\nwrote {out}")
    return 0


if __name__ == "__main__":
    run_main(main)
