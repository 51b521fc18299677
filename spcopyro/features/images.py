"""Camera images: finding them, decoding them with OpenCV, preprocessing with torchvision.

Preprocessing is torchvision's recipe for its ImageNet AlexNet (the ``ImageClassification``
preset of ``AlexNet_Weights.IMAGENET1K_V1``): resize the shorter side to 256 pixels (bilinear,
antialiased), crop the central 224 x 224, scale to [0, 1] and normalise each channel,
``x' = (x / 255 - mean_c) / std_c`` with the ImageNet mean (0.485, 0.456, 0.406) and standard
deviation (0.229, 0.224, 0.225), channels in RGB order.
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path

import cv2
import numpy as np
import torch
from torchvision.transforms import InterpolationMode, v2

from spcopyro._util.messages import echo, shown_count, warn_once
from spcopyro.data import IMAGE_SUFFIXES
from spcopyro.data.dataset_files import read_pose_file
from spcopyro.data.text import fold_word

__all__ = [
    "CROP_SIZE",
    "IMAGENET_MEAN",
    "IMAGENET_STD",
    "RESIZE_SIZE",
    "ImageBatch",
    "ImageReadError",
    "UnreadableImagesError",
    "iter_image_batches",
    "list_images",
    "make_transform",
    "read_image",
    "read_labelled_images",
    "spelt_twice",
]

RESIZE_SIZE = 256  # shorter side after resizing
CROP_SIZE = 224  # side of the central crop the network sees
OTHER_IMAGE_SUFFIXES = (".bmp", ".dib", ".gif", ".jp2", ".jpe", ".pbm", ".pgm", ".pnm", ".ppm",
                        ".tif", ".tiff", ".webp", ".avif", ".heic")  # fmt: skip
"""Image files not read (not :data:`spcopyro.data.IMAGE_SUFFIXES`): an error, not a silent skip."""
IMAGENET_MEAN = (0.485, 0.456, 0.406)  # RGB
IMAGENET_STD = (0.229, 0.224, 0.225)  # RGB


class ImageReadError(ValueError):
    """One image file could not be decoded; ``path`` and ``reason`` say which and why."""

    def __init__(self, path: str | os.PathLike[str], reason: str) -> None:
        self.path = Path(path)
        self.reason = reason
        super().__init__(f"{self.path}: {reason}")


class UnreadableImagesError(ValueError):
    """Some images could not be read; ``failures`` lists every ``(path, reason)``."""

    def __init__(self, failures: Sequence[tuple[Path, str]], total: int) -> None:
        self.failures = tuple((Path(p), r) for p, r in failures)
        named = shown_count(len(self.failures), 20)  # 21 named whole, not "... and 1 more"
        listed = "; ".join(f"{p}: {r}" for p, r in self.failures[:named])
        more = f"; ... and {len(self.failures) - named} more" if len(self.failures) > named else ""
        super().__init__(
            f"{len(self.failures)} of {total} image(s) could not be read (nothing was written; "
            f"fix or remove them): {listed}{more}"
        )


def read_image(path: str | os.PathLike[str]) -> np.ndarray:
    """Decode an image file into ``[H, W, 3]`` uint8 **RGB** (grey and alpha images converted;
    an EXIF orientation is applied, as OpenCV does, unlike PIL and torchvision's decoders).

    The bytes are read with Python and decoded with ``cv2.imdecode``, which rejects a truncated
    JPEG (``cv2.imread`` would silently return it with its missing part grey).

    Raises:
        FileNotFoundError: no such file (the message names it).
        ImageReadError: the file is not a decodable image, or one more than
            :data:`MAX_ASPECT_RATIO` times as wide as high (or high as wide).
    """
    path = Path(path)
    if not path.is_file():
        if path.is_symlink():
            raise FileNotFoundError(f"{path}: a link to {os.readlink(path)}, which is no file")
        raise FileNotFoundError(f"{path}: image file not found")
    data = np.fromfile(path, dtype=np.uint8)  # [bytes]
    if data.size == 0:
        raise ImageReadError(path, "empty file")
    bgr = cv2.imdecode(data, cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH)  # [H, W, 3] BGR or None
    if bgr is not None and bgr.dtype == np.uint16:
        _warn_if_dim(path, int(bgr.max()))
        bgr = (bgr >> 8).astype(np.uint8)  # the high byte: what IMREAD_COLOR alone gives
    elif bgr is not None and bgr.dtype != np.uint8:  # a float image: as IMREAD_COLOR converts it
        bgr = cv2.imdecode(data, cv2.IMREAD_COLOR)
    if bgr is None and path.name.startswith("._"):  # macOS writes them beside each file it
        raise ImageReadError(  # copies to a FAT or exFAT disk (a USB stick)
            path,
            f"a macOS metadata file (AppleDouble, for {path.name[2:]}), not an image: delete "
            "the ._* files (dot_clean FOLDER on the Mac)",
        )
    if bgr is None:
        raise ImageReadError(path, "OpenCV cannot decode it (not an image, or truncated)")
    height, width = bgr.shape[:2]
    if max(height, width) > MAX_ASPECT_RATIO * min(height, width):
        raise ImageReadError(
            path,
            f"a {width} x {height} image (width x height), more than {MAX_ASPECT_RATIO} times "
            f"as {'wide as high' if width > height else 'high as wide'}: not a camera frame "
            f"(its shorter side resized to {RESIZE_SIZE} pixels would make it "
            f"{RESIZE_SIZE * max(height, width) // max(min(height, width), 1)} pixels long, "
            f"of which the network sees a central {CROP_SIZE} x {CROP_SIZE} square)",
        )
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


MAX_ASPECT_RATIO = 32
"""Longer side over shorter: :func:`read_image` refuses an image beyond it (a strip, one pixel
high, say). Preprocessing resizes the shorter side to :data:`RESIZE_SIZE`, so a 100000 x 1
image became 25.6 million pixels long (20 GB) before its central crop; at this ratio the
resized image is at most 8192 x 256 (6 MB), of which the crop sees 224 pixels' length."""


DIM_16_BIT = 4096
"""A 16-bit image whose brightest value is below this (2^12) holds a 10- or 12-bit camera's
range: read at 16 bits, as every 16-bit image is, it is at most 1/16 bright."""


def _warn_if_dim(path: Path, peak: int) -> None:
    """Warn once a folder (logger ``"spcopyro"``) when a 16-bit image's ``peak`` is below
    :data:`DIM_16_BIT`: its features are those of a nearly black image."""
    if peak < DIM_16_BIT:
        warn_once(("dim 16-bit images", str(path.parent)), (
            f"{path}: a 16-bit image whose brightest value is {peak} of 65535 (a 10- or 12-bit "
            f"camera's range?): read at 16 bits it is at most {peak / 65535:.1%} bright, so its "
            "features are those of a nearly black image; scale such images to the full 16-bit "
            "range, or save them as 8-bit, first (said once a folder)"
        ))  # fmt: skip


def make_transform(
    resize: int = RESIZE_SIZE,
    crop: int = CROP_SIZE,
    mean: Sequence[float] = IMAGENET_MEAN,
    std: Sequence[float] = IMAGENET_STD,
) -> Callable[[np.ndarray], torch.Tensor]:
    """``[H, W, 3]`` uint8 RGB array -> ``[3, crop, crop]`` float32 normalised tensor.

    torchvision transforms (``v2``): ToImage, Resize(resize, bilinear, antialias),
    CenterCrop(crop), ToDtype(float32, scale=True), Normalize(mean, std).
    """
    return v2.Compose(
        [
            v2.ToImage(),
            v2.Resize(resize, interpolation=InterpolationMode.BILINEAR, antialias=True),
            v2.CenterCrop(crop),
            v2.ToDtype(torch.float32, scale=True),
            v2.Normalize(mean=list(mean), std=list(std)),
        ]
    )


def list_images(directory: str | os.PathLike[str]) -> list[Path]:
    """The images of a folder, in the order their feature rows take (the dataset's Ft.csv order).

    Either the images directly in ``directory``, sorted by name, or -- for a house folder of the
    dataset layout -- those of its ``img_K/`` subfolders, K ascending (numerically), each sorted
    by name, exactly as :func:`spcopyro.data.load_house` pairs them with Ft.csv rows. Images are
    the files ending in one of :data:`spcopyro.data.IMAGE_SUFFIXES` (any case).

    Image entries that are no files (a broken link) are listed too, so that reading them fails
    with their names instead of their rows silently missing.

    Raises:
        FileNotFoundError: ``directory`` does not exist, or holds no images.
        NotADirectoryError: ``directory`` is a file.
        ValueError: it holds both images and ``img_K/`` folders (which order is meant?), or
            image files of another type (``.bmp``, ``.webp``, ...), which would be left out.
    """
    directory = Path(directory)
    if directory.is_file():
        raise NotADirectoryError(
            f"{directory}: a file, not a folder: give the folder that holds the images"
        )
    if not directory.is_dir():
        raise FileNotFoundError(f"{directory}: image folder not found")
    flat = sorted(
        p for p in directory.iterdir() if not p.is_dir() and p.suffix.lower() in IMAGE_SUFFIXES
    )
    trial_folders = sorted(
        (int(m.group(1)), p)
        for p in directory.iterdir()
        if p.is_dir() and (m := re.fullmatch(r"img_([0-9]+)", p.name))
    )
    if flat and trial_folders:
        raise ValueError(
            f"{directory}: holds both images ({flat[0].name}, ...) and img_K folders "
            f"({trial_folders[0][1].name}, ...); give one of them"
        )
    if not trial_folders:  # a house folder's own files (a map.pgm, say) are not its images
        _check_other_images(directory)
        _warn_unpadded_numbers(directory, flat)
    for (trial, first), (again, second) in zip(trial_folders, trial_folders[1:], strict=False):
        if trial == again:  # img_1/ and img_01/: load_house refuses to pair either
            raise ValueError(
                f"{directory}: {first.name}/ and {second.name}/ are both trial {trial}"
            )
    _check_trials(directory, [trial for trial, _ in trial_folders])
    paths = list(flat)
    for trial, folder in trial_folders:
        _check_other_images(folder)
        images = sorted(
            q for q in folder.iterdir() if not q.is_dir() and q.suffix.lower() in IMAGE_SUFFIXES
        )
        _check_against_poses(directory, trial, folder, images)
        _warn_unpadded_numbers(folder, images)
        paths += images
    if not paths:
        raise FileNotFoundError(
            f"{directory}: no images (files ending in {', '.join(IMAGE_SUFFIXES)}, directly or "
            f"in img_K/ folders){_images_deeper(directory)}"
        )
    return paths


def _images_deeper(directory: Path, depth: int = 2) -> str:
    """``"; images are in FOLDER (N), ...: ..."`` naming the folders up to ``depth`` levels
    below ``directory`` that hold images (a camera's ``images/`` or ``trial0/`` folder, which
    :func:`list_images` does not look into), else ``""``."""
    found: list[tuple[Path, int]] = []
    level = [directory]
    for _ in range(depth):
        below = []
        for folder in level:
            try:
                below += sorted(q for q in folder.iterdir() if q.is_dir())
            except OSError:  # unreadable: the hint is only a hint
                continue
        level = below
        for folder in level:
            try:
                count = sum(1 for q in folder.iterdir() if q.suffix.lower() in IMAGE_SUFFIXES)
            except OSError:
                continue
            if count:
                found.append((folder, count))
    if not found:
        return ""
    named = ", ".join(f"{folder} ({count})" for folder, count in found[:3])
    more = f", ... ({len(found)} folders)" if len(found) > 3 else ""
    return (
        f"; images are in {named}{more}: give that folder, or, for a house folder, name the "
        "trials' folders img_0, img_1, ... beside their pose_0.csv, pose_1.csv, ..."
    )


def _warn_unpadded_numbers(folder: Path, images: list[Path]) -> None:
    """Warn (logger ``"spcopyro"``) when name order is not number order: frames numbered
    without zero padding (``frame_10.jpg`` sorts before ``frame_2.jpg``), whose rows would then
    not follow the order the images were taken in (the order of their poses)."""

    def numbers_first(path: Path) -> list[object]:
        parts = re.split(r"([0-9]+(?:\.[0-9]+)?)", path.name)  # a timestamp's fraction with it
        return [(0, Decimal(p), "") if p[:1].isdigit() else (1, 0, p) for p in parts]

    by_number = sorted(images, key=numbers_first)
    if by_number == images:
        return
    first = next(i for i, (a, b) in enumerate(zip(images, by_number, strict=True)) if a != b)
    logging.getLogger("spcopyro").warning(
        "%s: image names number their frames without zero padding: rows follow name order "
        "(row %d is %s, not %s), not the numbers' order; if the numbers give the order the "
        "images were taken in (that of their poses), rename them with zero padding "
        "(00001.jpg, ...)",
        folder, first + 1, images[first].name, by_number[first].name,
    )  # fmt: skip


def _check_other_images(folder: Path) -> None:
    """ValueError naming the image files of ``folder`` that are not read (their suffix is not
    one of IMAGE_SUFFIXES): left out, they would silently drop rows from Ft.csv."""
    others = sorted(
        p.name for p in folder.iterdir() if p.is_file() and p.suffix.lower() in OTHER_IMAGE_SUFFIXES
    )
    if others:
        raise ValueError(
            f"{folder}: {len(others)} image file(s) of a type not read ({', '.join(others[:5])}"
            f"{', ...' if len(others) > 5 else ''}): only {', '.join(IMAGE_SUFFIXES)} files are "
            "images here (as for load_house); convert them or move them out"
        )


def _pose_lines(poses: Path) -> int:
    """The poses ``poses`` lists, read as load_house reads them: a header line, a bad number
    or row is an error naming its line (a header was counted as one more pose, and reported as
    a missing image)."""
    return read_pose_file(poses).shape[0]


def _check_trials(directory: Path, trials: list[int]) -> None:
    """A house folder's trials are those of its ``pose_K.csv`` files (as for load_house): an
    ``img_K/`` without one would add rows with no pose, a pose file without its ``img_K/`` leave
    its trial's rows out; either shifts Ft.csv against Xtx.csv. ValueError naming them."""
    poses = {
        int(m.group(1)): p
        for p in directory.glob("pose_*.csv")
        if (m := re.fullmatch(r"pose_([0-9]+)\.csv", p.name))
    }
    if not trials or not poses:
        return
    extra = sorted(set(trials) - set(poses))
    if extra:
        raise ValueError(
            f"{directory}: img_{extra[0]}/ has no pose_{extra[0]}.csv (the trials are "
            f"{', '.join(map(str, sorted(poses)))}, from the pose files): its images would be "
            "Ft.csv rows without a pose; move the folder out"
        )
    missing = [k for k in sorted(set(poses) - set(trials)) if _pose_lines(poses[k])]
    if missing:
        raise ValueError(
            f"{directory}: {poses[missing[0]].name} lists {_pose_lines(poses[missing[0]])} "
            f"poses but there is no img_{missing[0]}/ folder: Ft.csv would lack that trial's "
            "rows"
        )


def _check_against_poses(directory: Path, trial: int, folder: Path, images: list[Path]) -> None:
    """A house folder's ``img_K/`` must hold one image per line of its ``pose_K.csv`` (when
    there is one): a missing image would shift every later image's features onto the wrong
    pose. ValueError naming the folder, both counts and the missing names if they are numbered."""
    poses = next(
        (p for p in directory.glob("pose_*.csv") if re.fullmatch(rf"pose_0*{trial}\.csv", p.name)),
        None,
    )
    if poses is None:
        return
    num_poses = _pose_lines(poses)
    if num_poses == len(images):
        return
    missing = ""
    numbered = [int(p.stem) for p in images if p.stem.isdigit()]
    if len(numbered) == len(images) and len(images) < num_poses:
        width = len(images[0].stem) if images else 5
        suffix = images[0].suffix if images else ".jpg"
        expected = range(min(numbered, default=0), min(numbered, default=0) + num_poses)
        gaps = sorted(set(expected) - set(numbered))[:5]
        if gaps:
            missing = "; missing: " + ", ".join(f"{g:0{width}d}{suffix}" for g in gaps)
    if len(images) > num_poses:  # an extra image shifts every later one as a missing one does
        apple = [p.name for p in images if p.name.startswith("._")]
        stray = (
            f"; {len(apple)} are macOS metadata files (AppleDouble: {', '.join(apple[:3])}"
            f"{', ...' if len(apple) > 3 else ''}), not images: delete the ._* files"
            if apple
            else ""
        )
        raise ValueError(
            f"{folder}: {len(images)} images but {poses.name} has {num_poses} poses: every "
            f"image after an extra one would get the wrong pose's features{stray}"
        )
    raise ValueError(
        f"{folder}: {len(images)} images but {poses.name} has {num_poses} poses: every image "
        f"after a missing one would get the wrong pose's features{missing}"
    )


@dataclass(frozen=True)
class ImageBatch:
    """Images ``start`` to ``start + len(paths) - 1`` of a list; ``pixels`` holds the decoded.

    ``pixels`` is ``[B, 3, crop, crop]`` float32 (B = len(paths)) when ``failures`` is empty;
    otherwise ``None``, and ``failures`` lists ``(path, reason)`` of every image that did not.
    """

    start: int
    paths: tuple[Path, ...]
    pixels: torch.Tensor | None  # [B, 3, crop, crop] float32
    failures: tuple[tuple[Path, str], ...]


def iter_image_batches(
    paths: Sequence[str | os.PathLike[str]],
    batch_size: int,
    transform: Callable[[np.ndarray], torch.Tensor] | None = None,
) -> Iterator[ImageBatch]:
    """Decode and preprocess ``paths`` in batches of ``batch_size`` (the last may be smaller).

    Every image is tried; a batch with unreadable images carries their paths and reasons in
    ``failures`` (and no pixels), so a caller can report all bad files at once.
    """
    if batch_size < 1:
        raise ValueError(f"batch_size must be >= 1, got {batch_size}")
    transform = transform or make_transform()
    for start in range(0, len(paths), batch_size):
        chunk = tuple(Path(p) for p in paths[start : start + batch_size])
        tensors, failures = [], []
        for path in chunk:
            try:
                tensors.append(transform(read_image(path)))  # [3, crop, crop]
            except (OSError, ValueError) as error:
                reason = getattr(error, "reason", None) or str(error).removeprefix(f"{path}: ")
                failures.append((path, reason))
        pixels = torch.stack(tensors) if not failures else None
        yield ImageBatch(start=start, paths=chunk, pixels=pixels, failures=tuple(failures))


SPELT_TWICE = (
    "they differ only in case, Unicode form or spaces, and would be two classes; write every "
    "image's place the same way"
)


def spelt_twice(names: Sequence[str]) -> tuple[int, int] | None:
    """The first two of ``names`` that are one place written two ways (``Kitchen`` and
    ``kitchen``, ``living room`` and ``living  room``, full-width ``ＴＶ`` and ``TV``: equal under
    :func:`~spcopyro.data.text.fold_word` with their spaces collapsed, yet not equal), as their
    indices ``(i, j)``, ``i < j``; None when there are none. A head would learn them as two
    classes, splitting the place's images between them."""
    first: dict[str, int] = {}
    for j, name in enumerate(names):
        i = first.setdefault(" ".join(fold_word(name).split()), j)
        if names[i] != name:
            return i, j
    return None


def _beside(labels_file: Path, image: str) -> Path:
    """A labels file's IMAGE: absolute, or relative to the file's folder."""
    path = Path(image)
    return path if path.is_absolute() else labels_file.parent / path


def read_labelled_images(path: str | os.PathLike[str]) -> tuple[list[Path], list[str]]:
    """A labels file: one ``IMAGE,PLACE`` line per image (IMAGE relative to the file's folder,
    or absolute; a Windows path's backslashes, ``img_0\\1.jpg``, read as slashes where only
    that names a file; blank lines and lines starting with ``#`` skipped) -> (paths, place
    names).

    Raises:
        FileNotFoundError: no such file, or images it names that do not exist (with their
            lines, and the folder relative paths start from).
        ValueError: a line without exactly one comma, or with an empty field (the message
            names the file, the 1-based line and the line, shortened when long), no labelled
            images at all, one place written two ways (:func:`spelt_twice`, naming both lines),
            or a file that is not UTF-8 text.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such labels file (nor house folder)")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not UTF-8 text ({error.reason})") from None
    paths, names, lines = [], [], []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = [f.strip() for f in line.split(",")]
        if len(fields) != 2 or not all(fields):
            raise ValueError(f"{path}, line {number}: expected IMAGE,PLACE: {echo(line)}")
        image = _beside(path, fields[0])
        if "\\" in fields[0] and os.sep == "/" and not image.exists():
            image = _beside(path, fields[0].replace("\\", "/"))  # written on Windows: img_0\1.jpg
        paths.append(image)
        names.append(fields[1])
        lines.append(number)
    if not paths:
        raise ValueError(f"{path}: holds no labelled images")
    seen: dict[Path, int] = {}  # image -> index of its first line
    for k, image in enumerate(paths):
        first = seen.setdefault(Path(os.path.normpath(image)), k)
        if names[first] != names[k]:
            raise ValueError(
                f"{path}, line {lines[k]}: image {image} is labelled {names[k]!r} here "
                f"but {names[first]!r} on line {lines[first]}: one place per image"
            )
    twice = spelt_twice(names)
    if twice is not None:
        i, j = twice
        raise ValueError(
            f"{path}, line {lines[j]}: place {names[j]!r} is written {names[i]!r} on line "
            f"{lines[i]}: {SPELT_TWICE}"
        )
    missing = [(n, p) for n, p in zip(lines, paths, strict=True) if not p.exists()]
    if missing:
        named = shown_count(len(missing), 5)  # 6 named whole, not "... and 1 more"
        listed = "; ".join(f"line {n}: {p}" for n, p in missing[:named])
        more = f"; ... and {len(missing) - named} more" if len(missing) > named else ""
        raise FileNotFoundError(
            f"{path}: {len(missing)} of {len(paths)} image(s) not found ({listed}{more}); an "
            f"IMAGE that is not absolute is relative to the labels file's folder, "
            f"{path.parent.resolve()}"
        )
    return paths, names
