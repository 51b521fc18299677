"""The variants of ``benchmarks/coarse_variants.py`` (:data:`VARIANTS`), what each resolves to
(:func:`variant`, :func:`variant_settings`) and the data preparation its records store
(:func:`preparation`, checked on a resume by :func:`check_preparations`).

Since 86d6df4 (2026-12-06, 18:20 UTC) the default ``coarse`` carries a reach share of 0.2 in
rooms (``footprint_reach_share`` 0.2, ``footprint_reach_door_width`` 1 m, first stage). Every
variant measured before it was measured on the old ``coarse`` (share 0, no cut), and keeps that
meaning through explicit overrides (2026-12-06, 18:40 UTC): the variants of settings other than
the share carry :data:`BEFORE` (share 0, which drops the preset's door width), the reach shares
without "in rooms" :data:`UNCUT` (no door cut). The stored ``coarse`` and ``coarse, --refine
never`` results were the old default's: renamed ``coarse before the reach share`` and ``coarse
before the reach share, --refine never`` in the JSONs, the variants of that meaning; ``coarse``
(and ``coarse, --refine never``) is the current preset, with no results stored before then.

The reach-share variants (issue 21's open plans, 2026-12-06: ``footprint_reach_share``, a
share of each observation over its geodesic Voronoi cell) come in three forms: the default's two
stages with the share in the first (the refinement prepares the data as ``auto`` does, share
0), the first stage alone (``--refine never``, :data:`real_houses.UNREFINED`), and the share in
both stages (:data:`STAGE_TWO`: the refinement's settings patched for the variant's fits, a
screening, not an option of the library). ``reach 0.25 within R m``: the share's Voronoi cells
cut at R metres from their cell (``footprint_reach_radius``; sparse seed 1's spots reach through
a doorway into the next room without it), in the first stage. ``reach E in rooms``: the share's
Voronoi cells drawn within the room segments at ``DEFAULT_DOOR_WIDTH`` (1 m) doors
(``footprint_reach_door_width``), in the first stage (``, stage two too``: in the refinement as
well, :data:`STAGE_TWO`); ``reach 0.2 in rooms`` is the current ``coarse`` (``reach 0.2 in rooms,
stage two too``: the current ``coarse`` with its share kept in the refinement).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
from pathlib import Path
from unittest.mock import patch

import real_houses as rh

from spcopyro.baselines.geometry import DEFAULT_DOOR_WIDTH
from spcopyro.config import SpCoSettings
from spcopyro.fit import refine

BASE = "coarse"
STAGE_TWO = "stage two"
"""An override of :data:`VARIANTS` that is no setting: settings the refinement's own
(:func:`spcopyro.fit.refine.refined_settings`) are replaced with for the variant's fits
(:func:`variant`)."""
REACH = "footprint_reach_share"
REACH_RADIUS = "footprint_reach_radius"
REACH_DOORS = "footprint_reach_door_width"
IN_ROOMS = {REACH_DOORS: DEFAULT_DOOR_WIDTH}
BEFORE = {REACH: 0.0}
"""The overrides that give ``coarse`` before 86d6df4 (2026-12-06, 18:20 UTC): share 0, which
drops the preset's 1 m door width (:func:`spcopyro.config.preset`'s share-0 rule)."""
UNCUT = {REACH_DOORS: None}
"""The door cut off under a share (None: ``real_houses.settings_of`` sets it over the preset's
1 m)."""
VARIANTS: dict[str, tuple[str, dict[str, object]]] = {
    "coarse before the reach share": (BASE, BEFORE),
    "coarse": (BASE, {}),
    "paper-dp": ("paper-dp", {}),
    "footprint 0.5 m": (BASE, {**BEFORE, "footprint_radius": 0.5}),
    "gamma 2.5": (BASE, {**BEFORE, "gamma": 2.5}),
    "words x20": (BASE, {**BEFORE, "word_scaling": 20.0}),
    "words x40": (BASE, {**BEFORE, "word_scaling": 40.0}),
    "footprint 0.5 m, words x20": (BASE, {**BEFORE, "footprint_radius": 0.5, "word_scaling": 20.0}),
    "gamma 2.5, footprint 0.5 m": (BASE, {**BEFORE, "gamma": 2.5, "footprint_radius": 0.5}),
    "footprint 0.5 m, gamma 3.5": (BASE, {**BEFORE, "footprint_radius": 0.5, "gamma": 3.5}),
    "footprint 0.75 m": (BASE, {**BEFORE, "footprint_radius": 0.75}),
    "words x15": (BASE, {**BEFORE, "word_scaling": 15.0}),
    "footprint 0.75 m, words x15": (
        BASE,
        {**BEFORE, "footprint_radius": 0.75, "word_scaling": 15.0},
    ),
    "footprint 0.75 m, words x20": (
        BASE,
        {**BEFORE, "footprint_radius": 0.75, "word_scaling": 20.0},
    ),
    "words x5": (BASE, {**BEFORE, "word_scaling": 5.0}),
    "gamma 3.5": (BASE, {**BEFORE, "gamma": 3.5}),
    "alpha 1e5": (BASE, {**BEFORE, "alpha": 1e5}),
    "words-at-cell": (BASE, {**BEFORE, "word_footprint_radius": 0.0}),
    "coarse before the reach share, --refine never": (rh.UNREFINED, BEFORE),
    "coarse, --refine never": (rh.UNREFINED, {}),
    "reach 0.25": (BASE, {REACH: 0.25, **UNCUT}),
    "reach 0.5": (BASE, {REACH: 0.5, **UNCUT}),
    "reach 0.25, --refine never": (rh.UNREFINED, {REACH: 0.25, **UNCUT}),
    "reach 0.5, --refine never": (rh.UNREFINED, {REACH: 0.5, **UNCUT}),
    "reach 0.25, stage two too": (BASE, {REACH: 0.25, **UNCUT, STAGE_TWO: {REACH: 0.25}}),
    "reach 0.1": (BASE, {REACH: 0.1, **UNCUT}),
    "reach 0.1, --refine never": (rh.UNREFINED, {REACH: 0.1, **UNCUT}),
    "reach 0.2": (BASE, {REACH: 0.2, **UNCUT}),
    "reach 0.25 within 2 m": (BASE, {REACH: 0.25, REACH_RADIUS: 2.0, **UNCUT}),
    "reach 0.25 within 3 m": (BASE, {REACH: 0.25, REACH_RADIUS: 3.0, **UNCUT}),
    "reach 0.25 in rooms": (BASE, {REACH: 0.25, **IN_ROOMS}),
    "reach 0.2 in rooms": (BASE, {REACH: 0.2, **IN_ROOMS}),
    "reach 0.25 in rooms, stage two too": (
        BASE,
        {REACH: 0.25, **IN_ROOMS, STAGE_TWO: {REACH: 0.25, **IN_ROOMS}},
    ),
    "reach 0.2 in rooms, stage two too": (
        BASE,
        {REACH: 0.2, **IN_ROOMS, STAGE_TWO: {REACH: 0.2, **IN_ROOMS}},
    ),
}
"""Name -> (preset, overrides), in the order run: the references at the same sweeps first
(``coarse before the reach share``, ``coarse``, ``paper-dp``), then the variants by the prior
that they could raise held-out top-1 (finer concepts around where words were said) without
losing the places; the reach shares last (the open plans' borders). Since 2026-12-06, 18:40
UTC each variant measured on the old ``coarse`` says so in its overrides (:data:`BEFORE`,
:data:`UNCUT`; the module docstring)."""


@contextlib.contextmanager
def variant(name: str):
    """``(preset, overrides)`` of variant ``name`` for fits made within: its :data:`STAGE_TWO`
    settings, if any, taken out of the overrides and put into every refinement's settings
    (``refine.refined_settings`` patched, restored on leaving). An override of None
    (:data:`UNCUT`) stays in the overrides: ``real_houses.settings_of`` sets it over the
    preset's value."""
    base, overrides = VARIANTS[name]
    stage_two = overrides.get(STAGE_TWO)
    overrides = {k: v for k, v in overrides.items() if k != STAGE_TWO}
    original = refine.refined_settings
    patched = (
        patch.object(refine, "refined_settings",
                     lambda settings, model_cells, map_cells: original(
                         settings, model_cells, map_cells).replace(**stage_two))
        if stage_two else contextlib.nullcontext()
    )  # fmt: skip
    with patched:
        yield base, overrides


def variant_settings(name: str) -> SpCoSettings:
    """The first stage's settings of variant ``name``'s fits, resolved as ``real_houses``'
    ``fit_result`` resolves them (``real_houses.settings_of``, of :func:`variant`'s preset and
    overrides)."""
    with variant(name) as (base, overrides):
        return rh.settings_of(base, **overrides)


def preparation(name: str) -> dict[str, object]:
    """What a record of variant ``name`` stores of how its fits prepared the data: every field
    of :func:`variant_settings`' :class:`~spcopyro.config.preparation.DataPreparation`, and its
    :data:`STAGE_TWO` settings (``"stage two"``) where it has them, as JSON values."""
    prepared = dataclasses.asdict(variant_settings(name).data)
    stage_two = VARIANTS[name][1].get(STAGE_TWO)
    return json.loads(json.dumps(prepared | ({"stage two": stage_two} if stage_two else {})))


def check_preparations(report: dict, out: Path) -> str | None:
    """Why ``report`` (read from ``out``) cannot be resumed, or None: a record (a variant and
    seed's public results, its ``"synthetic"``) whose stored ``"preparation"`` differs from what
    the variant now resolves to (:func:`preparation`; the preset or :data:`VARIANTS` changed
    since). A record without one (written before 2026-12-06, 18:40 UTC) is trusted, as are
    variants no longer in :data:`VARIANTS`."""
    for name, seeds in report.get("variants", {}).items():
        if name not in VARIANTS:
            continue
        now = preparation(name)
        for seed, row in seeds.items():
            for what, record in (("public", row), ("synthetic", row.get("synthetic", {}))):
                stored = record.get("preparation", now)
                for field in [*now, *(f for f in stored if f not in now)]:
                    if stored.get(field) != now.get(field):
                        return (f"{out}: {name!r} {seed}'s {what} results were fitted with "
                                f"{field} = {stored.get(field)!r}, the variant now resolves to "
                                f"{now.get(field)!r}; give another --out, or rename the "
                                "variant's entry in the JSON to what it measured")  # fmt: skip
    return None
