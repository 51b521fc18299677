"""A dataset folder that lists houses without holding any: what the study commands' option
checks (``--houses``, ``--public-houses``) read, :func:`spcopyro.data.list_houses`, and no
more (nothing in it loads)."""

from __future__ import annotations

from pathlib import Path


def fake_dataset(root: Path, *houses: str) -> Path:
    """``root`` holding each house (default: room1) as a folder with ``img_0/`` and its
    ``map/NAME.yaml``; returns ``root``."""
    (root / "map").mkdir(parents=True)
    for house in houses or ("room1",):
        (root / house / "img_0").mkdir(parents=True)
        (root / "map" / f"{house}.yaml").write_text(f"image: {house}.pgm\n")
    return root
