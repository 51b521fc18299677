"""Issue 15's measurements for ``benchmarks/gibbs.py``: the run loop against the bare kernel per
preset, a user's whole ``spcopyro fit`` (sweeps and fixed cost, in fresh processes), and many
chains at once.

* :func:`kernel_and_run`: S sweeps of the backend's bare sweep (``backend.sweep`` in a loop, the
  state passed from one to the next, nothing recorded) against the run loop's S sweeps of the
  same chain from the same seed (what :func:`~spcopyro.gibbs.run.run_gibbs` runs), so the
  difference is exactly what the run loop adds (the per-sweep log joint, the trace, the best
  visited state, Ctrl-C bookkeeping). The two alternate in blocks of 250 sweeps, so that a
  machine whose speed drifts (a shared one) slows both alike.
* :func:`whole_fit`: ``spcopyro fit`` of a house for S sweeps in a fresh process
  (:func:`fixed_cost.fit_once`): ms per sweep from the fit's own trace (run loop included) and
  the fixed cost outside the sweeps.
* :func:`chains_in_process`: K chains advanced together by
  :func:`~spcopyro.gibbs.chains.advance_chains` (one thread per usable CPU) against the same K
  chains one after another; :func:`chains_as_fits`: ``spcopyro fit --chains K`` against K single
  fits, each a fresh process.
"""

from __future__ import annotations

import statistics
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import torch
from fixed_cost import fit_once

from spcopyro._util.threads import AUTO, resolve_threads, torch_threads
from spcopyro.config import SpCoConfig
from spcopyro.gibbs import GibbsOptions, run_gibbs
from spcopyro.gibbs.backends import get_backend
from spcopyro.gibbs.chain_processes import processes_usable
from spcopyro.gibbs.chains import advance_chains, resolve_workers, usable_cpus
from spcopyro.gibbs.run import advance, start_chain
from spcopyro.gibbs.state import make_sweep_plan
from spcopyro.model import ModelData


def kernel_and_run(
    data: ModelData,
    config: SpCoConfig,
    sweeps: int,
    *,
    backend: str = "numba",
    seed: int = 0,
    block: int = 250,
    threads: int | str = AUTO,
) -> dict[str, Any]:
    """Under ``threads`` (fit's thread policy by default, :func:`_kernel_and_run`): the bare
    kernel's and ``run_gibbs``'s seconds for the same chain, and the torch threads used."""
    with torch_threads(resolve_threads(threads, data.num_free)) as used:
        row = _kernel_and_run(data, config, sweeps, backend=backend, seed=seed, block=block)
    return {**row, "torch_threads": used}


def _kernel_and_run(
    data: ModelData, config: SpCoConfig, sweeps: int, *, backend: str, seed: int, block: int
) -> dict[str, Any]:
    """The bare kernel's and ``run_gibbs``'s seconds for the same ``sweeps``-sweep chain, timed
    in alternating blocks of ``block`` sweeps (kernel block, run-loop block, ...), so that both
    meet the same machine: the bare loop is ``backend.sweep`` from the state of
    :func:`~spcopyro.gibbs.run.start_chain` with ``seed`` (the start is timed by neither), the
    other :func:`~spcopyro.gibbs.run.advance` of that chain, then its ``to_run()``. Both draw
    the same chain; ``same_chain`` checks it at the end."""
    options = GibbsOptions(backend=backend)
    run_gibbs(data, config, 2, options=options, seed=seed, progress=False)  # kernels loaded
    sweep = get_backend(backend).sweep
    chain = start_chain(data, config, options=options, seed=seed)
    bare = start_chain(data, config, options=options, seed=seed)  # its state and generator
    state, generator, plan = bare.state, bare.generator, make_sweep_plan(data)
    kernel_s = run_s = 0.0
    done = 0
    while done < sweeps:
        count = min(block, sweeps - done)
        start = time.perf_counter()
        for _ in range(count):
            state = sweep(state, data, config, generator, plan, 1.0)
        kernel_s += time.perf_counter() - start
        start = time.perf_counter()
        advance(chain, count, progress=False)
        run_s += time.perf_counter() - start
        done += count
    start = time.perf_counter()
    chain.to_run()
    run_s += time.perf_counter() - start
    return {
        "sweeps": sweeps,
        "block": block,
        "backend": backend,
        "free_cells": data.num_free,
        "num_concepts": config.num_concepts,
        "kernel_s": kernel_s,
        "run_gibbs_s": run_s,
        "kernel_ms_per_sweep": 1e3 * kernel_s / sweeps,
        "run_gibbs_ms_per_sweep": 1e3 * run_s / sweeps,
        "kernel_ns_per_cell": 1e9 * kernel_s / sweeps / data.num_free,
        "ratio": run_s / kernel_s,
        "same_chain": bool(torch.equal(state.labels, chain.state.labels)),
    }


def whole_fit(
    house: Path | None, preset: str, sweeps: int, *, figures: bool = True
) -> dict[str, Any]:
    """``spcopyro fit`` of ``house`` (None: the embedded default) for ``sweeps`` sweeps in a fresh
    process: ms per sweep (the fit's trace: run loop included) and the seconds outside them."""
    row = fit_once(house, preset, sweeps, figures)
    row["preset"] = preset
    row["ms_per_sweep"] = 1e3 * row["sweep_seconds"] / sweeps
    row["steady_ms_per_sweep"] = (
        1e3 * (row["sweep_seconds"] - row["first_sweep_seconds"]) / (sweeps - 1)
        if sweeps > 1 else row["ms_per_sweep"]
    )  # fmt: skip
    return row


def chains_in_process(
    data: ModelData,
    config: SpCoConfig,
    chains: int,
    sweeps: int,
    *,
    backend: str = "numba",
    processes_of: tuple[str, str] | None = None,
) -> dict[str, Any]:
    """``chains`` chains of ``sweeps`` sweeps advanced together (one worker per usable CPU) and
    one after another (one worker): seconds of each, and a single chain's, with torch at one
    intra-op thread (what ``spcopyro fit``'s thread policy sets for maps of this size; two
    threads' pools would fight the chains' workers for the CPUs).

    With ``processes_of`` = (the dataset's folder or ``"-"`` for none, preset), the same chains
    (on :func:`bench_setup.load_headline_house`'s house) are also
    advanced in one fresh process per worker (:func:`chains_in_processes`), each running its
    share one after another: processes share no GIL, so the two "together" rows tell what the
    GIL costs the threads."""
    options = GibbsOptions(backend=backend)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        run_gibbs(data, config, 2, options=options, seed=0, progress=False)  # kernels loaded
        seconds = {}
        ways = [("one_chain", 1, "off"), ("sequential", 1, "off"), ("together", "auto", "off")]
        if processes_usable() is None:  # else no row (not Linux, another thread running)
            ways.append(("forked", "auto", "on"))
        for name, workers, mode in ways:
            count = 1 if name == "one_chain" else chains
            runs = [start_chain(data, config, options=options, seed=k) for k in range(count)]
            start = time.perf_counter()
            advance_chains([(chain, sweeps) for chain in runs], workers=workers, progress=False,
                           processes=mode)  # fmt: skip
            seconds[name] = time.perf_counter() - start
    finally:
        torch.set_num_threads(threads)
    record: dict[str, Any] = {
        "chains": chains,
        "sweeps": sweeps,
        "workers": resolve_workers("auto", chains),
        "usable_cpus": usable_cpus(),
        "torch_threads": 1,
        "one_chain_s": seconds["one_chain"],
        "sequential_s": seconds["sequential"],
        "together_s": seconds["together"],
        "together_over_one": seconds["together"] / seconds["one_chain"],
        "together_over_sequential": seconds["together"] / seconds["sequential"],
    }
    if "forked" in seconds:  # what `fit --chains` does where it can
        record["forked_s"] = seconds["forked"]
        record["forked_over_sequential"] = seconds["forked"] / seconds["sequential"]
    if processes_of is not None:
        processes = chains_in_processes(*processes_of, chains, sweeps, backend=backend)
        record["processes"] = processes
        record["processes_over_sequential"] = processes["wall_s"] / seconds["sequential"]
    return record


_PROCESS_CHAINS = """
import sys, time
import torch
torch.set_num_threads(1)
from pathlib import Path
from bench_setup import load_headline_house, make_problem
from spcopyro.config import preset
from spcopyro.gibbs import GibbsOptions, run_gibbs
from spcopyro.gibbs.chains import advance_chains
from spcopyro.gibbs.run import start_chain
dataset, name, backend, sweeps, *seeds = sys.argv[1:]
house = load_headline_house(None if dataset == "-" else Path(dataset))
problem = make_problem(house, preset(name))
options = GibbsOptions(backend=backend)
run_gibbs(problem.data, problem.config, 2, options=options, seed=0, progress=False)
runs = [start_chain(problem.data, problem.config, options=options, seed=int(k)) for k in seeds]
print("ready", flush=True)
sys.stdin.readline()
start = time.perf_counter()
advance_chains([(chain, int(sweeps)) for chain in runs], workers=1, progress=False)
print(time.perf_counter() - start, flush=True)
"""


def chains_in_processes(
    dataset: str, preset: str, chains: int, sweeps: int, *, backend: str = "numba"
) -> dict[str, Any]:
    """Chains 0..K-1 of ``sweeps`` sweeps in one fresh process per usable CPU (at most one per
    chain; chain k in process k mod P), each advancing its chains one after another with torch
    at one thread. The wall runs from the moment every process is ready (imports, data, kernels
    loaded, its chains started) until the last one is done: the sweeps alone, as in
    :func:`chains_in_process`."""
    import os
    import subprocess
    import sys

    workers = resolve_workers("auto", chains)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")])}  # fmt: skip
    shares = [[str(k) for k in range(chains) if k % workers == w] for w in range(workers)]
    command = [sys.executable, "-c", _PROCESS_CHAINS, dataset, preset, backend, str(sweeps)]
    procs = [
        subprocess.Popen(
            [*command, *share],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,  # a few warning lines at most: read on failure
            text=True,
            env=env,
        )  # fmt: skip
        for share in shares
    ]
    try:
        for proc in procs:
            if proc.stdout.readline().strip() != "ready":  # type: ignore[union-attr]
                proc.wait()
                tail = proc.stderr.read()[-2000:]  # type: ignore[union-attr]
                raise RuntimeError(f"a chains process failed before its sweeps:\n{tail}")
        start = time.perf_counter()
        for proc in procs:
            proc.stdin.write("go\n")  # type: ignore[union-attr]
            proc.stdin.flush()  # type: ignore[union-attr]
        own = [float(proc.stdout.readline()) for proc in procs]  # type: ignore[union-attr]
        wall = time.perf_counter() - start
    except BaseException:
        for proc in procs:
            proc.kill()
        raise
    finally:
        for proc in procs:
            proc.wait()
    return {"processes": workers, "wall_s": wall, "per_process_s": own}


def chains_as_fits(
    house: Path | None, preset: str, chains: int, sweeps: int, repeats: int = 1
) -> dict[str, Any]:
    """``spcopyro fit --chains K`` against K single fits (seeds 0..K-1), each a fresh process,
    figures off (they are the same for both). ``repeats`` times, alternated (the fit, then the
    single fits): ``ratio`` is the median of the repeats' ratios, since the machine's speed
    drifts within a minute; the other fields are the first repeat's."""

    def single(seed: int) -> dict[str, Any]:
        return fit_once(house, preset, sweeps, False, seed=seed)

    rounds = []
    for _ in range(repeats):
        together = fit_once(house, preset, sweeps, False, extra=["--chains", str(chains)])
        rounds.append((together, [single(k) for k in range(chains)]))
    together, singles = rounds[0]
    single_s = sum(r["wall"] for r in singles)
    ratios = [t["wall"] / sum(r["wall"] for r in s) for t, s in rounds]
    # Seeds 0 and 1's single fits again, two at a time in two processes: what the CPUs give two
    # chains that share no GIL (their sweeps' seconds against the same fits' alone).
    start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=2) as pool:
        pair = list(pool.map(single, (0, 1)))
    pair_s = time.perf_counter() - start
    return {
        "preset": preset,
        "chains": chains,
        "sweeps": sweeps,
        "chains_fit_s": together["wall"],
        "chains_fit_sweeps_s": together["seconds_parts"].get("sweeps"),
        "single_fits_s": single_s,
        "single_fit_each_s": [r["wall"] for r in singles],
        "single_fit_sweeps_s": [r["sweep_seconds"] for r in singles],
        "ratio": statistics.median(ratios),
        "ratios": ratios,
        "pair_s": pair_s,
        "pair_sweeps_s": [r["sweep_seconds"] for r in pair],
    }
