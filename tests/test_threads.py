"""The thread policy (spcopyro._util.threads): what it chooses, that it restores torch's setting,
that fits use it, and that the thread count changes no label."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import spcopyro.fit.house
import spcopyro.gibbs.chains
from spcopyro._util.threads import (
    MIN_CELLS_FOR_MORE_THREADS,
    describe_threads,
    policy_threads,
    resolve_threads,
    torch_threads,
)
from spcopyro.cli.main import build_parser
from spcopyro.config import preset
from spcopyro.fit.house import fit_house, fit_house_converged
from spcopyro.fit.registry import get_method as registered_method
from spcopyro.gibbs import GibbsOptions
from spcopyro.synthetic import HouseSpec, make_house


@pytest.fixture
def restore_threads():
    """Leave torch's thread count as the test found it, whatever the test does."""
    before = torch.get_num_threads()
    yield before
    torch.set_num_threads(before)


@pytest.fixture(scope="module")
def small_house():
    return make_house(seed=3, spec=HouseSpec(height=30, width=40, num_rooms=2, num_trials=1))


def test_the_policy_runs_small_maps_on_one_thread():
    assert policy_threads(1) == 1
    assert policy_threads(MIN_CELLS_FOR_MORE_THREADS - 1) == 1
    assert policy_threads(MIN_CELLS_FOR_MORE_THREADS) is None  # torch's own setting


@pytest.mark.parametrize(
    ("threads", "expected"),
    [("auto", 1), (None, None), (0, None), (3, 3), (np.int64(2), 2)],
)
def test_resolve_threads(threads, expected):
    assert resolve_threads(threads, 100) == expected


@pytest.mark.parametrize("bad", [-1, 1.5, "2", "all", True, [1]])
def test_resolve_threads_names_a_bad_value(bad):
    with pytest.raises(ValueError, match="threads must be") as error:
        resolve_threads(bad, 100)
    assert repr(bad) in str(error.value)


def test_describe_threads_says_what_and_why(fresh_load, monkeypatch):
    monkeypatch.setattr(fresh_load, "other_load", lambda: None)  # a machine that does not say
    assert describe_threads("auto", 100) == (
        f"1 torch intra-op thread (policy: 100 free cells < {MIN_CELLS_FOR_MORE_THREADS})"
    )
    assert describe_threads(3, 100) == "3 torch intra-op threads (as asked)"
    big = describe_threads("auto", MIN_CELLS_FOR_MORE_THREADS)
    assert big.endswith(f"(policy: {MIN_CELLS_FOR_MORE_THREADS} free cells >= "
                        f"{MIN_CELLS_FOR_MORE_THREADS})")  # fmt: skip


def test_torch_threads_sets_and_restores(restore_threads):
    torch.set_num_threads(2)
    with torch_threads(1) as count:
        assert count == 1 and torch.get_num_threads() == 1
    assert torch.get_num_threads() == 2
    with torch_threads(None) as count:  # leaves the setting alone
        assert count == 2 and torch.get_num_threads() == 2
    assert torch.get_num_threads() == 2


def test_torch_threads_restores_after_an_error(restore_threads):
    torch.set_num_threads(2)
    with pytest.raises(RuntimeError, match="inside"), torch_threads(1):
        raise RuntimeError("inside")
    assert torch.get_num_threads() == 2


@pytest.mark.parametrize("bad", [0, -2, 1.0, True])
def test_torch_threads_rejects_a_bad_count(bad, restore_threads):
    with pytest.raises(ValueError, match="positive integer"), torch_threads(bad):
        pass


class _RecordingMethod:
    """Wraps an inference method; records torch's thread count while it runs."""

    def __init__(self, method):
        self.method, self.seen = method, []

    def __getattr__(self, name):
        return getattr(self.method, name)

    def run(self, *args, **kwargs):
        self.seen.append(torch.get_num_threads())
        return self.method.run(*args, **kwargs)


@pytest.mark.parametrize(("threads", "during"), [("auto", 1), (0, 2), (None, 2), (3, 3)])
def test_fit_house_runs_with_the_chosen_count_and_restores(
    small_house, monkeypatch, restore_threads, threads, during
):
    recorder = {}

    def get_method(name):
        recorder["method"] = _RecordingMethod(registered_method(name))
        return recorder["method"]

    monkeypatch.setattr(spcopyro.fit.house, "get_method", get_method)
    torch.set_num_threads(2)
    fit_house(small_house, preset("original-code", gamma=3.0), sweeps=2, progress=False,
              threads=threads)  # fmt: skip
    assert recorder["method"].seen == [during]
    assert torch.get_num_threads() == 2


def test_fit_house_converged_restores_the_setting(small_house, restore_threads):
    torch.set_num_threads(2)
    fit_house_converged(small_house, preset("original-code", gamma=3.0), chains=2, block=2,
                        max_sweeps=2, progress=False, threads=1)  # fmt: skip
    assert torch.get_num_threads() == 2


def test_fit_house_names_a_bad_thread_count(small_house):
    with pytest.raises(ValueError, match="got -1"):
        fit_house(small_house, sweeps=1, threads=-1)


def test_fit_command_line_threads_option():
    parse = build_parser().parse_args
    assert parse(["fit", "--out", "x"]).threads == "auto"
    assert parse(["fit", "--out", "x", "--threads", "0"]).threads == 0
    assert parse(["fit", "--out", "x", "--threads", "3"]).threads == 3


@pytest.mark.parametrize("bad", ["-1", "two", "1.5"])
def test_fit_command_line_rejects_a_bad_thread_count(bad, capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["fit", "--out", "x", "--threads", bad])
    assert "argument --threads: must be 'auto' or an integer >= 0" in capsys.readouterr().err


@pytest.fixture
def house_folder(tmp_path):
    from spcopyro.synthetic import write_synthetic

    spec = HouseSpec(height=30, width=40, num_rooms=2, num_trials=1)
    return write_synthetic(tmp_path / "data", seed=3, spec=spec)


@pytest.mark.parametrize("sweeps", ["2", "auto"])
def test_fit_command_passes_threads_to_the_fit(
    house_folder, tmp_path, monkeypatch, capsys, restore_threads, sweeps
):
    from spcopyro.cli.main import main

    seen = []
    real_converged, real_advance = (
        spcopyro.fit.house.run_until_converged,
        spcopyro.gibbs.chains.advance,
    )

    def run_until_converged(*args, **kwargs):
        seen.append(torch.get_num_threads())
        return real_converged(*args, **kwargs)

    def advance(*args, **kwargs):  # the fixed-sweeps Gibbs chains run through advance
        seen.append(torch.get_num_threads())
        return real_advance(*args, **kwargs)

    monkeypatch.setattr(spcopyro.fit.house, "run_until_converged", run_until_converged)
    monkeypatch.setattr(spcopyro.gibbs.chains, "advance", advance)
    torch.set_num_threads(2)
    capped = ["--max-sweeps", "2"] if sweeps == "auto" else []  # refused without auto
    argv = ["fit", str(house_folder), "--out", str(tmp_path / "fit"), "--sweeps", sweeps,
            *capped, "--chains", "2", "--threads", "3"]  # fmt: skip
    assert main(argv) == 0
    if sweeps == "auto":
        assert seen == [3, 3, 3]  # the driver, then its one block's run per chain
    else:
        assert seen == [3, 3]  # one run per chain
    assert "threads          3 torch intra-op threads (as asked)" in capsys.readouterr().out
    assert torch.get_num_threads() == 2


@pytest.mark.parametrize(("threads", "during"), [("auto", 1), (3, 3)])
def test_experiment_fits_follow_the_policy(
    small_house, monkeypatch, restore_threads, threads, during
):
    import spcopyro.experiments.methods as methods

    recorder = {}

    def get_method(name):
        recorder["method"] = _RecordingMethod(registered_method(name))
        return recorder["method"]

    monkeypatch.setattr(methods, "get_method", get_method)
    torch.set_num_threads(2)
    methods.fit_spco(small_house, preset("original-code", gamma=3.0), sweeps=2, seed=0,
                     threads=threads)  # fmt: skip
    assert recorder["method"].seen == [during]
    assert torch.get_num_threads() == 2


@pytest.fixture
def fresh_load(monkeypatch):
    """No load reading kept from an earlier test (other_load reuses one for a while)."""
    import spcopyro._util.threads as threads_module

    monkeypatch.setattr(threads_module, "_last_load", None)
    return threads_module


@pytest.mark.parametrize(
    ("load", "cpus", "default", "expected"),
    [(None, 2, 2, None), (0.0, 2, 2, None), (0.4, 2, 2, None), (0.6, 2, 2, 1), (1.5, 2, 2, 1),
     (5.0, 2, 2, 1), (4.0, 16, 16, 12), (2.0, 16, 8, None)],
)  # fmt: skip
def test_the_policy_leaves_a_busy_machine_one_thread(load, cpus, default, expected):
    cells = MIN_CELLS_FOR_MORE_THREADS
    assert policy_threads(cells, load, cpus=cpus, default=default) == expected
    assert policy_threads(cells - 1, load, cpus=cpus, default=default) == 1


def test_auto_reads_the_load_for_a_large_map(fresh_load, monkeypatch, restore_threads):
    """On 2 cores beside 1.8 busy ones a large map runs on one thread (two were 5-20x slower
    there, results bit-identical: docs/speed.md, "Threads"); idle, torch's own setting."""
    torch.set_num_threads(2)
    monkeypatch.setattr(fresh_load, "usable_cpus", lambda: 2)
    monkeypatch.setattr(fresh_load, "other_load", lambda: 1.8)
    assert resolve_threads("auto", MIN_CELLS_FOR_MORE_THREADS) == 1
    assert describe_threads("auto", MIN_CELLS_FOR_MORE_THREADS) == (
        f"1 torch intra-op thread (policy: {MIN_CELLS_FOR_MORE_THREADS} free cells >= "
        f"{MIN_CELLS_FOR_MORE_THREADS}, other processes busy on 1.8 of 2 cores)"
    )
    monkeypatch.setattr(fresh_load, "other_load", lambda: 0.1)
    assert resolve_threads("auto", MIN_CELLS_FOR_MORE_THREADS) is None
    assert resolve_threads(2, MIN_CELLS_FOR_MORE_THREADS) == 2  # a count asked is kept


def test_other_load_leaves_out_this_process(fresh_load, monkeypatch):
    ticks = iter([(100, 1000), (140, 1050)])  # (busy, total): 40 of 50 ticks busy
    own = iter([3.0, 3.0 + 0.6 * fresh_load.LOAD_WINDOW_S])  # this process: 0.6 cores
    monkeypatch.setattr(fresh_load, "_cpu_ticks", lambda: next(ticks))
    monkeypatch.setattr(fresh_load, "_own_cpu_seconds", lambda: next(own))
    monkeypatch.setattr(fresh_load.time, "sleep", lambda s: None)
    monkeypatch.setattr(fresh_load.os, "cpu_count", lambda: 2)
    assert fresh_load.other_load() == pytest.approx(0.8 * 2 - 0.6)
    assert fresh_load.other_load() == pytest.approx(1.0)  # reused: no second reading


def test_other_load_unknown_without_proc_stat(fresh_load, monkeypatch):
    monkeypatch.setattr(fresh_load, "_cpu_ticks", lambda: None)
    assert fresh_load.other_load() is None
    assert resolve_threads("auto", MIN_CELLS_FOR_MORE_THREADS) is None  # torch's setting


@pytest.mark.parametrize(("load", "during"), [(1.8, 1), (0.0, 2)])
def test_fit_follows_the_load_and_records_the_threads_that_ran(
    small_house, fresh_load, monkeypatch, restore_threads, load, during
):
    recorder = {}

    def get_method(name):
        recorder["method"] = _RecordingMethod(registered_method(name))
        return recorder["method"]

    monkeypatch.setattr(spcopyro.fit.house, "get_method", get_method)
    monkeypatch.setattr(fresh_load, "MIN_CELLS_FOR_MORE_THREADS", 10)  # the small house is large
    monkeypatch.setattr(fresh_load, "usable_cpus", lambda: 2)
    monkeypatch.setattr(fresh_load, "other_load", lambda: load)
    torch.set_num_threads(2)
    result = fit_house(small_house, preset("original-code", gamma=3.0), sweeps=2,
                       progress=False)  # fmt: skip
    assert recorder["method"].seen == [during]
    assert result.settings_json()["threads"] == during  # config.json: what ran
    assert torch.get_num_threads() == 2


@pytest.mark.parametrize(("load", "during"), [(1.8, 1), (0.0, 2)])
def test_an_update_follows_the_load_and_records_the_threads_that_ran(
    small_house, fresh_load, monkeypatch, restore_threads, load, during
):
    """``fit --update`` (fit_update) chose its threads as the fit does but left them out of
    config.json."""
    from spcopyro.robot.online import fit_update

    settings = preset("original-code", gamma=3.0)
    saved = fit_house(small_house, settings, sweeps=2, progress=False, threads=1)
    monkeypatch.setattr(fresh_load, "MIN_CELLS_FOR_MORE_THREADS", 10)  # the small house is large
    monkeypatch.setattr(fresh_load, "usable_cpus", lambda: 2)
    monkeypatch.setattr(fresh_load, "other_load", lambda: load)
    torch.set_num_threads(2)
    for method in ("gibbs", "cavi"):
        (result,) = fit_update(saved, small_house, settings, method=method, sweeps=2,
                               progress=False)  # fmt: skip
        assert result.settings_json()["threads"] == during, method  # config.json: what ran
    assert torch.get_num_threads() == 2


@pytest.mark.parametrize(("threshold", "printed"), [(100, True), (10**6, False)])
def test_a_refinement_on_other_threads_says_so(
    house_folder, tmp_path, fresh_load, monkeypatch, capsys, restore_threads, threshold, printed
):
    """fit's 'threads' line describes the first stage (54 free cells of 0.25 m here); on the
    map's 684 cells the policy may choose another count, which only the log and config.json
    gave: a line says it where it differs."""
    import json

    from spcopyro.cli.main import main

    monkeypatch.setattr(fresh_load, "MIN_CELLS_FOR_MORE_THREADS", threshold)
    monkeypatch.setattr(fresh_load, "usable_cpus", lambda: 2)
    monkeypatch.setattr(fresh_load, "other_load", lambda: 0.0)
    torch.set_num_threads(2)
    out = tmp_path / "fit"
    argv = ["fit", str(house_folder), "--out", str(out), "--sweeps", "2", "--refine", "always",
            "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    lines = [x for x in capsys.readouterr().out.splitlines() if x.startswith("threads ")]
    assert lines[0].startswith("threads          1 torch intra-op thread (policy: 54 free cells")
    refined = ("threads          the refinement on the map's 684 free cells ran 2 torch intra-op "
               "threads, the first stage 1 (config.json records the refinement's)")  # fmt: skip
    assert lines[1:] == ([refined] if printed else [])
    assert json.loads((out / "config.json").read_text())["threads"] == (2 if printed else 1)
    assert torch.get_num_threads() == 2


CHAIN_WORKERS_LINES = [
    ("2", "1 torch intra-op thread per chain, 2 chains side by side (policy: one each when "
          "chains run at once)", 1),
    ("1", "2 torch intra-op threads (policy: 54 free cells >= 10, other processes busy on 0.0 "
          "of 2 cores)", 2),
]  # fmt: skip
"""--chain-workers, the threads line fit prints and the threads each chain ran (54 free cells
counted as a large map, 2 usable cores, no other load, torch at 2 threads)."""


def _large_map_on_two_idle_cores(monkeypatch, threads_module) -> None:
    """CHAIN_WORKERS_LINES' machine: chains on threads of this process (lighter here), the
    54-cell house counted as a large map, 2 usable cores, no other load, torch at 2 threads."""
    monkeypatch.setenv(spcopyro.gibbs.chains.PROCESSES_ENV, "off")
    monkeypatch.setattr(threads_module, "MIN_CELLS_FOR_MORE_THREADS", 10)
    monkeypatch.setattr(threads_module, "usable_cpus", lambda: 2)
    monkeypatch.setattr(threads_module, "other_load", lambda: 0.0)
    torch.set_num_threads(2)


@pytest.mark.parametrize(("workers", "line", "ran"), CHAIN_WORKERS_LINES)
def test_fit_prints_the_threads_each_chain_ran(
    house_folder, tmp_path, fresh_load, monkeypatch, capsys, restore_threads, workers, line, ran
):
    """With chains side by side, ``--threads auto`` runs each on one thread (fit_house_chains);
    fit's 'threads' line named the policy's count for the map (2 here) all the same."""
    import json

    from spcopyro.cli.main import main

    _large_map_on_two_idle_cores(monkeypatch, fresh_load)
    out = tmp_path / "fit"
    argv = ["fit", str(house_folder), "--out", str(out), "--sweeps", "2", "--chains", "2",
            "--chain-workers", workers, "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    lines = [x for x in capsys.readouterr().out.splitlines() if x.startswith("threads ")]
    assert lines == [f"threads          {line}"]
    assert json.loads((out / "config.json").read_text())["threads"] == ran  # what ran
    assert torch.get_num_threads() == 2


@pytest.mark.parametrize(("workers", "line", "ran"), CHAIN_WORKERS_LINES)
def test_sweeps_auto_runs_chains_side_by_side_on_one_thread_each(
    house_folder, tmp_path, fresh_load, monkeypatch, capsys, restore_threads, workers, line, ran
):
    """``--sweeps auto``'s chains (fit_house_converged) ran side by side on the policy's count
    for the map each (2 chains x 2 threads on 2 cores), and ignored ``--chain-workers``: they
    follow fit_house_chains' rule now, and the line and config.json say what ran."""
    import json

    import spcopyro.gibbs.convergence
    from spcopyro.cli.main import main

    seen_workers, seen_threads = [], []
    real_chains, real_advance = (
        spcopyro.gibbs.convergence.advance_chains,
        spcopyro.gibbs.chains.advance,
    )

    def advance_chains(*args, **kwargs):
        seen_workers.append(kwargs.get("workers"))
        return real_chains(*args, **kwargs)

    def advance(*args, **kwargs):  # each chain's block, on a thread of this process
        seen_threads.append(torch.get_num_threads())
        return real_advance(*args, **kwargs)

    monkeypatch.setattr(spcopyro.gibbs.convergence, "advance_chains", advance_chains)
    monkeypatch.setattr(spcopyro.gibbs.chains, "advance", advance)
    _large_map_on_two_idle_cores(monkeypatch, fresh_load)
    out = tmp_path / "fit"
    argv = ["fit", str(house_folder), "--out", str(out), "--sweeps", "auto", "--max-sweeps", "2",
            "--chains", "2", "--chain-workers", workers, "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    lines = [x for x in capsys.readouterr().out.splitlines() if x.startswith("threads ")]
    assert lines == [f"threads          {line}"]
    assert seen_workers == [int(workers)]  # --chain-workers honoured: one block of 2 sweeps
    assert seen_threads == [ran, ran]  # each chain's block ran on the count the line gives
    assert json.loads((out / "config.json").read_text())["threads"] == ran  # what ran
    assert torch.get_num_threads() == 2


def test_fit_house_passes_chain_workers_to_sweeps_auto(small_house, monkeypatch):
    """fit_house(sweeps="auto") dropped chain_workers: its chains ran one per usable CPU."""
    seen = {}

    class Stop(Exception):
        pass

    def fit_house_converged(*args, **kwargs):
        seen.update(kwargs)
        raise Stop

    monkeypatch.setattr(spcopyro.fit.house, "fit_house_converged", fit_house_converged)
    with pytest.raises(Stop):
        fit_house(small_house, sweeps="auto", chains=2, chain_workers=1, progress=False)
    assert seen["chain_workers"] == 1


@pytest.fixture(scope="module")
def threaded_product_house():
    """A house whose [M, 205] x [205, L] image product (observation_log_likelihood's
    ``counts @ log_phi.T``) MKL splits across 2 threads: 105 observed cells (the small house's
    30 are too few for the product to differ between 1 and 2 threads)."""
    return make_house(seed=3, spec=HouseSpec(height=30, width=40, num_rooms=2, num_trials=4))


def _outputs(result) -> dict[str, np.ndarray]:
    """Every array of a result that a seeded fit fixes ([N] labels, [L] pi, [L, K_m] tables,
    [S] trace, [N, L] marginals, ...)."""
    arrays = {"labels": result.labels, "pi": result.pi, "objective": result.trace.objective,
              "num_concepts": result.trace.num_concepts}  # fmt: skip
    arrays.update({t.name: t.probabilities for t in result.emissions})
    for name in ("marginals", "labels_final", "agreement"):
        if getattr(result, name) is not None:
            arrays[name] = getattr(result, name)
    return arrays


def _fits_on_one_and_two_threads(house, method, iterations, options=None, *, differing=True):
    """The same seeded fit with 1 and 2 torch threads. With ``differing``, skipped where this
    machine's BLAS gives the house's image product the same bits on both: a test that the
    floats differ in their last bits only says nothing there. A test of bit-identity passes
    ``differing=False`` and runs everywhere (the claim holds whatever the BLAS does)."""
    from spcopyro.fit.house import prepare_model_data

    settings = preset("original-code", gamma=3.0)
    _, data = prepare_model_data(house, settings)
    counts = data.modalities[0].counts  # [M, 205]
    log_phi = torch.randn(120, counts.shape[1], dtype=counts.dtype,
                          generator=torch.Generator().manual_seed(0))  # fmt: skip
    products = []
    for threads in (1, 2):
        with torch_threads(threads):
            products.append(counts @ log_phi.T)  # [M, L]
    if differing and torch.equal(*products):
        pytest.skip("this BLAS gives the product the same bits on 1 and 2 threads")
    fits = [fit_house(house, settings, method=method, options=options, sweeps=iterations,
                      seed=1, progress=False, threads=threads) for threads in (1, 2)]  # fmt: skip
    return [_outputs(fit) for fit in fits]


def test_vi_gibbs_is_bit_identical_on_one_and_two_threads(threaded_product_house):
    """``--method vi-gibbs``: the CAVI start (numba backend) and the sweeps give every output the
    same bits with 1 and 2 threads, where the image product in it differs in its last bits (MKL
    on this house: the labels, drawn against it, and the tables, drawn from counts, do not see
    them) and where it does not."""
    one, two = _fits_on_one_and_two_threads(threaded_product_house, "vi-gibbs", 20,
                                            differing=False)  # fmt: skip
    assert one.keys() == two.keys()
    for name in one:
        assert one[name].tobytes() == two[name].tobytes(), name


def test_svi_floats_differ_in_their_last_bits_only(threaded_product_house):
    """``--method svi`` differentiates through the image product, so its last-bit difference
    between 1 and 2 threads (MKL splits the float64 product's inner dimension of 205 with a
    transposed right operand) reaches pi, the tables and the ELBO; the labels stay the same
    (docs/speed.md, "Threads")."""
    one, two = _fits_on_one_and_two_threads(threaded_product_house, "svi", 10)
    np.testing.assert_array_equal(one["labels"], two["labels"])
    np.testing.assert_array_equal(one["num_concepts"], two["num_concepts"])
    for name in ("pi", "images", "words", "objective"):  # float64
        np.testing.assert_allclose(one[name], two[name], rtol=1e-9, atol=1e-15, err_msg=name)
    # float32: a last-bit change of q(C) may round to the neighbouring float32
    np.testing.assert_allclose(one["marginals"], two["marginals"], rtol=2.5e-7, atol=1e-12)


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_gibbs_is_bit_identical_on_one_and_two_threads(threaded_product_house, backend):
    """Gibbs on either backend: every output (labels, labels_final, pi, the tables, the
    objective trace) has the same bits on 1 and 2 threads: torch's CPU random draws are serial,
    so the chain is the same, although the log-likelihood table the labels are drawn against
    (observation_log_likelihood for the torch sweep; the compiled one's products run on one
    thread, the tests below) may differ in its last bits, as MKL's does on this house. A
    draw flips only where a uniform lands within those bits of a boundary between two concepts'
    cumulative weights (docs/speed.md, "Threads"). Runs whatever the BLAS does: it replaced a
    test of the labels alone on a 30-cell house, whose product never differed."""
    if backend == "numba":
        pytest.importorskip("numba")
    options = GibbsOptions(backend=backend, cluster_moves=0.2)
    one, two = _fits_on_one_and_two_threads(threaded_product_house, "gibbs", 30, options,
                                            differing=False)  # fmt: skip
    assert one.keys() == two.keys()
    for name in one:
        assert one[name].tobytes() == two[name].tobytes(), name


def test_the_compiled_background_table_is_the_same_on_one_and_two_threads(threaded_product_house):
    """What the test above draws against: the compiled sweep's background table has the same
    bits on 1 and 2 threads, as its products run on one thread whatever the fit's count (with
    MKL's thread split they differed in their last bits, up to 5.4e-14 on this house)."""
    pytest.importorskip("numba")
    from spcopyro.fit.house import prepare_model_data
    from spcopyro.gibbs.numba_background import background_table
    from spcopyro.gibbs.sampler import init

    settings = preset("original-code", gamma=3.0)
    _, data = prepare_model_data(threaded_product_house, settings)
    state = init(data, settings.model, torch.Generator().manual_seed(4))
    tables = []
    for threads in (1, 2):
        with torch_threads(threads):
            tables.append(background_table(state, data, settings.model))  # [M + 1, L + D]
    assert tables[0].tobytes() == tables[1].tobytes()


PRODUCT_ROWS = (1, 2, 30, 60, 85, 86, 100, 105, 500, 5000)
"""Row counts of the background's products: MKL split the [rows, 205] x [205, 120] float64
product across threads with other last bits at 60-105 rows and from 86 on (its AVX2 and AVX-512
paths, the transposed or the copied operand)."""


def _background_products_differing(rows_list=PRODUCT_ROWS, thread_counts=(2, 3)) -> list:
    """(rows, threads) where numba_background.write_log_likelihood's products -- the dense
    ``matmul(out=)`` [rows, 205], the dense ``addmm_`` [rows, 15] and the factored [rows, 205]
    through an identity CSR, into one [rows, 120] table -- differ from one thread's bits."""
    from types import SimpleNamespace

    from spcopyro.gibbs.numba_background import write_log_likelihood

    differing = []
    for rows in rows_list:
        generator = torch.Generator().manual_seed(rows)
        tables = [
            torch.randn(120, k, dtype=torch.float64, generator=generator) for k in (205, 15, 205)
        ]
        observed = [  # [rows, K_m] each
            torch.poisson(3 * torch.rand(rows, k, dtype=torch.float64, generator=generator),
                          generator=generator) for k in (205, 15, 205)]  # fmt: skip
        spread = SimpleNamespace(sources=observed[2].numpy(), indptr=np.arange(rows + 1),
                                 indices=np.arange(rows), weights=np.ones(rows),
                                 pays=lambda: True)  # fmt: skip
        modalities = [SimpleNamespace(name=str(i), counts=c, factored=lambda: None)
                      for i, c in enumerate(observed[:2])]  # fmt: skip
        modalities.append(
            SimpleNamespace(name="2", counts=observed[2], factored=lambda spread=spread: spread)
        )
        data = SimpleNamespace(modalities=modalities)
        state = SimpleNamespace(log_emissions=tables)
        config = SimpleNamespace(uses=lambda name: True)
        outs = {}
        for threads in (1, *thread_counts):
            with torch_threads(threads):
                outs[threads] = torch.empty(rows, 120, dtype=torch.float64)  # [rows, L]
                write_log_likelihood(state, data, config, outs[threads])
        differing += [(rows, t) for t in thread_counts if not torch.equal(outs[t], outs[1])]
    return differing


def test_the_background_products_give_the_same_bits_on_any_thread_count():
    """numba_background.write_log_likelihood's three kinds of product have the same bits on 1, 2
    and 3 threads at every row count, a single row included."""
    pytest.importorskip("numba")
    assert _background_products_differing() == []


@pytest.mark.parametrize("instructions", ["AVX2", "AVX512"])
def test_the_background_products_are_thread_independent_on_every_mkl_code_path(instructions):
    """The same on MKL's AVX2 path (what it runs on AMD and pre-AVX-512 Intel CPUs), where a
    contiguous log(phi)^T, which kept MKL's AVX-512 split to the same bits, did not (60, 85, 86,
    100, 105 rows): the products run on one thread, not on MKL's split rules. A subprocess, as
    MKL reads MKL_ENABLE_INSTRUCTIONS once; on a CPU without the instructions MKL takes the best
    path it has, and without MKL the variable does nothing."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    pytest.importorskip("numba")
    code = ("import sys; sys.path.insert(0, sys.argv[1]); "
            "from test_threads import _background_products_differing as f; print(f())")  # fmt: skip
    env = {**os.environ, "MKL_ENABLE_INSTRUCTIONS": instructions}
    out = subprocess.run([sys.executable, "-c", code, str(Path(__file__).parent)], env=env,
                         capture_output=True, text=True, timeout=600)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_one_blas_thread_leaves_the_other_threads_their_count(restore_threads):
    """one_blas_thread changes MKL's count for the calling thread only: torch's count stays, and
    a thread that starts inside the block (a Gibbs chain on a thread) takes torch's, not 1 (with
    torch_threads(1) there, a chain of ``fit --threads 3 --chains 2`` ran on one thread)."""
    import threading

    from spcopyro._util.threads import _mkl_set_num_threads_local, one_blas_thread

    if _mkl_set_num_threads_local() is None:
        pytest.skip("this torch has no MKL thread-local count (one_blas_thread: torch_threads)")
    torch.set_num_threads(3)
    seen = []
    with one_blas_thread():
        assert torch.get_num_threads() == 3
        thread = threading.Thread(target=lambda: seen.append(torch.get_num_threads()))
        thread.start()
        thread.join()
    assert seen == [3]
    with pytest.raises(KeyError), one_blas_thread():
        raise KeyError("x")
    assert _mkl_set_num_threads_local()(3) == 3  # this thread's MKL count restored after a raise
    assert torch.get_num_threads() == 3


def test_one_blas_thread_holds_in_a_fresh_thread_whose_first_parallel_op_is_inside(
    restore_threads,
):
    """torch sets a new thread's MKL count at its first parallel op: inside the block (a chain
    thread's first sweep reaching the background table) that overwrote the block's 1 with
    torch's count, and the restore then left MKL's global default (0, every core) behind."""
    import threading

    from spcopyro._util.threads import _mkl_set_num_threads_local, one_blas_thread

    setter = _mkl_set_num_threads_local()
    if setter is None:
        pytest.skip("this torch has no MKL thread-local count (one_blas_thread: torch_threads)")
    torch.set_num_threads(3)
    seen = {}

    def fresh_thread() -> None:
        with one_blas_thread():
            torch.ones(1_000_000).add_(1)  # this thread's first parallel op
            seen["inside"] = setter(1)
        seen["after"] = setter(3)

    thread = threading.Thread(target=fresh_thread)
    thread.start()
    thread.join()
    assert seen == {"inside": 1, "after": 3}


@pytest.mark.parametrize("method", ["cavi", "lbp"])
def test_cavi_and_lbp_floats_differ_in_their_last_bits_only(threaded_product_house, method):
    """CAVI and loopy BP (compiled backends by default; the torch ones call the same
    observation_log_likelihood) add the image product's last-bit difference between 1 and 2
    threads into every iteration's q(C), so pi, the tables and the ELBO may differ in their last
    bits; the labels stay the same (docs/speed.md, "Threads")."""
    one, two = _fits_on_one_and_two_threads(threaded_product_house, method, 20)
    assert one.keys() == two.keys()
    for name in ("labels", "num_concepts"):
        np.testing.assert_array_equal(one[name], two[name], err_msg=name)
    for name in ("pi", "images", "words", "objective"):  # float64
        np.testing.assert_allclose(one[name], two[name], rtol=1e-9, atol=1e-15, err_msg=name)
    if "marginals" in one:  # float32: a last-bit change of q(C) may round to the next float32
        np.testing.assert_allclose(one["marginals"], two["marginals"], rtol=2.5e-7, atol=1e-12)
