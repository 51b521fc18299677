"""``fit --refine``: the refinement of a coarse fit on the map's own cells, as the command
runs it (the decision printed, Ctrl-C keeping the coarse chains); :mod:`spcopyro.fit.refine`
holds the method. ``fit --update``'s own lines (its settings after a refined fit, what it
printed) are in :mod:`spcopyro.cli.fit_update`."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import argparse

    from spcopyro.config import DataPreparation, SpCoSettings
    from spcopyro.data import House
    from spcopyro.fit.gibbs_chains import FitCheckpoint
    from spcopyro.fit.refine import RefineDecision
    from spcopyro.results.result import SpCoResult

__all__ = [
    "LARGE_REFINEMENT_CELLS", "REFINED_AWAY", "check_refinable", "prepares_data", "refine",
    "replaced_options", "report_unrefined",
]  # fmt: skip

LARGE_REFINEMENT_CELLS = 100_000
"""From this many free cells of the map, the refinement's decision comes with a note that its
sweeps take much longer than the first stage's (a 228,934-cell map: 5000 sweeps of the 0.25 m
grid's 22,179 cells in ~4 min, then 4-7 sweeps a second on the map's own cells, 12-18 min more;
docs/variational.md, "From spcopyro fit on a large map") and how to stop at the first stage."""

REFINED_AWAY = ("cell_size", "feature_scaling", "word_scaling", "footprint",
                "footprint_kernel", "footprint_fov", "word_footprint",
                "footprint_reach_share", "footprint_reach_radius",
                "footprint_reach_door_width")  # fmt: skip
"""The options of the data preparation the refinement replaces (:mod:`spcopyro.fit.refine`):
given on the command line, the recommended refinement is not run."""


def prepares_data(args: argparse.Namespace) -> bool:
    """Whether the command line gives a data preparation of its own (:data:`REFINED_AWAY`)."""
    return any(getattr(args, name, None) is not None for name in REFINED_AWAY)


def _map_cells_cause(args: argparse.Namespace, settings: SpCoSettings, on_map: House) -> str:
    """Which option leaves the model on the map's own cells (``on_map``'s), as the command line
    names it: ``--cell-size map``, a ``--cell-size`` or preset cell size that rounds to the
    map's cells, a preset without one, or a map too thin to coarsen."""
    from spcopyro.maps.coarse import coarsening_factor

    size = settings.data.cell_size
    resolution = f"{on_map.grid.resolution:g} m"
    given = f"--cell-size {args.cell_size}" if args.cell_size is not None else None
    if size is None or size == "map":
        named = given or f"--preset {args.preset} (no cell size)"
        return f"{named} fits on the map's own {resolution} cells"
    named = given or f"--preset {args.preset}'s {size:g} m cells"
    s = "s" if given else ""
    if coarsening_factor(on_map.grid.resolution, size) == 1:
        return f"{named} round{s} to the map's own {resolution} cells"
    return f"{named} leave{s} no free cell of the map (a warning above says so)"


def report_unrefined(args: argparse.Namespace, model: House) -> None:
    """Print why a fit the preset would refine (``--refine`` left unset) is not: another
    ``--method`` or ``--update`` (``args.unrefined_by``, set by
    :func:`spcopyro.cli.fit_settings.apply_preset_inference`), and the cells it stays on
    (``model``'s grid), on the line where a Gibbs fit prints its decision (:func:`_decide`).
    Nothing where nothing was kept from refining."""
    by = getattr(args, "unrefined_by", None)
    if by is None:
        return
    resolution = f"{model.grid.resolution:g} m"
    cells = (f"the {resolution} model grid" if model.grid.coarsened_from is not None
             else f"the map's own {resolution} cells")  # fmt: skip
    if by == "--update":
        print(f"not refined      --refine refines a new fit only: --update continues the saved "
              f"fit on {cells}")  # fmt: skip
    else:
        print(f"not refined      --refine refines --method gibbs fits only: {by} keeps {cells}")


def check_refinable(
    args: argparse.Namespace, settings: SpCoSettings, model: House, on_map: House
) -> None:
    """``--refine always`` refines a fit on model cells coarser than the map: refused before the
    fit, naming the option that leaves ``model`` on the map's own cells (``on_map``'s); with
    ``--refine auto`` the fit is not refined, the ``not refined`` line says why (:func:`_decide`).
    """
    if args.refine != "always" or model.grid.coarsened_from is not None:
        return
    raise ValueError(
        "--refine always refits a fit on model cells coarser than the map on the map's own "
        f"cells, and {_map_cells_cause(args, settings, on_map)}: leave out --refine always "
        "(--refine auto does not refine there), or give --cell-size METRES coarser than the "
        f"map's {on_map.grid.resolution:g} m cells"
    )


_FLAGS = {"footprint_radius": "--footprint", "word_footprint_radius": "--word-footprint"}
"""The :class:`~spcopyro.config.preparation.DataPreparation` fields whose option of
:data:`REFINED_AWAY` is not ``--`` and the field's name in dashes."""


def replaced_options(
    settings: SpCoSettings, refined: DataPreparation
) -> dict[str, dict[str, object]]:
    """The data preparation options the command line gave that the refinement replaces:
    ``--flag`` -> ``{"given": the first stage's value, "refinement": the refinement's}``, by
    :func:`spcopyro.fit.refine.replaced_preparation`'s rule (``fit_house``'s warning names the
    same fields): ``settings`` are the command line's (its options the preset's overrides,
    ``settings.chosen``), ``refined`` the refinement's preparation. Empty for a command line
    that gave none (the default fit)."""
    from spcopyro.fit.refine import replaced_preparation

    return {
        _FLAGS.get(field, "--" + field.replace("_", "-")): change
        for field, change in replaced_preparation(settings, refined).items()
    }


def _shown(value: object) -> str:
    """An option's value as the command line writes it (None: ``none``)."""
    if value is None:
        return "none"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _replaced_note(replaced: dict[str, dict[str, object]]) -> str:
    """The note ``fit`` prints (stderr) when the refinement replaces options the command line
    gave (:func:`replaced_options`): which, with what, and how to keep them."""
    changes = ", ".join(f"{flag} {_shown(v['given'])} -> {_shown(v['refinement'])}"
                        for flag, v in replaced.items())  # fmt: skip
    return (f"note: the refinement on the map's own cells prepares the data as preset auto "
            f"does, replacing {changes}; the first stage used yours (config.json: "
            "inference.refine.replaced); --refine never keeps them for the whole fit, "
            "--cell-size map fits with them on the map's own cells")  # fmt: skip


def refine(
    args: argparse.Namespace,
    results: list[SpCoResult],
    kept: int,
    *,
    model: House,
    on_map: House,
    settings: SpCoSettings,
    options: object | None,
    keeper: FitCheckpoint | None,
    chains: int | None = None,
    sweeps: int | None = None,
    point_estimate: str | None = None,
    source: str | None = None,
) -> tuple[bool, list[SpCoResult]]:
    """``--refine``: the decision for ``results[kept]`` (the kept chain of the fit of ``model``,
    the house on its model grid) printed; whether it refined, and the chains to report: the
    chains refitted on the map's own cells (``on_map``) from it, or ``results``, the kept chain
    recording the decision (:func:`spcopyro.fit.refine.refine_chains`). Ctrl-C there keeps the
    finished first stage's checkpoint (``keeper``): resuming it runs the refinement again.
    ``chains``, ``sweeps`` and ``point_estimate`` of the refinement: by default ``results``'
    count, ``--sweeps`` and ``--point-estimate`` (after ``--sweeps auto``: the chains run, the
    sweeps they needed to converge, and the preset's point estimate). ``source``: the data's
    origin for ``config.json`` (:func:`spcopyro.fit.house.provenance`)."""
    from spcopyro.fit.gibbs_chains import FitInterrupted
    from spcopyro.fit.house import fit_house_chains
    from spcopyro.fit.refine import refine_chains

    chains = len(results) if chains is None else chains
    decision, replaced = _decide(args, results[kept], chains, model, on_map, settings)
    first_threads = results[kept].provenance.get("threads")  # the first stage's, as it ran
    try:
        _, results = refine_chains(
            results, kept, on_map, settings, args.refine, fit_house_chains, decision=decision,
            warn_replaced=False, method="gibbs", options=options, sweeps=sweeps or args.sweeps,
            seeds=[args.seed + k for k in range(chains)], threads=args.threads,
            marginal_samples=args.marginal_samples,
            point_estimate=point_estimate or args.point_estimate, chain_workers=args.chain_workers,
            source=source,
        )  # fmt: skip
    except KeyboardInterrupt as stop:  # the refinement's own sweeps are not kept
        saved = keeper.save() if keeper is not None else None
        where = "while refining on the map's own cells"
        if isinstance(stop, FitInterrupted):  # how far the refinement's chains got
            where += f": {stop.where}"
        if saved is not None:
            where += "; the first stage is kept and resuming refines again"
        raise FitInterrupted(where, saved) from None
    if decision.refine:
        _report_threads(first_threads, results[0].provenance.get("threads"), on_map)
        results = [_with_replaced(r, replaced) for r in results]
    return decision.refine, results


def _with_replaced(result: SpCoResult, replaced: dict[str, dict[str, object]]) -> SpCoResult:
    """A refined ``result`` recording the options of the command line its refinement replaced
    (``inference.refine.replaced``, written to ``config.json``; empty when none were)."""
    import dataclasses

    record = {**result.inference["refine"], "replaced": replaced}
    return dataclasses.replace(result, inference={**result.inference, "refine": record})


def _report_threads(first: object, refined: object, on_map: House) -> None:
    """Print the refinement's thread count where it differs from the first stage's (``fit``'s
    ``threads`` line describes the first stage; the policy may choose again for the map's own
    cells, or under another load): config.json records the refinement's."""
    from spcopyro._util.messages import plural

    if refined is None or refined == first:
        return
    print(f"threads          the refinement on the map's {on_map.grid.num_free:,} free cells ran "
          f"{plural(int(refined), 'torch intra-op thread')}, the first stage {first} "
          "(config.json records the refinement's)")  # fmt: skip


def _decide(
    args: argparse.Namespace,
    first: SpCoResult,
    chains: int,
    model: House,
    on_map: House,
    settings: SpCoSettings,
) -> tuple[RefineDecision, dict[str, dict[str, object]]]:
    """The decision for ``first`` (the kept one of ``chains`` chains on ``model``'s grid),
    printed: ``refining ...``, why and on which cells, with the alpha that changes (the first
    stage's sweeps, cells and log joint are on the lines above and in config.json, the
    refinement's preparation in ``fit --help``), or ``not refined ...`` and why; and
    the options of the command line the refinement replaces (:func:`replaced_options`), named
    in a note (stderr) where there are any."""
    from spcopyro.fit.refine import refine_decision, refined_settings

    decision = refine_decision(first, model, args.refine)
    replaced: dict[str, dict[str, object]] = {}
    if decision.refine:
        cells, first_cells = on_map.grid.num_free, model.grid.num_free
        refined = refined_settings(settings, first_cells, cells)
        observed = _observed_cells(on_map, refined.data)
        alpha, why = _alpha_scaled(settings, refined, cells, first_cells)
        start = f" from the best of {chains} chains" if chains > 1 else ""
        print(f"refining         {decision.reason}: continuing{start} on the map's own "
              f"{on_map.grid.resolution:g} m cells ({observed} observed), {alpha}")  # fmt: skip
        if why is not None:  # the rule's words, indented under the line (fit's listings' way)
            print(why)
        replaced = replaced_options(settings, refined.data)
        if replaced:  # the user's own preparation: not replaced silently
            print(_replaced_note(replaced), file=sys.stderr)
        if cells >= LARGE_REFINEMENT_CELLS:  # the first stage's bar did not count this one
            print(f"note: the refinement sweeps the map's {cells:,} free cells, "
                  f"{cells / max(first_cells, 1):.0f}x the first stage's {first_cells:,}: it takes "
                  "much longer than the first stage (its own progress bar gives the time); "
                  "--refine never keeps the first stage's map, --method stochastic-vi fits large "
                  "maps in passes", file=sys.stderr)  # fmt: skip
    elif model.grid.coarsened_from is None:  # no coarser grid: which option says so
        print(f"not refined      {_map_cells_cause(args, settings, on_map)}: there is no "
              "coarser model grid to refine from")  # fmt: skip
    else:  # config.json says why too
        print(f"not refined      {decision.reason}")
    return decision, replaced


def _alpha_scaled(settings: SpCoSettings, refined: SpCoSettings, cells: int,
                  first_cells: int) -> tuple[str, str | None]:  # fmt: skip
    """The refining line's alpha with the sum that gave it, and the line under it that says why
    (None where alpha did not change): the first stage's alpha times the square of the free
    cells' ratio, ``cells`` on the map over ``first_cells`` on the model grid
    (:func:`~spcopyro.fit.refine.refined_settings`, which keeps alpha where the model grid has no
    free cells), so that the label counts' prior weighs what it did on the model grid. On the
    embedded house ``alpha 1.22e+09 (1e+07 x (3,620 / 328)^2)``, then ``  alpha grows as the
    free cells squared, so ...`` (under 100 characters)."""
    alpha = f"alpha {refined.model.alpha:.3g}"
    if refined.model.alpha == settings.model.alpha:
        return alpha, None
    return (f"{alpha} ({settings.model.alpha:.3g} x ({cells:,} / {first_cells:,})^2)",
            "  alpha grows as the free cells squared, so the label counts' prior weighs as on "
            "the model grid")  # fmt: skip


def _observed_cells(house: House, data: DataPreparation) -> int:
    """How many of ``house``'s free cells hold counts under ``data`` (``concepts.json``'s
    ``observed_cells`` of a refined fit add up to it)."""
    from spcopyro.data import prepared_cell_counts

    counts = prepared_cell_counts(house.grid, house.observations, data, source=house.source,
                                  warn=False)  # fmt: skip
    return len(counts.cells)
