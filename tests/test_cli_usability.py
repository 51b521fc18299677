"""Small things of the command line: every option's help shows its default, ``--version``, the
flag named where the library names its keyword, and ``--sweeps auto``'s one progress bar and
the wall time of the whole fit."""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys

import pytest
from gibbs_problems import config as small_config
from gibbs_problems import random_problem

import spcopyro.gibbs.convergence
from spcopyro import __version__
from spcopyro._util.arguments import figure_path
from spcopyro.cli.main import build_parser, main
from spcopyro.gibbs.convergence import run_until_converged
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.synthetic import HouseSpec, write_synthetic


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (sub,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_every_option_has_a_help_that_shows_its_default():
    parser = build_parser()
    commands = {"spcopyro": parser, **_subcommands(parser)}
    assert {"simulate", "show", "fit", "where", "experiment", "features"} <= set(commands)
    for name, command in commands.items():
        formatter = command._get_formatter()
        for action in command._actions:
            if isinstance(action, argparse._HelpAction | argparse._VersionAction):
                continue
            if isinstance(action, argparse._SubParsersAction):
                continue
            where = f"spcopyro {name} {'/'.join(action.option_strings) or action.dest}"
            assert action.help, f"{where} has no help"
            if action.option_strings and not action.required:
                shown = formatter._expand_help(action)
                assert "default" in shown.lower(), f"{where} does not show its default: {shown}"


def test_fit_help_shows_the_defaults_of_seed_and_backend(capsys):
    with pytest.raises(SystemExit) as done:
        main(["fit", "--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())  # lines joined
    assert re.search(r"--seed SEED seed of the sampler .*? \(default: 0\)", text)
    assert re.search(r"--backend \{auto,torch,numba\} Gibbs sweep .*? \(default: auto\)", text)
    assert "--sweeps SWEEPS Gibbs iterations" in text and "(default: 5000)" in text


def test_fit_help_names_the_default_presets_inference_and_footprint():
    """`--point-estimate` said 'vi with --preset auto, else map-visited' and `--footprint`
    'default 0' while the default preset coarse reports vi and spreads over 1 m (its footprint
    then, the default before 2026-12-06; 0.75 m since). The help says '--preset's value', so it
    names no radius to go stale. So do --footprint-reach-share and --footprint-reach-door-width,
    which said 'default 0: off' and 'default: no cut' once coarse took 0.2 and 1 m (2026-12-06)."""
    from spcopyro.config import DEFAULT_PRESET, PRESETS, preset_inference

    fit = _subcommands(build_parser())["fit"]
    helps = {a.dest: " ".join(a.help.split()) for a in fit._actions if a.help}
    if preset_inference(DEFAULT_PRESET).get("point_estimate") == "vi":
        assert f"vi with --preset {DEFAULT_PRESET}" in helps["point_estimate"]
    if PRESETS[DEFAULT_PRESET].get("footprint_radius"):
        assert "default 0" not in helps["footprint"]
        assert "--preset's value" in helps["footprint"]
    if PRESETS[DEFAULT_PRESET].get("footprint_reach_share"):  # coarse's 0.2 since 2026-12-06
        for option in ("footprint_reach_share", "footprint_reach_door_width"):
            assert "default 0" not in helps[option] and "default: no cut" not in helps[option]
            assert "--preset's value" in helps[option]


def test_fit_help_says_resume_writes_a_finished_fits_outputs():
    """`--resume` said only 'continue the interrupted fit', while for a finished fit of another
    method than Gibbs stopped while writing (spcopyro.cli.fit_finished) it fits nothing; then it
    said 'that Ctrl-C stopped', where an error keeps that fit too (3a0a64b); then it named no
    --chains or --update, whose finished fits are kept too (b2843ec)."""
    fit = _subcommands(build_parser())["fit"]
    helps = {a.dest: " ".join(a.help.split()) for a in fit._actions if a.help}
    said = "another method than Gibbs (its --chains too), or of --update, that Ctrl-C or an error"
    assert said in helps["resume"]
    assert "without fitting again" in helps["resume"]


def test_version(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out == f"spcopyro {__version__}\n"


def test_a_closed_output_pipe_ends_the_command_quietly(tmp_path):
    """`spcopyro show ... | head -1`: the reader leaves before the command prints; it exits with
    141 (128 + SIGPIPE, as a shell reports it) and says nothing (it printed 'error: [Errno 32]
    Broken pipe' and exited 2)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    path = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)
    process = subprocess.Popen(
        [sys.executable, "-m", "spcopyro", "show", "--out", str(tmp_path / "house.png")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, "PYTHONPATH": path},
    )  # fmt: skip
    process.stdout.close()  # before the command has written anything
    error = process.stderr.read()
    process.stderr.close()
    assert process.wait(timeout=120) == 141
    assert error == b""


def test_simulate_into_an_existing_folder_names_the_flag(tmp_path, capsys):
    argv = ["simulate", "--out", str(tmp_path), "--size", "40", "50"]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert "already exists; pass --overwrite to replace it" in error
    assert "overwrite=True" not in error
    assert main([*argv, "--overwrite"]) == 0


class _Bar:
    """Stands in for tqdm: records every bar made, its total, whether shown, and its count."""

    made: list[_Bar] = []

    def __init__(self, iterable=None, *, total=None, disable=False, unit="it", **_):
        self.iterable, self.total, self.disable, self.n = iterable, total, disable, 0
        self.unit = unit
        _Bar.made.append(self)

    def __iter__(self):
        for item in self.iterable:
            self.n += 1
            yield item

    def update(self, n=1):
        self.n += n

    def set_postfix(self, **_):
        pass

    def close(self):
        pass

    @classmethod
    def set_lock(cls, lock):  # a forked chain worker gives tqdm a fresh lock (fresh_tqdm_lock)
        pass

    def __enter__(self):
        return self

    def __exit__(self, *_):
        self.close()


@pytest.mark.parametrize("anneal", [0, 3])
def test_sweeps_auto_shows_one_bar_over_all_chains(monkeypatch, anneal):
    monkeypatch.setattr(_Bar, "made", [])
    monkeypatch.setattr(spcopyro.gibbs.convergence, "tqdm", _Bar)
    monkeypatch.setattr("tqdm.auto.tqdm", _Bar)  # the chains' sweeps
    _, data = random_problem(0)
    _, diagnostics = run_until_converged(
        data, small_config(), options=GibbsOptions(anneal_sweeps=anneal), chains=3, block=5,
        max_sweeps=15, threshold=1 + 1e-12, progress=True,
    )  # fmt: skip
    assert diagnostics.sweeps == 15 and len(diagnostics.checks) == 3
    shown = [bar for bar in _Bar.made if not bar.disable]
    assert len(shown) == 1, [(bar.total, bar.disable) for bar in _Bar.made]
    assert shown[0].total == 3 * (anneal + 15)  # the most that may run, all chains
    assert shown[0].n == 3 * (anneal + 15)  # every sweep of every chain counted once


def test_the_chains_bar_counts_sweeps(monkeypatch):
    """fit's bar said '1.39it/s' while every other sampler bar says sweep/s."""
    from spcopyro.gibbs.chains import advance_chains
    from spcopyro.gibbs.run import start_chain

    monkeypatch.setattr(_Bar, "made", [])
    monkeypatch.setattr("tqdm.auto.tqdm", _Bar)
    _, data = random_problem(0)
    chains = [start_chain(data, small_config(), seed=k) for k in range(2)]
    advance_chains([(chain, 3) for chain in chains], workers=1, progress=True, processes="off")
    [bar] = [bar for bar in _Bar.made if not bar.disable]
    assert bar.unit == "sweep" and bar.total == bar.n == 6


@pytest.fixture(scope="module")
def small_house(tmp_path_factory):
    root = tmp_path_factory.mktemp("data")
    return write_synthetic(root, seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3))


@pytest.mark.parametrize(
    ("options", "reported"),
    [
        (["--sweeps", "auto", "--chains", "2", "--max-sweeps", "20"], "2 chains x 20 sweeps"),
        (["--sweeps", "10", "--chains", "2"], "2 chains x 10 sweeps"),
        (["--sweeps", "10"], "10 sweeps"),
    ],
)
def test_fit_reports_the_wall_time_of_the_whole_fit(
    small_house, tmp_path, capsys, monkeypatch, options, reported
):
    clock = iter([100.0, 142.5])  # the fit starts at 100 s and ends at 142.5 s
    monkeypatch.setattr("spcopyro.cli.fit._clock", lambda: next(clock))
    argv = ["fit", str(small_house), "--out", str(tmp_path / "fit"), "--backend", "torch",
            "--preset", "original-code", "--gamma", "3", "--concepts", "10", *options]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert f"fitted {reported} in 42.5 s wall clock (" in printed
    # several chains: the pace is the kept chain's own clock (side by side, chains share the
    # CPUs, so it is slower than one chain alone while the wall clock is not): said as such
    own = "wall clock (the kept chain's own pace: "
    assert (own in printed) == ("--chains" in options), printed


def test_a_refined_fit_reports_each_stages_pace(small_house, tmp_path, capsys, monkeypatch):
    """A refined fit's line names both stages, their chains and each one's ms a sweep (it gave
    the refinement's pace as the whole fit's, and the refinement's chains not at all)."""
    clock = iter([100.0, 142.5])
    monkeypatch.setattr("spcopyro.cli.fit._clock", lambda: next(clock))
    argv = ["fit", str(small_house), "--out", str(tmp_path / "fit"), "--sweeps", "4",
            "--chains", "2", "--refine", "always"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out.splitlines()
    # the kept chain of the refinement, not of the coarse stage ('--sweeps auto' names that one)
    assert any(x.startswith("best of 2 refined chains: kept refined chain ") for x in printed)
    line = next(x for x in printed if x.startswith("fitted "))
    rate = r"the kept chain's own pace: \d+\.\d\d ms per sweep(?: after a first of \d+\.\d s)?"
    pattern = (rf"fitted 2 chains x 4 sweeps on 0\.\d+ m cells \({rate}\), then "
               rf"2 chains x 4 on the map's 0\.1 m cells \({rate}\) in 42\.5 s "
               r"wall clock; \d+ concepts in use"
               r"(?: \(\d+ of them (?:a speck|specks)\))?")  # fmt: skip
    assert re.fullmatch(pattern, line), line


def test_the_observed_cells_printed_are_those_concepts_json_counts(small_house, tmp_path, capsys):
    """With the default's footprint (1 m then, 0.75 m since 2026-12-06), fit printed the cells
    where observations were placed while concepts.json's observed_cells counted the cells the
    footprints reach (many more): both are printed now, and the second adds up to
    concepts.json's."""
    import json

    out = tmp_path / "fit"
    argv = ["fit", str(small_house), "--out", str(out), "--sweeps", "4", "--refine", "never",
            "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("observed cells"))
    match = re.fullmatch(
        r"observed cells +(\d+) \(where observations were placed\); (\d+) within their 0\.75 m "
        r"footprints and Voronoi cells within rooms at 1 m doors",  # coarse's since 2026-12-06
        line,
    )
    assert match, line
    placed, spread = map(int, match.groups())
    concepts = json.loads((out / "concepts.json").read_text())  # one entry a concept in use
    assert sum(c["observed_cells"] for c in concepts) == spread > placed
    # refined: concepts.json counts on the map's own cells, which the refining line gives
    argv = [*argv[:3], str(tmp_path / "refined"), "--sweeps", "4", "--refine", "always",
            "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("refining"))
    observed = int(re.search(r"m cells \((\d+) observed\)", line).group(1))
    concepts = json.loads((tmp_path / "refined" / "concepts.json").read_text())
    assert sum(c["observed_cells"] for c in concepts) == observed


def test_sweeps_auto_with_one_chain_names_chains(tmp_path, capsys):
    """It failed in the library with "chains must be >= 2 to compare chains, got 1"."""
    assert main(["fit", "--sweeps", "auto", "--chains", "1", "--out", str(tmp_path / "f")]) == 2
    assert "--sweeps auto compares chains (split R-hat): --chains 1 cannot" in (
        capsys.readouterr().err
    )
    assert not (tmp_path / "f").exists()


def test_one_sweep_is_singular(small_house, tmp_path, capsys):
    argv = ["fit", str(small_house), "--out", str(tmp_path / "fit"), "--sweeps", "1",
            "--refine", "never", "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("fitted "))
    assert line.startswith("fitted 1 sweep in "), line  # it read "fitted 1 sweeps"


def test_the_pace_leaves_out_a_first_sweep_that_compiled():
    """The first sweep of a first run compiles numba's code (seconds): the pace printed is the
    other sweeps', with the first apart (it made the embedded house's first stage look twice as
    slow as it ran); a first sweep near the pace is counted with the others."""
    from spcopyro.cli.common import pace

    assert pace(5.1, 5.1 + 4999 * 0.0016, 5000) == "1.60 ms per sweep after a first of 5.1 s"
    assert pace(0.002, 0.002 + 99 * 0.001, 100) == "1.01 ms per sweep"
    assert pace(0.3, 0.3 + 9 * 0.001, 10) == "30.90 ms per sweep"  # under half a second
    assert pace(2.0, 2.0, 1) == "2000.00 ms per sweep"
    assert pace(0.0, 0.5, 5, "iteration") == "100.00 ms per iteration"


def test_a_seed_beyond_64_bits_names_the_option(capsys):
    """Issue 22 item 10: --seed 99999999999999999999 used to fail inside torch with "Overflow
    when unpacking long long", without naming --seed."""
    with pytest.raises(SystemExit) as stop:
        main(["fit", "--seed", "99999999999999999999", "--out", "unused"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "argument --seed: must be at most 2**63 - 1" in err


def test_an_off_map_utterance_is_warned_about_once(tmp_path, capsys, monkeypatch):
    """Issue 22 item 10: every off-map warning of spcopyro fit was printed twice (once by the
    house summary, once by the fit's own counts)."""
    from spcopyro.synthetic import HouseSpec, write_synthetic

    monkeypatch.setenv("CI", "1")
    room = write_synthetic(tmp_path, seed=1, spec=HouseSpec(height=30, width=36, num_rooms=2))
    lines = (room / "StXtx.csv").read_text().splitlines()
    (room / "StXtx.csv").write_text("\n".join(["55.0", *lines[1:]]) + "\n")
    argv = ["fit", str(room), "--out", str(tmp_path / "out"), "--sweeps", "2", "--no-figures"]
    assert main(argv) == 0
    assert capsys.readouterr().err.count("farther than 0.25 m from free space") == 1
    assert main(["show", str(room), "--out", str(tmp_path / "house.png")]) == 0
    assert capsys.readouterr().err.count("farther than 0.25 m from free space") == 1


def test_a_full_disk_is_said_in_words():
    """Issue 22 item 10: a full disk gave a bare "[Errno 28] No space left on device"."""
    import errno

    from spcopyro.cli.main import _error_line

    full = OSError(errno.ENOSPC, "No space left on device", "/data/out/labels.npy")
    line = _error_line(full)
    assert line.startswith("the disk is full while writing /data/out/labels.npy")
    assert _error_line(ValueError("bad value")) == "bad value"


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("--cell-size", "-0.25", "--cell-size '-0.25': give a positive number of metres or 'map'"),
        ("--cell-size", "big", "--cell-size 'big': give a positive number of metres or 'map'"),
        ("--word-scaling", "0", "DataPreparation.word_scaling=0.0: must be a positive finite"),
        ("--region-moves", "1.5", "GibbsOptions.region_moves=1.5: must be a probability in [0, 1]"),
    ],
)
def test_bad_model_grid_options_name_themselves(tmp_path, capsys, option, value, message):
    """Issue 21's new options: a bad --cell-size, --word-scaling or --region-moves is one clear
    error (exit 2), nothing written."""
    out = tmp_path / "out"
    assert main(["fit", "--out", str(out), "--sweeps", "2", option, value]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["experiment", "--quick", "--sweeps", "0"],
        ["compare-inference", "--quick", "--workers", "0"],
    ],
)
def test_a_study_command_refuses_zero_counts_before_running(argv, tmp_path, capsys):
    """`experiment --sweeps 0` ran every cell into a failure, `ablation --seeds 0` an empty
    study that exited 0: both are usage errors naming the option now."""
    with pytest.raises(SystemExit) as stop:
        main([*argv, "--out", str(tmp_path / "out")])
    assert stop.value.code == 2
    assert f"argument {argv[-2]}: must be an integer >= 1, got '0'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_an_ablation_with_no_cell_is_refused_and_seeds_0_keeps_the_public_houses(
    tmp_path, capsys, monkeypatch
):
    """`ablation --seeds 0` ran an empty study and exited 0 when no public house was left; with
    public houses it is the public-houses-only ablation (docs/ablation/ablation_c.md)."""
    out = tmp_path / "out"
    assert main(["ablation", "--quick", "--seeds", "0", "--no-public", "--out", str(out)]) == 2
    assert "the ablation would run no cell" in capsys.readouterr().err
    assert not out.exists()
    import spcopyro.study.ablation as ablation

    ran = []
    monkeypatch.setattr(ablation, "run_ablation", lambda out, settings, **_: ran.append(settings))
    monkeypatch.setattr("spcopyro.data.find_dataset_root", lambda data=None: tmp_path)
    main(["ablation", "--quick", "--seeds", "0", "--out", str(out)])  # the stub writes nothing
    assert ran and ran[0].seeds == 0 and ran[0].public_seeds == 1
    assert ran[0].dataset_root == tmp_path


def test_several_variational_fits_report_their_objective(small_house, tmp_path, capsys):
    """`--chains 2` of a variational method compares ELBOs, and says so (it called them log
    joints); their final ones, the reported q's (it said best), and the fits are not chains of
    one length ('fitted 2 chains x 3 iterations')."""
    argv = ["fit", str(small_house), "--out", str(tmp_path / "fit"), "--method", "cavi",
            "--chains", "2", "--sweeps", "3", "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "best of 2 fits: kept fit " in printed and " final ELBOs " in printed
    assert "log joint" not in printed.split("best of 2 fits")[1].splitlines()[0]
    assert "fitted 2 fits, the kept one 3 iterations, in " in printed and "chains" not in printed
    report = json.loads((tmp_path / "fit" / "chains.json").read_text())  # ELBOs not log joints
    assert report["objective"] == "ELBO" and "best_log_joint" not in report
    assert len(report["final_elbo"]) == 2
    argv[argv.index("cavi")] = "vi-gibbs"  # CAVI starts, then Gibbs chains: chains
    argv[argv.index(str(tmp_path / "fit"))] = str(tmp_path / "vi-gibbs")
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "best of 2 chains: kept chain " in printed and " best log joints " in printed
    assert "fitted 2 chains x 3 sweeps in " in printed and "2 fits" not in printed
    sampled = json.loads((tmp_path / "vi-gibbs" / "chains.json").read_text())
    assert len(sampled["best_log_joint"]) == 2


def test_a_dataset_root_given_as_the_house_names_its_houses(small_house, tmp_path, capsys):
    """``fit DATASET`` for ``fit DATASET/HOUSE`` said only that map/DATASET.yaml was missing."""
    root = small_house.parent
    assert main(["fit", str(root), "--out", str(tmp_path / "out"), "--sweeps", "2"]) == 2
    err = capsys.readouterr().err
    assert "map of house" not in err  # a path the user never gave, read first (QA)
    assert f"{root} is not a house folder but holds house folders ({small_house.name}): " in err
    assert not (tmp_path / "out").exists()
    # a folder with neither houses nor observations (the dataset's map/, say) is named as such
    maps = tmp_path / "map"
    maps.mkdir()
    assert main(["fit", str(maps), "--out", str(tmp_path / "out"), "--sweeps", "2"]) == 2
    assert f"{maps} is not a house folder: it holds no Ft.csv or St.csv" in capsys.readouterr().err


def test_simulate_names_its_flags_when_the_rooms_do_not_fit(tmp_path, capsys):
    """--density sparse keeps its 6 rooms at any --size; the error named HouseSpec's fields."""
    assert main(["simulate", "--out", str(tmp_path), "--size", "60", "80", "--density",
                 "sparse"]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "--density sparse draws 6 rooms:" in err and err.rstrip().endswith(
        "lower --rooms or enlarge --size"
    )
    assert "min_room_size" not in err.split("fit at most")[1]
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize(
    "argv",
    [
        ["where", "FIT", "kitchen", "--out", "k.txt"],
        ["show", "--out", "h.TXT"],
        ["show", "FIT", "--graph", "--out", "g.docx"],
    ],  # fmt: skip
)
def test_a_figure_format_matplotlib_cannot_write_is_refused_first(argv, capsys):
    """The answer was printed, then matplotlib's "Format 'txt' is not supported" (no --out)."""
    with pytest.raises(SystemExit) as error:
        main(argv)  # FIT does not exist: the option is refused before anything is read
    assert error.value.code == 2
    err = capsys.readouterr().err
    assert "argument --out" in err and "matplotlib cannot write" in err and "png" in err
    assert figure_path("map") == "map" and figure_path("dir.v2/k.JPG") == "dir.v2/k.JPG"


def test_a_warning_during_a_progress_bar_gets_its_own_line(capsys):
    """A library warning logged while a tqdm bar was shown was written after the bar on its line
    ("cells 0/1: 0%|...]warning: gamma is annealed ..."): the handler writes through tqdm."""
    import logging

    from tqdm import tqdm

    from spcopyro.cli.main import _configure_logging

    _configure_logging(logging.WARNING)
    bar = tqdm(total=10, desc="cells 0/1")
    bar.update(1)
    logging.getLogger("spcopyro").warning("gamma is annealed over 20 iterations")
    bar.close()
    err = capsys.readouterr().err
    (line,) = [p for p in re.split(r"[\r\n]", err) if "warning:" in p]
    assert line.startswith("warning: gamma is annealed"), repr(line)
    logging.getLogger("spcopyro").warning("no bar now")  # the plain handler again
    assert capsys.readouterr().err == "warning: no bar now\n"


def test_method_option_help_says_what_the_fit_prints(capsys):
    """--method-option's help said the method's defaults are "printed by the fit": its
    inference line names only the options set away from them (room1ldk5's default cavi fit:
    "cavi: 200 iterations (every setting: OUT/config.json)") and points to config.json."""
    from spcopyro.cli.fit_summary import inference_line
    from spcopyro.guides.options import VariationalOptions

    with pytest.raises(SystemExit):
        main(["fit", "--help"])
    text = " ".join(capsys.readouterr().out.split())  # lines joined
    assert "printed by the fit" not in text
    assert ("(default: the method's defaults; the fit's inference line names the options set "
            "away from them, OUT/config.json records every one)") in text  # fmt: skip
    default = inference_line("cavi", VariationalOptions(), False, "200 iterations", "OUT")
    assert default.split(None, 1)[1] == "cavi: 200 iterations (every setting: OUT/config.json)"
    changed = VariationalOptions(anneal_iterations=5)
    assert "anneal iterations 5 (" in inference_line("cavi", changed, False, "5 iterations", "O")
