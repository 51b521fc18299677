"""house.png's word markers (spcopyro.figures.map_pieces.spread_markers): placed as before, each
compared with the markers placed near it only."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from spcopyro.figures import map_pieces  # noqa: E402


def _every_marker(ax, xy, size, spacing=0.8):
    """The placement compared with every marker placed before (the quadratic reference)."""
    ax.apply_aspect()
    pixels = ax.transData.transform(xy)
    gap = spacing * np.sqrt(size) * ax.figure.dpi / 72.0
    placed = np.empty_like(pixels)
    for k, point in enumerate(pixels):
        candidates = [point[None, :]]
        for ring in range(1, 6):
            angles = np.pi / 2 + 2 * np.pi * np.arange(6 * ring) / (6 * ring)
            candidates.append(point + ring * gap * np.stack([np.cos(angles), np.sin(angles)], 1))
        options = np.concatenate(candidates)
        if k:
            near = np.linalg.norm(options[:, None, :] - placed[None, :k, :], axis=-1).min(1)
            free = np.flatnonzero(near >= gap * (1 - 1e-9))
            options = options[free[:1]] if len(free) else options[-1:]
        placed[k] = options[0]
    return ax.transData.inverted().transform(placed)


def test_markers_are_placed_as_against_every_marker_comparing_only_nearby_ones(monkeypatch):
    """Crowded spots (words heard at one place, rings full) and scattered ones: the positions
    equal the quadratic reference's exactly, and no marker is compared with more than a few
    placed ones (the reference compares the last with all 599; a 10^6-cell map's house.png took
    minutes)."""
    rng = np.random.default_rng(0)
    spots = rng.uniform(0, 50, (40, 2))
    xy = np.concatenate([spots[rng.integers(0, 40, 400)], rng.uniform(0, 50, (200, 2))])
    fig, ax = plt.subplots(figsize=(6, 6), dpi=100)
    ax.set_xlim(0, 50)
    ax.set_ylim(0, 50)
    ax.set_aspect("equal")
    expected = _every_marker(ax, xy, 22.0)
    compared = []
    norm = np.linalg.norm

    def counted(x, *args, **kwargs):
        compared.append(x.shape[1] if x.ndim == 3 else 0)
        return norm(x, *args, **kwargs)

    monkeypatch.setattr(np.linalg, "norm", counted)
    placed = map_pieces.spread_markers(ax, xy, 22.0)
    monkeypatch.undo()
    plt.close(fig)
    np.testing.assert_array_equal(placed, expected)
    assert compared and max(compared) < 100, max(compared)
