"""Study files (issue 26) as read: the spec from TOML and from Python, each bad key or
value named with its file and table, quoted numbers, the methods' grid and sweeps, and
what reaches the cells and their keys (seeds, observations_off, hyper.*, C-spcoa's options,
ari_every). The shipped study parses.
"""

from __future__ import annotations

import json
import re

import pytest
from study_setup import TINY, TINY_DICT, _write

from spcopyro.cli.study import study_path
from spcopyro.study import STUDIES
from spcopyro.study.cells import cells_of
from spcopyro.study.spec import StudyError, load_study, study_from_dict

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]


def test_spec_from_toml_equals_spec_from_python(tmp_path):
    from_file = load_study(_write(tmp_path))
    from_python = study_from_dict(TINY_DICT)
    assert from_file == from_python
    assert [v.name for v in from_file.variants] == ["og3", "dp"]
    assert from_file.seeds == (0, 1) and from_file.sweeps_for("gibbs") == 8
    assert len(cells_of(from_file)) == 2 * (2 + 1)  # seeds x (variants + baseline)


@pytest.mark.parametrize(
    "old, new, words",
    [
        (
            "num_rooms = 2",
            "num_roms = 2",
            ["[data.small] num_roms", "2", "HouseSpec has no", "; did you mean num_rooms?"],
        ),
        ("seeds = 2", "seeds = -1", ["[study] seeds", "-1"]),
        ("sweeps = 8", "sweeps = { gibs = 8 }", ["sweeps.gibs", "8", "unknown method"]),
        ('baselines = ["F-geometry"]', 'baselines = ["G-nothing"]', ["baselines", "G-nothing"]),
        # the known keys, and a suggestion as for an unknown study name (it had none)
        (
            "gamma = 3.0",
            "gama = 3.0",
            ["[variants.og3]", "gama", "unknown key", "'gamma', ", "; did you mean gamma?"],
        ),
        ("gamma = 3.0", 'gamma = "hot"', ["[variants.og3]", "gamma", "hot"]),
        ('synthetic = "default"', 'synthetic = "castle"', ["[data.small] synthetic", "castle"]),
        ("seeds = 2", "seedz = 2", ["[study] seedz", "unknown key", "; did you mean seeds?"]),
        # a misspelt prefix is suggested as a misspelt key is (it got no suggestion)
        ("gamma = 3.0", "setings.gamma = 3.0", ["setings.gamma", "did you mean settings.gamma?"]),
        (
            "gamma = 3.0",
            "option = { cluster_moves = 0.2 }",
            ["option.cluster_moves", "did you mean options.cluster_moves?"],
        ),
        ("seeds = 2", "seeds = [", ["not valid TOML"]),
        ("heldout = true", "heldout = true\nseeds = 0", ["[data.small] seeds", "0"]),
        ("seeds = 2", "seeds = 2\nobservations_off = 1", ["[study] observations_off", "1"]),
        # a number in quotes is TOML text: the message says how to write it (1_000 unquoted)
        (
            "sweeps = 8",
            'sweeps = "1_000"',
            ["[study] sweeps = '1_000'", "write 1_000 without the quotes"],
        ),
        ("seeds = 2", 'seeds = "2"', ["[study] seeds = '2'", "write 2 without the quotes"]),
        # a public house is loaded, not drawn: its seed changed nothing, silently
        (
            'synthetic = "default"\nheight = 24\nwidth = 30\nnum_rooms = 2\nnum_trials = 2\n'
            "min_room_size = 8",
            'public = "room1dk5"\nseed = 1',
            ["[data.small] seed = 1", "a public house is loaded, not drawn"],
        ),
        # one source's maps figure was drawn over the other's
        (
            "[data.small]",
            '[data."big house"]\nsynthetic = "default"\n[data.big_house]',
            ["[data.big_house] = 'big_house'", "maps_big_house.png is also [data.big house]'s"],
        ),
        # each of their cells failed at run time
        ("[data.small]", '[data."small/house"]', ["[data.small/house] = 'small/house'", "no '/'"]),
        (
            "num_trials = 2",
            "num_trials = 1",
            ["[data.small] heldout", "a held-out source needs num_trials >= 2, it has 1"],
        ),
        (
            "gamma = 3.0",
            'gamma = 3.0\npoint_estimate = "binder"',
            ["[variants.og3]", "point_estimate='binder'", "needs marginal_samples > 0"],
        ),
        # a trace keeps no ARI in a fit shorter than ari_every (it was ignored, silently)
        ("sweeps = 8", "sweeps = 8\nari_every = 10", ["[study] ari_every = 10", "gibbs for 8"]),
        # a prior of a hyperparameter the chain does not sample changed nothing, silently
        (
            "gamma = 3.0",
            "gamma = 3.0\nhyper = { log_gamma_sd = 2.0 }",
            ["[variants.og3]", "hyper.log_gamma_sd=2.0", "no hyperparameter the chain samples"],
        ),
        (
            "gamma = 3.0",
            'gamma = 3.0\nhyper.alpha = true\n"hyper.gamma_step" = 1.0',
            ["[variants.og3]", "hyper.gamma_step=1.0", "no hyperparameter the chain samples"],
        ),
    ],
)
def test_bad_spec_names_file_key_and_value(tmp_path, old, new, words):
    path = _write(tmp_path, TINY.replace(old, new), name="bad.toml")
    with pytest.raises(StudyError) as caught:
        load_study(path)
    message = str(caught.value)
    assert str(path) in message
    for word in words:
        assert word in message, message


def test_fit_keywords_a_studys_method_or_scoring_cannot_take_are_refused_when_read():
    """Each cell of these failed at run time (fit_house's or the comparison's own checks)."""
    values = json.loads(json.dumps(TINY_DICT))
    values["variants"]["og3"].update(point_estimate="binder", marginal_samples=5)
    study_from_dict(values)  # Gibbs keeps the label maps binder needs ...
    values["study"]["methods"] = ["gibbs", "cavi"]  # ... CAVI does not
    with pytest.raises(StudyError, match=r"\[variants.og3\].*method 'cavi'"):
        study_from_dict(values)
    values = json.loads(json.dumps(TINY_DICT))
    values["variants"]["og3"]["init"] = "rooms"
    values["study"].update(scoring="comparison", baselines=[])
    with pytest.raises(StudyError, match="variant 'og3' sets fit_house keywords .'init': 'rooms'"):
        study_from_dict(values)


def test_hyper_options_of_a_study_reach_its_cells(tmp_path):
    """``hyper.*`` of a variant (nested or dotted) set the Gibbs chain's hyperparameter
    sampling of its cells, and are in their keys."""
    text = TINY.replace("gamma = 3.0", 'gamma = 3.0\nhyper.gamma = "exchange"\n'
                        '"hyper.log_gamma_sd" = 2.0\nhyper.alpha = true')  # fmt: skip
    study = load_study(_write(tmp_path, text, name="hyper.toml"))
    cells = {c.row: c for c in cells_of(study) if c.seed == 0}
    hyper = cells["og3"].variant.method_options().hyper
    assert (hyper.gamma, hyper.log_gamma_sd, hyper.alpha) == ("exchange", 2.0, True)
    assert not cells["dp"].variant.method_options().hyper.active
    plain = {c.row: c for c in cells_of(load_study(_write(tmp_path))) if c.seed == 0}
    assert cells["og3"].key != plain["og3"].key and cells["dp"].key == plain["dp"].key


@pytest.mark.parametrize(
    "line, words",
    [
        ('categories = "kitchen"', "categories = 'kitchen': expected a list of category names"),
        ('door_width = "wide"', "door_width = 'wide': expected 'auto' or metres > 0"),
        ("num_trials = 0", "num_trials = 0: expected an integer >= 1"),
        (
            'num_trials = "3"',
            "num_trials = '3': expected an integer >= 1 (a number in quotes is text: write 3 "
            "without the quotes)",
        ),
        ("sentence_fraction = 2.0", "sentence_fraction = 2.0: expected a share in [0, 1]"),
    ],
)
def test_a_map_tours_values_are_checked_when_read(line, words):
    """MapTour checks none of its values: each cell failed at run time, or (``categories =
    "kitchen"``) simulated a house of the categories k, i, t, c, h, e, n."""
    text = f'[variants.a]\n[data.tour]\nmap = "room1dk5"\n{line}\n'
    with pytest.raises(StudyError, match=re.escape(f"t.toml: [data.tour] {words}")):
        study_from_dict(tomllib.loads(text), source="t.toml")
    fine = study_from_dict(tomllib.loads(text.replace(line, 'categories = ["kitchen", "bath"]')))
    assert fine.data[0].map_tour().categories == ("kitchen", "bath")


@pytest.mark.parametrize(
    "line, said",
    [
        ('num_trials = "3"', "num_trials = '3': expected an integer >= 1 (a number in quotes is "
         "text: write 3 without the quotes)"),
        # no hint where the unquoted number would fail too: a count is an integer
        ('num_trials = "2.5"', "num_trials = '2.5': expected an integer >= 1"),
        ('images_per_room = "1e3"', "images_per_room = '1e3': expected an integer >= 1"),
        ('utterances_per_room = "inf"', "utterances_per_room = 'inf': expected an integer >= 0"),
        # a share or metres may be a decimal, not an infinity
        ('sentence_fraction = "0.5"', "sentence_fraction = '0.5': expected a share in [0, 1] (a "
         "number in quotes is text: write 0.5 without the quotes)"),
        ('min_room_area = "inf"', "min_room_area = 'inf': expected square metres > 0"),
        # nor where the number is of the right kind but out of the field's range
        ('num_trials = "0"', "num_trials = '0': expected an integer >= 1"),
        ('images_per_room = "-2"', "images_per_room = '-2': expected an integer >= 1"),
        ('door_width = "-1"', "door_width = '-1': expected 'auto' or metres > 0"),
        ('sentence_fraction = "2"', "sentence_fraction = '2': expected a share in [0, 1]"),
        ('door_width = "0.9"', "door_width = '0.9': expected 'auto' or metres > 0 (a number in "
         "quotes is text: write 0.9 without the quotes)"),
    ],
)  # fmt: skip
def test_a_quoted_number_is_hinted_only_where_it_would_pass_unquoted(line, said):
    """A count written "2.5" was told to write 2.5 without the quotes, which then still failed: the
    hint checked float(), not what the field wants; "0" for a count >= 1 or "2" for a share was
    told so too (the hint checked the kind of number, not the field's own check)."""
    text = f'[variants.a]\n[data.tour]\nmap = "room1dk5"\n{line}\n'
    with pytest.raises(StudyError) as error:
        study_from_dict(tomllib.loads(text), source="t.toml")
    assert str(error.value) == f"t.toml: [data.tour] {said}"


@pytest.mark.parametrize(
    "table, line, said",
    [
        ("study", 'sweeps = "0"', "[study] sweeps = '0': expected an integer >= 1"),
        ("study", 'seeds = "0"', "[study] seeds = '0': expected a count >= 1 or a list of seeds "
         ">= 0"),
        ("data.s", 'seed = "-1"', "[data.s] seed = '-1': expected an integer >= 0"),
        # where the unquoted number would pass, the hint stays (a seed may be 0)
        ("data.s", 'seed = "0"', "[data.s] seed = '0': expected an integer >= 0 (a number in "
         "quotes is text: write 0 without the quotes)"),
        ("study", 'sweeps = "8"', "[study] sweeps = '8': expected an integer >= 1 (a number in "
         "quotes is text: write 8 without the quotes)"),
    ],
)  # fmt: skip
def test_a_quoted_count_out_of_range_gets_no_hint_to_unquote_it(table, line, said):
    """``sweeps = "0"`` was told to write 0 without the quotes, which is refused too: the hint
    checked only that the text was an integer, not the field's minimum."""
    tables = {"study": "", "data.s": 'synthetic = "default"\n'}
    tables[table] += line + "\n"
    text = f"[study]\n{tables['study']}[variants.a]\n[data.s]\n{tables['data.s']}"
    with pytest.raises(StudyError) as error:
        study_from_dict(tomllib.loads(text), source="t.toml")
    assert str(error.value) == f"t.toml: {said}"


def test_python_spec_errors_and_method_grid():
    with pytest.raises(StudyError, match="<python>: \\[data\\]"):
        study_from_dict({"variants": {"a": {}}})
    values = json.loads(json.dumps(TINY_DICT))
    values["study"]["methods"] = ["gibbs", "cavi"]
    study = study_from_dict(values)
    assert [c.method for c in cells_of(study)][:4] == ["gibbs", "cavi", "gibbs", "cavi"]
    values["study"]["sweeps"] = {"og3": 7, "cavi": 3, "*": 5}  # variant, then method, then *
    study = study_from_dict(values)
    assert [(c.row, c.method, c.sweeps) for c in cells_of(study)][:4] == [
        ("og3", "gibbs", 7), ("og3", "cavi", 7), ("dp", "gibbs", 5), ("dp", "cavi", 3)
    ]  # fmt: skip
    values["study"]["sweeps"] = {"og4": 7}
    with pytest.raises(StudyError, match="sweeps.og4.*unknown method or variant"):
        study_from_dict(values)
    values["study"]["sweeps"] = 5
    values["variants"]["og3"]["method"] = "lbp"
    with pytest.raises(StudyError, match="variants.og3. method"):
        study_from_dict(values)


def test_source_seeds_and_observations_off_reach_the_cells():
    """A source's own seeds replace the study's; observations_off changes the variants' keys
    (and only theirs), so earlier cells of a study without it keep theirs."""
    values = json.loads(json.dumps(TINY_DICT))
    plain = {c.key for c in cells_of(study_from_dict(values))}
    values["data"]["small"]["seeds"] = [3]
    values["data"]["other"] = {"synthetic": "scaled", "height": 24, "width": 30, "seeds": 1}
    cells = cells_of(study_from_dict(values))
    assert [(c.data.name, c.seed) for c in cells] == [("small", 3)] * 3 + [("other", 0)] * 3
    values = json.loads(json.dumps(TINY_DICT))
    values["study"]["observations_off"] = True
    off = cells_of(study_from_dict(values))
    assert [c.observations_off for c in off] == [True, True, False] * 2
    assert {c.key for c in off} & plain == {c.key for c in off if c.variant is None}


def test_a_spcoa_cell_key_holds_the_options_its_fit_is_given(monkeypatch):
    """C-spcoa's key held its word weighting as a special case, and not its L (a constant
    _fit_spcoa passed beside it): a change of L would have reused the cached cells. Its key now
    holds the one options dict (experiments.methods.SPCOA_OPTIONS) the row's fit passes
    fit_spcoa, which this reads back from the fit itself."""
    from spcopyro.experiments import methods
    from spcopyro.study import cells as study_cells
    from spcopyro.synthetic import HouseSpec, make_house

    given: dict[str, object] = {}

    class Given(Exception):
        pass

    def fit_spcoa(house, **keywords):
        given.update(keywords)
        raise Given

    values = json.loads(json.dumps(TINY_DICT))
    values["study"]["baselines"] = ["C-spcoa", "F-geometry"]
    cells = [c for c in cells_of(study_from_dict(values)) if c.row == "C-spcoa"]
    assert [c.seed for c in cells] == [0, 1]
    inputs = study_cells._cell_inputs(cells[1], "digest")
    monkeypatch.setattr(methods, "fit_spcoa", fit_spcoa)
    house = make_house(seed=0, spec=HouseSpec(height=40, width=50, num_rooms=3))
    run = methods.RunSettings(spcoa_iterations=cells[1].spcoa_iterations)
    with pytest.raises(Given):
        methods.fit_method("C-spcoa", house, run, seed=cells[1].seed)
    assert given.pop("iterations") == inputs["spcoa_iterations"]
    assert given.pop("seed") == inputs["seed"] == 1
    assert given == inputs["spcoa_options"]
    assert {"num_concepts", "word_weighting", "alpha", "pair_distance"} <= set(given)
    # a change of an option changes the C-spcoa cells' keys and no other
    keys = {(c.row, c.seed): c.key for c in cells_of(study_from_dict(values))}
    changed = {**methods.SPCOA_OPTIONS, "num_concepts": 10}
    monkeypatch.setattr(study_cells, "SPCOA_OPTIONS", changed)
    after = {(c.row, c.seed): c.key for c in cells_of(study_from_dict(values))}
    assert {cell for cell in keys if keys[cell] != after[cell]} == {("C-spcoa", 0), ("C-spcoa", 1)}


def test_shipped_study_parses():
    path = study_path("ablation_small")
    assert path.parent == STUDIES
    study = load_study(path)
    assert len(cells_of(study)) == 16


@pytest.mark.parametrize(
    "extra, words",
    [
        ('scoring = "comparison"\nari_every = 2', ["ari_every", "scoring"]),
        ("ari_every = 0.5", ["ari_every", "0.5"]),
    ],
)
def test_ari_every_is_checked(tmp_path, extra, words):
    text = TINY.replace('baselines = ["F-geometry"]', extra)
    with pytest.raises(StudyError) as caught:
        load_study(_write(tmp_path, text))
    assert all(word in str(caught.value) for word in words), caught.value


def test_ari_every_needs_fits_from_random_labels(tmp_path):
    text = TINY.replace("sweeps = 8", "sweeps = 8\nari_every = 2").replace(
        'preset = "paper-dp"', 'preset = "paper-dp"\ninit = "rooms"'
    )
    with pytest.raises(StudyError, match="variant 'dp' sets fit keywords"):
        load_study(_write(tmp_path, text))
    study = load_study(_write(tmp_path, TINY.replace("sweeps = 8", "sweeps = 8\nari_every = 2")))
    keys = {c.key for c in cells_of(study)} & {c.key for c in cells_of(load_study(_write(
        tmp_path, TINY, "plain.toml")))}  # fmt: skip
    assert len(keys) == 2  # the variants' keys change with it; the baseline's do not
