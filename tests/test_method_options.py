"""``spcopyro fit --method-option NAME=VALUE``: any method's options set from the command line."""

from __future__ import annotations

import json

import pytest

from spcopyro.cli.main import main
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.guides.lbp_method import LBPOptions
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.svi_method import SVIOptions
from spcopyro.guides.vi_gibbs import VIGibbsOptions
from spcopyro.inference.protocol import with_options


def test_values_are_parsed_as_their_fields_types_nested_included():
    options = with_options(VariationalOptions(), ["anneal_iterations=7", "damping=0.25"])
    assert options.anneal_iterations == 7 and options.damping == 0.25
    nested = with_options(VIGibbsOptions(), ["variational.anneal_iterations=3", "vi_iterations=9"])
    assert nested.variational.anneal_iterations == 3 and nested.vi_iterations == 9
    gibbs = with_options(GibbsOptions(), ["cluster_moves=0.1", "backend=torch"])
    assert gibbs.cluster_moves == 0.1 and gibbs.backend == "torch"


@pytest.mark.parametrize(
    "assignment, message",
    [
        ("anneal_iterations", "expected NAME=VALUE"),
        ("anneal=3", "has no field 'anneal'; it has .*anneal_iterations"),
        ("anneal_iterations=x", "expected an integer, got 'x'"),
        ("damping=much", "expected a number"),
        ("damping=2", "damping"),  # the dataclass's own validation
        ("damping.x=1", "has no fields"),
    ],
)
def test_bad_assignments_are_clear_errors(assignment, message):
    with pytest.raises(ValueError, match=message):
        with_options(VariationalOptions(), [assignment])


def test_fit_runs_a_method_with_the_options_given(tmp_path, capsys):
    out = tmp_path / "lbp"
    args = ["fit", "--out", str(out), "--method", "lbp", "--sweeps", "2", "--preset",
            "original-code", "--concepts", "6", "--method-option", "damping=0.3"]  # fmt: skip
    assert main(args) == 0
    assert "lbp: 2 iterations, damping 0.3 (every setting:" in capsys.readouterr().out
    assert json.loads((out / "config.json").read_text())["inference"]["damping"] == 0.3
    assert main([*args[:-1], "dampin=0.3", "--overwrite"]) == 2
    assert "has no field 'dampin'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("options", "field", "why"),
    [
        (VariationalOptions, "anneal_iterations", "must be an integer >= 0"),
        (VariationalOptions, "damping", r"must lie in \[0, 1\)"),
        (VariationalOptions, "tolerance", "must be a finite number >= 0"),
        (VariationalOptions, "support", "must be an integer >= 0"),
        (VariationalOptions, "threshold", r"must lie in \[0, 1\)"),
        (VariationalOptions, "active_tolerance", "must be a finite number >= 0"),
        (LBPOptions, "damping", r"must lie in \[0, 1\)"),
        (LBPOptions, "anneal_iterations", "must be an integer >= 0"),
        (LBPOptions, "support", "must be an integer >= 0"),
        (SVIOptions, "num_particles", "must be an integer >= 1"),
        (VIGibbsOptions, "vi_iterations", "must be an integer >= 1"),
    ],
)
@pytest.mark.parametrize("flag", [True, False])
def test_a_bool_is_no_count_or_number_of_the_variational_options(options, field, why, flag):
    """True is an int: ``SVIOptions(num_particles=True)`` ran one particle, ``support=True`` kept
    one concept per cell, ``damping=False`` ran undamped (a library caller's or a study file's
    ``options.num_particles = true``; the command line parses a field as its type). Refused now
    with the message a bad value gets, as the fields beside them (``passes``, ``window``) did."""
    with pytest.raises(ValueError, match=rf"{options.__name__}\.{field}={flag}: {why}"):
        options(**{field: flag})


@pytest.mark.parametrize("field", ["variational", "gibbs"])
def test_vi_gibbs_refuses_a_wrong_options_object_by_name(field):
    """Each part's options are checked: a wrong one failed inside the fit as an AttributeError
    (``'GibbsOptions' object has no attribute 'init'``) naming neither field."""
    wrong = GibbsOptions() if field == "variational" else VariationalOptions()
    with pytest.raises(ValueError, match=f"VIGibbsOptions.{field} must be a"):
        VIGibbsOptions(**{field: wrong})
    with pytest.raises(ValueError, match=f"VIGibbsOptions.{field} must be a"):
        with_options(VIGibbsOptions(), [f"{field}=3"])


def test_every_example_in_the_help_is_an_option_of_its_method():
    """The help's examples are set on their methods' options as a user would copy them (it gave
    lr=0.05 for svi, whose field is learning_rate)."""
    import re

    from spcopyro.cli.main import build_parser
    from spcopyro.fit.registry import INFERENCE_METHODS

    fit = build_parser()._subparsers._group_actions[0].choices["fit"]
    [action] = [a for a in fit._actions if "--method-option" in a.option_strings]
    examples = re.findall(r"([\w.]+=[\w.]+) \(([\w-]+)\)", " ".join(action.help.split()))
    assert {method for _, method in examples} == {"cavi", "lbp", "svi", "stochastic-vi", "vi-gibbs"}
    for assignment, method in examples:
        with_options(INFERENCE_METHODS[method].default_options(), [assignment])


def test_gibbs_flags_reach_vi_gibbs_and_are_refused_by_methods_without_a_sampler(tmp_path, capsys):
    """--backend, --anneal-sweeps and the move rates were ignored silently under --method
    cavi (and under vi-gibbs, whose second stage is the sampler they set)."""
    base = ["fit", "--sweeps", "4", "--no-figures", "--concepts", "6"]
    out = tmp_path / "vg"
    argv = [*base, "--out", str(out), "--method", "vi-gibbs", "--backend", "torch",
            "--cluster-moves", "0.5", "--anneal-sweeps", "2",
            "--method-option", "vi_iterations=3"]  # fmt: skip
    assert main(argv) == 0
    inference = json.loads((out / "config.json").read_text())["inference"]  # the Gibbs stage's
    assert inference["vi_iterations"] == 3 and inference["backend_used"] == "torch"
    assert inference["cluster_moves"] == 0.5 and inference["anneal_sweeps"] == 2
    capsys.readouterr()
    for flags in (["--backend", "torch"], ["--merge-moves", "0.2", "--anneal-sweeps", "10"]):
        argv = [*base, "--out", str(tmp_path / "cavi"), "--method", "cavi", *flags]
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"{flags[0]} {flags[1]}" in err and "--method cavi does not run" in err
    assert not (tmp_path / "cavi").exists()


def test_cavi_records_its_q_start_beside_the_start_labels(tmp_path, capsys):
    """config.json's inference.init is the labels' start of every method; CAVI's own ``init``
    (q's random start) was overwritten by it: a soft start read 'random'. And soft with start
    labels, which replace it, was ignored silently."""
    out = tmp_path / "soft"
    args = ["fit", "--out", str(out), "--method", "cavi", "--sweeps", "2", "--preset",
            "original-code", "--concepts", "6", "--no-figures"]  # fmt: skip
    assert main([*args, "--method-option", "init=soft"]) == 0
    inference = json.loads((out / "config.json").read_text())["inference"]
    assert inference["init"] == "random" and inference["q_init"] == "soft"
    assert main([*args, "--overwrite", "--init", "gaussian"]) == 0
    inference = json.loads((out / "config.json").read_text())["inference"]
    assert inference["init"] == "gaussian" and inference["q_init"] == "one-hot start labels"
    capsys.readouterr()
    soft = ["--method-option", "init=soft", "--overwrite"]
    assert main([*args, *soft, "--init", "gaussian"]) == 2
    assert "init=soft draws q(C) at random, but --init gaussian" in capsys.readouterr().err
    vi_gibbs = [*args[:4], "vi-gibbs", *args[5:], "--init", "rooms", "--overwrite"]
    assert main([*vi_gibbs, "--method-option", "variational.init=soft"]) == 2
    assert "variational.init=soft draws q(C) at random" in capsys.readouterr().err


@pytest.mark.parametrize("method, name", [("cavi", "init"), ("vi-gibbs", "variational.init")])
def test_a_soft_q_start_is_refused_by_an_update(tmp_path, capsys, method, name):
    """An update starts from the saved fit's labels, which replace q's soft start: ``--update
    OUT --method-option init=soft`` fitted from the saved labels and said nothing."""
    saved = tmp_path / "saved"
    args = ["fit", "--sweeps", "2", "--preset", "original-code", "--concepts", "6",
            "--no-figures"]  # fmt: skip
    assert main([*args, "--out", str(saved), "--method", "cavi"]) == 0
    capsys.readouterr()
    update = [*args, "--out", str(tmp_path / "updated"), "--method", method, "--update",
              str(saved), "--method-option", f"{name}=soft"]  # fmt: skip
    assert main(update) == 2
    assert f"{name}=soft draws q(C) at random, but --update {saved}" in capsys.readouterr().err
    assert not (tmp_path / "updated").exists()


@pytest.mark.parametrize("method", ["cavi", "lbp", "svi", "stochastic-vi"])
def test_marginal_samples_is_refused_by_methods_that_do_not_sample(tmp_path, capsys, method):
    """--marginal-samples counts a sampler's kept label maps; a variational fit ignored it
    silently (its uncertainty map is q(C_i)). Its default is still 50 for the samplers."""
    from spcopyro.cli.common import MARGINAL_SAMPLES, given

    args = ["fit", "--out", str(tmp_path / "x"), "--method", method, "--sweeps", "2"]
    assert main([*args, "--marginal-samples", "10"]) == 2
    assert "--marginal-samples 10: label maps of a sampler's sweeps" in capsys.readouterr().err
    assert MARGINAL_SAMPLES == 50 and not given(MARGINAL_SAMPLES) and given(50)


def test_a_field_that_may_be_none_takes_its_declared_type_and_none():
    """svi's global_learning_rate (default None) took the text as it was: '0.01' was refused as
    'must be None or a finite number > 0'."""
    from spcopyro.guides.svi_method import SVIOptions

    options = with_options(SVIOptions(), ["global_learning_rate=0.01"])
    assert options.global_learning_rate == 0.01
    assert with_options(options, ["global_learning_rate=none"]).global_learning_rate is None
    with pytest.raises(ValueError, match="expected a number, got 'fast'"):
        with_options(SVIOptions(), ["global_learning_rate=fast"])


def test_the_help_names_the_hyperparameter_options_of_gibbs():
    """Sampling alpha, the concentrations or gamma is only a --method-option; fit --help did
    not say so anywhere (nor that --merge-moves' and --region-moves' preset defaults are
    gibbs's alone: vi-gibbs runs with 0)."""
    import re

    from spcopyro.cli.main import build_parser

    fit = build_parser()._subparsers._group_actions[0].choices["fit"]
    helps = {a.dest: " ".join(a.help.split()) for a in fit._actions if a.help}
    found = re.findall(r"(?<![\w.])(hyper\.\w+=\w+)", helps["method_option"])
    assert {a.split("=")[0] for a in found} == {"hyper.alpha", "hyper.concentrations",
                                               "hyper.gamma"}  # fmt: skip
    for assignment in found:
        assert with_options(GibbsOptions(), [assignment]).hyper.active
    assert with_options(VIGibbsOptions(), ["gibbs.hyper.alpha=true"]).gibbs.hyper.alpha
    assert "for gibbs" in helps["merge_moves"] and "for gibbs" in helps["region_moves"]


def test_a_gibbs_flag_and_a_method_option_on_the_same_field_are_refused(tmp_path, capsys):
    """gibbs took --method-option's value and vi-gibbs the flag's, silently; a move rate the
    preset filled in (coarse: merge_moves 0.2) is still overridden by the option."""
    base = ["fit", "--sweeps", "2", "--no-figures", "--refine", "never"]
    for method, name in (("gibbs", "cluster_moves"), ("vi-gibbs", "gibbs.cluster_moves")):
        argv = [*base, "--out", str(tmp_path / method), "--method", method,
                "--cluster-moves", "0.1", "--method-option", f"{name}=0.3"]  # fmt: skip
        assert main(argv) == 2
        assert f"--cluster-moves 0.1 and --method-option {name}=0.3" in capsys.readouterr().err
        # argparse takes a flag's prefix: the command line was scanned for the whole flag
        argv[argv.index("--cluster-moves")] = "--cluster-mov"
        assert main(argv) == 2
        assert f"--cluster-moves 0.1 and --method-option {name}=0.3" in capsys.readouterr().err
    out = tmp_path / "preset"
    assert main([*base, "--out", str(out), "--method-option", "merge_moves=0"]) == 0
    assert json.loads((out / "config.json").read_text())["inference"]["merge_moves"] == 0.0


@pytest.mark.parametrize("method, noted", [("svi", False), ("cavi", False), ("vi-gibbs", True)])
def test_the_gibbs_random_streams_note_is_written_for_the_samplers_only(tmp_path, method, noted):
    """config.json of an svi or stochastic-vi fit said the torch and numba Gibbs backends draw
    different streams and pointed at an inference.backend_used it does not have."""
    out = tmp_path / method
    argv = ["fit", "--out", str(out), "--method", method, "--sweeps", "2", "--preset",
            "original-code", "--concepts", "6", "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    assert ("reproducibility" in json.loads((out / "config.json").read_text())) == noted


def test_vi_gibbs_sweeps_are_its_gibbs_sweeps_as_the_help_says(tmp_path, capsys):
    """The help put vi-gibbs's CAVI among the methods --sweeps caps; --sweeps counts its Gibbs
    sweeps, run in full, and vi_iterations caps the CAVI start."""
    from spcopyro.cli.main import build_parser

    fit = build_parser()._subparsers._group_actions[0].choices["fit"]
    [action] = [a for a in fit._actions if "--sweeps" in a.option_strings]
    assert "for vi-gibbs its Gibbs sweeps, run in full" in " ".join(action.help.split())
    assert "vi-gibbs's CAVI" not in action.help
    out = tmp_path / "vg"
    argv = ["fit", "--out", str(out), "--method", "vi-gibbs", "--sweeps", "3", "--concepts", "6",
            "--method-option", "vi_iterations=4", "--no-figures"]  # fmt: skip
    capsys.readouterr()
    assert main(argv) == 0
    inference = json.loads((out / "config.json").read_text())["inference"]
    assert inference["sweeps"] == 3 and inference["vi_iterations_run"] <= 4
    # how the CAVI stage ended is printed, as a cavi fit's "stopped" line is
    printed = capsys.readouterr().out
    assert f"CAVI start       {inference['vi_stopped']} (" in printed
    assert "s, not in the sweeps' pace above); the sweeps began at its labels" in printed
    assert len((out / "trace.csv").read_text().splitlines()) == 1 + 3


@pytest.mark.parametrize("method", ["cavi", "vi-gibbs"])
def test_chain_workers_is_refused_by_methods_whose_fits_run_one_after_another(
    tmp_path, capsys, method
):
    """fit_house_chains runs only Gibbs chains side by side; --chain-workers 2 was ignored
    silently under the other methods."""
    args = ["fit", "--out", str(tmp_path / "x"), "--method", method, "--chains", "2"]
    assert main([*args, "--chain-workers", "2"]) == 2
    assert "--chain-workers 2: Gibbs chains advancing at once" in capsys.readouterr().err


def test_svi_clip_norm_without_the_clipping_optimiser_is_refused(tmp_path, capsys):
    """clip_norm is ClippedAdam's; with the default adam it changed nothing, silently."""
    out = tmp_path / "svi"
    args = ["fit", "--out", str(out), "--method", "svi", "--sweeps", "2", "--concepts", "6",
            "--no-figures", "--method-option", "clip_norm=1"]  # fmt: skip
    assert main(args) == 2
    assert "clip_norm clips the gradients of optimiser=clipped-adam" in capsys.readouterr().err
    assert main([*args, "--method-option", "optimiser=clipped-adam"]) == 0
    inference = json.loads((out / "config.json").read_text())["inference"]
    assert inference["clip_norm"] == 1 and inference["optimiser"] == "clipped-adam"


def test_a_hyper_tuning_option_of_an_unsampled_hyperparameter_is_refused(tmp_path, capsys):
    """hyper.log_gamma_sd=2 alone sampled nothing and said nothing (a prior's width of a gamma
    the chain keeps fixed); with hyper.gamma set it runs."""
    from spcopyro.gibbs.hyper_options import HyperparameterOptions

    assert "log_gamma_sd" in HyperparameterOptions().unused()
    assert "log_gamma_sd" not in HyperparameterOptions(gamma="pseudolikelihood").unused()
    assert "aux_sweeps" in HyperparameterOptions(gamma="pseudolikelihood").unused()
    assert "aux_sweeps" not in HyperparameterOptions(alpha=True).unused()
    base = ["fit", "--out", str(tmp_path / "g"), "--sweeps", "2", "--no-figures", "--refine",
            "never", "--method-option", "hyper.log_gamma_sd=2"]  # fmt: skip
    assert main(base) == 2
    assert "hyper.log_gamma_sd=2: no hyperparameter the chain samples" in capsys.readouterr().err
    assert main([*base, "--method-option", "hyper.gamma=pseudolikelihood"]) == 0


@pytest.mark.parametrize(
    "method, extra",
    [("cavi", []), ("lbp", []), ("lbp", ["--gamma", "80"]), ("stochastic-vi", [])],
)
def test_a_variational_fit_prints_the_backend_it_ran(tmp_path, capsys, method, extra):
    """`fit` printed "backend used" for Gibbs fits only, though config.json's
    inference.backend_used is said to be printed too; it is the same name (lbp's auto: torch
    where gamma D > 300)."""
    out = tmp_path / "fit"
    args = ["fit", "--out", str(out), "--method", method, "--sweeps", "2", "--no-figures",
            "--preset", "original-code", "--concepts", "6", *extra]  # fmt: skip
    assert main(args) == 0
    used = json.loads((out / "config.json").read_text())["inference"]["backend_used"]
    assert f"backend used     {used}\n" in capsys.readouterr().out


def test_options_that_depend_on_the_start_are_asked_through_the_protocol():
    """SVI's start-dependent defaults (``for_start``) were looked up by name in each place that
    needed them (``hasattr(defaults, "for_start")`` in the comparison report, ``getattr`` in
    VariationalSaving and fit's lines); the options protocol owns it now
    (:func:`~spcopyro.inference.protocol.options_for_start`), and every place asks it."""
    from dataclasses import dataclass

    from spcopyro.guides.svi_method import SVIOptions
    from spcopyro.inference.protocol import StartDependentOptions, options_for_start

    assert options_for_start(SVIOptions(), given_start=False) == SVIOptions(
        anneal_iterations=100, label_smoothing=0.9
    )
    assert options_for_start(SVIOptions(), given_start=True) == SVIOptions(
        anneal_iterations=0, label_smoothing=0.05
    )
    assert options_for_start(SVIOptions(anneal_iterations=7), True).anneal_iterations == 7
    for options in (GibbsOptions(), VariationalOptions(), VIGibbsOptions()):
        assert not isinstance(options, StartDependentOptions)
        assert options_for_start(options, given_start=True) is options

    @dataclass(frozen=True)
    class Other:  # another method's start-dependent options: read the same way
        window: int | None = None

        def for_start(self, given_start: bool) -> Other:
            return Other(5 if given_start else 50)

    assert options_for_start(Other(), given_start=True) == Other(5)
    assert _read_by_name("for_start") == []


def test_fields_a_resumed_run_ignores_are_asked_through_the_protocol():
    """SVIOptions.RESUME_IGNORES was read by name (``getattr(type(options), "RESUME_IGNORES",
    ())`` in guides/checkpoint.py); the options protocol owns it now, as it owns
    ``for_start``: :func:`~spcopyro.inference.protocol.resume_ignores`, the same fields."""

    from spcopyro.guides.svi_method import SVIOptions
    from spcopyro.inference.protocol import ResumeIgnoringOptions, resume_ignores

    assert isinstance(SVIOptions(), ResumeIgnoringOptions)
    assert resume_ignores(SVIOptions()) == ("label_smoothing",)
    for options in (GibbsOptions(), VariationalOptions(), VIGibbsOptions(), None):
        assert not isinstance(options, ResumeIgnoringOptions)
        assert resume_ignores(options) == ()

    class Other:  # another method's options with a field its resumed runs ignore
        RESUME_IGNORES = ("window",)

    assert resume_ignores(Other()) == ("window",)
    assert _read_by_name("RESUME_IGNORES") == []


def _read_by_name(attribute: str) -> list[str]:
    """The package's modules that look ``attribute`` up by name (``getattr``/``hasattr`` with it
    as a constant): what the options protocol should be asked instead."""
    import ast
    from pathlib import Path

    package = Path(__file__).resolve().parents[1] / "spcopyro"
    return [
        str(path.relative_to(package))
        for path in sorted(package.rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
        and node.func.id in ("getattr", "hasattr")
        and any(isinstance(a, ast.Constant) and a.value == attribute for a in node.args)
    ]  # fmt: skip
