"""``fit --update`` and ``where`` as a user meets them: an interrupted update says how far it got,
an update whose DATA lacks the saved fit's words warns that the old trials are missing, and
``where`` reads a word as the data's tokenizer does (punctuation at its ends stripped)."""

from __future__ import annotations

import dataclasses
import os
import shutil

import numpy as np
import pytest
from hand_results import two_rooms
from test_online_update import SETTINGS, _trials

import spcopyro.robot.online
from spcopyro.cli.main import main
from spcopyro.data import save_house
from spcopyro.fit.gibbs_chains import FitInterrupted
from spcopyro.fit.house import fit_house
from spcopyro.fit.registry import get_method
from spcopyro.gibbs.run import advance
from spcopyro.inference.driver import DriveInterrupted, Trajectory
from spcopyro.results.result import SpCoResult
from spcopyro.robot.online import fit_update
from spcopyro.robot.update_history import fit_folder
from spcopyro.synthetic import make_house

FLAGS = ["--preset", "original-code", "--gamma", "3", "--no-figures"]


@pytest.fixture(scope="module")
def house():
    return make_house(0)


@pytest.fixture(scope="module")
def first(tmp_path_factory, house):
    """Trials 0-1 of the synthetic house fitted by ``spcopyro fit`` (40 sweeps), the house's
    folders with trials 0-1, trial 2 alone and all three."""
    root = tmp_path_factory.mktemp("update")
    for name, trials in (("old", [0, 1]), ("new", [2]), ("all", [0, 1, 2])):
        save_house(_trials(house, trials), root / name)
    assert main(["fit", str(root / "old" / "synthetic"), "--out", str(root / "first"),
                 "--sweeps", "40", *FLAGS]) == 0  # fmt: skip
    return root


def test_an_interrupted_update_says_how_far_it_got(first, monkeypatch, capsys):
    """Ctrl-C during an update's sweeps: exit 130 and, as for every fit, how far it got (it said
    only 'interrupted: nothing written ...')."""

    def interrupted_advance(chain, num_sweeps, callback=None, **kwargs):
        def stop(sweep, state):
            if sweep == 3:  # after the 4th sweep, recorded
                raise KeyboardInterrupt

        return advance(chain, num_sweeps, callback=stop, **kwargs)

    monkeypatch.setattr(spcopyro.robot.online, "advance", interrupted_advance)
    out = first / "interrupted"
    capsys.readouterr()
    assert main(["fit", str(first / "all" / "synthetic"), "--update", str(first / "first"),
                 "--out", str(out), "--sweeps", "10", *FLAGS]) == 130  # fmt: skip
    err = capsys.readouterr().err
    assert f"interrupted (chain 1 of 1, 4 of 10 sweeps done): nothing written to {out}" in err
    assert "no checkpoint kept (--update)" in err
    assert not out.exists()


def test_an_interrupted_variational_update_names_its_method_and_iterations(house, monkeypatch):
    saved = fit_house(_trials(house, [0, 1]), SETTINGS, sweeps=5, progress=False)
    stopped = Trajectory(
        state=None, objective=np.zeros(7), num_concepts=np.ones(7, dtype=np.int64),
        seconds=np.zeros(7), gammas=np.ones(7), label_samples=None, sample_iterations=None,
        stop_reason="interrupted",
    )  # fmt: skip

    def interrupted_run(*args, **kwargs):
        raise DriveInterrupted(stopped)

    monkeypatch.setattr(get_method("cavi"), "run", interrupted_run)
    with pytest.raises(FitInterrupted) as stop:
        fit_update(saved, house, SETTINGS, method="cavi", sweeps=20, seeds=(0, 1), progress=False)
    assert stop.value.where == "cavi fit 1 of 2, 7 of 20 iterations done"


def test_an_update_whose_data_lacks_the_saved_words_warns(first, capsys):
    """DATA holding only the new trial fits the update on it alone: the old trials'
    observations are gone, which only config.json's unheard_words recorded."""
    capsys.readouterr()
    assert main(["fit", str(first / "new" / "synthetic"), "--update", str(first / "first"),
                 "--out", str(first / "only_new"), "--sweeps", "5", *FLAGS]) == 0  # fmt: skip
    captured = capsys.readouterr()
    assert "new words        2: kitchen, sofa" in captured.out
    warning = next(line for line in captured.err.splitlines() if "are not in this run's" in line)
    assert warning.startswith(f"warning: 6 word(s) of the fit in {first / 'first'} are not")
    assert "DATA must hold the old trials' observations" in warning
    # all the trials: nothing missing, no warning
    assert main(["fit", str(first / "all" / "synthetic"), "--update", str(first / "first"),
                 "--out", str(first / "all_trials"), "--sweeps", "5", *FLAGS]) == 0  # fmt: skip
    assert "are not in this run's data" not in capsys.readouterr().err


@pytest.mark.parametrize("asked", ["kitchen?", "Kitchen.", "'kitchen'", " KITCHEN!\n"])
def test_where_strips_punctuation_as_the_data_does(asked):
    """The data's words are tokens with their edge punctuation stripped ("Here is the
    kitchen." holds 'kitchen'), so "where is kitchen?" finds it (it was unknown, with the
    confusing hint "did you mean kitchen?")."""
    result = two_rooms()
    answer = result.where(asked)
    assert answer.word == "kitchen" and answer.concept == result.where("kitchen").concept
    np.testing.assert_array_equal(
        result.concept_given_word(asked), result.concept_given_word("kitchen")
    )


def test_where_command_with_punctuation_and_japanese(tmp_path, capsys):
    out = two_rooms().save(tmp_path / "fit")
    assert main(["where", str(out), "Kitchen?", "--out", str(tmp_path / "k.png")]) == 0
    assert "'kitchen' is concept 0" in capsys.readouterr().out
    assert main(["where", str(out), "the kitchen"]) == 2  # two words: not one of the vocabulary
    assert "'the kitchen' holds 2 words; give one word" in capsys.readouterr().err
    result = two_rooms()
    words = dataclasses.replace(result.emission("words"), items=("台所", "寝室", "リビング"))
    japanese = dataclasses.replace(result, emissions=(result.emissions[0], words))
    assert japanese.where("台所。").word == "台所"  # a full stop of Japanese text
    assert japanese.where("台所。").concept == result.where("kitchen").concept


@pytest.mark.parametrize("name", ["config.png", "config", "concepts.svg", "semantic_map.png"])
def test_show_graph_never_replaces_the_fits_files(tmp_path, capsys, name):
    """``show OUT --graph --out OUT/config.png`` wrote the graph's JSON over the fit's
    config.json (the fit no longer loaded: "do not form a spcopyro result"); ``where --out``
    refused such names already."""
    out = two_rooms().save(tmp_path / "fit")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert main(["show", str(out), "--graph", "--out", str(out / name)]) == 2
    assert "is a file of the fit" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert main(["show", str(out), "--graph", "--out", str(out / "graph.png")]) == 0
    assert (out / "graph.png").is_file() and (out / "graph.json").is_file()


def test_show_of_a_fit_without_figures_says_so(tmp_path, capsys):
    """``show OUT`` of a ``--no-figures`` fit said "its figures are in it already"."""
    out = two_rooms().save(tmp_path / "fit")  # result files only, as after --no-figures
    assert main(["show", str(out), "--out", str(tmp_path / "h.png")]) == 2
    err = capsys.readouterr().err
    assert "it was fitted with --no-figures" in err and "already" not in err
    (out / "semantic_map.png").write_bytes(b"")
    assert main(["show", str(out), "--out", str(tmp_path / "h.png")]) == 2
    assert "its figures are in it already" in capsys.readouterr().err


def test_a_semantic_map_of_japanese_words_keeps_matplotlibs_glyph_warnings_quiet(
    tmp_path, monkeypatch
):
    """The labels' boxes, measured before the figure is saved, let matplotlib's per-glyph
    warnings through ("UserWarning: Glyph 23460 ... missing from font(s) DejaVu Sans" in the
    output of ``fit``), beside the one warning in words that the figures give."""
    import warnings

    import spcopyro.figures.fonts as fonts
    import spcopyro.figures.plotting as plotting

    monkeypatch.setattr(fonts, "CJK_FONTS", ())  # as on a machine without such a font
    result = two_rooms()
    words = dataclasses.replace(result.emission("words"), items=("台所", "寝室", "リビング"))
    japanese = dataclasses.replace(result, emissions=(result.emissions[0], words))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plotting.plot_semantic_map(japanese, tmp_path / "map.png")
    assert not [w for w in caught if "missing from font" in str(w.message)]


def test_the_missing_glyphs_warning_names_the_words_without_punctuation(
    tmp_path, monkeypatch, caplog
):
    """``where --out`` of a Japanese word said "no glyphs for ... (in '台所'), '台所'?, 台所)":
    the words as the title and legend split on spaces, quotes and brackets kept."""
    import logging

    import spcopyro.figures.fonts as fonts
    import spcopyro.figures.plotting as plotting

    monkeypatch.setattr(fonts, "CJK_FONTS", ())
    monkeypatch.setattr(fonts, "_warned_glyphs", set())
    result = two_rooms()
    words = dataclasses.replace(result.emission("words"), items=("台所", "寝室", "リビング"))
    japanese = dataclasses.replace(result, emissions=(result.emissions[0], words))
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        plotting.plot_where(japanese, japanese.where("台所"), tmp_path / "where.png")
    (told,) = [r.getMessage() for r in caplog.records if "no glyphs" in r.getMessage()]
    listed = told.split(" (in ")[1].split("): ")[0]
    assert "台所" in listed.split(", ") and not set(listed) & set("'?()")


def test_where_of_a_phrase_asks_for_one_word():
    """'the kitchen' said only "not in the vocabulary; did you mean kitchen?"."""
    from spcopyro.results.semantic_map import UnknownWordError, word_index

    vocabulary = ("kitchen", "sink", "bed")
    with pytest.raises(UnknownWordError, match=r"'the kitchen' holds 2 words; give one word .*"
                       r"\(of these, kitchen is known\)"):  # fmt: skip
        word_index(vocabulary, "the kitchen")
    with pytest.raises(UnknownWordError, match=r"kitchen, sink are known"):
        word_index(vocabulary, "Kitchen sink")
    assert word_index(vocabulary, " Sink? ") == 1


def test_an_update_of_an_update_records_the_history_and_notes_unchanged_data(first, capsys):
    """Updated twice: config.json's update_of nests the saved fit's own update_of, back to the
    first fit; an update on the very data the saved fit was fitted on says nothing was added."""
    import json

    once, twice = first / "once", first / "twice"
    capsys.readouterr()
    assert main(["fit", str(first / "all" / "synthetic"), "--update", str(first / "first"),
                 "--out", str(once), "--sweeps", "5", *FLAGS]) == 0  # fmt: skip
    assert "no observation was added" not in capsys.readouterr().out  # trial 2 was added
    assert main(["fit", str(first / "all" / "synthetic"), "--update", str(once),
                 "--out", str(twice), "--sweeps", "5", *FLAGS]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert (f"note: this data is the data the fit in {once} was fitted on (the same sha256 of "
            "the model data): no observation was added") in out  # fmt: skip
    record = json.loads((twice / "config.json").read_text())["inference"]["update_of"]
    assert fit_folder(record, twice) == str(once) and record["new_words"] == []
    (earlier,) = record["earlier"]  # the first update's small record: flat, not nested
    assert fit_folder(earlier, twice) == str(first / "first") and earlier["iterations"] == 40
    assert earlier["new_words"] == 2 and "update_of" not in record


def test_the_update_history_stays_flat_and_reads_old_nested_records(first, capsys):
    """Each update nested the saved fit's whole update_of in its own, so the record grew
    without bound (every word list of every update, again and again): now update_of.earlier
    is a flat list, one small entry per earlier fit; a record nested the old way is read."""
    import json

    old = first / "old_nested"  # an update written before: nested, paths as given
    shutil.copytree(first / "first", old)
    config = json.loads((old / "config.json").read_text())
    inner = {"fit": str(first / "zeroth"), "method": "gibbs", "iterations": 7,
             "new_words": ["a", "b", "c"], "unheard_words": []}  # fmt: skip
    config["inference"]["update_of"] = {
        "fit": str(first / "first"), "method": "gibbs", "iterations": 40,
        "new_words": ["kitchen", "sofa"], "unheard_words": [], "update_of": inner,
    }  # fmt: skip
    (old / "config.json").write_text(json.dumps(config))
    sizes, saved = [], old
    for k in range(3):
        out = first / f"chain{k}"
        assert main(["fit", str(first / "all" / "synthetic"), "--update", str(saved),
                     "--out", str(out), "--sweeps", "2", *FLAGS]) == 0  # fmt: skip
        record = json.loads((out / "config.json").read_text())["inference"]["update_of"]
        assert "update_of" not in record and fit_folder(record, out) == str(saved)
        folders = [fit_folder(e, out) for e in record["earlier"]]
        fits = [first / "zeroth", first / "first", old] + [first / f"chain{j}" for j in range(k)]
        assert folders == [str(f) for f in reversed(fits[:-1])]  # newest first, back to zeroth
        assert all(not isinstance(e.get("new_words"), list) for e in record["earlier"])
        assert [e.get("new_words") for e in record["earlier"]][-2:] == [2, 3]
        sizes.append(len(json.dumps(record["earlier"])))
        saved = out
    assert sizes[2] - sizes[1] <= sizes[1] - sizes[0] + 20  # one small entry an update


def test_an_update_says_how_many_observations_it_added(first, house, capsys):
    """The update's lines said which words it added, not how many observations: now how many
    it added and the fit holds (placed on free cells, as config.json records for every fit),
    and, for a fit saved before fits recorded theirs, that the number added is not known."""
    import json

    capsys.readouterr()
    added = first / "added"
    assert main(["fit", str(first / "all" / "synthetic"), "--update", str(first / "first"),
                 "--out", str(added), "--sweeps", "2", *FLAGS]) == 0  # fmt: skip
    out = capsys.readouterr().out
    obs = house.observations
    given = [obs.select_trials(t).num_images + len(obs.select_trials(t).utterances)
             for t in ([0, 1], [0, 1, 2])]  # fmt: skip
    config = json.loads((first / "first" / "config.json").read_text())
    assert config["source"]["observations"] == {"given": given[0], "placed": given[0]}
    record = json.loads((added / "config.json").read_text())["inference"]["update_of"]
    assert record["observations"] == given[1] and record["observations_before"] == given[0]
    assert (f"observations     +{given[1] - given[0]} added: {given[1]} in the fit now, "
            f"{given[0]} before (those placed on the map's free cells)") in out  # fmt: skip
    older = first / "older"  # the first fit as an older spcopyro saved it
    shutil.copytree(first / "first", older)
    del config["source"]["observations"]
    (older / "config.json").write_text(json.dumps(config))
    assert main(["fit", str(first / "all" / "synthetic"), "--update", str(older),
                 "--out", str(first / "from_older"), "--sweeps", "2", *FLAGS]) == 0  # fmt: skip
    assert (
        f"observations     {given[1]} in the fit now (placed on the map's free cells); the "
        f"fit in {older} does not record how many it held"
    ) in capsys.readouterr().out


def test_report_update_says_the_observations_first(capsys):
    """report_update prints the observations line (report_observations' before it was merged
    in), then the words; no line where the record holds no count."""
    from spcopyro.cli.fit_update import report_update

    record = {"new_words": ["sink"], "unheard_words": [], "observations": 9,
              "observations_before": 5}  # fmt: skip
    report_update(record, "OUT")
    assert capsys.readouterr().out.splitlines() == [
        "observations     +4 added: 9 in the fit now, 5 before (those placed on the map's "
        "free cells)",
        "new words        1: sink",
    ]
    report_update({**record, "observations": None}, "OUT")
    assert capsys.readouterr().out.splitlines() == ["new words        1: sink"]


def test_an_earlier_fit_no_longer_there_is_recorded_absolute(tmp_path, monkeypatch):
    """The saved fit's record names the fit before it relative to the saved fit's folder; with
    that earlier folder deleted and --update given relative to the working directory, the
    earlier entry held a path relative to the working directory, unmarked (read later from
    another directory or with OUT moved, it named the wrong folder). Now it is absolute, and
    relative_record makes it relative to OUT, marked."""
    from types import SimpleNamespace

    from spcopyro.robot.update_history import (
        RELATIVE_TO,
        RESULT_FOLDER,
        relative_record,
        update_record,
    )

    monkeypatch.chdir(tmp_path)
    (tmp_path / "first").mkdir()  # the saved fit, an update of "zeroth", deleted since
    saved = SimpleNamespace(
        provenance={"source": {}}, method="gibbs", trace=SimpleNamespace(objective=[0.0]),
        inference={"update_of": {"fit": "../zeroth", RELATIVE_TO: RESULT_FOLDER}},
    )  # fmt: skip
    record = update_record(saved, ((), ()), "first")
    zeroth = os.path.join(os.getcwd(), "zeroth")
    assert record["earlier"][0]["fit"] == zeroth
    kept = relative_record(record, "second")["earlier"][0]
    assert kept == {"fit": os.path.join("..", "zeroth"), RELATIVE_TO: RESULT_FOLDER}
    assert fit_folder(kept, os.path.abspath("second")) == zeroth


def test_the_updated_fit_is_recorded_relative_to_the_result(first, tmp_path, monkeypatch):
    """update_of.fit held --update as given, relative to the working directory: read from
    another directory, or with both folders moved, it named no fit. Now it is relative to the
    result's folder; an older record (no marker) is still read as stored."""
    import json

    work = tmp_path / "work"
    shutil.copytree(first / "first", work / "fits" / "first")
    monkeypatch.chdir(work)
    assert main(["fit", str(first / "all" / "synthetic"), "--update", "fits/first",
                 "--out", "fits/updated", "--sweeps", "2", *FLAGS]) == 0  # fmt: skip
    inference = json.loads((work / "fits/updated/config.json").read_text())["inference"]
    record = inference["update_of"]
    assert record["fit"] == "../first" and record["fit_relative_to"] == "result folder"
    # init named the fit again as given here ("update of fits/first", relative to this working
    # directory, not to the result's folder as update_of.fit is): now it points to update_of
    assert inference["init"] == "update of the fit in update_of"
    moved = tmp_path / "elsewhere"
    shutil.move(work / "fits", moved)
    monkeypatch.chdir(tmp_path)
    assert fit_folder(record, moved / "updated") == str(moved / "first")
    assert SpCoResult.load(fit_folder(record, moved / "updated")).method == "gibbs"
    older = {key: value for key, value in record.items() if key != "fit_relative_to"}
    assert fit_folder({**older, "fit": "fits/first"}, moved / "updated") == "fits/first"
