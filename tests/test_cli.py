"""The `spcopyro` command line and the saved result (what it writes, and that it reads back,
whatever the inference method), end to end on small inputs."""

from __future__ import annotations

import dataclasses
import json
import pathlib
import shlex

import numpy as np
import pytest

from spcopyro.cli.main import main
from spcopyro.data import load_house
from spcopyro.results.result import SpCoResult, UnknownWordError
from spcopyro.synthetic import HouseSpec, write_synthetic


@pytest.fixture
def small_house(tmp_path):
    return write_synthetic(
        tmp_path / "data", seed=1, spec=HouseSpec(height=40, width=50, num_rooms=3)
    )


def test_simulate_writes_the_dataset_layout(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path / "d"), "--seed", "2"]) == 0
    room = tmp_path / "d" / "synthetic"
    for name in ("Ft.csv", "Xtx.csv", "St.csv", "StXtx.csv", "truth.npy", "categories.json"):
        assert (room / name).is_file(), name
    assert (tmp_path / "d" / "map" / "synthetic.yaml").is_file()
    assert load_house(room).truth is not None
    assert "wrote synthetic house" in capsys.readouterr().out


def test_show_prints_a_summary_and_draws(small_house, tmp_path, capsys):
    out = tmp_path / "house.png"
    assert main(["show", str(small_house), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert out.stat().st_size > 1000
    for needle in ("free", "images", "utterances", "vocabulary", "snapped", "unplaced"):
        assert needle in text, needle


def test_fit_then_where(small_house, tmp_path, capsys):
    out = tmp_path / "fit"
    argv = ["fit", str(small_house), "--out", str(out), "--sweeps", "20",
            "--preset", "original-code", "--gamma", "3", "--concepts", "20"]  # fmt: skip
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "adjusted Rand index" in text
    # what is fitted, as a person reads it (they printed SpCoConfig(...), DataPreparation(...)
    # and GibbsOptions(..., hyper=HyperparameterOptions(...)) reprs): config.json has the rest
    assert ("\nmodel            preset original-code: 20 concepts (dp, alpha 1e7), gamma 3 "
            "(4-neighbour), beta 0.1, chi 1\n") in text, text  # fmt: skip
    assert "\ndata             the map's own cells, feature scaling floor100\n" in text, text
    assert (f"\ninference        gibbs: 20 sweeps (every setting: {out}/config.json)\n"
            in text), text  # fmt: skip
    for name in ("labels.npy", "semantic_map.png", "concepts.json", "trace.csv", "trace.png"):
        assert (out / name).is_file(), name
    labels = np.load(out / "labels.npy")
    house = load_house(small_house)
    assert labels.shape == house.grid.shape
    assert labels.dtype.kind == "i"
    assert (labels[~house.grid.free] == -1).all() and (labels[house.grid.free] >= 0).all()
    concepts = json.loads((out / "concepts.json").read_text())
    assert sum(c["cells"] for c in concepts) == house.grid.num_free
    assert all(len(c["top_words"]) > 0 or c["words_note"] == "no words heard here"
               for c in concepts)  # fmt: skip
    assert any(len(c["top_words"]) > 0 for c in concepts)
    trace = (out / "trace.csv").read_text().splitlines()
    assert trace[0] == "iteration,log_joint,num_concepts,seconds" and len(trace) == 21
    settings = json.loads((out / "config.json").read_text())
    assert {"model", "data", "method", "inference"} <= set(settings)  # + provenance: test_outputs
    assert settings["method"] == "gibbs" and settings["model"]["gamma"] == 3.0
    assert settings["data"]["feature_scaling"] == "floor100"  # the preset's data preparation
    assert settings["inference"]["sweeps"] == 20 and settings["inference"]["seed"] == 0

    # the fit's last line says what to open and the next command, which runs as printed
    last = text.strip().splitlines()[-1]
    assert last.startswith(f"next: open {out / 'semantic_map.png'}; ask where the "), last
    command = shlex.split(last.split(": ")[-1])
    assert command[:3] == ["spcopyro", "where", str(out)] and main(command[1:]) == 0
    assert pathlib.Path(command[-1]).is_file() and "' is concept" in capsys.readouterr().out

    word = house.observations.vocabulary[0]
    assert main(["where", str(out), word, "--out", str(tmp_path / "where.png")]) == 0
    text = capsys.readouterr().out
    assert f"'{word}' is concept" in text and "region:" in text and "area prior" in text
    assert (tmp_path / "where.png").stat().st_size > 0
    assert main(["where", str(out), "zzznotaword"]) == 2
    assert "not in the vocabulary" in capsys.readouterr().err


def test_fit_warns_below_the_critical_coupling(small_house, tmp_path, capsys):
    argv = ["fit", str(small_house), "--out", str(tmp_path / "f"), "--sweeps", "2",
            "--preset", "original-code"]  # fmt: skip
    assert main(argv) == 0
    assert "below the Potts critical coupling" in capsys.readouterr().err


def test_fit_says_when_the_word_prior_swamps_the_words(small_house, tmp_path, capsys):
    argv = ["fit", str(small_house), "--out", str(tmp_path / "f"), "--sweeps", "3",
            "--concepts", "10", "--preset", "paper-dp"]  # fmt: skip
    assert main(argv) == 0  # paper-dp: beta = 500
    assert "close to uniform" in capsys.readouterr().err
    argv += ["--beta", "0.01", "--out", str(tmp_path / "g")]
    assert main(argv) == 0
    assert "close to uniform" not in capsys.readouterr().err


def test_fit_says_when_the_vocabulary_holds_one_word(small_house, tmp_path, capsys):
    """With one word every w is uniform, and the note blamed beta or stopwords."""
    import re
    import shutil

    house = shutil.copytree(small_house.parent, tmp_path / "copy") / small_house.name
    for words in [house / "St.csv", *house.glob("word_*.csv")]:
        words.write_text(re.sub(r"[^,\s]+", "kitchen", words.read_text()))
    argv = ["fit", str(house), "--out", str(tmp_path / "f"), "--sweeps", "3", "--concepts", "10"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "note: the vocabulary holds one word ('kitchen'): the words cannot tell" in err
    assert "close to uniform" not in err


def test_bad_input_is_one_clear_line(tmp_path, capsys):
    assert main(["show", str(tmp_path / "nowhere"), "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "nowhere" in err
    assert main(["where", str(tmp_path), "kitchen"]) == 2
    assert "no fitted result" in capsys.readouterr().err


def test_result_round_trips_and_answers_where(small_house, tmp_path):
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house

    house = load_house(small_house)
    result = fit_house(house, preset("original-code", gamma=3.0, num_concepts=10), sweeps=10,
                       progress=False)  # fmt: skip
    loaded = SpCoResult.load(result.save(tmp_path / "r"))
    np.testing.assert_array_equal(loaded.label_image(), result.label_image())
    np.testing.assert_array_equal(loaded.w, result.w)
    assert loaded.vocabulary == result.vocabulary and loaded.config == result.config
    assert_same_result(loaded, result)
    word = result.vocabulary[0]
    answer = result.where(word, prior="pi")
    posterior = result.concept_given_word(word, prior="pi")
    assert answer.concept == int(np.argmax(posterior))
    assert posterior.sum() == pytest.approx(1.0)
    # eq. (19) by hand: proportional to w[l, word] * pi[l] over concepts in use
    used = result.concepts_in_use()
    by_hand = result.w[used, 0] * result.pi[used]
    assert answer.concept == used[np.argmax(by_hand)]
    assert (answer.region == (result.label_image() == answer.concept)).all()
    # the default prior is the area: w[l, word] * (cells of l) over concepts in use
    by_area = result.w[used, 0] * result.concept_sizes()[used]
    assert result.where(word).concept == used[np.argmax(by_area)]
    assert result.where(word).prior == "area"
    with pytest.raises(UnknownWordError, match="did you mean"):
        result.where(word + "x")


def assert_same_result(loaded: SpCoResult, result: SpCoResult) -> None:
    """Every field of a loaded result equals the saved one's."""
    np.testing.assert_array_equal(loaded.labels, result.labels)  # [N]
    np.testing.assert_array_equal(loaded.pi, result.pi)  # [L]
    assert [t.name for t in loaded.emissions] == [t.name for t in result.emissions]
    for mine, theirs in zip(loaded.emissions, result.emissions, strict=True):
        assert mine.items == theirs.items
        np.testing.assert_array_equal(mine.probabilities, theirs.probabilities)  # [L, K_m]
    for name in ("objective", "num_concepts", "seconds"):
        np.testing.assert_array_equal(getattr(loaded.trace, name), getattr(result.trace, name))
    assert loaded.trace.objective_name == result.trace.objective_name
    assert loaded.best_iteration == result.best_iteration
    assert loaded.best_objective == result.best_objective
    assert loaded.method == result.method and loaded.name == result.name
    assert loaded.inference == result.inference
    assert loaded.config == result.config and loaded.preparation == result.preparation
    for name in ("labels_final", "marginals"):
        mine, theirs = getattr(loaded, name), getattr(result, name)
        assert (mine is None) == (theirs is None), name
        if theirs is not None:
            np.testing.assert_array_equal(mine, theirs)
    np.testing.assert_array_equal(loaded.grid.occupancy, result.grid.occupancy)


def test_result_round_trips_every_field(small_house, tmp_path):
    """A Gibbs result (trace, inference record, last state's labels, no marginals) and the same
    result as a variational method would hand it (ELBO trace, marginals, no last state) both
    read back field for field."""
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house
    from spcopyro.gibbs.options import GibbsOptions

    house = load_house(small_house)
    settings = preset("original-code", gamma=3.0, num_concepts=6, snap_distance=0.5)
    result = fit_house(house, settings, sweeps=6, seed=3, progress=False,
                       options=GibbsOptions(cluster_moves=0.25))  # fmt: skip
    assert result.method == "gibbs" and result.trace.objective_name == "log joint"
    assert result.inference["sweeps"] == 6 and result.inference["seed"] == 3
    assert result.inference["cluster_moves"] == 0.25
    assert result.labels_final is not None and result.marginals is None
    # the word weighting "auto" recorded as resolved: single words are counted
    assert result.preparation == settings.data.replace(word_weighting="count")
    assert result.name == house.name
    assert_same_result(SpCoResult.load(result.save(tmp_path / "gibbs")), result)

    rng = np.random.default_rng(0)
    marginals = rng.dirichlet(np.ones(6), size=house.grid.num_free)  # [N, L]
    variational = dataclasses.replace(
        result,
        method="variational",
        marginals=marginals,
        labels=marginals.argmax(1),
        labels_final=None,
        trace=dataclasses.replace(result.trace, objective_name="ELBO"),
        inference={"iterations": 6, "learning_rate": 0.1},
    )
    loaded = SpCoResult.load(variational.save(tmp_path / "vi"))
    assert_same_result(loaded, variational)
    assert loaded.trace.objective_name == "ELBO"
    with pytest.raises(ValueError, match="^a variational result has no final state"):
        loaded.labels_of("final")
    header = (tmp_path / "vi" / "trace.csv").read_text().splitlines()[0]
    assert header == "iteration,elbo,num_concepts,seconds"


def test_loading_an_old_result_says_to_fit_again(small_house, tmp_path, capsys):
    """A folder written before results became method-neutral (result.npz with labels_best,
    theta, w; a flat config.json) gives one clear error, also through `spcopyro where`."""
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house

    house = load_house(small_house)
    result = fit_house(house, preset("original-code", gamma=3.0, num_concepts=4), sweeps=2,
                       progress=False)  # fmt: skip
    out = result.save(tmp_path / "old")
    np.savez_compressed(
        out / "result.npz",
        labels_best=result.labels,
        labels_final=result.labels_final,
        pi=result.pi,
        theta=result.theta,
        w=result.w,
        vocabulary=np.array(result.vocabulary, dtype=str),
        log_joint=result.trace.objective,
        num_concepts=result.trace.num_concepts,
        seconds=result.trace.seconds,
        best_sweep=np.array(result.best_iteration),
    )
    flat = {**result.config.to_json(), "feature_scaling": "floor100", "word_weighting": "count"}
    (out / "config.json").write_text(json.dumps(flat))
    with pytest.raises(ValueError, match="before its results became method-neutral"):
        SpCoResult.load(out)
    assert main(["where", str(out), result.vocabulary[0]]) == 2
    assert "fit again" in capsys.readouterr().err


def test_fit_lists_the_concepts_and_the_next_step_from_one_list(tmp_path, capsys, monkeypatch):
    """print_concepts and next_step share one result.concepts() (next_step computed it again;
    save's concepts.json, of 10 words each, is the only other)."""
    calls = []
    concepts = SpCoResult.concepts

    def counted(self, n_words=3):
        calls.append(n_words)
        return concepts(self, n_words)

    monkeypatch.setattr(SpCoResult, "concepts", counted)
    out = tmp_path / "fit"
    assert main(["fit", "--method", "cavi", "--out", str(out), "--no-figures"]) == 0
    assert calls.count(3) == 1, calls
    assert "next: ask where the " in capsys.readouterr().out


@pytest.mark.parametrize("method", ["cavi", "lbp"])
def test_variational_fits_stop_by_themselves_and_say_why(method, tmp_path, capsys):
    """Issue 23: `fit --method lbp` ran all 5000 iterations on the embedded house (2 minutes);
    --sweeps is now a ceiling for the variational methods, and the summary says why they
    stopped (also in config.json's record)."""
    out = tmp_path / "fit"
    assert main(["fit", "--method", method, "--out", str(out), "--no-figures"]) == 0
    printed = capsys.readouterr().out
    line = next(text for text in printed.splitlines() if text.startswith("stopped "))
    iterations = int(line.split("converged after ")[1].split()[0])
    assert iterations < 100 and f"fitted {iterations} iterations" in printed
    assert "tolerance 1e-07 x |objective|" in line
    record = json.loads((out / "config.json").read_text())
    assert "converged after" in json.dumps(record)
    # and the objective's final value, named (it said "the objective" and no value): the last
    # row of trace.csv, whose column names it too
    name = {"cavi": "ELBO", "lbp": "Bethe ELBO"}[method]
    header, *rows = (out / "trace.csv").read_text().splitlines()
    assert header.split(",")[1] == name.lower().replace(" ", "_")
    assert line.endswith(f"; final {name} {float(rows[-1].split(',')[1]):.1f} nats"), line


@pytest.mark.parametrize(
    ("options", "where"),
    [
        (["--method", "gibbs"], " on the map's cells"),
        (["--method", "gibbs", "--refine", "never"], ""),
        (["--method", "vi-gibbs"], ""),
    ],
)
def test_a_sampler_s_summary_gives_its_highest_log_joint_and_when(options, where, tmp_path, capsys):
    """A Gibbs fit printed no objective at its end, where a variational fit's "stopped" line
    gives its final ELBO in nats: a sampler's summary gives its highest log joint, in nats, and
    the sweep that reached it, trace.csv's (its column log_joint, its 1-based iteration; the
    default Gibbs fit's: of its refinement on the map's cells, the trace it keeps)."""
    out = tmp_path / "fit"
    assert main(["fit", *options, "--sweeps", "30", "--out", str(out), "--no-figures"]) == 0
    printed = capsys.readouterr().out
    header, *rows = (out / "trace.csv").read_text().splitlines()
    assert header.split(",")[:2] == ["iteration", "log_joint"]
    values = [float(row.split(",")[1]) for row in rows]
    best = max(range(len(values)), key=values.__getitem__)
    expected = (f"log joint        highest {values[best]:.1f} nats, at sweep "
                f"{rows[best].split(',')[0]} of 30{where} (every sweep's: trace.csv)")  # fmt: skip
    assert expected in printed.splitlines(), printed
    assert not any(line.startswith("stopped ") for line in printed.splitlines())


def test_a_fit_left_unrefined_gives_its_highest_log_joint_of_its_own_sweeps(
    dataset_root, tmp_path, capsys
):
    """room1dk5's default fit decides not to refine (its images do not tell the places apart),
    and records that decision: its log joint line said "of 200 on the map's cells", as a
    refined fit's."""
    out = tmp_path / "fit"
    argv = ["fit", str(dataset_root / "room1dk5"), "--sweeps", "30", "--out", str(out),
            "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert json.loads((out / "config.json").read_text())["inference"]["refine"]["refine"] is False
    (line,) = [text for text in printed.splitlines() if text.startswith("log joint ")]
    assert line.endswith(" of 30 (every sweep's: trace.csv)"), line


@pytest.mark.parametrize("method", ["cavi", "lbp", "stochastic-vi", "vi-gibbs"])
def test_a_variational_default_on_a_public_house_is_not_one_concept(method, dataset_root,
                                                                     tmp_path, capsys):  # fmt: skip
    """Issue 21: `fit --method cavi` (lbp, stochastic-vi, vi-gibbs) on a public house took the
    default preset's rooms start, which is one room there, and a variational method has no move
    that splits it: one concept. The rooms start is Gibbs's (its merge moves split); the others
    start random, as the real-house benchmark measured them."""
    out = tmp_path / method
    argv = ["fit", str(dataset_root / "room1dk5"), "--method", method, "--sweeps", "60",
            "--out", str(out), "--no-figures"]  # fmt: skip
    assert main(argv) == 0
    capsys.readouterr()
    assert json.loads((out / "config.json").read_text())["inference"]["init"] == "random"
    labels = np.load(out / "labels.npy")
    sizes = np.bincount(labels[labels >= 0])
    assert sizes.max() / sizes.sum() < 0.6  # no concept over 60 % of the house
