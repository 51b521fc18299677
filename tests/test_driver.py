"""The shared driver of the variational methods and the one annealing schedule (issue 23 item 1):
every method is an init / step pair run by spcopyro.inference.driver.drive, which anneals on
Gibbs' schedule, stops at convergence by default (the iterations a ceiling), thins, and hands
back what it completed on Ctrl-C."""

from __future__ import annotations

import dataclasses
import re
from typing import NamedTuple

import numpy as np
import pytest
import torch
from gibbs_problems import config, random_problem

from spcopyro._util.progress import COMPILE_ITERATIONS
from spcopyro.cli.main import main
from spcopyro.fit.registry import get_method
from spcopyro.gibbs.anneal import annealed_config
from spcopyro.gibbs.options import GibbsOptions
from spcopyro.guides import cavi
from spcopyro.guides.lbp_method import LBPOptions
from spcopyro.guides.memoized import StochasticOptions
from spcopyro.guides.options import VariationalOptions
from spcopyro.guides.run import initial_q, resolve_backend, run_variational
from spcopyro.guides.svi_method import SVIOptions
from spcopyro.guides.vi_gibbs import VIGibbsOptions
from spcopyro.inference.driver import DriveInterrupted, drive
from spcopyro.inference.schedule import annealed_gamma, converged, short_runs_meant

VARIATIONAL = ("cavi", "lbp", "stochastic-vi", "svi")


@pytest.fixture(scope="module")
def problem():
    _, data = random_problem(seed=4, copies=2)
    return data, config(num_concepts=4, gamma=1.2)


class _Info(NamedTuple):
    objective: float
    num_concepts: int
    gamma: float


def _counting_step(values):
    """A step whose objective is ``values[state]`` and whose state counts the steps."""

    def step(state, gamma):
        return state + 1, _Info(values[state], 1, gamma)

    return step


def test_one_schedule_for_gibbs_and_every_variational_method(problem):
    """The ramp is gamma min(1, (s + 1) / A) everywhere: Gibbs' sweeps and a CAVI run with the
    same A see the same couplings (CAVI's was (s + 1) / (A + 1) before issue 23)."""
    data, cfg = problem
    A = 4
    expected = [annealed_gamma(cfg.gamma, s, A) for s in range(7)]
    assert expected[:4] == pytest.approx([cfg.gamma * k / 4 for k in (1, 2, 3, 4)])
    assert [annealed_config(cfg, s, A).gamma for s in range(7)] == expected
    options = VariationalOptions(anneal_iterations=A, tolerance=0.0, backend="torch")
    q = initial_q(data, cfg, torch.Generator().manual_seed(0))
    run = run_variational(data, cfg, 7, options=options, q=q, progress=False)
    assert run.gammas.tolist() == expected


def test_converged_compares_single_iterations_or_window_means():
    gammas = [1.0] * 6
    assert converged([-10.0, -10.0 + 1e-9], gammas[:2], 1.0, 1e-7)
    assert not converged([-10.0, -9.0], gammas[:2], 1.0, 1e-7)
    assert not converged([-10.0, -10.0], [0.5, 1.0], 1.0, 1e-7)  # the step before annealed
    assert not converged([-10.0, -10.0], gammas[:2], 1.0, 0.0)  # tolerance 0: never
    noisy = [-10.0, -12.0, -11.0, -10.0, -12.0, -11.0]  # window means equal, steps not
    assert converged(noisy, gammas, 1.0, 1e-3, window=3)
    assert not converged(noisy, gammas, 1.0, 1e-3, window=1)
    assert not converged(noisy[:5], gammas[:5], 1.0, 1e-3, window=3)


def test_drive_stops_at_the_tolerance_or_the_ceiling_and_says_why():
    values = [-100.0, -50.0, -40.0, -40.0 + 1e-8, -40.0, -40.0]
    run = drive(0, _counting_step(values), 6, gamma=1.0, tolerance=1e-7, progress=False)
    assert run.state == 4 and run.converged and len(run.objective) == 4
    assert run.stop_reason.startswith("converged after 4 iterations")
    run = drive(0, _counting_step(values), 6, gamma=1.0, tolerance=0.0, progress=False)
    assert run.state == 6 and not run.converged
    assert run.stop_reason == "ran the 6 iterations asked for (not converged within them)"
    run = drive(0, _counting_step(values), 1, gamma=1.0, tolerance=0.0, progress=False)
    assert run.stop_reason == "ran the 1 iteration asked for (not converged within it)"
    run = drive(0, _counting_step(values), 6, gamma=1.0, anneal=5, tolerance=1e-7,
                progress=False)  # fmt: skip
    assert run.state == 6  # iterations 0-3 annealed: no stop before two at full gamma
    assert run.gammas == pytest.approx([0.2, 0.4, 0.6, 0.8, 1.0, 1.0], rel=1e-15)


def test_a_first_note_stays_on_the_bar_over_the_compiling_iterations(capsys, monkeypatch):
    """The first compiled sweeps compile numba's code (seconds; the merge and region moves at
    their first use, a few sweeps on): the bar says so over the first COMPILE_ITERATIONS, and
    shows no rate or time left then (it read 12:55:58 for a fit of 57 s)."""
    import tqdm.auto

    seen: list[str] = []

    def step(state, gamma):
        seen.append(bar_text())
        return state + 1, _Info(-1.0, 1, gamma)

    bars = []
    real = tqdm.auto.tqdm

    def recording(*args, **kwargs):
        bars.append(real(*args, **kwargs))
        return bars[-1]

    def bar_text() -> str:
        return bars[-1].desc

    monkeypatch.setattr(tqdm.auto, "tqdm", recording)
    capsys.readouterr()
    drive(0, step, COMPILE_ITERATIONS + 2, gamma=1.0, progress=True, description="Gibbs sweeps",
          first_note="compiling")  # fmt: skip
    noted = [line for line in capsys.readouterr().err.split("\r") if "(compiling)" in line]
    drive(0, step, 2, gamma=1.0, progress=True, description="CAVI")
    assert seen == ["Gibbs sweeps (compiling)"] * COMPILE_ITERATIONS + ["Gibbs sweeps"] * 2 + [
        "CAVI",
        "CAVI",
    ]
    assert len(noted) >= COMPILE_ITERATIONS and not [s for s in noted if re.search(r"<\d", s)]
    capsys.readouterr()


@pytest.mark.parametrize(
    ("argument", "value", "message"),
    [
        ("iterations", True, "iterations must be an integer >= 1, got True"),
        ("iterations", False, "iterations must be an integer >= 1, got False"),
        ("thin", True, "thin must be an integer >= 0, got True"),
    ],
)
def test_drive_refuses_a_bool_for_a_count(argument, value, message):
    """True is an int: ``drive(..., iterations=True)`` ran one iteration (thin refused bools
    already); np.int64 counts stay accepted."""
    arguments = {"iterations": 2, argument: value}

    def step(state, gamma):
        return state + 1, _Info(-1.0, 1, gamma)

    with pytest.raises(ValueError, match=message):
        drive(0, step, gamma=1.0, progress=False, **arguments)
    assert drive(0, step, np.int64(2), gamma=1.0, progress=False).state == 2


def test_a_compiled_run_leaves_nothing_to_compile_for_the_next():
    """numba_compile_pending: the hint is False once the compiled sweep has run (its cache
    written; True only before a checkout's first compiled run)."""
    pytest.importorskip("numba")
    from spcopyro.gibbs.backends import numba_compile_pending
    from spcopyro.gibbs.run import run_gibbs

    data, cfg = random_problem(seed=2)[1], config()
    run_gibbs(data, cfg, 2, options=GibbsOptions(backend="numba"), seed=0, progress=False)
    assert numba_compile_pending() is False


def test_drive_thins_and_checks_its_arguments():
    labels = lambda state: torch.full((3,), state)  # noqa: E731
    run = drive(0, _counting_step([0.0] * 9), 9, gamma=1.0, thin=4, labels=labels,
                num_concepts=5, progress=False)  # fmt: skip
    assert run.sample_iterations.tolist() == [3, 7]
    assert run.label_samples.dtype == np.int16 and run.label_samples[:, 0].tolist() == [4, 8]
    with pytest.raises(ValueError, match="thin"):
        drive(0, _counting_step([0.0]), 1, gamma=1.0, thin=-1, progress=False)
    with pytest.raises(ValueError, match="needs labels"):
        drive(0, _counting_step([0.0]), 1, gamma=1.0, thin=1, progress=False)
    with pytest.raises(ValueError, match="iterations"):
        drive(0, _counting_step([0.0]), 0, gamma=1.0, progress=False)


def test_ctrl_c_hands_back_the_completed_iterations():
    def step(state, gamma):
        if state == 3:
            raise KeyboardInterrupt
        return state + 1, _Info(float(state), 1, gamma)

    with pytest.raises(KeyboardInterrupt) as caught:
        drive(0, step, 10, gamma=1.0, progress=False)
    assert isinstance(caught.value, DriveInterrupted)
    trajectory = caught.value.trajectory
    assert trajectory.state == 3 and trajectory.objective.tolist() == [0.0, 1.0, 2.0]
    assert trajectory.stop_reason == "interrupted (Ctrl-C) after 3 iterations"


def test_a_continued_run_goes_on_with_its_schedule_thinning_and_numbers():
    """``first``: a run continued at iteration 3 anneals, thins and calls back as the iterations
    3.. of one run would, and an interrupt in the callback keeps its iteration."""
    seen = []
    labels = lambda state: torch.full((2,), state)  # noqa: E731
    run = drive(0, _counting_step([0.0] * 9), 4, gamma=2.0, anneal=5, first=3, thin=2,
                labels=labels, num_concepts=3, progress=False,
                callback=lambda s, state: seen.append(s))  # fmt: skip
    assert seen == [3, 4, 5, 6]
    assert run.gammas.tolist() == [annealed_gamma(2.0, s, 5) for s in (3, 4, 5, 6)]
    assert run.sample_iterations.tolist() == [3, 5]

    def stop_at_5(iteration, state):
        if iteration == 5:
            raise KeyboardInterrupt

    with pytest.raises(DriveInterrupted) as caught:
        drive(0, _counting_step([0.0] * 9), 4, gamma=2.0, first=3, progress=False,
              callback=stop_at_5)  # fmt: skip
    assert caught.value.trajectory.state == 3 and len(caught.value.trajectory.objective) == 3


def test_a_run_resumed_from_its_interrupted_record_is_the_unbroken_run():
    """``resume``: the record of an interrupted run (what a variational checkpoint keeps) comes
    first, the new iterations are numbered on from it, the stopping rule sees both; ``marginals``
    hands the interrupted state's q(C) back."""
    values = [-100.0, -50.0, -40.0, -30.0, -30.0 + 1e-9, -30.0, -30.0]
    labels = lambda state: torch.full((2,), state)  # noqa: E731
    kwargs = dict(gamma=2.0, anneal=3, tolerance=1e-7, thin=2, labels=labels, num_concepts=3,
                  progress=False)  # fmt: skip
    unbroken = drive(0, _counting_step(values), 7, **kwargs)

    def stop_at_3(state, gamma):
        if state == 3:
            raise KeyboardInterrupt
        return _counting_step(values)(state, gamma)

    with pytest.raises(DriveInterrupted) as caught:
        drive(0, stop_at_3, 7, marginals=lambda state: torch.full((2, 3), state / 3), **kwargs)
    stopped = caught.value.trajectory
    assert stopped.state == 3 and caught.value.marginals[0, 0] == 1.0
    resumed = drive(stopped.state, _counting_step(values), 7 - 3, resume=stopped, **kwargs)
    assert resumed.state == unbroken.state == 5 and resumed.converged
    assert resumed.stop_reason == unbroken.stop_reason
    for name in ("objective", "num_concepts", "gammas", "label_samples", "sample_iterations"):
        np.testing.assert_array_equal(getattr(resumed, name), getattr(unbroken, name))
    assert np.all(np.diff(resumed.seconds) >= 0) and resumed.seconds[2] == stopped.seconds[2]


def test_gibbs_sweeps_run_through_the_same_driver(problem, monkeypatch):
    """One driver runs every method: a Gibbs chain's sweeps are drive()'s iterations (its log
    joint the objective, numbered on from the chain's sweeps), and Ctrl-C hands back the
    completed sweeps as a DriveInterrupted."""
    import spcopyro.gibbs.run as gibbs_run

    data, cfg = problem
    calls = []
    real = gibbs_run.drive

    def spy(state, step, iterations, **kwargs):
        calls.append((iterations, kwargs["first"], kwargs["unit"]))
        return real(state, step, iterations, **kwargs)

    monkeypatch.setattr(gibbs_run, "drive", spy)
    chain = gibbs_run.start_chain(data, cfg, seed=0)
    after: list[np.ndarray] = []  # the chain's labels after each sweep

    def keep(sweep, state):
        assert state is chain.state  # the callback sees the sweep's own state
        after.append(chain.state.labels.numpy().copy())

    gibbs_run.advance(chain, 3, thin=1, progress=False, callback=keep)
    gibbs_run.advance(chain, 2, progress=False)
    assert calls == [(3, 0, "sweep"), (2, 3, "sweep")]
    assert chain.sample_sweeps == [0, 1, 2]  # each kept map is its own sweep's, not the one before
    for kept, state in zip(chain.label_samples, after, strict=True):
        np.testing.assert_array_equal(kept, state)
    assert len(chain.log_joint) == 5 and np.all(np.diff(chain.seconds) >= 0)

    def stop(sweep, state):
        if sweep == 6:
            raise KeyboardInterrupt

    with pytest.raises(DriveInterrupted) as caught:
        gibbs_run.advance(chain, 4, progress=False, callback=stop)
    assert caught.value.trajectory.objective.tolist() == chain.log_joint[5:7]
    assert chain.sweeps_done == 7


def test_the_torch_cavi_step_is_pure(problem):
    data, cfg = problem
    options = VariationalOptions(backend="torch")
    q = initial_q(data, cfg, torch.Generator().manual_seed(1))
    state = cavi.init(q, data, cfg, options)
    before = state.q.clone()
    new, info = cavi.step(state, data, cfg, cfg.gamma, options)
    assert torch.equal(state.q, before) and not torch.equal(new.q, before)
    assert info.gamma == cfg.gamma and 1 <= info.num_concepts <= cfg.num_concepts
    again, _ = cavi.step(state, data, cfg, cfg.gamma, options)
    torch.testing.assert_close(again.q, new.q, rtol=0, atol=0)


OPTIONS = {
    "cavi": VariationalOptions(tolerance=1e-6),
    "lbp": LBPOptions(tolerance=1e-6),
    "stochastic-vi": StochasticOptions(block_size=3, tolerance=1e-6, dtype="float64"),
    "svi": SVIOptions(tolerance=1e-3, window=10, anneal_iterations=0),
}


@pytest.mark.parametrize("name", VARIATIONAL)
def test_every_variational_method_stops_by_itself_records_it_and_thins(problem, name):
    data, cfg = problem
    method = get_method(name)
    assert method.default_options().tolerance > 0  # on by default
    output = method.run(data, cfg, iterations=2000, generator=torch.Generator().manual_seed(0),
                        options=OPTIONS[name], progress=False, thin=2)  # fmt: skip
    S = len(output.trace.objective)
    assert S < 2000 and output.options["stopped"].startswith(f"converged after {S} iterations")
    assert output.options["tolerance"] == OPTIONS[name].tolerance
    assert output.sample_iterations.tolist() == list(range(1, S, 2))
    assert output.label_samples.shape == (S // 2, data.num_free)


@pytest.mark.parametrize("name", VARIATIONAL)
def test_a_run_shorter_than_its_annealing_is_warned_about(problem, name, caplog):
    """Every variational method says when it stops before its annealing ends (gamma never
    reaches the model's value: `fit --method svi --sweeps 30` annealed over SVI's default 100
    steps without a word), and says nothing when the run is long enough."""
    data, cfg = problem
    field = "anneal_passes" if name == "stochastic-vi" else "anneal_iterations"
    method = get_method(name)
    said = {}
    for anneal in (8, 5):
        options = dataclasses.replace(OPTIONS[name], tolerance=0.0, **{field: anneal})
        caplog.clear()
        method.run(data, cfg, iterations=5, generator=torch.Generator().manual_seed(0),
                   options=options, progress=False)  # fmt: skip
        said[anneal] = [r.getMessage() for r in caplog.records if "annealed over" in r.getMessage()]
    assert said[5] == []
    assert len(said[8]) == 1
    assert f"({field}) but the run has 5: it ends at 62% of the model's gamma" in said[8][0]
    unit = {"stochastic-vi": "passes", "svi": "steps"}.get(name, "iterations")
    assert f"annealed over 8 {unit} (" in said[8][0]
    caplog.clear()  # runs cut short on purpose (the comparison's curve) say nothing
    with short_runs_meant():
        method.run(data, cfg, iterations=5, generator=torch.Generator().manual_seed(0),
                   options=dataclasses.replace(options, **{field: 8}), progress=False)  # fmt: skip
    assert not [r for r in caplog.records if "annealed over" in r.getMessage()]


def test_vi_gibbs_warns_of_its_cavi_annealing_in_its_own_options(problem, caplog):
    """vi-gibbs's CAVI runs vi_iterations, not --sweeps: its warning named anneal_iterations and
    said 'run at least N iterations', which --sweeps (its Gibbs sweeps) does not change."""
    data, cfg = problem
    variational = VariationalOptions(anneal_iterations=8, tolerance=0.0)
    options = VIGibbsOptions(vi_iterations=5, variational=variational)
    get_method("vi-gibbs").run(data, cfg, iterations=2, generator=torch.Generator().manual_seed(0),
                               options=options, progress=False)  # fmt: skip
    said = [r.getMessage() for r in caplog.records if "annealed over" in r.getMessage()]
    assert len(said) == 1 and "(variational.anneal_iterations) but the run has 5" in said[0]
    assert "set vi_iterations=8 or more, or set variational.anneal_iterations=5" in said[0]


def test_the_help_states_each_default_tolerance(capsys):
    with pytest.raises(SystemExit):
        main(["fit", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    per_iteration = float(re.search(r"tolerance (\S+) per iteration", text).group(1))
    for name in ("cavi", "lbp", "stochastic-vi"):
        assert get_method(name).default_options().tolerance == per_iteration, name
    svi = re.search(r"svi: (\S+) between the means of windows of (\d+)", text)
    tolerance, window = svi.groups()
    assert (float(tolerance), int(window)) == (SVIOptions().tolerance, SVIOptions().window)
    assert VIGibbsOptions().variational.tolerance == per_iteration


def test_vi_gibbs_honours_every_option_it_accepts(problem):
    """Each field of VIGibbsOptions, and run's thin, changes what ran (or its record)."""
    data, cfg = problem
    method = get_method("vi-gibbs")

    def run(options, thin=0, seed=0):
        return method.run(data, cfg, iterations=6, generator=torch.Generator().manual_seed(seed),
                          options=options, progress=False, thin=thin)  # fmt: skip

    base = VIGibbsOptions(vi_iterations=5, variational=VariationalOptions(tolerance=0.0))
    plain = run(base)
    assert plain.options["vi_iterations_run"] == 5
    assert run(dataclasses.replace(base, vi_iterations=3)).options["vi_iterations_run"] == 3
    variational = {
        "anneal_iterations": 3, "damping": 0.5, "pi_family": "stick-breaking",
        "tolerance": 1.0, "backend": "torch", "init": "soft",
    }  # fmt: skip
    if resolve_backend("auto") == "numba":  # the compiled backend's own options
        variational.update(support=2, threshold=0.2, active_tolerance=0.5)
    for field, value in variational.items():
        options = dataclasses.replace(
            base, variational=dataclasses.replace(base.variational, **{field: value})
        )
        output = run(options)
        assert output.options["variational"][field] == value, field
        changed = output.options["vi_elbo"] != plain.options["vi_elbo"]
        if field == "tolerance":  # a change below |ELBO| stops it after two iterations
            changed = output.options["vi_iterations_run"] == 2
        assert changed or field == "backend", field  # torch and numba agree at these settings
    gibbs = dataclasses.replace(base, gibbs=GibbsOptions(anneal_sweeps=3, backend="torch"))
    output = run(gibbs)
    assert output.options["anneal_sweeps"] == 3
    assert not np.array_equal(output.trace.objective, plain.trace.objective)
    thinned = run(base, thin=2)
    assert thinned.sample_iterations.tolist() == [1, 3, 5]
