"""What ``spcopyro fit --preset NAME`` runs beyond the preset's model and data settings, for
library fits: :func:`preset_fit_kwargs` gives :func:`~spcopyro.fit.house.fit_house` the
preset's recommended inference settings (:func:`~spcopyro.config.preset_inference`), and
:func:`log_skipped_preset_inference` warns when a fit runs without them."""

from __future__ import annotations

from spcopyro._util.messages import warn_once
from spcopyro.config import PRESETS, SpCoSettings, preset_inference
from spcopyro.fit.starts import Init, init_name
from spcopyro.gibbs.options import GibbsOptions

__all__ = ["log_skipped_preset_inference", "preset_fit_kwargs"]


def preset_fit_kwargs(name: str, marginal_samples: int = 50) -> dict[str, object]:
    """The :func:`fit_house` keywords of a Gibbs fit that runs preset ``name`` as ``spcopyro fit
    --preset name`` does: its recommended start, merge moves and point estimate
    (:func:`~spcopyro.config.preset_inference`), with ``marginal_samples`` label maps kept when
    that point estimate needs them. Empty recommendations give the paper's run."""
    recommended = preset_inference(name)
    estimate = str(recommended.get("point_estimate", "map-visited"))
    return {
        "options": GibbsOptions(
            merge_moves=float(recommended.get("merge_moves", 0.0)),
            region_moves=float(recommended.get("region_moves", 0.0)),
        ),
        "init": str(recommended.get("init", "random")),
        "marginal_samples": marginal_samples if estimate != "map-visited" else 0,
        "point_estimate": estimate,
        "refine": str(recommended.get("refine", "never")),
    }


def log_skipped_preset_inference(
    settings: SpCoSettings,
    init: Init,
    options: object | None,
    point_estimate: str,
    refine: str = "never",
) -> dict[str, object]:
    """Warn (logger ``"spcopyro"``) when a Gibbs fit from a preset's settings runs without the
    inference settings that preset recommends (:func:`~spcopyro.config.preset_inference`), which
    ``spcopyro fit`` applies: the library and the command would give different maps. Once a
    process for each preset and settings run (:func:`~spcopyro._util.messages.warn_once`).
    Returns those skipped, name -> recommended value (empty: none, or settings of no preset)."""
    recommended = preset_inference(settings.preset) if settings.preset in PRESETS else {}
    if not recommended:
        return {}
    running = {
        "init": init_name(init),
        "merge_moves": float(getattr(options, "merge_moves", 0.0) or 0.0),
        "region_moves": float(getattr(options, "region_moves", 0.0) or 0.0),
        "point_estimate": point_estimate,
        "refine": refine,
    }
    skipped = {k: v for k, v in recommended.items() if k in running and running[k] != v}
    key = ("preset inference", settings.preset, tuple((k, running[k]) for k in skipped))
    if skipped:  # once: a study's cells ran it hundreds of times
        recommends = ", ".join(f"{k}={v!r}" for k, v in skipped.items())
        runs = ", ".join(f"{k}={running[k]!r}" for k in skipped)
        warn_once(key, f"preset {settings.preset!r} recommends {recommends} (what spcopyro fit "
                  f"runs); this fit runs {runs}, so its map can differ from the command's: pass "
                  f"them (spcopyro.fit.house.preset_fit_kwargs({settings.preset!r}))")  # fmt: skip
    return skipped
