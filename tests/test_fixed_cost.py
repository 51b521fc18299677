"""The fit's fixed cost (issue #15 item 2): ``fit --no-figures``, the phase timings
(:mod:`spcopyro._util.timings`) and the heavy optional modules kept off the fit's import path.

Nothing here times anything: ``benchmarks/fixed_cost.py`` measures the seconds.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from spcopyro._util.timings import OPTIONAL_HEAVY, TIMINGS_ENV, Phases
from spcopyro.cli.main import main

ROOT = Path(__file__).resolve().parents[1]


def _env() -> dict[str, str]:
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path, "CI": "1"}


def test_fit_no_figures_writes_outputs_but_no_png(tmp_path, capsys, monkeypatch):
    timings = tmp_path / "timings.json"
    monkeypatch.setenv(TIMINGS_ENV, str(timings))
    out = tmp_path / "fit"
    assert main(["fit", "--sweeps", "4", "--out", str(out), "--no-figures"]) == 0
    printed = capsys.readouterr().out
    assert "figures skipped" in printed and "concept" in printed
    assert printed.strip().splitlines()[-1].startswith("next: ask where the ")  # no figure to open
    assert not list(out.glob("*.png"))
    for name in ("labels.npy", "concepts.json", "config.json", "result.npz", "trace.csv"):
        assert (out / name).is_file(), name
    assert json.loads((out / "concepts.json").read_text())
    record = json.loads(timings.read_text())
    refine = json.loads((out / "config.json").read_text())["inference"]["refine"]
    coarse_sweeps = refine["coarse"]["sweeps"] if refine["refine"] else 0  # both stages count
    assert record["figures"] is False and record["sweeps"] == 4 + coarse_sweeps
    assert set(record["seconds"]) >= {"load", "fit", "save", "figures", "report", "commit"}


def test_fit_with_figures_writes_the_pngs_and_times_them(tmp_path, capsys, monkeypatch):
    timings = tmp_path / "timings.json"
    monkeypatch.setenv(TIMINGS_ENV, str(timings))
    out = tmp_path / "fit"
    assert main(["fit", "--sweeps", "4", "--out", str(out)]) == 0
    assert "figures skipped" not in capsys.readouterr().out
    pngs = {p.name for p in out.glob("*.png")}
    assert {"semantic_map.png", "trace.png", "house.png"} <= pngs
    record = json.loads(timings.read_text())
    assert record["figures"] is True and record["seconds"]["figures"] > 0.0


def test_a_refined_fit_draws_the_maps_house_while_the_refinement_runs(tmp_path, monkeypatch):
    """--refine: house.png is the map's own house (not the model grid's the prefetch drew while
    the first stage ran), drawn again on the prefetch thread while the refinement's chains run,
    so that no figure drawn after the fit is the house."""
    from spcopyro.cli import fit_figures
    from spcopyro.figures.plotting import plot_house
    from spcopyro.synthetic import HouseSpec, make_house

    drawn_after: list[str] = []

    def recording(draw):
        def draws(figures, *claims):
            figures = list(figures)
            drawn_after.extend(name for name, _ in figures)
            return draw(figures, *claims)

        return draws

    monkeypatch.setattr(fit_figures, "_draw", recording(fit_figures._draw))
    monkeypatch.setattr(fit_figures, "_draw_in_child", recording(fit_figures._draw_in_child))
    out = tmp_path / "fit"
    assert main(["fit", "--sweeps", "4", "--refine", "always", "--out", str(out)]) == 0
    assert json.loads((out / "config.json").read_text())["inference"]["refine"]["refine"]
    assert "house" not in drawn_after and "semantic_map" in drawn_after
    plot_house(make_house(seed=0, spec=HouseSpec.embedded()), tmp_path / "expected.png")
    assert (out / "house.png").read_bytes() == (tmp_path / "expected.png").read_bytes()


def test_no_timings_file_unless_asked(tmp_path, monkeypatch):
    monkeypatch.delenv(TIMINGS_ENV, raising=False)
    clock = Phases()
    clock.mark("a")
    clock.mark("a")
    assert set(clock.seconds) == {"a"} and clock.seconds["a"] >= 0.0
    assert clock.write() is None
    monkeypatch.setenv(TIMINGS_ENV, str(tmp_path / "t.json"))
    assert clock.write(extra=1) == tmp_path / "t.json"
    record = json.loads((tmp_path / "t.json").read_text())
    assert record["extra"] == 1 and record["total"] >= 0.0 and "entered" in record


def test_the_fit_path_imports_no_optional_heavy_module():
    """Importing the command (and the fit) loads none of matplotlib, scikit-learn, torchvision
    and the scipy subpackages a fit uses only in some configurations."""
    code = (
        "import sys, spcopyro.cli.main, spcopyro.fit.house, spcopyro.gibbs.backends; "
        f"print(sorted(m for m in sys.modules if m in {list(OPTIONAL_HEAVY)!r}))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=_env(), timeout=300, check=True)  # fmt: skip
    assert done.stdout.strip() == "[]", done.stdout


_FIT_AND_LOAD_MAP = """
import json, sys
from spcopyro.cli.main import main
from spcopyro.maps import load_map
assert main(["fit", "--sweeps", "2", "--no-figures", "--out", sys.argv[1]]) == 0
load_map(sys.argv[1] + "/map.yaml")  # a map_saver pgm, as a ROS map's fit reads one
print(json.dumps("cv2" in sys.modules))
"""


def test_a_fit_writes_and_reads_a_map_saver_pgm_without_opencv(tmp_path):
    """A fit of the embedded house (--no-figures) writes its map, and a map_saver map
    is read, without OpenCV's import (0.03 s of CPU; spcopyro.maps.map_image); the timings list
    the optional modules imported, cv2 among them."""
    out, timings = tmp_path / "fit", tmp_path / "timings.json"
    done = subprocess.run([sys.executable, "-c", _FIT_AND_LOAD_MAP, str(out)], capture_output=True,
                          text=True, env={**_env(), TIMINGS_ENV: str(timings)}, timeout=300,
                          check=True)  # fmt: skip
    assert json.loads(done.stdout.strip().splitlines()[-1]) is False
    assert "cv2" in OPTIONAL_HEAVY and "cv2" not in json.loads(timings.read_text())["imported"]
    assert (out / "map.pgm").read_bytes().startswith(b"P5\n")


def test_a_default_fit_runs_without_pyro(tmp_path):
    """A whole default fit of the embedded house (Gibbs, figures, refined) never imports Pyro
    (about 200 modules, 0.05-0.1 s of its start-up): the model's data, the likelihood, the
    sampler, its checkpoint and the method registry import none of it; the timings list it."""
    out, timings = tmp_path / "fit", tmp_path / "timings.json"
    subprocess.run([sys.executable, "-m", "spcopyro", "fit", "--sweeps", "2", "--out", str(out)],
                   capture_output=True, text=True, env={**_env(), TIMINGS_ENV: str(timings)},
                   timeout=300, check=True)  # fmt: skip
    record = json.loads(timings.read_text())
    assert record["figures"] is True and (out / "semantic_map.png").is_file()
    assert "pyro" in OPTIONAL_HEAVY and "pyro" not in record["imported"], record["imported"]


def test_a_variational_fit_other_than_svi_runs_without_pyro(tmp_path):
    """A cavi fit (and lbp's, stochastic-vi's, vi-gibbs') never imports Pyro: whether Ctrl-C
    keeps its checkpoint asks only the fitted method whether it resumes
    (:func:`spcopyro.cli.fit_resume.is_resumable`), not every method (svi's module imports
    Pyro); the methods that resume are the same."""
    from spcopyro.cli.fit_resume import is_resumable, resumable_methods

    out, timings = tmp_path / "fit", tmp_path / "timings.json"
    subprocess.run([sys.executable, "-m", "spcopyro", "fit", "--method", "cavi", "--sweeps", "2",
                    "--no-figures", "--out", str(out)], capture_output=True, text=True,
                   env={**_env(), TIMINGS_ENV: str(timings)}, timeout=300, check=True)  # fmt: skip
    record = json.loads(timings.read_text())
    assert (out / "labels.npy").is_file()
    assert "pyro" not in record["imported"], record["imported"]
    assert resumable_methods() == ["cavi", "lbp", "svi", "stochastic-vi"]
    assert not is_resumable("gibbs") and not is_resumable("vi-gibbs")
    assert not is_resumable("no-such-method")


_PYRO_ON_USE = """
import json, sys
import spcopyro.gibbs, spcopyro.guides, spcopyro.model
from spcopyro.fit.registry import INFERENCE_METHODS, get_method
seen = {"names": list(INFERENCE_METHODS), "in": "svi" in INFERENCE_METHODS, "len":
        len(INFERENCE_METHODS), "gibbs": type(get_method("gibbs")).__name__}
seen["pyro before"] = "pyro" in sys.modules
seen["kernel"] = spcopyro.gibbs.SpCoGibbs.__module__
seen["guide"] = [spcopyro.guides.MeanFieldELBO.__module__, spcopyro.guides.WrongLossError.__name__]
seen["svi"] = type(INFERENCE_METHODS["svi"]).__name__
seen["same"] = INFERENCE_METHODS["svi"] is get_method("svi")
seen["pyro after"] = "pyro" in sys.modules
print(json.dumps(seen))
"""


def test_pyro_is_imported_where_its_names_are_used():
    """spcopyro.gibbs's kernel names, spcopyro.guides's Pyro guide and the registry's methods
    are imported on first use (the same objects as before), the registry's names without."""
    from spcopyro.inference.names import INFERENCE_METHOD_NAMES

    done = subprocess.run([sys.executable, "-c", _PYRO_ON_USE], capture_output=True, text=True,
                          env=_env(), timeout=300, check=True)  # fmt: skip
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen == {
        "names": list(INFERENCE_METHOD_NAMES), "in": True, "len": len(INFERENCE_METHOD_NAMES),
        "gibbs": "GibbsInference", "pyro before": False, "kernel": "spcopyro.gibbs.kernel",
        "guide": ["spcopyro.guides.loss", "WrongLossError"], "svi": "SVIInference",
        "same": True, "pyro after": True,
    }  # fmt: skip


def test_the_command_exits_with_mains_code():
    """``python -m spcopyro`` (console_main: main, gc.freeze, exit) returns main's status."""
    done = subprocess.run([sys.executable, "-m", "spcopyro", "where", "/nonexistent/fit", "x"],
                          capture_output=True, text=True, env=_env(), timeout=300)  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("error:")


def test_point_estimate_tables_over_pairs_equal_the_cells_tables(rng):
    """The point estimate's contingency tables, summed over (cluster, sample column) pairs,
    equal :func:`contingency` over the cells, and its distinct columns are np.unique's."""
    from spcopyro.results import point_estimate as pe

    for trial in range(30):
        samples = rng.integers(0, 1 + trial % 5, size=(1 + trial % 6, 40 + trial))  # [S, N]
        samples[:, ::3] = samples[0, ::3]  # shared columns
        prepared = pe._prepare(samples, "vi")
        signatures, signature = np.unique(prepared.codes, axis=1, return_inverse=True)
        assert np.array_equal(prepared.signatures, signatures)
        assert np.array_equal(prepared.signature, signature.reshape(-1))
        estimate, k = pe.compact(rng.integers(0, 4, size=samples.shape[1]))
        tables = pe._sample_tables(pe._pairs(estimate, prepared), k + 1, prepared).tables
        for table, codes, j in zip(tables, prepared.codes, prepared.sizes, strict=True):
            assert np.array_equal(table, pe.contingency(estimate, codes, k + 1, j))


def test_adjusted_rand_score_equals_scikit_learns(rng):
    """The numpy ARI the fit reports (no scikit-learn import) returns scikit-learn's float."""
    import pytest

    sklearn_metrics = pytest.importorskip("sklearn.metrics")
    from spcopyro.metrics.rand import adjusted_rand_score

    cases = [([], []), ([0] * 5, [0] * 5), (list(range(5)), [0] * 5), (["a", "b", "a"], [1, 2, 2])]
    for _ in range(200):
        n = int(rng.integers(1, 200))
        high = rng.integers(1, 9, size=2)
        cases.append((rng.integers(-1, high[0], n), rng.integers(0, high[1], n)))
    for first, second in cases:
        expected = sklearn_metrics.adjusted_rand_score(np.asarray(first), np.asarray(second))
        assert adjusted_rand_score(np.asarray(first), np.asarray(second)) == expected


def _fitted_house(tmp_path):
    """A short default fit of the embedded house (with marginals: every figure has data)."""
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house, preset_fit_kwargs
    from spcopyro.synthetic import HouseSpec, make_house

    house = make_house(seed=0, spec=HouseSpec.embedded())
    kwargs = preset_fit_kwargs("coarse", marginal_samples=4)
    result = fit_house(house, preset("coarse"), sweeps=8, seed=0, progress=False, **kwargs)
    return result, house


def test_figures_shared_with_a_forked_child_are_each_taken_once():
    """_Claims: a parent and its forked child taking figures as they go take every index once."""
    import multiprocessing

    import pytest

    from spcopyro.cli.fit_figures import _Claims

    if not sys.platform.startswith("linux"):
        pytest.skip("figures are drawn in a forked child on Linux only")
    context = multiprocessing.get_context("fork")
    claims, taken_there = _Claims(200), context.Queue()

    def take_all() -> None:
        taken_there.put([index for index in iter(claims.take, None)])

    child = context.Process(target=take_all)
    child.start()
    taken_here = [index for index in iter(claims.take, None)]
    there = taken_there.get(timeout=60)
    child.join(timeout=60)
    claims.close()
    assert sorted(taken_here + there) == list(range(200))
    with pytest.raises(ValueError, match="at most 255"):
        _Claims(256)


def test_figures_drawn_in_a_forked_child_are_the_files_drawn_here(tmp_path, monkeypatch):
    """figures_drawn shares its figures (the semantic map, trace, house, uncertainty and
    agreement maps) with a forked child where forking is safe: the PNGs are byte for byte those
    drawn in one process; a child that dies leaves its figures to the parent, which draws them."""
    import pytest

    from spcopyro.cli import fit_figures
    from spcopyro.cli.fit_figures import figures_drawn

    if not sys.platform.startswith("linux"):
        pytest.skip("figures are drawn in a forked child on Linux only")
    result, house = _fitted_house(tmp_path)
    assert result.agreement is not None
    folders = {name: tmp_path / name for name in ("here", "forked", "child died")}
    for folder in folders.values():
        folder.mkdir()
    with figures_drawn(result, house, folders["here"], uncertainty=True, fork=False):
        pass
    children: list[object] = []
    start = fit_figures._draw_in_child

    def recorded(figures, claims):
        children.append(start(figures, claims))
        return children[-1]

    monkeypatch.setattr(fit_figures, "_draw_in_child", recorded)
    with figures_drawn(result, house, folders["forked"], uncertainty=True):
        pass
    assert len(children) == 1 and children[0].exitcode == 0  # drawn there
    monkeypatch.setattr(fit_figures, "_child_draws", lambda *args: os._exit(3))
    with figures_drawn(result, house, folders["child died"], uncertainty=True):
        pass
    assert children[-1].exitcode == 3
    names = {"semantic_map.png", "trace.png", "house.png", "uncertainty.png", "agreement.png"}
    for name in names:
        expected = (folders["here"] / name).read_bytes()
        for folder in ("forked", "child died"):
            assert (folders[folder] / name).read_bytes() == expected, (folder, name)


_IMPORT_FROZEN = """
import gc, json, sys
collections = []  # those once torch's import began (it is in sys.modules from its start)
gc.callbacks.append(lambda phase, info: phase == "start" and "torch" in sys.modules
                    and collections.append(info["generation"]))
from spcopyro._util.collector import import_frozen
import_frozen("spcopyro.cli.fit")
count = len(collections)  # allocates no tracked object: cannot start a collection
during = collections[:count]
again = import_frozen("spcopyro.cli.fit")  # imported: nothing frozen again
print(json.dumps({"during": during, "enabled": gc.isenabled(), "frozen": gc.get_freeze_count(),
                  "torch": "torch" in sys.modules, "run_fit": hasattr(again, "run_fit")}))
"""


def test_the_fits_imports_run_without_the_collector_and_are_frozen():
    """torch's and pyro's objects: no collection while they are imported (the plain import ran
    three full ones), and frozen after, so that later collections skip them."""
    done = subprocess.run([sys.executable, "-c", _IMPORT_FROZEN], capture_output=True,
                          text=True, env=_env(), timeout=300, check=True)  # fmt: skip
    record = json.loads(done.stdout.strip().splitlines()[-1])
    assert record["torch"] and record["run_fit"]
    assert record["during"] == []
    assert record["enabled"]
    assert record["frozen"] > 100_000


def test_import_frozen_leaves_a_paused_collector_paused():
    code = (
        "import gc; gc.disable(); from spcopyro._util.collector import import_frozen; "
        "import_frozen('json'); import_frozen('spcopyro.maps'); print(gc.isenabled())"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=_env(), timeout=300, check=True)  # fmt: skip
    assert done.stdout.strip() == "False"


def test_the_fit_command_imports_the_fit_frozen(monkeypatch):
    """``spcopyro fit`` imports :mod:`spcopyro.cli.fit` through
    :func:`~spcopyro._util.collector.import_frozen`."""
    import types

    from spcopyro._util import collector
    from spcopyro.cli import fit_parser

    asked = []
    fit = types.SimpleNamespace(run_fit=lambda args: 17)
    monkeypatch.setattr(collector, "import_frozen", lambda name: asked.append(name) or fit)
    assert fit_parser._run_fit(object()) == 17  # type: ignore[arg-type]
    assert asked == ["spcopyro.cli.fit"]


def test_the_figures_thread_imports_frozen(tmp_path, monkeypatch):
    """The figures' prefetch thread imports matplotlib's figures and scipy.optimize as the fit
    imports torch: through :func:`~spcopyro._util.collector.import_frozen`."""
    from spcopyro.cli import fit_figures

    asked = []
    real = fit_figures.import_frozen
    monkeypatch.setattr(fit_figures, "import_frozen", lambda name: asked.append(name) or real(name))
    monkeypatch.setattr("spcopyro.figures.plotting.plot_house", lambda *a: None)
    prefetch = fit_figures.FigurePrefetch(house=object(), out=tmp_path)  # type: ignore[arg-type]
    assert prefetch.join()
    assert asked == ["scipy.optimize", "spcopyro.figures.plotting"]


def _blocking_prefetch(monkeypatch, tmp_path, block: str):
    """A FigurePrefetch whose part ``block`` ("prefetch imports" or "prefetch house") waits
    for the returned event ``go_on``; ``plot_house`` records the houses drawn in ``drawn``."""
    import contextlib
    import threading

    from spcopyro.cli import fit_figures

    reached, go_on = threading.Event(), threading.Event()
    drawn: list[object] = []

    def blocking_timed(name):
        if name == block and not go_on.is_set():
            reached.set()
            go_on.wait(60)
        return contextlib.nullcontext()

    monkeypatch.setattr(fit_figures, "timed", blocking_timed)
    monkeypatch.setattr(
        "spcopyro.figures.plotting.plot_house", lambda house, path: drawn.append(house)
    )
    prefetch = fit_figures.FigurePrefetch(house="coarse", out=tmp_path)  # type: ignore[arg-type]
    assert reached.wait(60)
    return prefetch, go_on, drawn


def _redraw_returns_at_once(prefetch, house) -> bool:
    import threading

    caller = threading.Thread(target=prefetch.redraw, args=(house,), daemon=True)
    caller.start()
    caller.join(5)
    return not caller.is_alive()


def test_a_redraw_during_the_imports_replaces_the_first_house_without_waiting(
    tmp_path, monkeypatch
):
    """A short fit's refinement starts before the figures' imports end: redraw neither waits
    for the thread (the fit waited 0.3-0.8 s there) nor is the model grid's house drawn."""
    prefetch, go_on, drawn = _blocking_prefetch(monkeypatch, tmp_path, "prefetch imports")
    try:
        returned = _redraw_returns_at_once(prefetch, "map")
    finally:
        go_on.set()
    assert returned
    assert prefetch.join() and drawn == ["map"]


def test_a_redraw_while_the_first_house_is_drawn_draws_the_new_one_after(tmp_path, monkeypatch):
    prefetch, go_on, drawn = _blocking_prefetch(monkeypatch, tmp_path, "prefetch house")
    try:
        returned = _redraw_returns_at_once(prefetch, "map")
        assert not prefetch.house_drawn  # what join would report now: not the map's house
    finally:
        go_on.set()
    assert returned
    assert prefetch.join() and drawn == ["coarse", "map"]


def test_a_redraw_after_the_thread_ended_starts_another(tmp_path, monkeypatch):
    interval = sys.getswitchinterval()
    prefetch, go_on, drawn = _blocking_prefetch(monkeypatch, tmp_path, "prefetch imports")
    go_on.set()
    assert prefetch.join() and drawn == ["coarse"]
    prefetch.redraw("map")
    assert prefetch.join() and drawn == ["coarse", "map"]
    assert sys.getswitchinterval() == interval  # restored, the thread's work done
    prefetch.redraw("again")
    prefetch.abandon()
    assert drawn[-1] in ("map", "again") and sys.getswitchinterval() == interval
