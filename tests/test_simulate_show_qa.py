"""``spcopyro simulate`` and ``show`` as a user meets them: their summaries and messages (issues
found by running the commands on small and hand-drawn houses)."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from spcopyro.cli.main import main
from spcopyro.synthetic import HouseSpec, write_synthetic


def test_show_counts_one_category_trial_and_word_in_the_singular(tmp_path, capsys):
    """A one-room house's summary said "ground truth 1 categories: kitchen" (and would say
    "vocabulary of 1 words", "in 1 trial(s)"): each count now agrees with its noun."""
    spec = HouseSpec(height=30, width=30, num_rooms=1, num_open_plan=0, min_room_size=8)
    room = write_synthetic(tmp_path / "data", seed=0, spec=spec, name="one")
    assert main(["show", str(room), "--out", str(tmp_path / "one.png")]) == 0
    out = capsys.readouterr().out
    assert "ground truth     1 category: kitchen" in out
    assert "in 3 trials" in out and "trial(s)" not in out
    assert "vocabulary of 3 words" in out


def test_simulate_names_its_flags_not_the_librarys_fields(tmp_path, capsys):
    """``--sentences 1.5`` was refused as "HouseSpec.sentence_fraction must lie in [0, 1]" and
    ``--density open-plan --rooms 1`` as "HouseSpec.open_plan_share needs 1 <= num_open_plan <
    num_rooms": the user gave neither field. Each message now names the flag and its value."""
    out = str(tmp_path / "data")
    for value in ("1.5", "-0.1", "nan"):
        with pytest.raises(SystemExit) as stop:
            main(["simulate", "--out", out, "--sentences", value])
        assert stop.value.code == 2
        err = capsys.readouterr().err
        assert f"argument --sentences: '{value}': a share from 0 to 1" in err, err
    assert main(["simulate", "--out", out, "--density", "open-plan", "--rooms", "1"]) == 2
    err = capsys.readouterr().err
    assert "--rooms 1: an open-plan house has at least 2 rooms" in err and "HouseSpec" not in err
    small = ["simulate", "--out", out, "--density", "sparse", "--size", "50", "50"]
    assert main(small) == 2  # its 6 rooms were "HouseSpec.num_rooms 6", a field never given
    err = capsys.readouterr().err
    assert (
        "error: --density sparse draws 6 rooms: rooms of at least" in err and "HouseSpec" not in err
    )
    assert main([*small, "--rooms", "4"]) == 2
    assert "error: --rooms 4: rooms of at least" in capsys.readouterr().err
    assert not (tmp_path / "data").exists()


@pytest.mark.parametrize("name", ["coarse", "paper-dp"])
def test_a_prior_world_needs_whole_counts_and_says_so_first(name):
    """``sample_prior_world`` on data prepared by the default preset (image probabilities,
    words spread over a footprint) ran its label sweeps, then failed inside Pyro with
    "MultinomialCounts.sample needs non-negative integer total_count" after a dump of the
    model's trace; it now refuses such data first, naming the modality and the cell."""
    import torch

    from spcopyro.config import preset
    from spcopyro.fit.house import prepare_model_data
    from spcopyro.simulate import sample_observations, sample_prior_world
    from spcopyro.synthetic import make_house

    spec = HouseSpec(height=30, width=40, num_rooms=3, num_open_plan=0, min_room_size=8)
    settings = preset(name)
    _, data = prepare_model_data(make_house(seed=0, spec=spec), settings)
    generator = torch.Generator().manual_seed(0)
    with pytest.raises(ValueError, match=r"observed cell 0 \(free cell \d+\) holds .* images "
                                         r"counts in all, not a whole number"):  # fmt: skip
        sample_prior_world(data, settings.model, generator, sweeps=1)
    assert torch.equal(generator.get_state(), torch.Generator().manual_seed(0).get_state())
    whole = preset("original-code")
    _, counts = prepare_model_data(make_house(seed=0, spec=spec), whole)
    state, drawn = sample_prior_world(counts, whole.model, generator, sweeps=1)
    assert torch.equal(
        drawn.modality("words").counts.sum(-1), counts.modality("words").counts.sum(-1)
    )
    with pytest.raises(ValueError, match="not a whole number"):  # checked before the trace
        sample_observations(state, data, whole.model)


def test_the_printed_fit_command_runs_from_a_folder_with_a_space(tmp_path, capsys):
    """``simulate --out "my data"`` printed "fit it with: spcopyro fit my data/synthetic --out
    my data/fit", which a shell splits into other arguments; the command is quoted now."""
    import shlex

    out = tmp_path / "my data"
    assert main(["simulate", "--out", str(out), "--size", "30", "30", "--name", "a b"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "fit it with:" in x)
    words = shlex.split(line.split("fit it with:", 1)[1])
    assert words == ["spcopyro", "fit", str(out / "a b"), "--out", str(out / "fit")]


def test_a_figure_out_that_is_a_folder_or_under_a_file_is_a_usage_error(tmp_path, capsys):
    """``show --out /tmp`` wrote ``/tmp.png`` beside the folder, ``where OUT kitchen --out OUT``
    wrote ``OUT.png`` beside the fit, and ``--out FILE/x.png`` failed after the work with
    "[Errno 17] File exists": each is refused up front, naming the folder or file."""
    folder, afile = tmp_path / "figures", tmp_path / "notes.txt"
    folder.mkdir()
    afile.write_text("x")
    for out, told in (
        ("", "an empty file name"),  # show: "PosixPath('.') has an empty name" after the work
        (str(folder), "is a folder: give the figure's file name in it"),
        (str(tmp_path / "new") + "/", "is a folder: give the figure's file name in it"),
        (str(afile / "x.png"), f"{str(afile)!r} is a file, not a folder"),
        (str(afile / "a" / "x.png"), f"{str(afile)!r} is a file, not a folder"),
    ):
        with pytest.raises(SystemExit) as stop:
            main(["show", "--out", out])
        assert stop.value.code == 2
        assert f"argument --out: {out!r}" in (err := capsys.readouterr().err) and told in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figures", "notes.txt"]
    out = two_rooms_fit(tmp_path)  # where --out "" drew nothing, silently
    with pytest.raises(SystemExit):
        main(["where", str(out), "kitchen", "--out", ""])
    assert "argument --out: '': an empty file name" in capsys.readouterr().err


@pytest.mark.parametrize("sweeps", [-5, 2.5, None])
def test_a_prior_world_refuses_a_number_of_sweeps_that_is_no_count(sweeps):
    """``sweeps=-5`` ran no sweep at all and returned i.i.d. labels as a draw from the Potts
    prior; ``2.5`` failed inside ``range``."""
    import torch

    from spcopyro.config import preset
    from spcopyro.fit.house import prepare_model_data
    from spcopyro.simulate import sample_prior_world
    from spcopyro.synthetic import make_house

    spec = HouseSpec(height=30, width=40, num_rooms=3, num_open_plan=0, min_room_size=8)
    settings = preset("original-code")
    _, data = prepare_model_data(make_house(seed=0, spec=spec), settings)
    with pytest.raises(ValueError, match=f"sweeps must be an integer >= 0, got {sweeps!r}"):
        sample_prior_world(data, settings.model, torch.Generator().manual_seed(0), sweeps=sweeps)


def two_rooms_fit(tmp_path) -> Path:
    """A saved hand-made result (tests/hand_results.py's two rooms) to ask ``where``."""
    from hand_results import two_rooms

    return two_rooms().save(tmp_path / "fit")


def test_simulate_out_that_is_or_lies_under_a_file_is_refused_first(tmp_path, capsys):
    """``simulate --out FILE`` (or ``FILE/x``, with ``--map`` too) drew the house, then failed
    with "[Errno 20] Not a directory: 'FILE/synthetic'"; an empty ``--out`` wrote into the
    current folder. Each is refused before the draw, naming the file."""
    afile = tmp_path / "notes.txt"
    afile.write_text("x")
    plan = tmp_path / "plan.yaml"  # any map: the check comes first
    for extra in ([], ["--map", str(plan)]):
        for out in (afile, afile / "x"):
            assert main(["simulate", "--out", str(out), *extra]) == 2
            assert f"--out {out}: {afile} is a file, not a folder" in capsys.readouterr().err
    assert main(["simulate", "--out", ""]) == 2
    assert "--out '': an empty folder name" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def _dataset(root: Path) -> Path:
    """A dataset root as find_dataset_root knows one (a map/ folder) holding room1ldk5/ (with
    its map/room1ldk5.yaml, what makes it a house for list_houses)."""
    (root / "map").mkdir(parents=True)
    (root / "map" / "room1ldk5.yaml").write_text("image: room1ldk5.pgm\n")
    (root / "room1ldk5").mkdir()
    return root.resolve()


def test_a_missing_house_named_as_a_public_one_points_to_it(tmp_path, monkeypatch, capsys):
    """``fit room1ldk5`` (a house's name, not its folder) said only "room folder room1ldk5 does
    not exist": fit and show now ask whether the dataset's folder of that name was meant."""
    dataset = _dataset(tmp_path / "dataset")
    monkeypatch.setenv("SPCOPYRO_DATA", str(dataset))
    monkeypatch.chdir(tmp_path)
    for argv in (["show", "room1ldk5", "--out", "x.png"],
                 ["fit", "room1ldk5", "--out", "out/x", "--sweeps", "2"]):  # fmt: skip
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"room folder room1ldk5 does not exist; did you mean {dataset / 'room1ldk5'}?" in err
    assert not (tmp_path / "out").exists()


def test_a_missing_folder_named_map_is_not_pointed_to_the_datasets_maps(
    tmp_path, monkeypatch, capsys
):
    """``fit map`` asked "did you mean DATASET/map?", the dataset's folder of maps, no house:
    only a house of the dataset (:func:`spcopyro.data.list_houses`) is suggested."""
    dataset = _dataset(tmp_path / "dataset")
    monkeypatch.setenv("SPCOPYRO_DATA", str(dataset))
    monkeypatch.chdir(tmp_path)
    assert main(["fit", "map", "--out", "x", "--sweeps", "2"]) == 2
    err = capsys.readouterr().err
    assert "room folder map does not exist; " in err
    assert "did you mean" not in err
    assert f"one of the public dataset's (under {dataset})" in err
    assert not (tmp_path / "x").exists()


def test_a_missing_synthetic_house_says_the_simulate_that_writes_it(tmp_path, monkeypatch, capsys):
    """README's ``show out/data/synthetic`` before its ``simulate --out out/data`` said only that
    the folder does not exist: it now gives that command, which writes it (run here)."""
    monkeypatch.setenv("SPCOPYRO_DATA", str(_dataset(tmp_path / "dataset")))
    monkeypatch.chdir(tmp_path)
    show = ["show", "out/data/synthetic", "--out", "out/house.png"]
    assert main(show) == 2
    err = capsys.readouterr().err
    assert "room folder out/data/synthetic does not exist; " in err
    command = err.split("`")[1]
    assert command == "spcopyro simulate --out out/data"
    assert main(shlex.split(command)[1:]) == 0
    assert main(show) == 0
    # another missing folder: what a house folder is, and where the dataset is
    assert main(["show", "out/data/kitchen", "--out", "x.png"]) == 2
    err = capsys.readouterr().err
    assert f"one of the public dataset's (under {tmp_path / 'dataset'})" in err
    assert "`spcopyro simulate --out DIR` writes (DIR/synthetic)" in err


def test_show_on_a_fit_folder_gives_a_runnable_graph_command(tmp_path, capsys):
    """``show OUT --out x.png`` said "to draw its place graph pass --graph", and ``show OUT
    --graph`` was then refused for its missing --out: the hint is now a whole command."""
    from spcopyro._util.outputs import RESULT_MARKERS
    from spcopyro.cli.main import build_parser

    fit = tmp_path / "my fit"  # a space: the command is quoted for a shell
    fit.mkdir()
    for name in RESULT_MARKERS:
        (fit / name).write_text("{}")
    assert main(["show", str(fit), "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err.strip()
    command = err.split("to draw its place graph: ")[1]
    argv = shlex.split(command)
    assert argv[:2] == ["spcopyro", "show"]
    args = build_parser().parse_args(argv[1:])  # argparse's usage error would exit here
    assert args.graph and args.data == str(fit) and args.out == str(tmp_path / "x.png")


def test_show_on_a_fit_folder_with_warnings_still_ends_with_its_command(tmp_path, capsys):
    """A fit whose config.json lists warnings: their note came after the hinted command
    ("... --out x.png; its fit gave 2 warnings (...)"), so the line could not be pasted. The
    note now comes first, and the command ends the message."""
    import json

    from spcopyro._util.outputs import RESULT_MARKERS
    from spcopyro.cli.main import build_parser

    fit = tmp_path / "fit"
    fit.mkdir()
    for name in RESULT_MARKERS:
        (fit / name).write_text("{}")
    warnings = ["concept 3 is empty", "the chain did not mix"]
    (fit / "config.json").write_text(json.dumps({"warnings": warnings}))
    assert main(["show", str(fit), "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert "its fit gave 2 warnings" in err and warnings[0] in err
    command = err.split("to draw its place graph: ")[1]
    argv = shlex.split(command)
    assert argv[:2] == ["spcopyro", "show"]
    args = build_parser().parse_args(argv[1:])
    assert args.graph and args.data == str(fit) and args.out == str(tmp_path / "x.png")
