"""Variants of the default preset scored on the public houses' region truth and held-out words.

    python benchmarks/coarse_variants.py [--sweeps 2000] [--seeds 0] [--variants NAME ...]
        [--out benchmarks/coarse_variants.json] [--quick]
        [--synthetic [--open-plan-seeds 10] [--synthetic-seeds 3] [--kinds KIND ...]]

Issue 21's study of 2026-12-06 (docs/real_houses.md, "Variants of `coarse` on the held-out
words"): does a setting of ``coarse`` keep the ARI targets and reach ``paper-dp``'s held-out word
top-1? For every variant (:data:`VARIANTS`: ``coarse`` with some of its settings changed, with
``coarse``'s inference settings; ``coarse``, ``coarse before the reach share`` and
``paper-dp`` as references) and fit seed, on each public house:

* the ARI against the region truth of a fit on all three trials
  (:func:`spcopyro.experiments.public_truth.public_truth`), the largest concept's share and the
  concepts holding >= 1 % of the free cells, scored as ``benchmarks/real_houses.py`` scores them;
* the held-out word scores, each trial held out in turn (``real_houses.heldout_fold_scores``,
  pooled per house by ``real_houses.fold_summary``): top-1, top-3, mean rank of the true word.

The ARI targets are judged as docs/real_houses.md does: the mean ARI above the baseline (E)
nearest utterance's mean over the five public houses (``real_houses.nearest_scores``, measured
by every run that judges a variant: 0.510; with ``--quick`` too, though one house is fitted), no
concept over 60 % of the free cells, every house's concept count within 2 of Table 2's.

Results go to the JSON after every house, and a variant and seed already there is skipped on a
rerun (``--out`` the same file), so a long run can be stopped and resumed. Prints one markdown
table: per variant and seed, the public mean ARI, the largest share (max over the houses), the
concept counts beside Table 2's, held-out top-1 (mean of houses and pooled over words) and the
mean rank (mean of houses).

``--synthetic``: the houses a variant was not tuned on instead, as ``benchmarks/real_houses.py``
checks the default (issue 21's targets before a variant could become the default), through its
functions: the synthetic open-plan houses (seeds 0..n-1, ``--open-plan-seeds``, 10) against
(F) geometry's mean ARI + 0.2 (the better of its 1 m and 2 m door widths) beside the oracle, the
dense and sparse houses (seeds 0..n-1, ``--synthetic-seeds``, 3) against mean ARIs of 0.98 and
0.93, and ``simulate --map`` on each public map (``real_houses.simulated_on``) against 0.9 for
each map's mean over the fit seeds (``--seeds``, default 0 1 2 here, as real_houses.py's
``--fit-seeds``). real_houses.py fits synthetic house seed s at fit seed s; fit seed f here fits
it at s + f (f = 0: its fits). Stored under ``"synthetic"`` of each variant and fit seed (the
public results and their resume untouched; one already there is skipped), a synthetic house's
baselines and oracle, the same for every variant and seed, once under
``"synthetic_baselines"``; prints one table, a row a variant over its fit seeds, each target
PASS or FAIL. ``--kinds``: only those of ``open-plan``, ``sparse``, ``dense`` and ``simulated``
(default all); a house already in the JSON is skipped, so a later run adds the other kinds, and a
variant's summary is over every house it has (a kind it has none of shows ``-``).

The variants and what each means: ``benchmarks/coarse_variant_settings.py`` (its docstring).
Since 86d6df4 (2026-12-06, 18:20 UTC) ``coarse`` is the default with a reach share of 0.2 in
rooms; the variants measured before keep their meaning through explicit overrides, and the old
default's stored results are ``coarse before the reach share`` (2026-12-06, 18:40 UTC).

So that a changed preset cannot silently change what a stored variant means (the resume mixing
results of two settings under one name), every record begun since 2026-12-06, 18:40 UTC (a
variant and seed's public results; its ``"synthetic"``) stores its data preparation
(``"preparation"``: ``coarse_variant_settings.preparation``, every field of the first stage's
``DataPreparation`` and the variant's stage-two settings), and a run refuses, before fitting,
a JSON with a record whose stored preparation differs from what the variant now resolves to
(one line naming the variant, seed, field and both values). Records without one (written
before) are trusted, as before.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np
import real_houses as rh
from bench_cli import COUNT, INDEX, dataset_root, quick_or, results_path, run_main
from coarse_variant_settings import BASE, VARIANTS, check_preparations, preparation, variant

from spcopyro.data import load_house
from spcopyro.experiments.public_truth import public_truth
from spcopyro.experiments.table import PUBLIC_CATEGORIES
from spcopyro.results.refined import coarse_stage


def public_scores(house, truth: np.ndarray, name: str, sweeps: int, seed: int) -> dict:
    """ARI, largest share, concepts >= 1 % of the variant's fit on every trial
    (``real_houses.fit_result``: its preset's settings with the overrides, and the preset's
    recommended inference settings), on the map's cells; whether it was refined."""
    start = time.perf_counter()
    with variant(name) as (base, overrides):
        result = rh.fit_result(house, base, sweeps, seed, **overrides)[0]
    labels = rh.on_map(result, house)
    refined = coarse_stage(result.inference) is not None
    return {**rh.scores(labels, truth, house.grid.free), "refined": refined,
            "seconds": time.perf_counter() - start}  # fmt: skip


def heldout_scores(house, name: str, sweeps: int, seed: int) -> dict:
    """Held-out word scores, every trial held out in turn (``real_houses.heldout_fold_scores``,
    pooled by ``real_houses.fold_summary``)."""
    with variant(name) as (base, overrides):
        model = {name: rh.preset_model(base, sweeps, seed, **overrides)}
        return rh.fold_summary(rh.heldout_fold_scores(house, model)[name])


def nearest_ari(houses: dict, truths: dict[str, np.ndarray]) -> float:
    """The baseline (E) nearest utterance's mean ARI over ``houses`` (name -> house, each
    against ``truths[name]``), as ``real_houses.py`` scores its row: the ARI target's bar."""
    return float(np.mean([rh.nearest_scores(houses[h], truths[h])["ari"] for h in houses]))


class PublicHouses:
    """The public houses under ``root``, each with its region truth, loaded when first asked for,
    and the ARI bar of all five (:func:`nearest_ari`, --quick too) measured when first asked for:
    a rerun on a finished JSON loads none of them."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self._houses: dict[str, object] = {}
        self._truths: dict[str, np.ndarray] = {}  # name -> [H, W] region, -1 off the free cells
        self._nearest: float | None = None
        self._simulations: dict[str, object] = {}

    def house(self, name: str):
        if name not in self._houses:
            self._houses[name] = load_house(self.root / name)
        return self._houses[name]

    def simulation(self, name: str):
        """``real_houses.map_simulation`` of the house's map (deterministic: built once)."""
        if name not in self._simulations:
            self._simulations[name] = rh.map_simulation(self.house(name))
        return self._simulations[name]

    def truth(self, name: str) -> np.ndarray:
        if name not in self._truths:
            self._truths[name] = public_truth(self.house(name)).labels
        return self._truths[name]

    def nearest(self) -> float:
        if self._nearest is None:
            names = list(PUBLIC_CATEGORIES)
            self._nearest = nearest_ari({h: self.house(h) for h in names},
                                        {h: self.truth(h) for h in names})  # fmt: skip
        return self._nearest


def summary(per_house: dict[str, dict], nearest: float) -> dict[str, object]:
    """The means over the houses of one variant and seed, and the ARI targets judged: the mean
    ARI above ``nearest`` (:func:`nearest_ari` of the public houses) among them. Held-out scores
    as ``real_houses.py`` pools them (``mean_of_houses``, ``pooled`` over the words)."""
    houses = list(per_house)
    ari = float(np.mean([per_house[h]["public"]["ari"] for h in houses]))
    share = max(per_house[h]["public"]["largest_share"] for h in houses)
    counts = [per_house[h]["public"]["concepts_1pct"] for h in houses]
    within = all(abs(c - PUBLIC_CATEGORIES[h]) <= 2 for c, h in zip(counts, houses, strict=True))
    return {
        "ari": ari, "largest_share": share, "concepts_1pct": counts,
        "ari_targets": bool(ari > nearest and share <= 0.60 and within),
        "top1": rh.mean_of_houses(per_house, "heldout", "all folds"),
        "top1_pooled": rh.pooled(per_house, "heldout", "all folds"),
        "top3": rh.mean_of_houses(per_house, "heldout", "top 3"),
        "mean_rank": rh.mean_of_houses(per_house, "heldout", "mean rank"),
        "refined": [per_house[h]["public"]["refined"] for h in houses],
    }  # fmt: skip


def markdown(report: dict) -> str:
    lines = [
        f"| variant (fit seed) | public mean ARI | largest share | concepts >= 1 % (Table 2: "
        f"{', '.join(map(str, PUBLIC_CATEGORIES.values()))}) | ARI targets | held-out top-1, "
        "mean of houses | pooled over words | mean rank |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, seeds in report["variants"].items():
        for seed, row in seeds.items():
            s = row.get("summary")
            if s is None:
                continue
            lines.append(
                f"| {name} ({seed}) | {s['ari']:.3f} | {100 * s['largest_share']:.0f} % | "
                f"{', '.join(map(str, s['concepts_1pct']))} | "
                f"{'met' if s['ari_targets'] else 'not met'} | {s['top1']:.3f} | "
                f"{s['top1_pooled']:.3f} | {s['mean_rank']:.2f} |"
            )
    return "\n".join(lines)


OPEN_PLAN_MARGIN = 0.2
"""The open-plan target: mean ARI >= (F) geometry's + this."""
SYNTHETIC_TARGETS = {"dense": 0.98, "sparse": 0.93}
"""The dense and sparse houses' target: mean ARI not below this."""
SIMULATED_TARGET = 0.9
"""``simulate --map``'s target: each map's mean ARI over the fit seeds >= this."""
GEOMETRY = ("F geometry 1 m", "F geometry 2 m")


KINDS = (*rh.SYNTHETIC, "simulated")
"""The kinds of house of ``--synthetic`` (``--kinds``)."""


def synthetic_keys(
    open_plan_seeds: int, synthetic_seeds: int, maps: list[str], kinds: tuple[str, ...] = KINDS
) -> list[str]:
    """The houses of ``--synthetic`` in real_houses.py's order: ``"KIND seed S"`` of its
    synthetic kinds, then ``"simulated MAP"`` of each public map; only those of ``kinds``."""
    return [f"{kind} seed {s}" for kind in rh.SYNTHETIC if kind in kinds
            for s in rh.synthetic_seeds(kind, open_plan_seeds, synthetic_seeds)] + [
        f"simulated {m}" for m in maps if "simulated" in kinds]  # fmt: skip


def synthetic_house(key: str):
    """real_houses.py's synthetic house ``key`` (``"KIND seed S"``)."""
    kind, house_seed = key.rsplit(" seed ", 1)
    return rh.synthetic_house(kind, int(house_seed))


def synthetic_scores(house, key: str, name: str, sweeps: int, seed: int) -> dict[str, dict]:
    """The variant's fit (``real_houses.fit_preset``) on the synthetic house ``key`` (``"KIND
    seed S"``; ``house``) at fit seed S + ``seed``, scored against the house's own truth (row
    ``"variant"``; the baselines are the house's, :func:`house_baselines`)."""
    house_seed = int(key.rsplit(" seed ", 1)[1])
    with variant(name) as (base, overrides):
        labels, seconds = rh.fit_preset(house, base, sweeps, house_seed + seed, **overrides)
    return {"variant": {**rh.scores(labels, house.truth, house.grid.free), "seconds": seconds}}


def house_baselines(baselines: dict[str, dict], key: str, house=None) -> dict[str, dict]:
    """``baselines[key]``: ``real_houses.baseline_scores`` of the synthetic house ``key`` (the
    baselines and the oracle draw nothing: the same for every variant and fit seed), computed
    from ``house`` (built when not given) when missing."""
    if key not in baselines:
        house = synthetic_house(key) if house is None else house
        baselines[key] = rh.baseline_scores(house, house.truth, oracle=True)
    return baselines[key]


def adopted_baselines(report: dict) -> dict[str, dict]:
    """``report["synthetic_baselines"]`` (house key -> :func:`house_baselines`), made when
    missing, with those a JSON of the earlier layout kept beside each variant's row of each
    variant and seed (``"houses"`` of its ``"synthetic"``) taken into it; those rows are left
    as they are."""
    baselines = report.setdefault("synthetic_baselines", {})
    for seeds in report["variants"].values():
        for row in seeds.values():
            for key, scored in row.get("synthetic", {}).get("houses", {}).items():
                if rh.ORACLE in scored and key not in baselines:
                    baselines[key] = {k: v for k, v in scored.items() if k != "variant"}
    return baselines


def simulated_scores(public: PublicHouses, m: str, name: str, sweeps: int, seed: int) -> dict:
    """``real_houses.simulated_on`` of the variant on public map ``m``'s simulation (built once
    a map: :meth:`PublicHouses.simulation`) at one fit seed."""
    simulation = public.simulation(m)
    with variant(name) as (base, overrides):
        rows = rh.simulated_on(public.house(m), sweeps, [seed], base, simulation=simulation,
                               **overrides)  # fmt: skip
    return rows[f"fit seed {seed}"]


def synthetic_summary(done: dict[str, dict], baselines: dict[str, dict]) -> dict[str, dict]:
    """Per synthetic kind the variant's mean ARI over its houses and their count (open-plan:
    with (F)'s, the better door width's, and the oracle's, from the houses' ``baselines``), a
    kind with no house left out; ``"simulated"``: map -> ARI."""

    def mean(rows: list[dict], row: str) -> float:
        return float(np.mean([r[row]["ari"] for r in rows]))

    out: dict[str, dict] = {}
    for kind in rh.SYNTHETIC:
        keys = [key for key in done if key.startswith(f"{kind} seed ")]
        if not keys:
            continue
        out[kind] = {"ari": mean([done[key] for key in keys], "variant"), "houses": len(keys)}
        if kind == "open-plan":
            rows = [baselines[key] for key in keys]
            out[kind] |= {"F": max(mean(rows, g) for g in GEOMETRY),
                          "oracle": mean(rows, rh.ORACLE)}  # fmt: skip
    out["simulated"] = {key.removeprefix("simulated "): row["ari"]
                        for key, row in done.items() if key.startswith("simulated ")}  # fmt: skip
    return out


def synthetic_judged(summaries: list[dict]) -> dict[str, object]:
    """One variant's :func:`synthetic_summary` of each fit seed -> the means over them (a
    kind's weighted by its houses; a map's over the seeds that fitted it) and the targets of
    the kinds it has."""
    out: dict[str, object] = {}
    for kind in rh.SYNTHETIC:
        summaries_of = [s for s in summaries if kind in s]
        if not summaries_of:
            continue
        weights = [s[kind]["houses"] for s in summaries_of]
        keys = ("ari", "F", "oracle") if kind == "open-plan" else ("ari",)
        out[kind] = {k: float(np.average([s[kind][k] for s in summaries_of], weights=weights))
                     for k in keys} | {"houses": sum(weights)}  # fmt: skip
    maps = dict.fromkeys(m for s in summaries for m in s["simulated"])
    out["simulated"] = {m: float(np.mean([s["simulated"][m] for s in summaries
                                          if m in s["simulated"]])) for m in maps}  # fmt: skip
    judged: dict[str, bool] = {}
    if "open-plan" in out:
        judged["open-plan"] = out["open-plan"]["ari"] >= out["open-plan"]["F"] + OPEN_PLAN_MARGIN
    judged |= {k: out[k]["ari"] >= bar for k, bar in SYNTHETIC_TARGETS.items() if k in out}
    if out["simulated"]:
        judged["simulated"] = all(v >= SIMULATED_TARGET for v in out["simulated"].values())
    out["pass"] = judged
    return out


def synthetic_markdown(report: dict) -> str:
    """A row a variant with synthetic results: its means over the fit seeds and each target."""

    def verdict(ok: bool | None) -> str:
        return "-" if ok is None else "PASS" if ok else "FAIL"

    def ari(kind: dict | None) -> str:
        return "-" if kind is None else f"{kind['ari']:.3f} ({kind['houses']})"

    lines = [
        f"| variant (fit seeds) | open-plan mean ARI (houses) | (F) + {OPEN_PLAN_MARGIN:g} | "
        "oracle | open-plan | dense mean ARI (houses) | dense >= 0.98 | sparse mean ARI "
        f"(houses) | sparse >= 0.93 | simulate --map: mean ARI per map | every map >= "
        f"{SIMULATED_TARGET:g} |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, seeds in report["variants"].items():
        done = {s.removeprefix("seed "): row["synthetic"]["summary"] for s, row in seeds.items()
                if "summary" in row.get("synthetic", {})}  # fmt: skip
        if not done:
            continue
        j = synthetic_judged(list(done.values()))
        op, ok = j.get("open-plan"), j["pass"]
        bars = ("- | -" if op is None
                else f"{op['F'] + OPEN_PLAN_MARGIN:.3f} | {op['oracle']:.3f}")  # fmt: skip
        maps = ", ".join(f"{m} {v:.2f}" for m, v in j["simulated"].items()) or "-"
        lines.append(
            f"| {name} ({', '.join(done)}) | {ari(op)} | {bars} | "
            f"{verdict(ok.get('open-plan'))} | {ari(j.get('dense'))} | "
            f"{verdict(ok.get('dense'))} | {ari(j.get('sparse'))} | "
            f"{verdict(ok.get('sparse'))} | {maps} | {verdict(ok.get('simulated'))} |"
        )
    return "\n".join(lines)


def run_synthetic(args: argparse.Namespace, report: dict, out: Path, public: PublicHouses) -> None:
    """``--synthetic``: each variant and fit seed on the houses it was not tuned on (module
    docstring), into ``report["variants"][NAME]["seed S"]["synthetic"]``, written after every
    house; a house already there is skipped (a variant and seed with every house fitted)."""
    maps = list(PUBLIC_CATEGORIES)[: 1 if args.quick else None]
    keys = synthetic_keys(args.open_plan_seeds, args.synthetic_seeds, maps, tuple(args.kinds))
    baselines = adopted_baselines(report)
    for name in args.variants:
        for seed in args.seeds:
            row = report["variants"].setdefault(name, {}).setdefault(f"seed {seed}", {})
            record = row.setdefault("synthetic", {})
            done = record.setdefault("houses", {})
            if not done:  # a new record: how its fits prepare the data (check_preparations)
                record["preparation"] = preparation(name)
            if "summary" in record and all(key in done for key in keys):
                continue
            for key in keys:
                if key in done:
                    continue
                start = time.perf_counter()
                if key.startswith("simulated "):
                    m = key.removeprefix("simulated ")
                    done[key] = simulated_scores(public, m, name, args.sweeps, seed)
                    ari = done[key]["ari"]
                else:
                    house = synthetic_house(key)
                    done[key] = synthetic_scores(house, key, name, args.sweeps, seed)
                    house_baselines(baselines, key, house)
                    ari = done[key]["variant"]["ari"]
                seconds = time.perf_counter() - start
                print(f"{name} seed {seed} {key}: ARI {ari:.3f} ({seconds:.0f} s)",
                      file=sys.stderr, flush=True)  # fmt: skip
                out.write_text(json.dumps(report, indent=1, default=float))
            for key in done:  # any missing (none but for a JSON cut short between them)
                if not key.startswith("simulated "):
                    house_baselines(baselines, key)
            record["summary"] = synthetic_summary(done, baselines)  # every house it has
            out.write_text(json.dumps(report, indent=1, default=float))
    print(f"# Variants of {BASE} on the houses not tuned on ({args.sweeps} sweeps)\n\n"
          f"{synthetic_markdown(report)}")  # fmt: skip
    print(f"wrote {out}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=COUNT, help="sweeps of every fit (default 2000; "
                        "--quick: 20)")  # fmt: skip
    parser.add_argument("--seeds", type=INDEX, nargs="+", help="fit seeds (default 0; with "
                        "--synthetic 0 1 2, --quick: 0)")  # fmt: skip
    parser.add_argument(
        "--variants", nargs="+", choices=list(VARIANTS), metavar="NAME",
        help=f"variants to run, in this order (default all: {', '.join(VARIANTS)}; --quick: "
        "coarse and footprint 0.5 m)",
    )  # fmt: skip
    parser.add_argument("--out", help="JSON (default benchmarks/coarse_variants.json, "
                        "coarse_variants_quick.json with --quick); a variant and seed already "
                        "in it is skipped")  # fmt: skip
    parser.add_argument("--quick", action="store_true", help="a smoke run: 20 sweeps, one house")
    parser.add_argument(
        "--synthetic", action="store_true",
        help="score the variants on the houses they were not tuned on instead, as "
        "real_houses.py checks the default: synthetic open-plan, dense and sparse houses, and "
        "simulate --map on each public map (--quick: one of each)",
    )  # fmt: skip
    parser.add_argument("--open-plan-seeds", type=COUNT, help="with --synthetic: open-plan "
                        "seeds 0..n-1 (default 10, --quick: 1)")  # fmt: skip
    parser.add_argument("--synthetic-seeds", type=COUNT, help="with --synthetic: dense and "
                        "sparse seeds 0..n-1 (default 3, --quick: 1)")  # fmt: skip
    parser.add_argument("--kinds", nargs="+", choices=KINDS, help="with --synthetic: only these "
                        f"kinds of house (default all: {', '.join(KINDS)})")  # fmt: skip
    args = parser.parse_args(argv)
    for option in ("open_plan_seeds", "synthetic_seeds", "kinds"):
        if getattr(args, option) is not None and not args.synthetic:
            parser.error(f"--{option.replace('_', '-')}: only with --synthetic")
    args.open_plan_seeds = quick_or(args.open_plan_seeds, args.quick, 1, 10)
    args.synthetic_seeds = quick_or(args.synthetic_seeds, args.quick, 1, 3)
    args.kinds = args.kinds or list(KINDS)
    args.out = results_path(args.out, "coarse_variants", args.quick)
    args.sweeps = quick_or(args.sweeps, args.quick, 20, 2000)
    args.seeds = args.seeds or ([0] if args.quick or not args.synthetic else [0, 1, 2])
    args.variants = args.variants or (["coarse", "footprint 0.5 m"] if args.quick
                                      else list(VARIANTS))  # fmt: skip
    root = dataset_root(without="nothing to score")
    if root is None:
        return 0
    houses = list(PUBLIC_CATEGORIES)[: 1 if args.quick else None]
    logging.getLogger("spcopyro").setLevel(logging.ERROR)
    out = Path(args.out)
    report = json.loads(out.read_text()) if out.exists() else {}
    if report.get("sweeps", args.sweeps) != args.sweeps:
        parser.error(f"{out} holds {report['sweeps']}-sweep results; give another --out")
    if args.synthetic:  # the public results' "houses" left as they are
        report["sweeps"] = args.sweeps
    else:
        report |= {"sweeps": args.sweeps, "houses": houses}
    report.setdefault("variants", {})
    refused = check_preparations(report, out)
    if refused:
        parser.error(refused)
    public = PublicHouses(Path(root))  # loaded when first fitted or judged: none on a rerun
    if args.synthetic:
        run_synthetic(args, report, out, public)
        return 0
    for name in args.variants:
        for seed in args.seeds:
            row = report["variants"].setdefault(name, {}).setdefault(f"seed {seed}", {})
            if "summary" in row:
                continue
            if not row.get("houses"):  # a new record: how its fits prepare the data
                row["preparation"] = preparation(name)
            row.setdefault("houses", {})
            for h in houses:
                if h in row["houses"]:
                    continue
                house, truth = public.house(h), public.truth(h)  # not timed, as before
                start = time.perf_counter()
                scored = public_scores(house, truth, name, args.sweeps, seed)
                held = heldout_scores(house, name, args.sweeps, seed)
                row["houses"][h] = {"public": scored, "heldout": held,
                                    "seconds": time.perf_counter() - start}  # fmt: skip
                print(f"{name} seed {seed} {h}: ARI {scored['ari']:.3f}, held-out top-1 "
                      f"{held['all folds']:.3f} ({time.perf_counter() - start:.0f} s)",
                      file=sys.stderr, flush=True)  # fmt: skip
                out.write_text(json.dumps(report, indent=1, default=float))
            row["summary"] = summary(row["houses"], public.nearest())
            out.write_text(json.dumps(report, indent=1, default=float))
    print(f"# Variants of {BASE} ({args.sweeps} sweeps)\n\n{markdown(report)}")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    run_main(main)
