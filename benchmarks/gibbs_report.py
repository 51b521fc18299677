"""The report of ``benchmarks/gibbs.py``: its targets (PASS/FAIL) and the plain-text tables."""

from __future__ import annotations

from typing import Any

from bench_setup import HEADLINE_HOUSE
from machine import format_table

from spcopyro._util.threads import MIN_CELLS_FOR_MORE_THREADS

PRESET = "paper-dp"

# Issue 7's targets on a 2-core machine.
TARGET_SPEEDUP = 300.0  # x faster per iteration than the per-cell loop
TARGET_HEADLINE_SECONDS = 15.0  # 5000 iterations of room2ldk4
TARGET_PEAK_BYTES = 1 << 30  # 1 GiB resident-set high-water mark for the headline run
# Issue 15's.
TARGET_RUN_OVER_KERNEL = 1.2  # a 5000-sweep run_gibbs against 5000 bare kernel sweeps, per preset
TARGET_FIXED_SECONDS = 2.0  # a whole fit of room2ldk4 outside its sweeps
TARGET_NS_PER_CELL = 20.0  # the kernel at L = 120 on room2ldk4
TARGET_FIT_MS_PER_SWEEP = 0.5  # a whole 5000-sweep fit of room2ldk4, run loop included
TARGET_FIT_SPEEDUP = 600.0  # that fit against the per-cell loop, per sweep
TARGET_CHAINS_RATIO = 0.5  # `fit --chains 4` against four single fits: at most half


def _ms(result: dict[str, Any] | None, key: str = "ms_per_iteration", digits: int = 2) -> str:
    if result is None:
        return "-"
    if "error" in result:
        return "failed"
    return f"{result[key]:.{digits}f}"


def _mib(value: int | None) -> str:
    return "-" if value is None else f"{value / 2**20:.0f}"


def _verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def _ok(entry: dict[str, Any] | None) -> bool:
    return bool(entry) and "error" not in entry


def _per_cell_baseline(
    results: dict[str, Any], house: str, free_cells: int, sweeps: int | None = None
) -> str:
    """The per-cell loop timed in this run on ``house`` under :data:`PRESET` (the per-house rows,
    else the whole fits'), as ns a cell, or as ``sweeps`` iterations projected; or why none."""
    found = [h["per_cell"] for h in results.get("houses", [])
             if h.get("house") == house and "per_cell" in h]  # fmt: skip
    found += [f["per_cell"] for f in results.get("fits", []) if f.get("preset") == PRESET
              and (f.get("house") or "-") == house and "per_cell" in f]  # fmt: skip
    if not found:
        return "no per-cell loop on this house in this run"
    seconds = found[0]["seconds_per_iteration"]
    if sweeps is not None:
        return f"per-cell loop, same run: {sweeps * seconds:.0f} s projected"
    return f"per-cell loop, same run: {1e9 * seconds / free_cells:.0f} ns/cell"


def _import_baseline(results: dict[str, Any]) -> str:
    """``python -c 'import torch'`` and ``python -c pass`` timed in this run (the floor under a
    fit's fixed cost), or why not."""
    floor = results.get("import_floor") or {}
    if "torch" not in floor:
        return "import torch not timed in this run"
    return (f"same run: import torch alone {floor['torch']:.2f} s, python -c pass "
            f"{floor['pass']:.2f} s")  # fmt: skip


def issue15_targets(results: dict[str, Any]) -> list[dict[str, Any]]:
    """Issue 15's targets: the run loop, the whole fit, the fixed cost, the kernel, the chains."""
    targets = []
    for entry in results.get("run_loop", []):
        if _ok(entry):
            targets.append({
                "target": f"run_gibbs <= {TARGET_RUN_OVER_KERNEL:g}x the bare kernel, "
                          f"{entry['sweeps']} sweeps ({entry['preset']})",
                "measured": f"{entry['ratio']:.2f}x ({entry['run_gibbs_ms_per_sweep']:.3f} vs "
                            f"{entry['kernel_ms_per_sweep']:.3f} ms/sweep)",
                "ok": entry["ratio"] <= TARGET_RUN_OVER_KERNEL,
            })  # fmt: skip
    for entry in results.get("run_loop", []):
        if _ok(entry) and entry["preset"] == PRESET and entry["num_concepts"] == 120:
            targets.append({
                "target": f"kernel <= {TARGET_NS_PER_CELL:g} ns a cell at L = 120 "
                          f"({entry['house']}, {PRESET}, every row redrawn as Algorithm 1)",
                "measured": f"{entry['kernel_ns_per_cell']:.1f} ns/cell "
                            f"({_per_cell_baseline(results, entry['house'], entry['free_cells'])})",
                "ok": entry["kernel_ns_per_cell"] <= TARGET_NS_PER_CELL,
            })  # fmt: skip
    for entry in results.get("fits", []):
        if not _ok(entry):
            continue
        where = entry["house"] or "embedded default house (no dataset)"
        if entry["sweeps"] == 5000 and entry["preset"] != "auto":
            targets.append({
                "target": f"whole 5000-sweep fit <= {TARGET_FIT_MS_PER_SWEEP:g} ms a sweep, run "
                          f"loop included ({where}, {entry['preset']})",
                "measured": f"{entry['ms_per_sweep']:.3f} ms/sweep ("
                            + (f"per-cell loop, same run: "
                               f"{1e3 * entry['per_cell']['seconds_per_iteration']:.0f} ms/it)"
                               if "per_cell" in entry else "no per-cell loop in this run)"),
                "ok": entry["ms_per_sweep"] <= TARGET_FIT_MS_PER_SWEEP,
            })  # fmt: skip
            if "speedup_vs_per_cell" in entry:
                targets.append({
                    "target": f"that fit >= {TARGET_FIT_SPEEDUP:g}x the per-cell loop, per "
                              f"sweep, same run ({entry['preset']})",
                    "measured": f"{entry['speedup_vs_per_cell']:.0f}x",
                    "ok": entry["speedup_vs_per_cell"] >= TARGET_FIT_SPEEDUP,
                })  # fmt: skip
        if entry.get("fixed_direct") is not None:
            targets.append({
                "target": f"fixed cost < {TARGET_FIXED_SECONDS:g} s outside the sweeps ({where}, "
                          f"{entry['preset']}, figures written)",
                "measured": f"{entry['fixed_direct']:.2f} s ({_import_baseline(results)})",
                "ok": entry["fixed_direct"] < TARGET_FIXED_SECONDS,
            })  # fmt: skip
    fits = (results.get("chains") or {}).get("as_fits")
    if _ok(fits):
        targets.append({
            "target": f"fit --chains {fits['chains']} <= {TARGET_CHAINS_RATIO:g}x "
                      f"{fits['chains']} single fits ({fits['sweeps']} sweeps each)",
            "measured": f"{fits['ratio']:.2f}x ({_ratios(fits)})",
            "ok": fits["ratio"] <= TARGET_CHAINS_RATIO,
        })  # fmt: skip
    return targets


def evaluate_targets(results: dict[str, Any]) -> list[dict[str, Any]]:
    """Issue 7's targets (speed-up, headline run, memory, scaling) and issue 15's."""
    targets = issue15_targets(results)
    speedups = [
        max(h["speedup"].values()) for h in results["houses"] if h.get("speedup")
    ]  # best backend per house
    if speedups:
        worst = min(speedups)
        targets.append(
            {
                "target": f">= {TARGET_SPEEDUP:g}x faster per iteration than the per-cell loop",
                "measured": f"{worst:.0f}x (worst house, fastest backend)",
                "ok": worst >= TARGET_SPEEDUP,
            }
        )
    headline = results.get("headline")
    if headline and "error" not in headline:
        where = "synthetic stand-in" if headline["synthetic_stand_in"] else HEADLINE_HOUSE
        if headline["sweeps"] == 5000:
            targets.append(
                {
                    "target": f"5000 iterations of {HEADLINE_HOUSE} "
                    f"< {TARGET_HEADLINE_SECONDS:g} s",
                    "measured": f"{headline['wall_s']:.1f} s run_gibbs wall ({where}, "
                    f"{headline['backend']}; "
                    + _per_cell_baseline(results, headline["house"], headline["free_cells"], 5000)
                    + ")",
                    "ok": headline["wall_s"] < TARGET_HEADLINE_SECONDS,
                }
            )
        targets.append(
            {
                # named: without the 5000-sweep line (--quick) "that run" followed the speed-up
                "target": f"peak memory of the headline run_gibbs ({headline['sweeps']} sweeps, "
                f"{where}) < 1 GiB",
                "measured": f"{headline['peak_rss_bytes'] / 2**20:.0f} MiB peak RSS (after "
                f"the imports: {_mib(headline.get('rss_after_import_bytes'))} MiB)",
                "ok": headline["peak_rss_bytes"] < TARGET_PEAK_BYTES,
            }
        )
    scaling = results.get("scaling", {})
    for backend in results["backends"]:
        cells = [
            e["backends"][backend]
            for e in scaling.get("cells", [])
            if "error" not in e["backends"].get(backend, {"error": ""})
        ]
        if len(cells) >= 2:
            ratio = cells[-1]["ns_per_cell"] / cells[0]["ns_per_cell"]
            targets.append(
                {
                    "target": f"time linear in cells ({backend}: ns/cell largest / smallest map)",
                    "measured": f"{ratio:.2f}",
                    "ok": 0.5 <= ratio <= 2.0,
                }
            )
        for kind in ("num_concepts", "num_concepts_house", "num_concepts_house_refresh"):
            by_l = [
                e
                for e in scaling.get(kind, [])
                if "error" not in e["backends"].get(backend, {"error": ""})
            ]
            if len(by_l) < 2:
                continue
            low, high = by_l[0], by_l[-1]
            ratio = (
                high["backends"][backend]["ms_per_iteration"]
                / low["backends"][backend]["ms_per_iteration"]
            )
            targets.append(
                {
                    "target": f"time nearly flat in L ({backend}, {low['map']}"
                    + (", refresh 0.1" if kind.endswith("refresh") else "")
                    + f": ms at L={high['num_concepts']} / L={low['num_concepts']})",
                    "measured": f"{ratio:.2f}",
                    "ok": ratio <= 2.0,
                }
            )
    return targets


def _threads_note(threads: int | str | None) -> str:
    """The thread policy the per-house, headline, scaling and quality rows ran under
    (``results["scaling_threads"]``)."""
    if threads is None:
        return "torch threads: not recorded (torch's default count)"
    if threads == "auto":
        return (f"torch threads: spcopyro fit's policy (1 below {MIN_CELLS_FOR_MORE_THREADS} free "
                "cells, torch's own count above), as the whole fits")  # fmt: skip
    return f"torch threads: {threads} (--torch-threads)"


def render(results: dict[str, Any]) -> str:
    """The plain-text report printed to stdout."""
    info = results["machine"]
    backends = results["backends"]
    out = [
        f"SpCoMapping Gibbs benchmark ({'quick' if results['quick'] else 'full'}), {info['date']}",
        f"{info['cpu_model']}, {info['cpus_usable']} usable CPUs; torch {info['torch']} "
        f"({info['torch_threads']} threads); numba {info['numba'] or 'not installed'}",
        "one iteration = all cell labels (eq. 13) + pi, theta, w draws (eqs. 14-17); "
        f"preset {PRESET}",
    ]
    out += [f"backend {name}: skipped: {note}" for name, note in results["backend_notes"].items()]
    contention = results.get("contention", {})
    if contention:
        parts = [
            f"{name} {c['other_cpu_s']:.0f} of {c['wall_s']:.0f} s"
            + (f" (after waiting {c['waited_for_idle_s']:.0f} s)" if c["waited_for_idle_s"] else "")
            for name, c in contention.items()
            if c.get("other_cpu_s") is not None
        ]
        out.append(
            "CPU time used by OTHER processes during each section (0 = machine to ourselves): "
            + ", ".join(parts)
        )
    out.append("")
    out.append("== Per house (L=120) ==")
    out.append(_threads_note(results.get("scaling_threads")))
    if results["dataset"] is None:
        out.append(
            "SKIPPED: no public dataset (not found, or --no-dataset; set SPCOPYRO_DATA): "
            "synthetic maps only"
        )
    else:
        headers = ["house", "free cells", "obs cells", "torch threads", "per-cell s/it"]
        headers += [f"{b} ms/it" for b in backends]
        headers += [f"{b} speed-up" for b in backends]
        headers += [f"{b} 5000 it s" for b in backends]
        rows = []
        for h in results["houses"]:
            row = [h["house"], str(h["free_cells"]), str(h["observed_cells"])]
            row.append(str(h.get("torch_threads", "?")))
            row.append(
                f"{h['per_cell']['seconds_per_iteration']:.3f}" if "per_cell" in h else "skipped"
            )
            row += [_ms(h["backends"].get(b)) for b in backends]
            row += [
                f"{h['speedup'][b]:.0f}x" if b in h.get("speedup", {}) else "-" for b in backends
            ]
            row += [
                f"{h['projected_5000_s'][b]:.1f}" if b in h.get("projected_5000_s", {}) else "-"
                for b in backends
            ]
            rows.append(row)
        out.append(format_table(headers, rows))
        out.append(
            "(ms/it, s/it: median of the timed sweeps of the sweep function after warm-up; "
            "5000 it s: 5000 times that)"
        )

    headline = results.get("headline")
    out.append("")
    out.append("== Headline: run_gibbs in a fresh process ==")
    if headline is None:
        out.append("not run")
    elif "error" in headline:
        out.append(f"FAILED: {headline['error']}")
    else:
        where = headline["house"]
        if headline["synthetic_stand_in"]:
            where += " (synthetic stand-in)"
        out.append(
            format_table(
                [
                    "house",
                    "free cells",
                    "backend",
                    "torch threads",
                    "sweeps",
                    "wall s",
                    "ms/it",
                    "first sweep s",
                    "peak RSS MiB",
                    "RSS before / after run MiB",
                    "concepts",
                ],
                [
                    [
                        where,
                        str(headline["free_cells"]),
                        headline["backend"],
                        str(headline.get("torch_threads", "?")),
                        str(headline["sweeps"]),
                        f"{headline['wall_s']:.2f}",
                        f"{headline['ms_per_iteration']:.2f}",
                        f"{headline['first_sweep_s']:.2f}",
                        f"{headline['peak_rss_bytes'] / 2**20:.0f}",
                        f"{_mib(headline['rss_now_before_run_bytes'])} / "
                        f"{_mib(headline['rss_now_after_run_bytes'])}",
                        str(headline["final_concepts"]),
                    ]
                ],
            )
        )
        out.append(
            "(wall s: run_gibbs including its per-sweep log joint and trace; peak RSS: "
            "ru_maxrss of that process, interpreter and torch included)"
        )

    out += render_issue15(results)

    for kind, title in (
        ("cells", "Scaling in cells (L=120)"),
        ("num_concepts", "Scaling in L (synthetic {map}, {free_cells} free cells)"),
        ("num_concepts_house", f"Scaling in L ({HEADLINE_HOUSE})"),
        (
            "num_concepts_house_refresh",
            f"Scaling in L ({HEADLINE_HOUSE}, unobserved_refresh 0.1)",
        ),
    ):
        entries = results.get("scaling", {}).get(kind, [])
        if not entries:
            continue
        out.append("")
        out.append(f"== {title.format(**entries[0])} ==")  # the map actually timed
        out.append(_threads_note(results.get("scaling_threads")))
        headers = ["map", "free cells", "obs cells", "L", "torch threads"]
        headers += [h for b in backends for h in (f"{b} ms/sweep", f"{b} ns/cell")]
        rows = []
        for e in entries:
            row = [e["map"], str(e["free_cells"]), str(e["observed_cells"])]
            row += [str(e["num_concepts"]), str(e.get("torch_threads", "?"))]
            for b in backends:
                r = e["backends"].get(b)
                row += [_ms(r), _ms(r, "ns_per_cell", 1)]
            rows.append(row)
        out.append(format_table(headers, rows))

    quality = results.get("quality", [])
    if quality:
        q0 = quality[0]
        out.append("")
        out.append(
            f"== Quality vs time: default synthetic house ({q0['free_cells']} cells, "
            f"{q0['true_categories']} categories), L={q0['num_concepts']}, {q0['backend']}, "
            f"{q0.get('torch_threads', '?')} torch thread(s) =="
        )
        rows = []
        for q in quality:
            side = "above" if q["gamma"] > q["critical_gamma"] else "below"
            for p in q["points"]:
                rows.append(
                    [
                        f"{q['gamma']:g} ({side} {q['critical_gamma']:.2f})",
                        str(p["sweeps"]),
                        f"{p['seconds']:.2f}",
                        f"{p['ari']:.3f}",
                        str(p["concepts"]),
                    ]
                )
            best = [
                f"{q['gamma']:g} best visited",
                str(q["best_sweep"]),
                "",
                f"{q['best_ari']:.3f}",
            ]
            rows.append([*best, ""])
        out.append(format_table(["gamma (critical)", "sweeps", "seconds", "ARI", "concepts"], rows))

    targets = results.get("targets", [])
    if targets:
        out.append("")
        out.append("== Targets ==")
        out.append(
            format_table(
                ["target", "measured", ""],
                [[t["target"], t["measured"], _verdict(t["ok"])] for t in targets],
            )
        )
    out.append("")
    out.append(f"total {results['total_s']:.0f} s; JSON: {results['out']}")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------


def render_issue15(results: dict[str, Any]) -> list[str]:
    """The run loop against the kernel, the whole fits, the chains (issue 15)."""
    out: list[str] = []
    run_loop = [e for e in results.get("run_loop", []) if _ok(e)]
    if run_loop:
        out += ["", f"== Run loop against the bare kernel ({run_loop[0]['house']}, "
                    f"{run_loop[0]['sweeps']} sweeps, {run_loop[0]['backend']}, "
                    f"{run_loop[0].get('torch_threads', '?')} torch thread(s)) =="]  # fmt: skip
        out.append(format_table(
            ["preset", "L", "kernel ms/sweep", "kernel ns/cell", "run_gibbs ms/sweep",
             "run / kernel"],
            [[e["preset"], str(e["num_concepts"]), f"{e['kernel_ms_per_sweep']:.3f}",
              f"{e['kernel_ns_per_cell']:.1f}", f"{e['run_gibbs_ms_per_sweep']:.3f}",
              f"{e['ratio']:.2f}"] for e in run_loop],
        ))  # fmt: skip
        out.append(
            "(the same chain from the same seed: bare backend.sweep in a loop vs the run loop "
            "with its log joint, trace and best state, alternating in blocks of "
            f"{run_loop[0]['block']} sweeps; same chain: {all(e['same_chain'] for e in run_loop)})"
        )
    fits = [e for e in results.get("fits", []) if _ok(e)]
    if fits:
        where = fits[0]["house"] or "the embedded default house (no dataset)"
        out += ["", f"== Whole `spcopyro fit` of {where} in a fresh process =="]
        rows = []
        for e in fits:
            per_cell = e.get("per_cell", {}).get("seconds_per_iteration")
            rows.append([
                e["preset"], str(e["sweeps"]),
                "-" if per_cell is None else f"{per_cell:.3f}",
                f"{e['ms_per_sweep']:.3f}",
                "-" if "speedup_vs_per_cell" not in e else f"{e['speedup_vs_per_cell']:.0f}x",
                f"{e['wall']:.2f}", f"{e['startup']:.2f}", f"{e['load']:.2f}",
                f"{e['fit_outside_sweeps']:.2f}", f"{e['figures']:.2f}",
                "-" if e.get("fixed_direct") is None else f"{e['fixed_direct']:.2f}",
            ])  # fmt: skip
        out.append(format_table(
            ["preset", "sweeps", "per-cell loop s/it", "fit ms/sweep", "speed-up", "wall s",
             "startup s", "load s", "fit outside sweeps s", "figures s", "fixed cost s"],
            rows,
        ))  # fmt: skip
        out.append(
            "(fit ms/sweep: the fit's own trace, run loop included; speed-up: the "
            "benchmark's per-cell loop, timed in this run, per sweep; fixed cost: the "
            "wall less the sweeps at their steady cost. The released script's loop was "
            "measured elsewhere at 0.41-0.52 s an iteration on room2ldk4 (issue 15), "
            "about 1.5x the per-cell loop)"
        )
    chains = results.get("chains") or {}
    inside, fits_ = chains.get("in_process"), chains.get("as_fits")
    if _ok(inside) or _ok(fits_):
        out += ["", f"== Many chains ({chains.get('preset')}) =="]
        if _ok(inside):
            out.append(
                f"in one process: {inside['chains']} chains x {inside['sweeps']} sweeps together "
                f"on "
                f"{inside['workers']} threads {inside['together_s']:.2f} s; one after another "
                f"{inside['sequential_s']:.2f} s; one chain {inside['one_chain_s']:.2f} s "
                f"(together / one chain = {inside['together_over_one']:.2f}, "
                f"{inside['usable_cpus']} usable CPUs, torch at "
                f"{inside.get('torch_threads', '?')} thread)"
            )
            if inside.get("forked_s") is not None:
                out.append(
                    f"in processes forked from it (what fit --chains does on Linux): "
                    f"{inside['forked_s']:.2f} s, {inside['forked_over_sequential']:.2f} of one "
                    f"after another, against {inside['together_over_sequential']:.2f} on threads"
                )
            procs = inside.get("processes")
            if procs:
                out.append(
                    f"in {procs['processes']} processes (no GIL shared): the same chains "
                    f"{procs['wall_s']:.2f} s, {inside['processes_over_sequential']:.2f} of one "
                    f"after another, against {inside['together_over_sequential']:.2f} on threads"
                )
        if _ok(fits_):
            out.append(
                f"as fits: spcopyro fit --chains {fits_['chains']} {fits_['chains_fit_s']:.1f} s; "
                f"{fits_['chains']} single fits {fits_['single_fits_s']:.1f} s "
                f"(ratio {fits_['ratio']:.2f}: {_ratios(fits_)}; {fits_['sweeps']} sweeps each)"
            )
            if fits_.get("pair_s") is not None:
                alone = fits_["single_fit_sweeps_s"][:2]
                out.append(
                    f"two single fits at once in two processes: {fits_['pair_s']:.1f} s, their "
                    f"sweeps {' / '.join(f'{s:.1f}' for s in fits_['pair_sweeps_s'])} s against "
                    f"{' / '.join(f'{s:.1f}' for s in alone)} s alone; the {fits_['chains']} "
                    f"chains' sweeps in one fit {fits_['chains_fit_sweeps_s'] or float('nan'):.1f}"
                    f" s against {sum(fits_['single_fit_sweeps_s']):.1f} s for the single fits' "
                    "(threads sharing the GIL against processes sharing nothing)"
                )
        out.append(f"GPU: {chains.get('gpu')}")
    return out


def _ratios(fits: dict) -> str:
    """The chains-as-fits comparison's repeats: the median of their ratios, or the one run's
    seconds."""
    ratios = fits.get("ratios") or [fits["ratio"]]
    if len(ratios) == 1:
        return f"{fits['chains_fit_s']:.1f} s vs {fits['single_fits_s']:.1f} s"
    return "median of " + ", ".join(f"{r:.2f}" for r in ratios) + ", alternated"
