"""``fit --refine``: the refinement of a coarse fit on the map's own cells, as the command
runs it (the decision printed, Ctrl-C keeping the coarse chains); :mod:`spcopyro.fit.refine`
holds the method."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import argparse

    from spcopyro.config import SpCoSettings
    from spcopyro.data import House
    from spcopyro.fit.gibbs_chains import FitCheckpoint
    from spcopyro.results.result import SpCoResult

__all__ = ["refine"]


def refine(
    args: argparse.Namespace,
    first: SpCoResult,
    chains: int,
    *,
    model: House,
    on_map: House,
    settings: SpCoSettings,
    options: object | None,
    keeper: FitCheckpoint | None,
) -> list[SpCoResult] | None:
    """``--refine``: the decision for ``first`` (the kept chain of the fit of ``model``, the
    house on its model grid) printed, and where it refines, the chains refitted on the map's own
    cells (``on_map``) from it (:mod:`spcopyro.fit.refine`). Else None, ``first`` recording the
    decision in place. Ctrl-C there keeps the finished first stage's checkpoint (``keeper``):
    resuming it runs the refinement again."""
    from spcopyro.fit.gibbs_chains import FitInterrupted
    from spcopyro.fit.house import fit_house_chains
    from spcopyro.fit.refine import refine_chains, refine_decision, refined_settings

    decision = refine_decision(first, model, args.refine)
    if not decision.refine:
        print(f"not refined      {decision.reason}")
        first.inference["refine"] = decision.to_json()  # config.json says why
        return None
    alpha = refined_settings(settings, model.grid.num_free, on_map.grid.num_free)
    print(f"refining         {decision.reason}: the {chains} x {len(first.trace.objective)} "
          f"sweeps on {first.grid.resolution:g} m cells (best log joint "
          f"{first.best_objective:.1f}) go on on the map's own {on_map.grid.resolution:g} m "
          f"cells, images as 100 draws, words at their cell, alpha "
          f"{alpha.model.alpha:.3g}")  # fmt: skip
    try:
        _, refined = refine_chains(
            first, on_map, settings, args.refine, fit_house_chains, decision=decision,
            method="gibbs", options=options, sweeps=args.sweeps,
            seeds=[args.seed + k for k in range(chains)], threads=args.threads,
            marginal_samples=args.marginal_samples, point_estimate=args.point_estimate,
            chain_workers=args.chain_workers,
        )  # fmt: skip
    except KeyboardInterrupt:
        kept = keeper.save() if keeper is not None else None
        raise FitInterrupted("while refining on the map's own cells", kept) from None
    return refined
