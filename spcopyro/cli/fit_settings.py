"""``spcopyro fit``'s command line turned into settings: the inference options the preset
recommends where the command line left them unset (:func:`apply_preset_inference`), the checks
of ``--update`` (:func:`check_update_args`), and the model and data settings and the method's
options of the run (:func:`fit_settings`; ``--cell-size``: :func:`cell_size_setting`)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from spcopyro.cli.common import _concentrations, _feature_scaling
from spcopyro.cli.fit_options import SAMPLERS, method_options
from spcopyro.cli.fit_refine import prepares_data
from spcopyro.config import SpCoSettings, preset, preset_inference
from spcopyro.data.word_weighting import auto_word_weighting, resolved_settings
from spcopyro.gibbs.chains import chain_processes

if TYPE_CHECKING:
    from spcopyro.data import House

__all__ = [
    "apply_preset_inference",
    "cell_size_setting",
    "check_update_args",
    "fit_settings",
    "word_weighting_note",
]


def apply_preset_inference(args: argparse.Namespace) -> None:
    """Fill the inference options the command line left unset (None) with what the preset
    recommends (:func:`spcopyro.config.preset_inference`: ``auto`` starts from the rooms, adds
    merge moves and reports the variation-of-information point estimate), where they apply to
    this run, else with the plain defaults (random start, no merge moves, the highest-log-joint
    state visited). The
    start and the merge moves are Gibbs's: on the public houses the rooms start is one room, and
    a variational method started there stays one concept (it has no move that splits)."""
    recommended = preset_inference(args.preset)
    # --resume continues chains that started as the preset says: their start is the preset's
    # (the checkpoint checks it), so only --update and --init-from start elsewhere.
    starts_elsewhere = any(x is not None for x in (args.update, args.init_from))
    samples = args.sweeps != "auto" and args.method in SAMPLERS
    if args.init is None:  # the rooms start is Gibbs's: its merge (split) moves leave it
        gibbs = args.method == "gibbs" and not starts_elsewhere
        args.init = recommended.get("init", "random") if gibbs else "random"
    args.preset_filled = set()  # the move rates the preset chose, not the command line
    for move in ("merge_moves", "region_moves"):
        rate = recommended.get(move)
        if getattr(args, move) is None and args.method == "gibbs" and rate is not None:
            setattr(args, move, rate)
            args.preset_filled.add(move)
    refinable = args.method == "gibbs" and args.update is None
    # the option that keeps a fit the preset would refine unrefined: fit says so where a Gibbs
    # fit prints its decision (fit_refine.report_unrefined); a given preparation stays silent
    args.unrefined_by = None
    if args.refine is None:  # a preparation given on the command line is kept, not refined away
        refine = recommended.get("refine", "never")
        prepared = prepares_data(args)  # the reason, as for a Gibbs fit: nothing to say
        if refine != "never" and not refinable and not prepared:
            args.unrefined_by = f"--method {args.method}" if args.method != "gibbs" else "--update"
        args.refine = refine if refinable and not prepared else "never"
    elif args.refine != "never" and not refinable:
        raise ValueError(
            f"--refine {args.refine} refines a Gibbs fit (not --update or another --method): "
            "leave it out or pass --refine never"
        )
    if args.point_estimate is None:
        usable = samples and args.marginal_samples > 0
        args.point_estimate = (
            recommended.get("point_estimate", "map-visited") if usable else "map-visited"
        )


def check_update_args(args: argparse.Namespace) -> None:
    """``--update OUT``: a finished fit's folder, and no option that chooses another start
    (``--resume`` may name the finished update a stopped run kept,
    :mod:`spcopyro.cli.fit_finished`, whose outputs it writes)."""
    from spcopyro.cli.fit_finished import is_finished_fit

    resume = args.resume is not None and not is_finished_fit(args.resume)
    if resume or args.init_from is not None or args.init is not None:
        given = "--resume" if resume else (
            "--init-from" if args.init_from is not None else "--init"
        )  # fmt: skip
        raise ValueError(f"--update starts from the saved fit; {given} chooses another start")
    if args.sweeps == "auto":
        raise ValueError("--update runs a number of --sweeps; --sweeps auto starts from scratch")
    if not (Path(args.update) / "result.npz").is_file():
        raise FileNotFoundError(
            f"--update {args.update}: no finished fit there (a folder written by spcopyro fit "
            "--out, holding result.npz)"
        )


def cell_size_setting(value: str | None) -> float | None | str:
    """``--cell-size``: None (unset: the preset's), 'map' (the map's own cells) or metres."""
    if value is None:
        return None
    if value == "map":
        return "map"
    try:
        size = float(value)
    except ValueError:
        size = float("nan")
    if not (math.isfinite(size) and size > 0):
        raise ValueError(f"--cell-size {value!r}: give a positive number of metres or 'map'")
    return size


def fit_settings(args: argparse.Namespace, house: House) -> tuple[SpCoSettings, object | None]:
    """The model and data settings and the method's options (None: its defaults) of ``fit``."""
    overrides = dict(
        prior=args.prior, num_concepts=args.concepts, gamma=args.gamma, alpha=args.alpha,
        beta=args.beta, chi=args.chi, connectivity=args.connectivity,
        concentrations=_concentrations(args.concentration),
        word_weighting=args.word_weighting,
        feature_scaling=_feature_scaling(args.feature_scaling),
        snap_distance=args.snap_distance, footprint_radius=args.footprint,
        cell_size=cell_size_setting(args.cell_size), word_scaling=args.word_scaling,
        footprint_kernel=args.footprint_kernel, footprint_fov=args.footprint_fov,
        word_footprint_radius=args.word_footprint,
        footprint_reach_share=args.footprint_reach_share,
        footprint_reach_radius=args.footprint_reach_radius,
        footprint_reach_door_width=args.footprint_reach_door_width,
    )  # fmt: skip
    further = {m.name for m in house.observations.modalities}
    for name in overrides["concentrations"] or {}:
        if name not in further:
            has = (
                f"its further modalities: {', '.join(sorted(further))}"
                if further
                else "it has no further modality"
            )
            raise ValueError(
                f"--concentration {name}=...: the house {house.name!r} has no modality {name!r} "
                f"(no modality_{name}.csv; {has})"
            )
    if args.preset == "paper-dirichlet" and args.concepts is None and house.category_names:
        overrides["num_concepts"] = len(house.category_names)
    settings = preset(args.preset, **overrides)
    if args.update is None:  # an update keeps the saved fit's (fit_update.update_settings)
        settings = resolved_settings(settings, house.observations)
    options = method_options(args)
    if args.method == "gibbs":
        chain_processes()  # a bad $SPCOPYRO_CHAIN_PROCESSES: before anything is printed
    return settings, options


def word_weighting_note(args: argparse.Namespace, house: House, weighting: str) -> str | None:
    """Why the fit's word weighting (``weighting``, resolved) is the one it is, for the data
    line, where the command line left it to ``auto`` (None where ``--word-weighting`` or
    ``--tfidf`` chose it), from the rule's own counts
    (:class:`spcopyro.data.word_weighting.AutoWeighting`): the sentences against the share
    tf-idf needs, None for a house of single words (counted, as always: nothing to explain);
    under ``--update``, that it is the updated fit's, where it is tf-idf or this data alone
    would choose otherwise (None where both count: the public houses)."""
    if args.word_weighting not in (None, "auto"):
        return None
    decision = auto_word_weighting(house.observations)
    if args.update is not None:
        return decision.kept_note(weighting, args.update)
    return decision.note
