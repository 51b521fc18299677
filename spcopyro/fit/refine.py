r"""Refining a coarse fit on the map's own cells where the images tell the places apart
(issue 21; the numbers in docs/real_houses.md, "Refinement on the map's cells").

The default preset ``coarse`` fits on 0.25 m model cells, counts an image histogram as one
observation, spreads each utterance over a 0.75 m footprint and a fifth of each observation's
weight over its Voronoi cell within its room (cut at 1 m doorways): right for houses whose images
follow the camera's view rather than the place (the public houses), and the reason its borders
blur by up to a footprint's radius where the images would have placed them (the dense synthetic
houses, rooms meeting in wide openings). Whether the images tell places apart needs the places;
the coarse fit's concepts stand in for them (never a truth):

1. **Decide** (:func:`refine_decision`): the share of the images' variance the coarse fit's
   concepts explain (:func:`~spcopyro.fit.image_separation.image_separation`, ``explained``).
   ``refine="auto"`` refines when it is at least :data:`SEPARATES` = 0.5: the midpoint between
   the truth regions' 0.15-0.31 on the public houses and 0.72-0.80 on houses whose images are
   drawn per place (measured before any fit was scored).
2. **Refine** (:func:`refine_chains`): the same model on the map's own cells with preset
   ``auto``'s data preparation -- each histogram as 100 draws (``floor100``), each utterance
   once at its cell, no footprint and no reach share (:func:`refined_settings`) -- started from
   the coarse map refined to the map's cells (:func:`~spcopyro.fit.starts.result_labels`), with
   the same sampler options (but no ``anneal_sweeps``: annealing is for a start that is not
   yet a map), sweeps and seeds. After ``--sweeps auto`` (``sweeps="auto"``) the refinement
   runs as many sweeps as the coarse chains needed to converge, with the point estimate asked
   for, as a fit of that many sweeps would be refined: its chains all start from the kept
   coarse one, so an R-hat of theirs would not check what the coarse stage's dispersed starts
   did, and a single visited state on the map's cells keeps about 1 % of them as one-cell
   concepts, which the variation-of-information point estimate over the samples does not.

**Why alpha is scaled.** With pi integrated out, the label counts' term of the log joint is the
Dirichlet-multinomial :math:`\log DM(N_1..N_L \mid \alpha/L)`; a partition of the ``N`` cells
into shares :math:`s_l` gains about :math:`N^2 (1 - \sum_l s_l^2) / (2\alpha/L)` nats by
collapsing (docs/real_houses.md, "Why the posterior preferred one concept"). On ``k^2`` times as
many cells the same partition would gain ``k^4`` times as much, which at the public maps' 0.05 m
is what made ``auto`` put whole houses in one concept. The refinement therefore takes

.. math::  \alpha_\text{map} = \alpha \, (N_\text{map} / N_\text{model})^2,

which keeps that term what it was on the model grid: the prior over how the map is shared out
does not change with the cell size. (Measured on the open-plan synthetic houses, where the
images alone do not hold the categories of one open space apart: alpha 1e7 on the map's cells
0.534, 1e8 0.626, 1e9 0.645, 1e10 0.653, against the coarse fit's 0.656.)

The refined result is on the map's cells (its ``grid`` is the map, not a coarsening) and records
the decision, the coarse stage (its preparation among it) and the refinement's alpha and
preparation in ``result.inference["refine"]``.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from contextvars import ContextVar
from typing import Any

import numpy as np

from spcopyro._util.context import set_within
from spcopyro.config import DataPreparation, SpCoConfig, SpCoSettings
from spcopyro.data import House
from spcopyro.data.counts import KEEPS, scale_features, scaled_away
from spcopyro.data.model_grid import model_house
from spcopyro.fit.image_separation import ImageSeparation, image_labels, image_separation
from spcopyro.results.result import SpCoResult

__all__ = [
    "KEEPS",
    "REFINE_MODES",
    "SEPARATES",
    "RefineDecision",
    "check_coarse",
    "map_house",
    "on_map_cells",
    "refine_chains",
    "refine_decision",
    "refined_settings",
    "replaced_preparation",
    "with_decision",
]

logger = logging.getLogger("spcopyro")

COARSE_STAGE_MODEL: ContextVar[SpCoConfig | None] = ContextVar(
    "spcopyro_coarse_stage_model", default=None
)
"""While a refinement runs, the model settings of its coarse stage, whose warnings that stage
logged: the refinement's ``prepare_model_data`` does not log them again (a warning about gamma
came twice)."""

REFINE_MODES: tuple[str, ...] = ("auto", "never", "always")
"""``auto``: refine where the coarse fit's concepts explain the images; ``never``; ``always``."""

SEPARATES = 0.5
"""``refine="auto"`` refines when the coarse fit's concepts explain at least this share of the
images' variance (module docstring)."""


def check_refine(refine: str) -> str:
    if refine not in REFINE_MODES:
        raise ValueError(f"refine must be one of {REFINE_MODES}, got {refine!r}")
    return refine


def on_map_cells(model: House) -> str:
    """Why a fit of ``model`` is not refined when its grid is the map's own (no coarser model
    grid: cell size None or ``"map"``, one that rounds to the map's cells, or a map too thin to
    coarsen)."""
    return (f"the fit is on the map's own {model.grid.resolution:g} m cells: there is no coarser "
            "model grid to refine from")  # fmt: skip


def check_coarse(refine: str, model: House) -> None:
    """``refine="always"`` refits a fit on model cells coarser than the map: refused (before
    the fit) where ``model``'s grid is the map's own; ``"auto"`` then does not refine
    (:func:`on_map_cells`). Refitting the same cells with the refinement's preparation is a fit
    with ``preset("auto")``'s data preparation, not a refinement."""
    if refine == "always" and model.grid.coarsened_from is None:
        raise ValueError(f"refine='always' refits a fit on model cells coarser than the map, "
                         f"and {on_map_cells(model)}: pass refine='auto' or 'never', or a "
                         "settings cell_size coarser than the map's cells")  # fmt: skip


def map_house(house: House) -> House:
    """The house on its map's own cells: ``house`` itself, or the map a coarsened house's grid
    was made from (``grid.coarsened_from``; its truth, kept per model cell, is dropped)."""
    if house.grid.coarsened_from is None:
        return house
    return dataclasses.replace(house, grid=house.grid.coarsened_from, truth=None)


def refined_settings(settings: SpCoSettings, model_cells: int, map_cells: int) -> SpCoSettings:
    """``settings``' model on the map's own cells with preset ``auto``'s data preparation
    (images as 100 draws, words once at their cell, no footprint) and alpha scaled by
    ``(map_cells / model_cells)^2`` (module docstring). The snap distance and the words'
    weighting stay as they were."""
    scale = (map_cells / model_cells) ** 2 if model_cells > 0 else 1.0
    return settings.replace(
        alpha=settings.model.alpha * scale, feature_scaling="floor100", word_scaling=1.0,
        footprint_radius=0.0, word_footprint_radius=None, footprint_fov=None, cell_size=None,
        footprint_reach_share=0.0, footprint_reach_radius=None, footprint_reach_door_width=None,
    )  # fmt: skip


REPLACED_FIELDS = ("feature_scaling", "word_scaling", "footprint_radius", "footprint_kernel",
                   "footprint_fov", "word_footprint_radius", "footprint_reach_share",
                   "footprint_reach_radius", "footprint_reach_door_width")  # fmt: skip
"""The :class:`~spcopyro.config.preparation.DataPreparation` fields :func:`refined_settings` sets a
value of its own for (the cell size too, but the refinement is on the map's cells by definition)."""


UNUSED = "unused (no footprint)"
"""What :func:`replaced_preparation` gives as the refinement's footprint kernel or field of view
where it has no footprint."""


def replaced_preparation(
    settings: SpCoSettings, refined: DataPreparation
) -> dict[str, dict[str, object]]:
    """The fields of ``settings``' data preparation chosen by its caller that the refinement's
    preparation ``refined`` replaces: field -> ``{"given": settings', "refinement": refined's}``.
    The one rule of both entry points (``spcopyro fit`` names the fields by its options,
    :func:`spcopyro.cli.fit_refine.replaced_options`). Chosen
    (:meth:`~spcopyro.config.SpCoSettings.chose`): set by the caller (``settings.chosen``:
    :func:`~spcopyro.config.preset`'s overrides, as the command line passes its options, even
    one equal to the preset's value) or differing from the preset ``settings`` came from
    (``settings.preset``; every field of settings made without one). A footprint's kernel or
    field of view counts only where the first stage had a footprint that reads it (any
    footprint, the words' own too, for the kernel; the images' for the field of view): one given
    without it did nothing there, and is not replaced; the refinement's is :data:`UNUSED` where
    it has none. The words' own radius counts only where given (None is ``footprint_radius``'s),
    against the refinement's words at their cell (0). Empty for a preset's own preparation (the
    default fit: preset ``coarse``'s is the one the refinement is made to replace)."""
    first = settings.data
    replaced: dict[str, dict[str, object]] = {}
    for field in REPLACED_FIELDS:
        given, used = getattr(first, field), getattr(refined, field)
        if field == "word_footprint_radius":
            if given is None:
                continue  # the words' radius is footprint_radius's, named under that
            used = refined.words_radius  # the refinement's words: at their cell (its footprint's)
        if not settings.chose(field):
            continue  # the preset's value, not the caller's
        if field in ("footprint_kernel", "footprint_fov"):
            if not first.reads(field):
                continue  # no footprint in the first stage either: it did nothing there
            if not refined.reads(field):
                used = UNUSED  # kept in the refinement's preparation, doing nothing there
        if given != used:
            replaced[field] = {"given": given, "refinement": used}
    return replaced


def _replaced_warning(replaced: dict[str, dict[str, object]]) -> str:
    """The warning :func:`refine_chains` logs naming the ``replaced`` fields."""
    changes = ", ".join(f"{field} {v['given']!r} -> {v['refinement']!r}"
                        for field, v in replaced.items())  # fmt: skip
    return (f"refine: the refinement on the map's own cells prepares the data as preset 'auto' "
            f"does, replacing the settings' {changes}; the first stage used them "
            "(result.inference['refine']['coarse']['preparation']); refine='never' keeps them "
            "for the whole fit, settings with cell_size='map' fit with them on the map's own "
            "cells")  # fmt: skip


@dataclasses.dataclass(frozen=True)
class RefineDecision:
    """Whether a fit is refined on the map's cells, and why.

    Attributes:
        mode: ``"auto"``, ``"never"`` or ``"always"``.
        separation: the coarse fit's image separation (None when not measured: ``never``, or a
            fit without images).
        refine: whether the refinement runs.
        reason: one line saying why.
    """

    mode: str
    separation: ImageSeparation | None
    refine: bool
    reason: str

    def to_json(self) -> dict[str, Any]:
        separation = None if self.separation is None else dataclasses.asdict(self.separation)
        return {"mode": self.mode, "refine": self.refine, "reason": self.reason,
                "separation": separation, "threshold": SEPARATES}  # fmt: skip


def refine_decision(result: SpCoResult, house: House, refine: str = "auto") -> RefineDecision:
    """Whether to refine ``result``, a fit of ``house`` on its model grid (module docstring)."""
    check_refine(refine)
    if refine == "never":
        return RefineDecision(refine, None, False, "refine='never'")
    if house.grid.coarsened_from is None:  # the model's grid is the map's: nothing to refine
        check_coarse(refine, house)
        return RefineDecision(refine, None, False, on_map_cells(house))
    images = house.observations.image_features
    if images is None or images.shape[0] == 0 or not result.config.use_images:
        separation = None
        share = "no images to measure"
    else:
        separation = image_separation(images, image_labels(result, house))
        share = (f"the concepts explain {separation.explained:.0%} of the images' variance "
                 f"({separation.images} images in {separation.concepts} concepts)")  # fmt: skip
    if refine == "always":
        return RefineDecision(refine, separation, True, f"refine='always'; {share}")
    separates = separation is not None and separation.explained >= SEPARATES
    verdict = (f">= {SEPARATES:.0%}: the images tell the places apart" if separates else
               f"< {SEPARATES:.0%}: the images do not tell the places apart")  # fmt: skip
    if separation is None:
        verdict = "so the fit stays on its model grid"
    emptied = _emptied_by_floor100(images) if separates else 0
    if separates and emptied > KEEPS * images.shape[0]:  # the refinement would fit without them
        return RefineDecision(refine, separation, False, (
            f"{share} {verdict}, but the refinement counts each image as floor(100 f), which "
            f"leaves nothing of {emptied} of {images.shape[0]} images (every feature below "
            "0.01: a histogram over many classes, as spcopyro features' 1000 ImageNet "
            "classes), so the fit stays on its model grid, which reads them as probabilities"
        ))  # fmt: skip
    return RefineDecision(refine, separation, separates, f"{share} {verdict}")


def _emptied_by_floor100(images: np.ndarray) -> int:
    """How many of the image histograms ``images`` ``[T, K]`` hold something that
    floor(100 f), the refinement's counting (:func:`refined_settings`), makes all zero."""
    raw = np.asarray(images, dtype=np.float64)  # [T, K]
    return int(scaled_away(raw, scale_features(raw, "floor100")).size)


def with_decision(result: SpCoResult, decision: RefineDecision) -> SpCoResult:
    """``result`` recording a decision not to refine it (``inference["refine"]``, written to
    ``config.json``), so that a saved fit says why it stayed on its model grid."""
    return dataclasses.replace(result, inference={**result.inference, "refine": decision.to_json()})


def refine_chains(
    results: list[SpCoResult],
    kept: int,
    house: House,
    settings: SpCoSettings,
    refine: str,
    fit_chains: Callable[..., list[SpCoResult]],
    decision: RefineDecision | None = None,
    warn_replaced: bool = True,
    **chain_kwargs: Any,
) -> tuple[RefineDecision, list[SpCoResult]]:
    """The decision for ``results[kept]`` (the kept chain of a fit of ``house`` under
    ``settings``, on its model grid) and the chains to report: where it refines, the chains of
    the refinement -- ``fit_chains`` (:func:`~spcopyro.fit.house.fit_house_chains`) on the map's
    own cells under :func:`refined_settings`, every chain started from the kept one refined to
    the map's cells, with ``chain_kwargs`` (sweeps, seeds, options, ...), each recording the
    decision and the coarse stage in ``inference["refine"]``; else ``results``, the kept chain
    recording the decision (:func:`with_decision`). ``decision``: one already made by
    :func:`refine_decision` for the kept chain (else made here). Where it refines, one
    warning names the fields of ``settings``' preparation chosen by the caller that the
    refinement replaces (:func:`replaced_preparation`); ``warn_replaced=False`` for a caller
    that names them itself (``spcopyro fit``, by its options)."""
    first = results[kept]
    model = model_house(house, settings.data.cell_size)
    if decision is None:
        decision = refine_decision(first, model, refine)
    if not decision.refine:
        return decision, [with_decision(r, decision) if k == kept else r
                          for k, r in enumerate(results)]  # fmt: skip
    on_map = map_house(house)
    refined = refined_settings(settings, model.grid.num_free, on_map.grid.num_free)
    logger.info("refining on the map's %d cells: %s", on_map.grid.num_free, decision.reason)
    replaced = replaced_preparation(settings, refined.data) if warn_replaced else {}
    if replaced:  # the caller's own preparation: not replaced without a word
        logger.warning("%s", _replaced_warning(replaced))
    options = chain_kwargs.get("options")
    if getattr(options, "anneal_sweeps", 0):  # its start is the fitted map, not noise: only
        # the coarse stage anneals (annealed again: 0.984 against 0.990, docs/commands.md)
        chain_kwargs["options"] = dataclasses.replace(options, anneal_sweeps=0)
    with set_within(COARSE_STAGE_MODEL, settings.model):
        refits = fit_chains(on_map, refined, init=first, **chain_kwargs)
    record = {
        **decision.to_json(),
        "coarse": {
            "cell_size": float(model.grid.resolution), "free_cells": int(model.grid.num_free),
            "alpha": float(settings.model.alpha), "preparation": settings.data.to_json(),
            "best_log_joint": float(first.best_objective),
            "concepts": len(first.concepts_in_use()),
            "sweeps": len(first.trace.objective),
            "anneal_sweeps": int(getattr(options, "anneal_sweeps", 0)),  # the refinement's: 0
            "seconds": float(first.trace.seconds[-1]) if len(first.trace.seconds) else 0.0,
            "first_seconds": float(first.trace.seconds[0]) if len(first.trace.seconds) else 0.0,
            # sampled hyperparameters (hyper.*): the refinement samples its own from the preset's
            **({"hyperparameters": first.inference["hyperparameters"]}
               if first.inference.get("hyperparameters") else {}),
        },
        "alpha": float(refined.model.alpha),
        "preparation": refined.data.to_json(),  # the refinement's (config.json's data)
    }  # fmt: skip
    return decision, [
        dataclasses.replace(r, inference={**r.inference, "refine": record}) for r in refits
    ]
