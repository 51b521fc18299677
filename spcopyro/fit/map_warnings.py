"""The warnings on a fit's reported map, said after the fit (logger ``"spcopyro"``): a
degenerate map (:func:`log_degenerate_map`) and a weak-limit DP short of concept slots
(:func:`log_concept_slots`). :func:`log_map_warnings` logs both, for
:func:`~spcopyro.fit.house.fit_house` and ``spcopyro fit`` alike; the warnings of the settings
alone are :mod:`spcopyro.fit.setting_warnings`'."""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from spcopyro.fit.setting_warnings import freezes, gamma_warning
from spcopyro.inference.names import SAMPLERS
from spcopyro.results.map_checks import concept_slots_warning, house_map_warning

if TYPE_CHECKING:
    from spcopyro.data import House
    from spcopyro.results.result import SpCoResult

logger = logging.getLogger("spcopyro")


def log_degenerate_map(
    result: SpCoResult, house: House, default_preset_skipped: bool | None = None
) -> str | None:
    """Log (logger ``"spcopyro"``) and return the warning of a degenerate reported map -- one
    concept over most of the free cells while words said at different places lie inside it, or
    lie outside it in small concepts (:func:`spcopyro.results.map_checks.degenerate_map_warning`,
    with its ``default_preset_skipped``) -- else None."""
    sampled = result.method in SAMPLERS  # else --merge-moves needs --method gibbs
    snap, skipped = result.preparation.snap_distance, default_preset_skipped
    warning = house_map_warning(result.labels, house, snap, sampled, default_preset_skipped=skipped)
    if warning:
        logger.warning(warning)
    return warning


def log_concept_slots(result: SpCoResult) -> str | None:
    """Log (logger ``"spcopyro"``) and return the warning of a fit under the weak-limit DP prior
    whose reported map, or a refined fit's coarse stage (``inference["refine"]["coarse"]``),
    uses at least :data:`~spcopyro.results.map_checks.SATURATED_SLOTS` of its L concepts
    (:func:`~spcopyro.results.map_checks.concept_slots_warning`; disordered where
    :func:`~spcopyro.fit.setting_warnings.gamma_warning` warns, frozen where a sampler's gamma
    :func:`~spcopyro.fit.setting_warnings.freezes`), else None."""
    coarse = (result.inference.get("refine") or {}).get("coarse")
    stage = None if not coarse else (int(coarse["concepts"]), float(coarse["cell_size"]))
    config = result.config
    disordered = gamma_warning(config) is not None
    frozen = result.method in SAMPLERS and freezes(config)
    warning = concept_slots_warning(result.labels, result.grid, config, stage, disordered, frozen)
    if warning:
        logger.warning(warning)
    return warning


def log_map_warnings(
    result: SpCoResult, house: House, default_preset_skipped: bool | None = None
) -> None:
    """Log the warnings on ``result``'s reported map of ``house``: :func:`log_degenerate_map`
    (with its ``default_preset_skipped``), then :func:`log_concept_slots`."""
    log_degenerate_map(result, house, default_preset_skipped)
    log_concept_slots(result)
