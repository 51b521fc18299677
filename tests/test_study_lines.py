"""A study file's errors name the line of the key they refuse (``study.toml:12: ...``), so that
a researcher's editor jumps to it: they named the table and key only."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from spcopyro.maps import OccupancyGrid
from spcopyro.maps.map_server import save_map
from spcopyro.study import sources
from spcopyro.study.cells import cells_of
from spcopyro.study.lines import key_line, where_path
from spcopyro.study.sources import data_digest, resolve_source

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]
from spcopyro.study.spec import StudyError, load_study

STUDY = """\
# a study with comments
[study]
name = "lines"
seeds = 1
sweeps = { gibbs = 5, "*" = 3 }

[variants.a]
preset = "paper-dp"

[variants."b+sw"]
preset = "paper-dp"
cluster_moves = 0.2
hyper = { alpha = true }

[data.d]
synthetic = "scaled"
height = 30
width = 40
num_rooms = 2
"""


@pytest.mark.parametrize(
    "old, new, line, words",
    [
        ("gibbs = 5", "gibs = 5", 5, "[study] sweeps.gibs = 5: unknown method"),
        ("seeds = 1", "seeds = [1, 1]", 4, "[study] seeds = [1, 1]: a seed is given twice"),
        ("cluster_moves = 0.2", "cluster_moves = 2", 12, "cluster_moves=2"),
        ('preset = "paper-dp"\ncluster', 'preset = "paperdp"\ncluster', 11, "'paperdp'"),
        ("hyper = { alpha = true }", "hyper = { alpha = 3 }", 13, "alpha=3"),
        ("hyper = { alpha = true }", "hyper.alpha = 3", 13, "alpha=3"),
        ("num_rooms = 2", "num_roms = 2", 19, "[data.d] num_roms = 2: HouseSpec has no such"),
        ("num_rooms = 2", "num_rooms = 9", 19, "HouseSpec.num_rooms 9"),
        ('synthetic = "scaled"', 'synthetic = "scaledd"', 16, "synthetic = 'scaledd'"),
        ('name = "lines"', "description = 3", 3, "[study] description = 3: expected text"),
        (
            "width = 40",
            "",
            16,
            "synthetic = 'scaled': a scaled house needs height and width (cells); width not given",
        ),
    ],
)
def test_an_error_names_the_line_of_its_key(tmp_path, old, new, line, words):
    assert old in STUDY
    path = tmp_path / "study.toml"
    path.write_text(STUDY.replace(old, new, 1))
    with pytest.raises(StudyError) as caught:
        load_study(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:{line}: "), message
    assert words in message, message


def test_an_error_with_no_line_to_name_keeps_its_message(tmp_path):
    path = tmp_path / "study.toml"
    path.write_text('[study]\nname = "x"\n[variants.a]\n')  # no [data.*] table at all
    with pytest.raises(StudyError) as caught:
        load_study(path)
    assert str(caught.value).startswith(f"{path}: [data] = {{}}: expected at least one")


def test_key_line_reads_quoted_dotted_and_inline_keys():
    text = STUDY + '\n[data."my.house"]\npublic = "room1dk5"\n"seeds" = 3\n'
    assert key_line(text, where_path("[study] sweeps.cavi")) == 5  # the inline table
    assert key_line(text, where_path("[variants.b+sw] hyper.alpha")) == 13
    assert key_line(text, where_path("[variants.b+sw]")) == 10
    assert key_line(text, where_path("[data.my.house] seeds")) == 23
    assert key_line(text, where_path("[data.nothere] seeds")) is None
    assert key_line(text, where_path("top-level tables")) is None
    assert where_path("variants.a") == ("variants", "a")


def _tiny_map(folder: Path) -> Path:
    grid = OccupancyGrid(np.zeros((6, 8), dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    return save_map(grid, folder / "home.yaml")


MAP_STUDY = """\
[study]
seeds = 4
sweeps = 5
[variants.a]
preset = "paper-dp"
[data.tour]
map = "maps/home.yaml"
"""


def test_a_missing_source_names_the_study_file_line_and_value(tmp_path, monkeypatch):
    """It said "data source 'tour': maps/home.yaml does not exist": no file, no line, and not
    that a relative path is read from the current folder, not the study file's."""
    (tmp_path / "maps").mkdir()
    _tiny_map(tmp_path / "maps")
    path = tmp_path / "study.toml"
    path.write_text(MAP_STUDY)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    with pytest.raises(FileNotFoundError) as caught:
        cells_of(load_study(path))
    message = str(caught.value)
    assert message.startswith(f"{path}:7: [data.tour] map = 'maps/home.yaml': "), message
    assert f"not the study file's: give {tmp_path / 'maps' / 'home.yaml'}" in message, message
    monkeypatch.chdir(tmp_path)
    assert len(cells_of(load_study(path))) == 4


def test_a_name_the_dataset_does_not_hold_lists_what_it_holds(tmp_path):
    """``public = "room9"`` said "data source 'd': ROOT/room9 does not exist" and left the
    dataset's names to a directory listing; it names the dataset's houses (or maps) now."""
    from spcopyro.study.spec import DataSource

    (tmp_path / "map").mkdir()
    for name in ("roomA", "roomB"):
        (tmp_path / name).mkdir()
        (tmp_path / "map" / f"{name}.yaml").write_text("image: x.pgm\n")
    for kind, what in (("public", "houses"), ("map", "maps")):
        with pytest.raises(FileNotFoundError) as caught:
            sources.resolve_source(DataSource("d", kind, "room9"), root=tmp_path)
        assert str(caught.value).endswith(
            f"does not exist (the dataset {tmp_path} holds the {what} ['roomA', 'roomB'])"
        ), caught.value
    with pytest.raises(FileNotFoundError) as caught:  # a path: no dataset looked in
        sources.resolve_source(DataSource("d", "public", str(tmp_path / "nowhere")))
    assert str(caught.value).endswith("nowhere does not exist"), caught.value


def test_a_sources_files_are_read_once_for_all_its_seeds(tmp_path, monkeypatch):
    """Each seed read the house's files again: a dry run of a public house at 100000 seeds took
    minutes (14 MB a seed) before it printed anything. The keys stay the same."""
    (tmp_path / "maps").mkdir()
    _tiny_map(tmp_path / "maps")
    path = tmp_path / "study.toml"
    path.write_text(MAP_STUDY)
    monkeypatch.chdir(tmp_path)
    study = load_study(path)
    reads = []
    files_of = sources._files_of
    monkeypatch.setattr(sources, "_files_of", lambda data: reads.append(data) or files_of(data))
    cells = cells_of(study)
    assert len(cells) == 4 and len(reads) == 1, reads
    data = resolve_source(study.data[0])
    assert [c.key for c in cells] == [
        cells_of(dataclasses.replace(study, seeds=(seed,)))[0].key for seed in range(4)
    ]
    assert data_digest(data, 2) == data_digest(data, 2, sources.files_hash(data))


def test_a_public_source_that_is_no_house_folder_is_refused_before_any_fit(tmp_path):
    """A file passed (a map's yaml) raised "[Errno 20] Not a directory" while digesting; a
    folder with no observations planned its cells, each of which failed at run time."""
    (tmp_path / "maps").mkdir()
    yaml = _tiny_map(tmp_path / "maps")
    for target, what in [(yaml, "is a file, not a house folder"),
                         (yaml.parent, "is a folder without Ft.csv or St.csv")]:  # fmt: skip
        path = tmp_path / "study.toml"
        path.write_text(f'[study]\nsweeps = 5\n[variants.a]\n[data.p]\npublic = "{target}"\n')
        with pytest.raises(FileNotFoundError) as caught:
            cells_of(load_study(path))
        assert str(caught.value).startswith(f"{path}:5: [data.p] public = "), caught.value
        assert what in str(caught.value), caught.value


def test_a_large_grid_is_planned_without_redoing_each_cells_settings(monkeypatch):
    """Every cell resolved its variant's settings and drew its source's HouseSpec again to be
    planned: a dry run of 100000 cells took 40 s (19 s now; keys unchanged)."""
    from spcopyro.study import cells as cells_module
    from spcopyro.study import order
    from spcopyro.study.cells import cell_key
    from spcopyro.study.spec import study_from_dict

    study = study_from_dict({
        "study": {"seeds": 5, "sweeps": 5, "methods": ["gibbs", "cavi"],
                  "baselines": ["F-geometry"]},
        "variants": {"a": {"preset": "paper-dp"}, "b": {"gamma": 2.0}},
        "data": {"d": {"synthetic": "scaled", "height": 30, "width": 40, "num_rooms": 2}},
    })  # fmt: skip
    made, rates = [], []
    settings_json, static_rate = cells_module._settings_json, order._static_rate
    monkeypatch.setattr(cells_module, "_settings_json",
                        lambda variant: made.append(variant) or settings_json(variant))  # fmt: skip
    monkeypatch.setattr(order, "_static_rate", lambda cell: rates.append(cell) or static_rate(cell))
    cells = cells_of(study)
    assert len(cells) == 25 and len(made) == 4  # 2 variants x 2 methods, not x 5 seeds
    predicted = order.predicted_seconds(cells)
    assert len(rates) == 3  # gibbs, cavi, the baseline: once for the source
    monkeypatch.undo()
    assert predicted == order.predicted_seconds(cells)
    assert all(cell_key(c, data_digest(c.data, c.seed)) == c.key for c in cells)


def test_the_documented_study_files_load():
    """docs/studies.md's study file was refused (its og3+sw's cluster_moves under methods =
    ["gibbs", "cavi"], ari_every beside init, spcoa_iterations without C-spcoa), and spec.py's
    docstring's house (5 rooms in 24 x 30 cells) could not be drawn: a researcher copying
    either got an error first."""
    from spcopyro.study import spec
    from spcopyro.study.spec import study_from_dict

    docs = Path(__file__).parents[1] / "docs" / "studies.md"
    block = re.search(r"```toml\n(.*?)```", docs.read_text(encoding="utf-8"), re.S)
    study = study_from_dict(tomllib.loads(block.group(1)), source="studies.md")
    assert [v.name for v in study.variants] == ["og3", "og3+sw"] and len(study.data) == 3
    lines = [line[4:] for line in spec.__doc__.splitlines() if line.startswith("    ")]
    study = study_from_dict(tomllib.loads("\n".join(lines)), source="spec.py")
    assert [d.house_spec().num_rooms for d in study.data if d.kind == "synthetic"] == [2]


def test_a_study_named_without_its_suffix_points_at_the_file(tmp_path, monkeypatch):
    """``spcopyro study my_study`` beside my_study.toml listed only the shipped studies."""
    from spcopyro.cli.study import study_path

    (tmp_path / "my_study.toml").write_text("")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(FileNotFoundError, match="my_study does not exist; did you mean my_st"):
        study_path("my_study")
    assert study_path("my_study.toml") == Path("my_study.toml")
    with pytest.raises(FileNotFoundError, match=r"^study file other does not exist \(shipped"):
        study_path("other")


def test_a_name_with_a_bar_keeps_the_reports_columns():
    """``[variants."a|b"]`` wrote the row ``| a|b | gibbs | ...``: one column more than the
    header's, so the markdown table shifted every score of the row."""
    from spcopyro.study.report import report_markdown

    row = {"variant": "a|b", "data": "d|1", "method": "gibbs", "seed": 0, "status": "ok",
           "ari": 0.5, "source_digest": "x"}  # fmt: skip
    lines = report_markdown([row], scores=("ari",)).splitlines()
    (line,) = [line for line in lines if "gibbs" in line]
    header = lines[lines.index(line) - 2]
    assert line.replace("\\|", "").count("|") == header.count("|") == 5, (header, line)


def test_a_name_with_a_bar_keeps_the_dry_runs_columns(tmp_path):
    from spcopyro.study.run import plan_markdown, plan_study
    from spcopyro.study.spec import study_from_dict

    study = study_from_dict({
        "study": {"sweeps": 5}, "variants": {"a|b": {}},
        "data": {"d|1": {"synthetic": "scaled", "height": 30, "width": 40, "num_rooms": 2}},
    })  # fmt: skip
    text = plan_markdown(plan_study(study, tmp_path / "out"), study)
    (line,) = [line for line in text.splitlines() if "gibbs" in line]
    assert line.startswith("| d\\|1 | a\\|b | gibbs |") and line.count("|") == 9, line


def test_a_study_file_saved_with_a_byte_order_mark_loads(tmp_path):
    """Notepad's UTF-8 starts with a BOM: it was "not valid TOML: Invalid statement (at line 1,
    column 1)"; the lines of later errors still count from the first."""
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + STUDY.encode())
    assert load_study(path).name == "lines"
    path.write_bytes(b"\xef\xbb\xbf" + STUDY.replace("num_rooms", "num_roms").encode())
    with pytest.raises(StudyError, match=r"bom.toml:19: \[data.d\] num_roms = 2"):
        load_study(path)


def test_sources_whose_figures_differ_only_in_case_are_refused(tmp_path):
    """[data.Small] and [data.small] drew maps_Small.png and maps_small.png: one file on macOS's
    and Windows' file systems, so one source's maps were drawn over the other's."""
    house = 'synthetic = "scaled"\nheight = 30\nwidth = 40\nnum_rooms = 2\n'
    path = tmp_path / "study.toml"
    path.write_text(f"[variants.a]\n[data.Small]\n{house}[data.small]\n{house}")
    with pytest.raises(StudyError) as caught:
        load_study(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:7: [data.small] = 'small': its report figure "), message
    assert "maps_small.png is also [data.Small]'s (maps_Small.png" in message, message


def test_the_line_is_the_refused_keys_not_one_its_message_mentions(tmp_path):
    """``hyper.log_gamma_sd=2.0: ... (hyper.alpha, hyper.concentrations and hyper.gamma choose
    them)`` pointed at ``gamma = 3.0``: its ``.gamma `` was read as that key."""
    path = tmp_path / "study.toml"
    path.write_text(STUDY.replace("cluster_moves = 0.2", "gamma = 3.0").replace(
        "hyper = { alpha = true }", "hyper = { log_gamma_sd = 2.0 }"))  # fmt: skip
    with pytest.raises(StudyError) as caught:
        load_study(path)
    assert str(caught.value).startswith(f"{path}:13: [variants.b+sw]: "), caught.value
    assert "hyper.log_gamma_sd=2.0" in str(caught.value)
