"""A study's inputs as QA met them: a map whose image has another name, names given twice,
options that contradict each other, figures of an earlier run, ``--report-only --dry-run``.

Nothing here fits more than a geometry baseline on a tiny house; most tests stop before a fit.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from pathlib import Path

import numpy as np
import pytest
from study_setup import small_house_toml

from spcopyro.cli.main import main
from spcopyro.maps import OccupancyGrid
from spcopyro.maps.map_server import MapFormatError, load_map, save_map
from spcopyro.study.cells import cells_of
from spcopyro.study.sources import data_digest, resolve_source
from spcopyro.study.spec import DataSource, StudyError, study_from_dict

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]


def _map_with_image(folder: Path, image: str) -> Path:
    """``folder/mymap.yaml`` naming ``image`` (another stem than the yaml's)."""
    grid = OccupancyGrid(np.zeros((6, 8), dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    saved = save_map(grid, folder / "saved.yaml")
    written = folder / image
    if Path(image).suffix == ".png":
        import cv2

        cv2.imwrite(str(written), np.full((6, 8), 254, dtype=np.uint8))
    else:
        saved.with_suffix(".pgm").rename(written)
    yaml = folder / "mymap.yaml"
    yaml.write_text(saved.read_text().replace("saved.pgm", image))
    saved.unlink()
    return yaml


def test_a_map_that_does_not_read_is_refused_before_any_cell(tmp_path):
    """Its cells failed one by one at run time (MapFormatError, a missing image)."""
    yaml = _map_with_image(tmp_path, "other.pgm")
    (tmp_path / "other.pgm").unlink()
    with pytest.raises(FileNotFoundError, match="mymap.yaml names the image .*other.pgm, which"):
        resolve_source(DataSource("tour", "map", str(yaml)))
    yaml.write_text("image: [\n")
    with pytest.raises(ValueError, match="data source 'tour': .*mymap.yaml"):
        resolve_source(DataSource("tour", "map", str(yaml)))


@pytest.mark.parametrize("mode", ["scale", "SCALE", "raw"])
def test_a_map_in_a_mode_load_map_refuses_is_refused_before_any_cell(tmp_path, mode):
    """'mode: scale' read and every cell failed in load_map; 'mode: SCALE' was asked 'did you
    mean 'scale'?', which read and failed the same. Refused now before any cell, saying what a
    study's map source must be (load_map's own message named loaders a study does not use)."""
    yaml = _map_with_image(tmp_path, "other.pgm")
    yaml.write_text(yaml.read_text() + f"mode: {mode}\n")
    with pytest.raises(MapFormatError) as refused:
        load_map(yaml)
    assert "is not supported by load_map" in str(refused.value)
    with pytest.raises(ValueError) as error:
        resolve_source(DataSource("tour", "map", str(yaml)))
    # load_map's ending sent a study to load_filter_mask / load_label_map_server, which no map
    # source is read by: the study's message shares load_map's head (the mode and, for scale,
    # what to change) and ends saying what a map source must be
    shown = {"SCALE": "'SCALE' (taken for 'scale'; map_server refuses it as written)"}
    change = (
        ": a robot's map saved in scale mode (map_saver --mode scale, a SLAM's graded map) is an "
        "occupancy map: write 'mode: trinary' in its yaml (or leave the key out, trinary is "
        "map_server's default) and each pixel is read against its occupied_thresh / free_thresh"
        if mode != "raw"
        else ""
    )
    head = (
        f"{yaml}:7: key 'mode': {shown.get(mode, repr(mode))} is not supported by load_map (only "
        f"'trinary', an occupancy map){change}; "
    )
    assert str(error.value) == (
        f"data source 'tour': {head}a study's map source is read by load_map (its tours are "
        "drawn on an occupancy map): a costmap filter mask or a semantic label map cannot be one"
    )
    assert str(refused.value) == (
        f"{head}a Nav2 costmap filter mask (scale or raw) is read with load_filter_mask, a "
        "semantic map saved by save_label_map_server with load_label_map_server"
    )


@pytest.mark.parametrize("image", ["other.pgm", "pictures/other.png"])
def test_a_maps_digest_covers_the_image_its_yaml_names(tmp_path, image):
    (tmp_path / "pictures").mkdir()
    yaml = _map_with_image(tmp_path, image)
    data = resolve_source(DataSource("tour", "map", str(yaml)))
    before = data_digest(data, 0)
    assert data_digest(data, 0) == before
    picture = tmp_path / image
    picture.write_bytes(picture.read_bytes() + b"\0")  # the image edited
    assert data_digest(data, 0) != before


def test_a_study_says_a_map_yamls_warnings_once(tmp_path, caplog):
    """Planning a study read a map source's yaml twice, resolving it and digesting its files,
    and said each of its warnings (a misspelt key, a threshold out of range) twice."""
    yaml = _map_with_image(tmp_path, "other.pgm")
    yaml.write_text(yaml.read_text() + "mdoe: trinary\n")
    text = f'[variants.a]\npreset = "paper-dp"\n[data.tour]\nmap = "{yaml}"\n'
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        cells_of(study_from_dict(tomllib.loads(text), source="s.toml"))
    said = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert said == [f"{yaml}:7: unknown key 'mdoe' ignored, as map_server ignores it: did you "
                    "mean 'mode'?"]  # fmt: skip


TWICE = """
[study]
seeds = 2
sweeps = 20
methods = ["gibbs", "cavi"]
baselines = ["F-geometry"]

[variants.a]
preset = "original-code"

""" + small_house_toml(num_trials=None)


@pytest.mark.parametrize(
    "old, new, words",
    [
        ('["gibbs", "cavi"]', '["gibbs", "gibbs"]', ["[study] methods", "'gibbs' is given twice"]),
        ('["F-geometry"]', '["F-geometry", "F-geometry"]',
         ["[study] baselines", "'F-geometry' is given twice"]),
    ],
)  # fmt: skip
def test_a_study_file_refuses_a_method_or_baseline_given_twice(old, new, words):
    with pytest.raises(StudyError) as caught:
        study_from_dict(tomllib.loads(TWICE.replace(old, new)), source="twice.toml")
    for word in ["twice.toml", *words]:
        assert word in str(caught.value)


def test_a_study_built_in_python_refuses_a_cell_given_twice():
    study = study_from_dict(tomllib.loads(TWICE))
    doubled = dataclasses.replace(study, data=study.data * 2)
    with pytest.raises(ValueError, match="a / small / gibbs / seed 0 is given twice"):
        cells_of(doubled)
    assert len(cells_of(study)) == 2 * (2 + 1)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["experiment", "--quick", "--houses", "room1dk5", "room1dk5"],
         ["--houses: room1dk5 is given twice"]),
        (["experiment", "--quick", "--no-public", "--methods", "F-geometry", "F-geometry"],
         ["--methods: F-geometry is given twice"]),
        (["ablation", "--quick", "--no-public", "--houses", "dense", "dense"],
         ["--houses: dense is given twice"]),
        (["ablation", "--quick", "--no-public", "--baselines", "F-geometry", "F-geometry"],
         ["--baselines: F-geometry is given twice"]),
        (["ablation", "--quick", "--public-houses", "room1dk5", "room1dk5"],
         ["--public-houses: room1dk5 is given twice"]),
        (["ablation", "--quick", "--no-public", "--variant", "a:preset=original-code",
          "--variant", "a:preset=paper-dp"], ["--variant names must differ"]),
        (["compare-inference", "--quick", "--methods", "cavi", "cavi"],
         ["--methods: cavi is given twice"]),
        (["compare-inference", "--quick", "--public-houses", "room1dk5", "room1dk5"],
         ["--public-houses: room1dk5 is given twice"]),
    ],
)  # fmt: skip
def test_the_commands_refuse_a_name_given_twice(tmp_path, capsys, argv, words):
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    for word in words:
        assert word in err, err
    assert not out.exists()


@pytest.mark.parametrize(
    "argv, words",
    [
        (["experiment", "--houses", "room1dk5", "--no-public"],
         ["--houses room1dk5 and --no-public contradict"]),
        (["experiment", "--no-public", "--data", "/nowhere"],
         ["--data /nowhere and --no-public contradict"]),
        (["ablation", "--public-houses", "room1dk5", "--no-public"],
         ["--public-houses room1dk5 and --no-public contradict"]),
        (["ablation", "--public-seeds", "2", "--no-public"],
         ["--public-seeds 2 and --no-public contradict"]),
        (["ablation", "--public-houses", "room1dk5", "--public-seeds", "0"],
         ["--public-houses room1dk5 and --public-seeds 0 contradict"]),
        (["ablation", "--houses", "dense", "--seeds", "0"],
         ["--houses dense and --seeds 0 contradict"]),
        (["compare-inference", "--houses", "synthetic", "--public-houses", "room1dk5"],
         ["--public-houses room1dk5 and --houses synthetic contradict"]),
        (["compare-inference", "--houses", "synthetic", "--folds", "2"],
         ["--folds 2 and --houses synthetic contradict"]),
        (["compare-inference", "--houses", "public", "--seeds", "3"],
         ["--seeds 3 and --houses public contradict"]),
        (["compare-inference", "--iterations", "gibbs=3", "--methods", "cavi"],
         ["--iterations gibbs=3: gibbs is not compared (--methods cavi)"]),
        (["compare-inference", "--iterations", "cavi=3", "cavi=5", "--methods", "cavi"],
         ["--iterations: cavi is given twice (cavi=3, cavi=5)"]),
        # a bad value names its option (it was "variant 'gibbs': settings {'gamma': -1.0}: ...")
        (["compare-inference", "--gamma", "-1"], ["error: --gamma -1: SpCoConfig.gamma=-1.0"]),
        # an option no row chosen reads (it was ignored, the run exited 0)
        (["ablation", "--baselines", "F-geometry", "--spcoa-iterations", "7"],
         ["--spcoa-iterations 7 and --baselines F-geometry contradict", "no C-spcoa row"]),
        (["ablation", "--baselines", "--spcoa-iterations", "7"],
         ["--spcoa-iterations 7 and --baselines (none) contradict"]),
        (["experiment", "--methods", "F-geometry", "--spcoa-iterations", "7"],
         ["--spcoa-iterations 7 and --methods F-geometry contradict", "no C-spcoa row"]),
        (["experiment", "--methods", "F-geometry", "E-nearest", "--sweeps", "7"],
         ["--sweeps 7 and --methods F-geometry E-nearest contradict", "no SpCoMapping row"]),
    ],
)  # fmt: skip
def test_contradictory_options_are_refused_not_ignored(tmp_path, capsys, argv, words):
    out = tmp_path / "out"
    assert main([*argv, "--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    for word in words:
        assert word in err, err
    assert not out.exists()


def test_more_folds_than_a_house_has_trials_are_refused(tmp_path, capsys, dataset_root):
    out = tmp_path / "out"
    argv = [
        "compare-inference",
        "--quick",
        "--folds",
        "9",
        "--houses",
        "public",
        "--public-houses",
        "room1dk5",
        "--methods",
        "cavi",
        "--data",
        str(dataset_root),
    ]
    assert main([*argv, "--out", str(out)]) == 2  # fmt: skip
    assert "--folds 9: public house room1dk5 has 3 trials" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    "argv, named",
    [
        (["experiment", "--quick", "--houses", "room1dk5"], "--houses room1dk5"),
        (["ablation", "--quick", "--public-houses", "room1dk5"], "--public-houses room1dk5"),
        (["compare-inference", "--quick", "--houses", "public"], "--houses public"),
        (["compare-inference", "--quick", "--public-houses", "room1dk5"],
         "--public-houses room1dk5"),
    ],
)  # fmt: skip
def test_public_houses_asked_for_by_name_need_the_dataset(
    tmp_path, capsys, monkeypatch, argv, named
):
    """Without the dataset, a run asked for public houses by name skipped them with a note
    and exited 0, its table holding none of them; without such an option it still does."""
    import spcopyro.data

    monkeypatch.setattr(spcopyro.data, "find_dataset_root", lambda data=None: None)
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{named} asks for public houses, but the public dataset was not found" in err
    assert not out.exists()


def test_a_sweeps_table_without_a_star_says_which_methods_run_1000(tmp_path, capsys):
    path = tmp_path / "partial.toml"
    path.write_text(TWICE.replace("sweeps = 20", "sweeps = {cavi = 5}"))
    assert study_from_dict(tomllib.loads(path.read_text())).sweeps_defaulted() == ["gibbs"]
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--dry-run"]) == 0
    err = capsys.readouterr().err
    assert "[study] sweeps names neither gibbs nor '*': they run 1000 iterations" in err
    path.write_text(TWICE.replace("sweeps = 20", 'sweeps = {cavi = 5, "*" = 7}'))
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--dry-run"]) == 0
    assert "1000" not in capsys.readouterr().err


def test_data_for_a_study_of_synthetic_houses_only_is_refused(tmp_path, capsys):
    """``--data DIR`` was ignored: no source of the study is looked up there."""
    path = tmp_path / "tiny.toml"
    path.write_text(TWICE)
    argv = ["study", str(path), "--out", str(tmp_path / "out"), "--data", "/nowhere", "--dry-run"]
    assert main(argv) == 2
    assert "--data /nowhere: study" in capsys.readouterr().err


def test_report_only_with_dry_run_is_refused(tmp_path, capsys):
    path = tmp_path / "tiny.toml"
    path.write_text(TWICE)
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.csv").write_text("key,variant\n")
    argv = ["study", str(path), "--out", str(out), "--report-only", "--dry-run"]
    assert main(argv) == 2
    assert "--report-only and --dry-run contradict each other" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["results.csv"]


def _stale(out: Path, *names: str) -> list[Path]:
    """Figures an earlier run left in ``out`` (empty files)."""
    paths = [out / name for name in names]
    for path in paths:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"")
    return paths


def test_a_rerun_without_a_house_deletes_its_figures_and_keeps_others(tmp_path, capsys):
    out = tmp_path / "e1"
    stale = _stale(
        out, "maps_room1dk5.png", "figures/room1dk5_maps.png", "figures/synthetic_traces.png"
    )  # fmt: skip  (no SpCoMapping row: no traces)
    kept = _stale(out, "figures/stability.png", "notes.png", "figures/room1dk5.png")
    argv = ["experiment", "--out", str(out), "--quick", "--no-public", "--methods", "F-geometry",
            "--seeds", "1"]  # fmt: skip
    assert main(argv) == 0
    assert not any(path.exists() for path in stale), capsys.readouterr().out
    assert all(path.exists() for path in kept)
    for name in ("maps_synthetic.png", "figures/synthetic_maps.png", "quality_time.png"):
        assert (out / name).stat().st_size > 1000, name


def test_a_comparison_without_public_houses_deletes_their_figure(tmp_path):
    out = tmp_path / "c1"
    (stale,) = _stale(out, "comparison_public.png")
    argv = ["compare-inference", "--out", str(out), "--quick", "--houses", "synthetic",
            "--methods", "cavi", "--iterations", "cavi=2"]  # fmt: skip
    assert main(argv) == 0
    assert not stale.exists() and (out / "comparison_synthetic.png").is_file()


def test_a_report_of_a_table_without_them_deletes_earlier_maps_and_quality_figure(tmp_path):
    from spcopyro.study.report import write_report
    from spcopyro.study.table import write_table

    stale = _stale(tmp_path, "maps_room1dk5.png", "quality_time.png")
    (kept,) = _stale(tmp_path, "maps.png")  # not a name the report draws
    write_table(tmp_path / "results.csv", [])
    write_report(tmp_path / "results.csv", tmp_path / "report.md")
    assert not any(path.exists() for path in stale) and kept.exists()


@pytest.mark.parametrize(
    "command",
    [
        ["study", "STUDY", "--workers", "1"],
        ["study", "STUDY", "--dry-run"],
        ["ablation", "--quick", "--no-public", "--seeds", "1", "--sweeps", "2", "--no-off"],
        ["experiment", "--quick", "--no-public", "--methods", "F-geometry", "--seeds", "1"],
    ],
)
@pytest.mark.parametrize("below", [False, True])
def test_an_out_that_is_a_file_is_refused_before_any_cell(tmp_path, capsys, command, below):
    """It failed with a bare ``[Errno 17] File exists`` (or ``[Errno 20] Not a directory``)."""
    study = tmp_path / "tiny.toml"
    study.write_text(TWICE)
    blocker = tmp_path / "results"
    blocker.write_text("not a folder")
    out = blocker / "sub" if below else blocker
    argv = [str(study) if word == "STUDY" else word for word in command] + ["--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"--out {out}: {blocker} is a file, not a folder" in err, err
    assert blocker.read_text() == "not a folder"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results", "tiny.toml"]


def test_spcoa_iterations_without_a_spcoa_row_are_refused():
    text = TWICE.replace("seeds = 2", "seeds = 2\nspcoa_iterations = 50")
    with pytest.raises(StudyError, match=r"spcoa_iterations = 50: baselines = \['F-geometry'\]"):
        study_from_dict(tomllib.loads(text), source="t.toml")
    text = text.replace('["F-geometry"]', '["F-geometry", "C-spcoa"]')
    assert study_from_dict(tomllib.loads(text)).spcoa_iterations == 50


@pytest.mark.parametrize(
    "sweeps, methods, key",
    [
        ("{gibbs = 10, cavi = 5}", '["gibbs"]', "cavi"),  # a method no cell runs
        ('{a = 10, gibbs = 5, "*" = 7}', '["gibbs"]', "gibbs"),  # the variant's own entry wins
        ("{gibbs = 10, svi = 5}", '["gibbs", "cavi"]', "svi"),
    ],
)
def test_a_sweeps_entry_no_cell_takes_is_refused(tmp_path, sweeps, methods, key):
    """It changed nothing, silently: the cells ran the other entries' or 1000 iterations."""
    text = TWICE.replace("sweeps = 20", f"sweeps = {sweeps}")
    text = text.replace('methods = ["gibbs", "cavi"]', f"methods = {methods}")
    with pytest.raises(StudyError, match=rf"\[study\] sweeps\.{key} = \d+: no cell takes it"):
        study_from_dict(tomllib.loads(text), source="t.toml")


def test_a_study_of_other_methods_than_gibbs_takes_their_options():
    """With ``[study] methods = ["cavi"]`` a variant's CAVI option was refused (``unknown key
    'anneal_iterations'``: the variant was checked as Gibbs'), and a variant may not name its
    own method there: CAVI's options could not be set at all."""
    text = TWICE.replace('methods = ["gibbs", "cavi"]', 'methods = ["cavi"]')
    text = text.replace(
        'preset = "original-code"', 'preset = "original-code"\nanneal_iterations = 3'
    )
    (cell, *_) = cells_of(study_from_dict(tomllib.loads(text)))
    assert cell.method == "cavi" and cell.variant.method_options().anneal_iterations == 3
    both = text.replace('methods = ["cavi"]', 'methods = ["cavi", "gibbs"]')
    with pytest.raises(StudyError, match="no field 'anneal_iterations'.*methods' 'gibbs'"):
        study_from_dict(tomllib.loads(both))


def test_a_study_path_that_is_a_folder_or_not_text_is_named(tmp_path, capsys):
    """A folder was "does not exist"; a file not in UTF-8 "'utf-8' codec can't decode byte
    0xff ...", naming no file."""
    argv = ["study", str(tmp_path), "--out", str(tmp_path / "out"), "--dry-run"]
    assert main(argv) == 2
    assert f"study file {tmp_path} is a folder" in capsys.readouterr().err
    binary = tmp_path / "latin1.toml"
    binary.write_bytes('[study]\nname = "caf\xe9"\n'.encode("latin-1"))
    argv[1] = str(binary)
    assert main(argv) == 2
    assert f"{binary}: not UTF-8 text" in capsys.readouterr().err


def test_a_second_run_into_a_folder_in_use_is_refused_at_once(tmp_path, capsys):
    """Two runs into one --out ran the same unfinished cells and rewrote one table in turn."""
    from spcopyro._util.folder_lock import LOCK_NAME, folder_lock

    path = tmp_path / "geometry.toml"
    path.write_text(TWICE.replace('methods = ["gibbs", "cavi"]', "methods = []").replace(
        "seeds = 2", "seeds = 1"))  # fmt: skip
    out = tmp_path / "out"
    argv = ["study", str(path), "--out", str(out), "--workers", "1"]
    with folder_lock(out, "study run"):  # as a run in another process holds it
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"{out} is in use by another study run (process " in err
        assert "write to another --out" in err
        assert not (out / "cells").exists() and not (out / "results.csv").exists()
    assert main(argv) == 0  # the lock is dropped with its holder
    assert (out / "results.csv").is_file() and (out / LOCK_NAME).is_file()


def test_report_only_while_a_run_holds_the_folder_is_refused(tmp_path, capsys):
    """`--report-only` read results.csv and the cells while a run in the same folder wrote
    them (a half-written table, a report of it); it is refused, naming the running process, as
    a second run is."""
    from spcopyro._util.folder_lock import folder_lock

    path = tmp_path / "geometry.toml"
    path.write_text(TWICE.replace('methods = ["gibbs", "cavi"]', "methods = []").replace(
        "seeds = 2", "seeds = 1"))  # fmt: skip
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "1"]) == 0
    (out / "report.md").unlink()
    capsys.readouterr()
    argv = ["study", str(path), "--out", str(out), "--report-only"]
    with folder_lock(out, "study run"):  # as a run in another process holds it
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"--report-only: {out} is in use by a study run (process {os.getpid()}, " in err
        assert "wait for it to finish" in err
        assert not (out / "report.md").exists()
    assert main(argv) == 0  # the lock is dropped with its holder
    assert (out / "report.md").is_file()
