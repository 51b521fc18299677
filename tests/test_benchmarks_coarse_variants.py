"""coarse_variants.py and coarse_variant_settings.py: the variants of the coarse preset
screened on the public houses (ARI targets against the nearest utterance's bar, held-out
words pooled as real_houses.py pools them) and, with --synthetic, on the synthetic houses;
resuming a JSON (older layouts included) and refusing one prepared otherwise; the settings
each variant records and fits with.

--quick runs are smoke tests: their numbers are never asserted here. The other tests import
a script from benchmarks/ (the ``script`` fixture, tests/conftest.py: their folder on
sys.path, as when they run) and call its functions on small inputs. The tests needing the
public dataset skip without it.
"""

from __future__ import annotations

import argparse
import json

import pytest
from benchmark_setup import run_benchmark


@pytest.mark.slow
def test_coarse_variants_quick_scores_each_variant_and_resumes(tmp_path, dataset_root):
    """coarse_variants.py --quick: each variant's public and held-out scores on one house, in a
    JSON written as it goes; a rerun with the same --out fits nothing again (same JSON)."""
    out = tmp_path / "coarse_variants.json"
    done = run_benchmark("coarse_variants.py", out)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(out.read_text())
    assert results["sweeps"] == 20 and results["houses"] == ["room1dk5"]
    assert list(results["variants"]) == ["coarse", "footprint 0.5 m"]
    for seeds in results["variants"].values():
        row = seeds["seed 0"]
        held = row["houses"]["room1dk5"]["heldout"]
        assert 0.0 <= held["all folds"] <= held["top 3"] <= 1.0 and held["words"] > 0
        assert row["summary"]["top1"] == held["all folds"]
        assert row["summary"]["ari"] == row["houses"]["room1dk5"]["public"]["ari"]
    assert "| coarse (seed 0) |" in done.stdout
    again = run_benchmark("coarse_variants.py", out)
    assert again.returncode == 0 and "seed 0 room1dk5" not in again.stderr, again.stderr[-3000:]
    assert json.loads(out.read_text()) == results


def _variant_house(ari, share, count, top1=0.3, words=10):
    public = {"ari": ari, "largest_share": share, "concepts_1pct": count, "refined": False}
    held = {"all folds": top1, "top 3": 0.6, "mean rank": 3.0, "words": words}
    return {"public": public, "heldout": held}


def test_coarse_variants_judges_the_ari_targets_on_every_house(script):
    """A variant meets the ARI targets only with the mean above (E)'s (0.510 on the public
    houses; the bar given, no longer a 0.510 of the script's own), no concept over 60 % and
    every house's concept count within 2 of Table 2."""
    cv = script("coarse_variants")
    house = _variant_house
    table2 = dict(cv.PUBLIC_CATEGORIES)
    good = {h: house(0.6, 0.5, n) for h, n in table2.items()}
    assert cv.summary(good, 0.510)["ari_targets"] is True
    assert cv.summary(good, 0.610)["ari_targets"] is False  # the bar is the one measured
    assert cv.summary(good, 0.510)["top1"] == pytest.approx(0.3)
    assert cv.summary({**good, "room1dk5": house(0.6, 0.61, 6)}, 0.510)["ari_targets"] is False
    assert cv.summary({**good, "room1dk5": house(0.6, 0.5, 9)}, 0.510)["ari_targets"] is False
    low = {h: house(0.5, 0.5, n) for h, n in table2.items()}
    assert cv.summary(low, 0.510)["ari_targets"] is False


def test_coarse_variants_pools_held_out_words_as_real_houses_does(script):
    """The held-out summary is real_houses.py's: the mean of houses, and the pooling over the
    houses' words (``real_houses.pooled``: a house weighs by its words, one scoring none
    weighs nothing, where the script's own dot product made the pooled score NaN)."""
    cv = script("coarse_variants")
    per_house = {"room1dk5": _variant_house(0.6, 0.5, 6, top1=0.2, words=30),
                 "room1dk6": _variant_house(0.6, 0.5, 5, top1=0.6, words=10)}  # fmt: skip
    scored = cv.summary(per_house, 0.510)
    assert scored["top1"] == pytest.approx(0.4)
    assert scored["top1_pooled"] == pytest.approx((0.2 * 30 + 0.6 * 10) / 40)
    none = {**per_house, "room1ldk4": _variant_house(0.6, 0.5, 7, top1=float("nan"), words=0)}
    assert cv.summary(none, 0.510)["top1_pooled"] == pytest.approx(scored["top1_pooled"])


def test_coarse_variants_scores_held_out_words_as_real_houses_does(script):
    """coarse_variants.py's held-out scores of ``coarse`` are real_houses.py's at the same fit
    seed (one fold loop, ``real_houses.heldout_fold_scores``, where it had a copy)."""
    from spcopyro.synthetic import make_house

    cv, rh = script("coarse_variants"), script("real_houses")
    house = make_house(seed=0)
    ours = cv.heldout_scores(house, "coarse", 3, 0)
    theirs = rh.heldout_top1(house, 3, seeds=[0], presets=("coarse",))["coarse"]["seeds"]["0"]
    assert ours == theirs and ours["words"] > 0


def test_coarse_variants_ari_bar_is_the_nearest_utterances_public_mean(script, dataset_root):
    """The ARI target's bar is measured as real_houses.py scores (E) nearest utterance, over
    the five public houses: docs/real_houses.md's 0.510 (the script kept its own 0.510)."""
    from spcopyro.data import load_house

    cv = script("coarse_variants")
    houses = {h: load_house(dataset_root / h) for h in cv.PUBLIC_CATEGORIES}
    truths = {h: cv.public_truth(house).labels for h, house in houses.items()}
    bar = cv.nearest_ari(houses, truths)
    assert f"{bar:.3f}" == "0.510"


def test_coarse_variants_fits_held_out_words_with_real_houses_preset_model(script, monkeypatch):
    """A variant's held-out model is ``real_houses.preset_model`` of its preset and overrides
    (not a lambda of the script's own around the same fit)."""
    from spcopyro.synthetic import make_house

    cv, rh = script("coarse_variants"), script("real_houses")
    calls = []

    def preset_model(*args, **overrides):
        calls.append((args, overrides))
        return lambda train: rh.nearest_word_map(train.grid, train.observations)

    monkeypatch.setattr(rh, "preset_model", preset_model)
    assert cv.heldout_scores(make_house(seed=0), "footprint 0.5 m", 3, 0)["words"] > 0
    assert calls == [(("coarse", 3, 0), {"footprint_reach_share": 0.0, "footprint_radius": 0.5})]


def _stub_coarse_variants(cv, monkeypatch, dataset_root) -> dict[str, list]:
    """Stubs coarse_variants.py's loading, truths, fits and ARI bar; name -> what each was
    called with."""
    seen: dict[str, list] = {"load": [], "truth": [], "nearest": []}
    monkeypatch.setenv("SPCOPYRO_DATA", str(dataset_root))
    monkeypatch.setattr(cv, "load_house", lambda path: seen["load"].append(path.name) or path.name)

    def public_truth(house):
        seen["truth"].append(house)
        return argparse.Namespace(labels=house)

    def nearest_ari(houses, truths):
        seen["nearest"].append((list(houses), list(truths.values())))
        return 0.5

    monkeypatch.setattr(cv, "public_truth", public_truth)
    monkeypatch.setattr(cv, "nearest_ari", nearest_ari)
    public = {"ari": 0.6, "largest_share": 0.5, "concepts_1pct": 6, "refined": False}
    monkeypatch.setattr(cv, "public_scores", lambda house, truth, *_: dict(public))
    held = {"all folds": 0.3, "top 3": 0.6, "mean rank": 3.0, "words": 10}
    monkeypatch.setattr(cv, "heldout_scores", lambda house, *_: dict(held))
    return seen


def test_coarse_variants_rerun_on_a_finished_json_loads_no_house(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """The ARI bar (all five public houses, their truths and nearest-word maps: ~6 s) is
    measured when a summary is first judged, not before the resume check: a rerun on a finished
    JSON loads no house and fits nothing; the first run loads each house once and judges with
    the five houses' bar (--quick too, one house fitted)."""
    cv = script("coarse_variants")
    seen = _stub_coarse_variants(cv, monkeypatch, dataset_root)
    out = tmp_path / "cv.json"
    assert cv.main(["--quick", "--out", str(out)]) == 0
    five = list(cv.PUBLIC_CATEGORIES)
    assert seen["load"] == ["room1dk5", *five[1:]] and seen["truth"] == seen["load"]
    assert seen["nearest"] == [(five, five)]  # once, for both variants
    first, printed = out.read_text(), capsys.readouterr().out
    assert "| coarse (seed 0) |" in printed and "| footprint 0.5 m (seed 0) |" in printed
    for calls in seen.values():
        calls.clear()
    assert cv.main(["--quick", "--out", str(out)]) == 0
    assert seen == {"load": [], "truth": [], "nearest": []}
    assert out.read_text() == first and capsys.readouterr().out == printed


def test_coarse_variants_synthetic_scores_the_houses_not_tuned_on(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """Issue 21: before a variant could become the default it must pass on the houses it was
    not tuned on, as real_houses.py checks the default. --synthetic fits each variant through
    real_houses.fit_preset (its preset and overrides; stubbed here: the truth for ``coarse``,
    one concept for ``footprint 0.5 m``) on real_houses.py's synthetic houses (house seed S at
    fit seed S + f) and, through real_houses.simulated_on, on simulate --map of a public map;
    its results go under "synthetic" of the variant and seed, the public results beside them
    untouched; a rerun fits nothing; the table judges every target PASS or FAIL."""
    import numpy as np

    from spcopyro.data import load_house

    cv, rh = script("coarse_variants"), script("real_houses")
    out = tmp_path / "cv.json"
    _stub_coarse_variants(cv, monkeypatch, dataset_root)
    assert cv.main(["--quick", "--out", str(out)]) == 0  # the public results first
    public = json.loads(out.read_text())
    capsys.readouterr()
    monkeypatch.setattr(cv, "load_house", load_house)
    calls = []

    def fit_preset(house, name, sweeps, seed, **overrides):
        calls.append((house.name, name, sweeps, seed, overrides))
        return (np.zeros_like(house.truth) if overrides else house.truth), 0.0

    monkeypatch.setattr(rh, "fit_preset", fit_preset)
    built = _count_calls(monkeypatch, rh, "baseline_scores", "map_simulation")
    argv = ["--quick", "--synthetic", "--open-plan-seeds", "2", "--seeds", "1", "--out", str(out)]
    assert cv.main(argv) == 0
    kinds = [("synthetic", 1), ("synthetic", 2), ("synthetic", 1), ("synthetic", 1),
             ("room1dk5", 1)]  # open-plan seeds 0 and 1, sparse, dense; simulate --map  # fmt: skip
    assert calls == [(h, "coarse", 20, seed, {}) for h, seed in kinds] + [
        (h, "coarse", 20, seed, {"footprint_reach_share": 0.0, "footprint_radius": 0.5})
        for h, seed in kinds
    ]
    results = json.loads(out.read_text())
    houses = ["open-plan seed 0", "open-plan seed 1", "sparse seed 0", "dense seed 0"]
    # the baselines and the simulation draw nothing: once a house and a map, not a variant
    assert built == {"baseline_scores": houses, "map_simulation": ["room1dk5"]}
    baselines = results.pop("synthetic_baselines")
    assert list(baselines) == houses and rh.ORACLE in baselines["open-plan seed 0"]
    for name, seeds in results["variants"].items():
        record = seeds.pop("seed 1")["synthetic"]
        assert all(list(row) == ["variant"] for k, row in record["houses"].items()
                   if not k.startswith("simulated "))  # fmt: skip
        assert list(record["houses"]) == ["open-plan seed 0", "open-plan seed 1", "sparse seed 0",
                                          "dense seed 0", "simulated room1dk5"]  # fmt: skip
        summary = record["summary"]
        assert summary["open-plan"]["houses"] == 2 and summary["dense"]["houses"] == 1
        assert summary["dense"]["ari"] == (1.0 if name == "coarse" else 0.0)
        assert summary["simulated"] == {"room1dk5": 1.0 if name == "coarse" else 0.0}
        assert 0.0 < summary["open-plan"]["F"] < summary["open-plan"]["oracle"] <= 1.0
    assert results == public  # the public results and their keys as they were
    printed = capsys.readouterr().out
    rows = {line.split(" | ")[0]: line for line in printed.splitlines() if line.startswith("| ")}
    assert rows["| coarse (1)"].count("PASS") == 4 and "FAIL" not in rows["| coarse (1)"]
    assert rows["| footprint 0.5 m (1)"].count("FAIL") == 4
    assert "room1dk5 1.00" in rows["| coarse (1)"] and "| 1.000 (2) |" in rows["| coarse (1)"]
    calls.clear()
    first = out.read_text()
    assert cv.main(argv) == 0  # finished: skipped
    assert calls == [] and out.read_text() == first and capsys.readouterr().out == printed
    assert len(built["baseline_scores"]) == 4


def _count_calls(monkeypatch, module, *names: str) -> dict[str, list]:
    """Wraps ``module``'s functions ``names`` (a house first): name -> the key of each call's
    house (its name, or ``"KIND seed S"`` of a synthetic house made by ``synthetic_house``)."""
    seen: dict[str, list] = {name: [] for name in names}
    keys: dict[int, str] = {}
    synthetic_house = module.synthetic_house

    def made(kind, seed):
        house = synthetic_house(kind, seed)
        keys[id(house)] = f"{kind} seed {seed}"
        return house

    monkeypatch.setattr(module, "synthetic_house", made)
    for name in names:
        wrapped = getattr(module, name)

        def counted(house, *args, _name=name, _wrapped=wrapped, **kwargs):
            seen[_name].append(keys.get(id(house), house.name))
            return _wrapped(house, *args, **kwargs)

        monkeypatch.setattr(module, name, counted)
    return seen


def test_coarse_variants_synthetic_reads_a_json_with_the_baselines_in_every_entry(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """A JSON written before the baselines had their own slot kept each synthetic house's
    baselines and oracle beside the variant's row of every variant and seed: --synthetic takes
    them from there (computing only a house's missing), resumes, and prints the same table as
    from the new layout."""
    import numpy as np

    from spcopyro.data import load_house

    cv, rh = script("coarse_variants"), script("real_houses")
    _stub_coarse_variants(cv, monkeypatch, dataset_root)
    monkeypatch.setattr(cv, "load_house", load_house)
    monkeypatch.setattr(rh, "fit_preset", lambda house, name, sweeps, seed, **overrides: (
        np.zeros_like(house.truth) if overrides else house.truth, 0.0))  # fmt: skip
    new, old = tmp_path / "new.json", tmp_path / "old.json"
    argv = ["--quick", "--synthetic", "--open-plan-seeds", "2", "--seeds", "1", "--out"]
    assert cv.main([*argv, str(new)]) == 0
    printed = capsys.readouterr().out.replace(str(new), "OUT")
    report = json.loads(new.read_text())
    baselines = report.pop("synthetic_baselines")
    for seeds in report["variants"].values():  # the earlier layout
        for key, row in seeds["seed 1"]["synthetic"]["houses"].items():
            row |= baselines.get(key, {})
    records = [seeds["seed 1"]["synthetic"] for seeds in report["variants"].values()]
    del records[1]["summary"], records[1]["houses"]["sparse seed 0"]  # cut short: resumed
    del records[0]["houses"]["open-plan seed 1"][rh.ORACLE]  # not its slot: read from the other
    old.write_text(json.dumps(report, indent=1))
    built = _count_calls(monkeypatch, rh, "baseline_scores", "map_simulation")
    assert cv.main([*argv, str(old)]) == 0
    assert capsys.readouterr().out.replace(str(old), "OUT") == printed
    assert built == {"baseline_scores": [], "map_simulation": []}  # all were in the JSON
    assert json.loads(old.read_text())["synthetic_baselines"] == baselines
    report = json.loads(old.read_text())
    del report["synthetic_baselines"]
    for seeds in report["variants"].values():  # only the baselines: a house's slot computed
        seeds["seed 1"]["synthetic"].pop("summary")
        for row in seeds["seed 1"]["synthetic"]["houses"].values():
            row.pop(rh.ORACLE, None)
    old.write_text(json.dumps(report, indent=1))
    assert cv.main([*argv, str(old)]) == 0
    assert capsys.readouterr().out.replace(str(old), "OUT") == printed
    assert sorted(built["baseline_scores"]) == sorted(baselines)
    assert json.loads(old.read_text())["synthetic_baselines"] == baselines


def test_coarse_variants_synthetic_kinds_add_houses_and_stage_two_patches_the_refinement(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """--kinds fits only those kinds of house; a later run with other kinds adds them to the
    same variant and seed (the summary over every house it has, a kind without houses shown
    as '-'). A variant's STAGE_TWO settings are the refinement's own for its fits only
    (refine.refined_settings patched while it fits, restored after)."""
    import numpy as np

    from spcopyro.data import load_house
    from spcopyro.fit import refine

    cv, rh = script("coarse_variants"), script("real_houses")
    _stub_coarse_variants(cv, monkeypatch, dataset_root)
    monkeypatch.setattr(cv, "load_house", load_house)
    original = refine.refined_settings
    calls = []

    def fit_preset(house, name, sweeps, seed, **overrides):
        stage_two = refine.refined_settings(rh.settings_of("coarse", **overrides), 1, 4)
        calls.append((name, overrides, stage_two.data.footprint_reach_share))
        return house.truth, 0.0

    monkeypatch.setattr(rh, "fit_preset", fit_preset)
    out = tmp_path / "cv.json"
    variants = ["--variants", "reach 0.25, stage two too", "reach 0.5, --refine never"]
    argv = ["--quick", "--synthetic", "--open-plan-seeds", "2", "--seeds", "1", *variants,
            "--out", str(out)]  # fmt: skip
    assert cv.main([*argv, "--kinds", "open-plan"]) == 0
    uncut = {"footprint_reach_door_width": None}  # UNCUT: set by real_houses.settings_of
    assert calls == [("coarse", {"footprint_reach_share": 0.25, **uncut}, 0.25)] * 2 + [
        (rh.UNREFINED, {"footprint_reach_share": 0.5, **uncut}, 0.0)] * 2  # fmt: skip
    assert refine.refined_settings is original
    record = json.loads(out.read_text())["variants"]["reach 0.25, stage two too"]["seed 1"]
    assert list(record["synthetic"]["houses"]) == ["open-plan seed 0", "open-plan seed 1"]
    assert list(record["synthetic"]["summary"]) == ["open-plan", "simulated"]
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| reach")]
    assert len(rows) == 2 and all("| - | - |" in row and "PASS" in row for row in rows)
    calls.clear()
    assert cv.main([*argv, "--kinds", "dense"]) == 0
    assert [c[0] for c in calls] == ["coarse", rh.UNREFINED]  # dense seed 0 alone
    summary = json.loads(out.read_text())["variants"]["reach 0.25, stage two too"]["seed 1"][
        "synthetic"]["summary"]  # fmt: skip
    assert summary["open-plan"]["houses"] == 2 and summary["dense"]["ari"] == 1.0
    assert np.isclose(summary["open-plan"]["ari"], 1.0)
    with pytest.raises(SystemExit):
        cv.main(["--quick", "--kinds", "dense", "--out", str(out)])  # only with --synthetic


def test_coarse_variants_keep_what_their_stored_results_measured(script):
    """Since 86d6df4 ``coarse`` carries a reach share of 0.2 in rooms (1 m doors). Every variant
    measured before it, on ``coarse`` with share 0, resolves (through the script's own
    ``variant_settings``) to share 0 and no door cut, the reach shares without "in rooms" to
    their share and radius without a door cut; ``reach 0.2 in rooms`` and ``coarse`` to the
    current preset's preparation, ``coarse before the reach share`` to share 0. Every variant
    is listed here: one added must say what it means."""
    from spcopyro.config import preset

    cvs = script("coarse_variant_settings")
    now, before = preset("coarse").data, preset("coarse", footprint_reach_share=0.0).data
    assert (now.footprint_reach_share, now.footprint_reach_door_width) == (0.2, 1.0)
    current = ["coarse", "coarse, --refine never", "reach 0.2 in rooms"]
    in_rooms = {"reach 0.25 in rooms": 0.25, "reach 0.25 in rooms, stage two too": 0.25,
                "reach 0.2 in rooms, stage two too": 0.2}  # fmt: skip
    reach = {"reach 0.25": (0.25, None), "reach 0.5": (0.5, None),
             "reach 0.25, --refine never": (0.25, None), "reach 0.5, --refine never": (0.5, None),
             "reach 0.25, stage two too": (0.25, None), "reach 0.1": (0.1, None),
             "reach 0.1, --refine never": (0.1, None), "reach 0.2": (0.2, None),
             "reach 0.25 within 2 m": (0.25, 2.0),
             "reach 0.25 within 3 m": (0.25, 3.0)}  # fmt: skip
    old = [n for n in cvs.VARIANTS if n not in [*current, *in_rooms, *reach]]
    assert len(old) == 18 and "coarse before the reach share" in old and "paper-dp" in old
    for name in old:
        data = cvs.variant_settings(name).data
        assert (data.footprint_reach_share, data.footprint_reach_door_width) == (0.0, None), name
    assert cvs.variant_settings("coarse before the reach share").data == before
    for name, (share, radius) in reach.items():
        data = cvs.variant_settings(name).data
        cut = (data.footprint_reach_share, data.footprint_reach_radius)
        assert (*cut, data.footprint_reach_door_width) == (share, radius, None), name
    for name, share in in_rooms.items():
        data = cvs.variant_settings(name).data
        assert (data.footprint_reach_share, data.footprint_reach_door_width) == (share, 1.0)
    for name in current:
        assert cvs.variant_settings(name).data == now, name
    assert cvs.variant_settings("reach 0.2 in rooms").model == preset("coarse").model
    assert cvs.preparation("reach 0.2 in rooms, stage two too")["stage two"] == {
        "footprint_reach_share": 0.2, "footprint_reach_door_width": 1.0}  # fmt: skip


def test_coarse_variants_fit_with_the_settings_they_record(script, monkeypatch):
    """The settings a variant's fits get (public and held-out, through real_houses.fit_result:
    fit_house stubbed) are ``variant_settings``' (what its records store), and a None override
    (:data:`UNCUT`: no door cut) reaches the fit though ``preset`` ignores None: the reach
    shares without "in rooms" are fitted with no door width, literally (fails where fit_result
    builds its settings with ``preset`` alone, dropping the None)."""
    from spcopyro.synthetic import make_house

    cv, rh = script("coarse_variants"), script("real_houses")
    cvs = script("coarse_variant_settings")
    house, fitted, doors = make_house(seed=0), [], {}

    class Fitted(Exception):
        pass

    def fit_house(house, settings, **kwargs):
        fitted.append((settings, kwargs.get("refine")))
        raise Fitted

    monkeypatch.setattr(rh, "fit_house", fit_house)
    for name in cvs.VARIANTS:
        for call in (cv.public_scores, cv.heldout_scores):
            fitted.clear()
            with pytest.raises(Fitted):
                call(house, *([house.truth] if call is cv.public_scores else []), name, 3, 0)
            settings, refine = fitted[0]
            want = cvs.variant_settings(name)
            assert (settings.data, settings.model) == (want.data, want.model), name
            assert refine == "never" or not name.endswith("--refine never"), name
            doors[name] = (settings.data.footprint_reach_share,
                           settings.data.footprint_reach_door_width)  # fmt: skip
    assert doors["coarse"] == doors["coarse, --refine never"] == (0.2, 1.0)
    assert doors["reach 0.25"] == doors["reach 0.25, stage two too"] == (0.25, None)
    assert doors["reach 0.5, --refine never"] == (0.5, None)
    assert doors["reach 0.2"] == (0.2, None) and doors["reach 0.25 in rooms"] == (0.25, 1.0)
    recorded = cvs.preparation("reach 0.25, stage two too")
    assert recorded["footprint_reach_door_width"] is None and recorded["stage two"] == {
        "footprint_reach_share": 0.25}  # fmt: skip


def test_coarse_variants_refuse_to_resume_a_record_prepared_otherwise(
    script, monkeypatch, dataset_root, tmp_path, capsys
):
    """Each new record stores its data preparation; a resume refuses, before fitting, a record
    whose stored preparation differs from what the variant now resolves to (here: the variant
    defined as before 86d6df4's default changed, which then silently inherited the reach
    share), naming the variant, seed, field and both values. A record without one (older) is
    trusted."""
    from spcopyro.data import load_house

    cv, rh = script("coarse_variants"), script("real_houses")
    cvs = script("coarse_variant_settings")
    _stub_coarse_variants(cv, monkeypatch, dataset_root)
    out = tmp_path / "cv.json"
    assert cv.main(["--quick", "--out", str(out)]) == 0
    monkeypatch.setattr(cv, "load_house", load_house)
    monkeypatch.setattr(rh, "fit_preset", lambda house, *_, **__: (house.truth, 0.0))
    argv = ["--quick", "--synthetic", "--kinds", "dense", "--out", str(out)]
    assert cv.main(argv) == 0
    report = json.loads(out.read_text())
    for name, seeds in report["variants"].items():
        row = seeds["seed 0"]
        assert row["preparation"] == row["synthetic"]["preparation"] == cvs.preparation(name)
    assert report["variants"]["coarse"]["seed 0"]["preparation"]["footprint_reach_share"] == 0.2
    first = out.read_text()
    capsys.readouterr()
    fits = []
    monkeypatch.setattr(cv, "public_scores", lambda *args: fits.append(args))
    monkeypatch.setattr(rh, "fit_preset", lambda *args, **kwargs: fits.append(args))
    changed = {**cvs.VARIANTS, "footprint 0.5 m": ("coarse", {"footprint_radius": 0.5})}
    monkeypatch.setattr(cvs, "VARIANTS", changed)  # as it was: now with the reach share
    for run in (["--quick", "--variants", "coarse", "--out", str(out)], argv):
        with pytest.raises(SystemExit) as refused:
            cv.main(run)
        assert refused.value.code == 2
        message = capsys.readouterr().err.strip().splitlines()[-1]
        assert message.endswith(
            f"error: {out}: 'footprint 0.5 m' seed 0's public results were fitted with "
            "footprint_reach_share = 0.0, the variant now resolves to 0.2; give another --out, "
            "or rename the variant's entry in the JSON to what it measured"
        )
    assert fits == [] and out.read_text() == first
    for row in report["variants"]["footprint 0.5 m"].values():  # an older JSON: none recorded
        del row["preparation"], row["synthetic"]["preparation"]
    out.write_text(json.dumps(report, indent=1))
    assert cv.main(argv) == 0 and fits == []  # trusted, as before; nothing refitted
    synthetic = report["variants"]["coarse"]["seed 0"]["synthetic"]
    synthetic["preparation"]["footprint_reach_door_width"] = None
    out.write_text(json.dumps(report, indent=1))
    with pytest.raises(SystemExit):
        cv.main(argv)
    message = capsys.readouterr().err.strip().splitlines()[-1]
    assert (
        "'coarse' seed 0's synthetic results were fitted with footprint_reach_door_width = "
        "None, the variant now resolves to 1.0;" in message
    )
    assert fits == []
