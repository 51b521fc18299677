"""What every benchmark script does alike, checked without running a benchmark: its command
line (bench_cli: --out, --quick and its defaults, usage errors naming the option, unknown
houses, no dataset, Ctrl-C), the README's command lines and JSON names, and the wording of
the --quick tables. The scripts are imported from benchmarks/ (the ``script`` fixture,
tests/conftest.py: their folder on sys.path, as when they run) and parse their arguments.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys

import pytest
from benchmark_setup import BENCHMARKS, _Measuring


class _Parsed(Exception):
    """Raised with a script's parsed arguments, before it measures anything."""


@pytest.fixture
def parse(script, monkeypatch):
    """``parse("gibbs", [...])``: the namespace the script's main() parses from the argv (the
    parser's own usage errors are SystemExit(2), as on the command line)."""
    original = argparse.ArgumentParser.parse_args

    def capture(self, args=None, namespace=None):
        raise _Parsed(original(self, args, namespace))

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)

    def parsed(name: str, argv: list[str]) -> argparse.Namespace:
        with pytest.raises(_Parsed) as got:
            script(name).main(argv)
        return got.value.args[0]

    return parsed


def test_dataset_root_note_or_one_line_error(script, tmp_path, monkeypatch, capsys):
    """An empty $SPCOPYRO_DATA: a note and None where the script can go on without the dataset,
    a one-line error (exit 2) where it cannot or where --dataset names a folder that is none."""
    bench_cli = script("bench_cli")
    monkeypatch.setenv("SPCOPYRO_DATA", str(tmp_path))
    assert bench_cli.dataset_root(without="the public houses are skipped") is None
    assert "holds no map/ folder; the public houses are skipped" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        bench_cli.dataset_root()
    assert stop.value.code == 2 and "error: dataset folder" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        bench_cli.dataset_root(tmp_path / "none", without="skipped")
    assert stop.value.code == 2


def test_a_quick_run_never_overwrites_the_full_runs_json(script, tmp_path):
    """--quick wrote its smoke numbers over benchmarks/NAME.json, the full run's results (an
    hour's work on some scripts): every script with --quick writes NAME_quick.json instead,
    through bench_cli.results_path (or names its _quick.json itself); --out still wins."""
    bench_cli = script("bench_cli")
    assert bench_cli.results_path(None, "x", quick=True) == BENCHMARKS / "x_quick.json"
    assert bench_cli.results_path(None, "x", quick=False) == BENCHMARKS / "x.json"
    assert bench_cli.results_path(tmp_path / "o.json", "x", quick=True) == tmp_path / "o.json"
    overwriting = [
        path.name
        for path in sorted(BENCHMARKS.glob("*.py"))
        if '"--quick"' in (text := path.read_text())
        and "results_path(" not in text
        and "_quick.json" not in text
        and path.name != "bench_cli.py"
    ]
    assert overwriting == []


def test_scripts_find_the_dataset_through_bench_cli():
    """find_dataset_root raises on an empty $SPCOPYRO_DATA: every script goes through
    bench_cli.dataset_root, which turns that into a note or a one-line error."""
    call = re.compile(r"(=|else|return)\s+find_dataset_root\(")
    calls = [
        path.name
        for path in BENCHMARKS.glob("*.py")
        if path.name != "bench_cli.py" and call.search(path.read_text())
    ]
    assert calls == []


def test_an_out_in_a_missing_folder_gets_its_folder_before_the_run(script, tmp_path, capsys):
    """A script whose --out named a folder that did not exist ran its measurements, then
    failed with a traceback when it wrote the JSON."""
    bench_cli = script("bench_cli")
    bench_cli.prepare_out_folder(["--quick", "--out", str(tmp_path / "a" / "b" / "r.json")])
    bench_cli.prepare_out_folder([f"--out={tmp_path / 'c' / 'r.json'}"])
    assert (tmp_path / "a" / "b").is_dir() and (tmp_path / "c").is_dir()
    (tmp_path / "file").write_text("")
    with pytest.raises(SystemExit) as stop:
        bench_cli.prepare_out_folder(["--out", str(tmp_path / "file" / "r.json")])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "cannot make its folder" in err and "Traceback" not in err


@pytest.mark.parametrize("how", ["existing", "slash"])
def test_an_out_that_is_a_folder_is_an_error_before_the_run(script, tmp_path, capsys, how):
    """``--out /tmp`` ran the whole benchmark, then failed writing the JSON with an
    IsADirectoryError traceback (and ``--out new/`` made the folder to fail the same way)."""
    bench_cli = script("bench_cli")
    value = str(tmp_path) if how == "existing" else f"{tmp_path / 'new'}/"
    with pytest.raises(SystemExit) as stop:
        bench_cli.prepare_out_folder(["--out", value])
    err = capsys.readouterr().err.strip()
    assert stop.value.code == 2 and len(err.splitlines()) == 1, err
    assert f"error: --out {value}: is a folder" in err
    assert not (tmp_path / "new").exists()


def test_run_main_interrupted_one_line_and_130(script, tmp_path, capsys):
    """Ctrl-C: no traceback, one line saying what was (not) written, exit status 130."""
    bench_cli = script("bench_cli")

    def interrupted() -> int:
        raise KeyboardInterrupt

    with pytest.raises(SystemExit) as stop:
        bench_cli.run_main(interrupted)
    assert stop.value.code == 130
    assert capsys.readouterr().err.strip() == "interrupted: no JSON written"
    partial = tmp_path / "x.partial.json"
    partial.write_text("[]")
    bench_cli.WRITTEN.append(partial)
    try:
        with pytest.raises(SystemExit):
            bench_cli.run_main(interrupted)
    finally:
        bench_cli.WRITTEN.remove(partial)
    assert f"interrupted: {partial} holds the results so far" in capsys.readouterr().err


CTRL_C_AT_EXIT = """
import atexit, os, signal, sys, time
sys.path.insert(0, sys.argv[1])
from bench_cli import run_main


def ctrl_c_during_shutdown():  # a Ctrl-C while torch's exit callbacks run, after "wrote ..."
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(5)


def main():
    atexit.register(ctrl_c_during_shutdown)
    print("wrote results.json", file=sys.stderr)
    return {code}


run_main(main)
"""


@pytest.mark.parametrize("code", [0, "KeyboardInterrupt()"])
def test_ctrl_c_during_the_exit_is_no_traceback(tmp_path, code):
    """A Ctrl-C once main is done (its JSON written, or the interrupt reported), while the
    interpreter shuts down: the script ends quietly with main's status; it printed a
    KeyboardInterrupt traceback from an atexit callback after "wrote ..."."""
    source = CTRL_C_AT_EXIT.format(code=code)
    if code != 0:
        source = source.replace("    return KeyboardInterrupt()", "    raise KeyboardInterrupt")
    script = tmp_path / "ctrl_c_at_exit.py"
    script.write_text(source)
    done = subprocess.run([sys.executable, str(script), str(BENCHMARKS)], capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr, done.stderr
    if code == 0:
        assert (done.returncode, done.stderr) == (0, "wrote results.json\n")
    else:
        assert done.returncode == 130
        assert done.stderr.strip().endswith("interrupted: no JSON written")


def test_every_script_runs_main_through_run_main():
    """Each runnable script ends in bench_cli.run_main(main), not sys.exit(main())."""
    runnable = [p for p in BENCHMARKS.glob("*.py") if '__name__ == "__main__"' in p.read_text()]
    assert len(runnable) >= 20
    assert [p.name for p in runnable if "    run_main(main)\n" not in p.read_text()] == []


@pytest.mark.parametrize("name", ["coarse_losses", "collapse_terms", "navigation", "real_houses",
                                  "study_dask", "study_order", "two_stage"])  # fmt: skip
def test_default_out_is_beside_the_script(parse, script, name, tmp_path, monkeypatch):
    """The default --out is benchmarks/NAME.json wherever the script is run from (it was
    relative to the current folder: the run failed at the end, writing the JSON)."""
    monkeypatch.chdir(tmp_path)
    args = parse(name, [])
    assert args.out is None  # bench_cli.results_path's: NAME.json, or NAME_quick.json
    assert script("bench_cli").results_path(args.out, name, args.quick) == (
        BENCHMARKS / f"{name}.json"
    )


BAD_VALUES = [
    ("study_order", ["--quick", "--repeats", "0"], "--repeats"),
    ("merge_moves", ["--sweeps", "-5"], "--sweeps"),
    ("merge_moves", ["--quick", "--merge-moves", "-1"], "--merge-moves"),
    ("hyperparameters", ["--sweeps", "-1"], "--sweeps"),
    ("features", ["--quick", "--batch-sizes", "-1", "--no-dataset"], "--batch-sizes"),
    ("variational", ["--quick", "--torch-threads", "0"], "--torch-threads"),
    ("end_to_end", ["--quick", "--sweeps", "-5", "--no-startup"], "--sweeps"),
    ("prior_thread", ["--quick", "--busy-cores", "-1"], "--busy-cores"),
    ("study_dask", ["--quick", "--pairs", "0"], "--pairs"),
    ("fixed_cost", ["--repeats", "-1"], "--repeats"),
    ("fixed_cost", ["--sweeps", "3", "1"], "--sweeps"),
    ("batched_gpu", ["--seconds", "-1"], "--seconds"),
    ("batched_gpu", ["--torch-threads", "0"], "--torch-threads"),
    ("word_tables", ["--quick", "--seeds", "-1"], "--seeds"),
    ("svi_vs_cavi", ["--quick", "--steps", "-1"], "--steps"),
    ("real_houses", ["--quick", "--sweeps", "-1"], "--sweeps"),
    ("footprint", ["--quick", "--radii", "-1"], "--radii"),
    ("gibbs", ["--quick", "--wait-idle", "-1"], "--wait-idle"),
    # A preset or gamma the model refuses: a usage error, not its ValueError after the setup.
    ("merge_moves", ["--quick", "--preset", "bogus"], "--preset"),
    ("merge_moves", ["--quick", "--gamma", "-1"], "--gamma"),
    ("online_update", ["--quick", "--preset", "bogus"], "--preset"),
    ("online_update", ["--quick", "--gamma", "nan"], "--gamma"),
    ("variational", ["--quick", "--presets", "paper-dp,bogus"], "--presets"),
    ("fixed_cost", ["--quick", "--presets", "bogus"], "--presets"),
    # A map too small for HouseSpec.scaled: was a HouseSpecError traceback from the first child.
    ("stochastic_vi", ["--quick", "--side", "19"], "--side"),
]


@pytest.mark.parametrize(("name", "argv", "option"), BAD_VALUES)
def test_bad_values_are_usage_errors_naming_the_option(script, capsys, name, argv, option):
    """A count below 1 (or a share outside [0, 1], a negative time) is an argparse usage error
    naming the option (exit 2), also under --quick: no traceback, nothing run, no silent -1."""
    with pytest.raises(SystemExit) as stop:
        script(name).main(argv)
    assert stop.value.code == 2
    assert f"argument {option}" in capsys.readouterr().err


BAD_NAMES = [
    ("threads", ["--quick", "--backends", "torch,bogus"], "--backends"),
    ("features", ["--quick", "--no-dataset", "--devices", "bogus"], "--devices"),
    ("features", ["--quick", "--no-dataset", "--weights", "/nonexistent/alexnet.pt"], "--weights"),
    # No house at all: end_to_end.py fitted none and printed "... on every house: PASS".
    ("end_to_end", ["--houses", ",", "--no-startup"], "--houses"),
]


@pytest.mark.parametrize(("name", "argv", "option"), BAD_NAMES)
def test_bad_names_are_one_line_errors(script, capsys, name, argv, option):
    """A backend, device or weights file that is not there: a one-line error naming the option
    (exit 2) before anything is measured; threads.py measured the other backend with a note,
    features.py failed with torch's (or the loader's) traceback after loading the model."""
    with pytest.raises(SystemExit) as stop:
        script(name).main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert f"error: {option}" in err.splitlines()[-1], err
    assert "Traceback" not in err, err


def test_an_option_given_explicitly_wins_over_quick(script):
    """The rule of every script (benchmarks/README.md): --quick only changes the defaults."""
    fixed_cost, batched_gpu = script("fixed_cost"), script("batched_gpu")
    assert fixed_cost.parse_args(["--quick"]).repeats == 1
    assert fixed_cost.parse_args(["--quick", "--repeats", "2"]).repeats == 2
    assert fixed_cost.parse_args(["--quick", "--sweeps", "2", "5"]).sweeps == (2, 5)
    assert fixed_cost.parse_args([]).sweeps == fixed_cost.SWEEPS
    assert batched_gpu.parse_args(["--quick"]).seconds == 0.2
    assert batched_gpu.parse_args(["--quick", "--seconds", "1"]).seconds == 1.0
    assert script("bench_cli").quick_or(None, True, 1, 2) == 1


UNKNOWN_HOUSES = [
    ("end_to_end", ["--houses", "bogus", "--sweeps", "5", "--no-startup"]),
    ("merge_moves", ["--public", "bogus", "--sweeps", "4"]),
    ("navigation", ["--quick", "--houses", "bogus"]),
    ("footprint", ["--houses", "bogus", "--presets", "paper-dp", "--seeds", "0", "--sweeps", "5"]),
    ("fixed_cost", ["--quick", "--house", "bogus"]),
    ("online_update", ["--quick", "--houses", "bogus"]),
]


@pytest.mark.parametrize(("name", "argv"), UNKNOWN_HOUSES)
def test_an_unknown_house_is_a_one_line_error(script, capsys, keep_torch_threads, name, argv):
    """A house asked for by name that the dataset lacks: one line naming it and the houses
    there, exit 2 (fixed_cost fitted the synthetic house instead and exited 0)."""
    with pytest.raises(SystemExit) as stop:
        script(name).main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "error: --house" in err or "error: --public" in err, err
    assert "bogus" in err, err
    assert len(err.splitlines()) == 1, err


def test_quick_tables_say_what_min_rise_and_reached_measure(script):
    """stochastic_vi.py's 'min rise', footprint.py's 'reached' and online_update.py's
    'reached' rows did not say of what (the ELBO per pass at full gamma; the share of free
    cells the data reach; the first update length at the scratch fit's log joint)."""
    small = {"house": "h", "method": "m", "free_cells": 10, "passes": 3, "final_elbo": -1.0,
             "ari": 1.0, "concepts": 2, "seconds": 1.0, "seconds_per_pass": 0.3,
             "min_elbo_rise_at_full_gamma": -0.5}  # fmt: skip
    header = script("stochastic_vi").render({"small": [small]}).splitlines()[1]
    assert header.endswith("min ELBO rise per pass at full gamma"), header
    row = {"preset": "p", "house": "h", "fit": "f", "ari_truth": 1.0, "ari_between_seeds": None,
           "ari_vs_no_observations": 1.0, "concepts_1pct": 2, "cells_reached": 5,
           "free_cells": 10, "seconds": 1.0}  # fmt: skip
    header = script("footprint").summary_table({"rows": [row]}).splitlines()[0]
    assert "share of cells reached" in header, header
    point = {"sweeps": 0, "best_log_joint": 0.0, "typical_log_joint": 0.0, "seconds": 1.0,
             "ari_vs_scratch": 1.0, "concepts": 2}  # fmt: skip
    run = {"scratch": {"wall_seconds": 1.0, "best_log_joint": 0.0, "typical_log_joint": 0.0,
                       "concepts": 2}, "update": {"points": [point]},
           "reached": 0, "reached_typical": None}  # fmt: skip
    text = script("online_update").table([{"house": "h", "runs": [run],
                                           "scratch_vs_scratch_ari": []}], 10)  # fmt: skip
    assert "first sweeps: best LJ >= scratch" in text, text
    assert "first sweeps: typical LJ >= scratch" in text, text


def test_readme_names_the_json_each_quick_run_writes():
    """benchmarks/README.md said svi_vs_cavi.py, word_tables.py and hyperparameters.py write
    their NAME.json "also with --quick": they write NAME_quick.json (bench_cli.results_path),
    as their --help says. Every NAME_quick.json the README names is one a script writes."""
    readme = (BENCHMARKS / "README.md").read_text()
    assert "also with `--quick`" not in readme
    written = {"NAME_quick.json"}
    for path in BENCHMARKS.glob("*.py"):
        source = path.read_text()
        calls = [line for line in source.splitlines() if "results_path(" in line]
        written |= {f"{n}_quick.json" for line in calls for n in re.findall(r'"(\w+)"', line)}
        written |= set(re.findall(r'"(\w+_quick\.json)"', source))
    named = set(re.findall(r"(?<![/\w])(\w+_quick\.json)", readme))  # not an --out /tmp/... example
    assert named and named <= written, sorted(named - written)


@pytest.mark.parametrize(("name", "argv", "first_measure"), [
    ("end_to_end", ["--sweeps", "2", "--no-startup"], "fit_default"),
    ("hyperparameters", ["--sweeps", "2", "--public-sweeps", "2"], "run_variant"),
])  # fmt: skip
def test_no_dataset_is_one_note_line(script, monkeypatch, capsys, name, argv, first_measure):
    """Without the dataset (benchmarks/README.md: one `note: ...` line on stderr and the run
    goes on), end_to_end.py and hyperparameters.py printed a second note saying it again."""
    module = script(name)
    monkeypatch.setenv("SPCOPYRO_DATA", "/nonexistent")

    def measuring(*args, **kwargs):
        raise _Measuring

    monkeypatch.setattr(module, first_measure, measuring)
    with pytest.raises(_Measuring):
        module.main(argv)
    notes = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "/nonexistent" in notes[0], notes


QUICK_SIZES = {"threads.py": {"sweeps", "repeats", "sides"}}
"""Options whose default --quick changes through a sizes record, not bench_cli.quick_or."""


def _script_parsers(script, monkeypatch):
    """(path, source, argument parser) of every benchmark script that runs a main, its parser
    caught as main parses its arguments."""

    def capture(self, args=None, namespace=None):
        raise _Parsed(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    for path in sorted(BENCHMARKS.glob("*.py")):
        source = path.read_text()
        if "    run_main(main)\n" not in source or path.name == "bench_cli.py":
            continue
        with pytest.raises(_Parsed) as got:
            script(path.stem).main([])
        yield path, source, got.value.args[0]


def test_every_option_quick_changes_says_both_defaults_in_its_help(script, monkeypatch):
    """benchmarks/README.md: each option's --help gives both defaults. real_houses.py's
    --sweeps, --seeds, --open-plan-seeds, --method-iterations and --fit-seeds gave neither
    --quick's value (60, 1, 1, 5, 0) nor, for three of them, the full run's; threads.py's
    --sweeps, --repeats and --sides neither."""
    parsers = {}
    silent = []
    for path, source, parser in _script_parsers(script, monkeypatch):
        parsers[path.name] = parser
        quick = set(re.findall(r"quick_or\(\s*args\.(\w+)", source))
        quick |= QUICK_SIZES.get(path.name, set())
        for action in parser._actions:
            words = set(re.findall(r"\w+", action.help or ""))
            if action.dest in quick and not {"default", "quick"} <= words:
                silent.append(f"{path.name} {action.option_strings[0]}")
    assert len(parsers) >= 20 and silent == [], silent


def test_every_out_help_names_the_json_files_the_script_writes(script, monkeypatch):
    """The brief of benchmarks/README.md: a script writes its JSON where --help says. The --out
    of batched_gpu, features ('features_*.json'), footprint, merge_moves, prior_thread,
    stochastic_vi and variational named no default file."""
    wrong = []
    for path, source, parser in _script_parsers(script, monkeypatch):
        (out,) = [a for a in parser._actions if a.dest == "out"]
        named = set(re.findall(r"(?<![.\w])(\w+\.json)", out.help or ""))
        calls = [line for line in source.splitlines() if "results_path(" in line]
        written = set(re.findall(r'"(\w+\.json)"', source)) | {
            f"{n}{suffix}.json" for line in calls for n in re.findall(r'"(\w+)"', line)
            for suffix in ("", "_quick")
        }  # fmt: skip
        quick = {n for n in named if n.endswith("_quick.json")}
        if not quick or not named - quick or not named <= written:
            wrong.append(f"{path.name}: {out.help!r}")
    assert wrong == [], wrong


def test_readme_lists_every_script_with_command_lines_that_parse(script, monkeypatch):
    """Every runnable script has a `python benchmarks/NAME.py ...` line in benchmarks/README.md
    (rendered as docs/benchmarks.md), and each such line's options parse."""
    readme = (BENCHMARKS / "README.md").read_text()
    lines = re.findall(r"^python benchmarks/(\w+)\.py([^#\n]*)", readme, flags=re.M)
    runnable = {p.stem for p in BENCHMARKS.glob("*.py") if "    run_main(main)\n" in p.read_text()}
    assert runnable - {"bench_cli"} <= {name for name, _ in lines}

    def capture(self, args=None, namespace=None):
        raise _Parsed(self.parse_known_args(args, namespace))

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    for name, rest in lines:
        with pytest.raises(_Parsed) as got:
            script(name).main(rest.split())
        assert got.value.args[0][1] == [], (name, rest)
