"""A map whose free space reads as occupied (``negate: 1`` on a map drawn with free space white,
thresholds or an inverted image) is refused before a fit, not only when no observation at all
lands on free space (:meth:`spcopyro.data.PlacementReport.free_space_inverted`): with
``negate: 1`` a house's walls read free, a few observations snap onto them and the fit went
ahead on them with warnings only."""

from __future__ import annotations

import dataclasses
import logging
import threading
from pathlib import Path

import numpy as np
import pytest

from spcopyro.cli.main import main
from spcopyro.config import SpCoSettings
from spcopyro.data import House, Observations, cell_counts, load_house, save_house
from spcopyro.data.inverted_map import check_placement
from spcopyro.fit import house as house_module
from spcopyro.fit.house import prepare_model_data
from spcopyro.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid, load_map
from spcopyro.maps.coarse import coarsen_grid, coarsening_factor
from spcopyro.synthetic import make_house

HOUSES = ("room1dk5", "room1dk6", "room1ldk4", "room1ldk5", "room2ldk4")


def _negated(tmp_path: Path, negate: str = "1", walls: int = 3) -> Path:
    """The embedded house saved under ``tmp_path``, ``walls`` of its images moved onto walls
    (which the negated map reads free, as a robot's tour passes close to them), its yaml's negate
    set to ``negate``."""
    house = make_house(seed=0, name="flat")
    obs = house.observations
    on = house.grid.cell_to_world(np.argwhere(house.grid.occupancy == OCCUPIED)[:walls])  # [w, 2]
    image_xy = np.concatenate([on, obs.image_xy[walls:]])  # [T, 2]
    save_house(dataclasses.replace(house, observations=dataclasses.replace(obs, image_xy=image_xy)),
               tmp_path)  # fmt: skip
    yaml_path = tmp_path / "map" / "flat.yaml"
    text = yaml_path.read_text()
    assert "negate: 0" in text
    yaml_path.write_text(text.replace("negate: 0", f"negate: {negate}"))
    for truth in ("truth.npy", "categories.json"):  # its labels lie on cells no longer free
        (tmp_path / "flat" / truth).unlink(missing_ok=True)
    return yaml_path


def test_a_negated_map_is_refused_naming_its_yaml_and_negate_line(tmp_path, caplog):
    yaml_path = _negated(tmp_path)
    line = next(i for i, t in enumerate(yaml_path.read_text().splitlines(), 1) if "negate" in t)
    house = load_house(tmp_path / "flat")
    assert house.grid.num_free  # its walls read free: check_free_cells lets it through
    report = cell_counts(house.grid, house.observations).placement
    assert report.num_on_free == 3  # on the walls: not "no observation lands on free space"
    with caplog.at_level(logging.ERROR), pytest.raises(ValueError) as error:
        prepare_model_data(house, SpCoSettings())
    message = str(error.value)
    left_out, total = report.num_unplaced, report.num_observations
    assert message.startswith(
        f"{left_out} of {total} observations are left out, {left_out} of them on occupied "
        f"cells on map {yaml_path}: the map's free space reads as occupied: {yaml_path}:{line}: "
        "negate 1 on a map whose free space is drawn white (map_saver's maps need negate: 0): "
        "with negate 0, "
    )
    assert message.endswith(f"{left_out} of the {left_out} observations left out would lie on them")
    # the counts once (the placement warnings that gave the snapped ones are not said with it)
    assert message.count(f"of {total}") == 1 and "snapped" not in message


@pytest.mark.parametrize("walls", [3, 0])
def test_fit_refuses_a_negated_map_without_the_placement_warnings_before(tmp_path, capsys, walls):
    """`spcopyro fit` on a house whose map says negate: 1 (its walls read free) printed two long
    warnings -- the observations left out with their lines, then most of them off free space
    with the refusal's own counts -- before the refusal. The refusal comes alone now, naming the
    yaml, its negate line and value (images on the walls: the inverted map's refusal; none on
    free space: check_on_free's)."""
    yaml_path = _negated(tmp_path, walls=walls)
    line = next(i for i, t in enumerate(yaml_path.read_text().splitlines(), 1) if "negate" in t)
    argv = ["fit", str(tmp_path / "flat"), "--out", str(tmp_path / "fit"), "--sweeps", "2"]
    assert main([*argv, "--no-figures"]) == 2
    err = capsys.readouterr().err
    assert "left out of the cell counts" not in err, err
    assert "the sign of a wrong map or origin" not in err, err
    refusal = err.splitlines()[-1]
    if walls:
        assert refusal.startswith("error: ") and "observations are left out" in refusal
        assert f"{yaml_path}:{line}: negate 1 on a map whose free space is drawn white" in refusal
    else:
        assert refusal.startswith("error: no observation lands on free space: ")
        assert f"on map {yaml_path} " in refusal
        assert f"{yaml_path}:{line}: negate 1 on a map whose free space is drawn white" in refusal


def test_the_placement_warnings_of_a_fit_that_goes_on_are_said(tmp_path, caplog):
    """The warnings held while the counts are made are said once the placement is not refused."""
    house = make_house(seed=0)
    obs = house.observations
    image_xy = np.concatenate([[[500.0, 500.0]], obs.image_xy[1:]])  # [T, 2] one off the map
    house = dataclasses.replace(house, observations=dataclasses.replace(obs, image_xy=image_xy))
    with caplog.at_level(logging.WARNING, logger="spcopyro"):
        prepare_model_data(house, SpCoSettings())
    said = [
        r.getMessage() for r in caplog.records if "left out of the cell counts" in r.getMessage()
    ]
    assert len(said) == 1 and said[0].startswith("1 image(s) and 0 utterance(s) are farther")


def test_the_fit_s_counting_holds_back_no_record_of_another_thread(tmp_path, caplog, monkeypatch):
    """The placement warnings were held by a filter on the 'spcopyro' logger while the fit
    counted: it caught every record logged there meanwhile, by any thread (spcopyro fit's figure
    thread drawing house.png warns of a missing font), and a refusal that blames the map dropped
    them, the -v INFO line of the observations snapped with them. The counting now says nothing
    it holds: a warning of another thread during it, and the snapped line, are logged."""
    _negated(tmp_path)
    house = load_house(tmp_path / "flat")
    counting = house_module.prepared_cell_counts

    def counts_while_another_thread_warns(*args, **kwargs):
        thread = threading.Thread(
            target=lambda: logging.getLogger("spcopyro").warning("no font for these words")
        )
        thread.start()
        thread.join()
        return counting(*args, **kwargs)

    monkeypatch.setattr(house_module, "prepared_cell_counts", counts_while_another_thread_warns)
    with caplog.at_level(logging.INFO, logger="spcopyro"), pytest.raises(ValueError) as error:
        prepare_model_data(house, SpCoSettings())
    assert "the map's free space reads as occupied" in str(error.value)  # it blames negate
    said = [r.getMessage() for r in caplog.records]
    assert "no font for these words" in said, said
    assert any("snapped to the nearest free cell" in m for m in said), said
    assert not any("left out of the cell counts" in m for m in said), said


def test_the_public_houses_are_not_refused(dataset_root):
    for name in HOUSES:
        house = load_house(dataset_root / name)
        report = cell_counts(house.grid, house.observations).placement
        assert not report.free_space_inverted(), name
        assert report.unplaced_on_occupied == 0, name


def test_the_embedded_house_is_not_refused():
    house = make_house(seed=0)
    report = cell_counts(house.grid, house.observations).placement
    assert not report.free_space_inverted() and report.num_unplaced == 0


def _plan(tmp_path: Path, image: np.ndarray, negate: int = 0) -> Path:
    """``image`` ``[H, W]`` uint8 saved as ``plan.pgm`` beside ``plan.yaml``: 0.05 m cells, its
    lower-left corner at the origin, map_saver's thresholds."""
    height, width = image.shape
    header = f"P5\n{width} {height}\n255\n".encode()
    (tmp_path / "plan.pgm").write_bytes(header + image.astype(np.uint8).tobytes())
    yaml_path = tmp_path / "plan.yaml"
    yaml_path.write_text(
        f"image: plan.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: {negate}\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    return yaml_path


def test_a_negated_map_is_refused_on_a_coarsened_model_grid(tmp_path, caplog):
    """The presets' 0.25 m cells over a 0.05 m map (fit_house's model grid): the left-out
    observations are counted on the map it was coarsened from, the negate line read from its
    yaml. A 5 m plan drawn with free space white inside 0.5 m thick black walls, negate 1: the
    walls read free, in whole model cells; most of the tour, in the room, is left out."""
    image = np.zeros((100, 100), dtype=np.uint8)  # [H, W] the walls
    image[10:90, 10:90] = 254  # the room, x and y 0.5..4.5 m
    yaml_path = _plan(tmp_path, image, negate=1)
    fine = load_map(yaml_path)
    grid = coarsen_grid(fine, coarsening_factor(0.05, 0.25))  # the auto and coarse presets'
    assert grid.resolution == 0.25 and grid.coarsened_from is fine and grid.num_free
    room = np.array([[1.0 + 0.3 * i, 2.5] for i in range(10)])  # [10, 2] in the room
    walls = np.array([[0.2, 1.0 + 0.5 * i] for i in range(4)])  # [4, 2] on the walls
    obs = _observations(np.concatenate([room, walls]))
    report = cell_counts(grid, obs, warn=False).placement
    assert report.num_unplaced == 20 and report.unplaced_on_occupied == 20
    # the refusal blames negate: alone, without the warnings listing the 20 left out
    with caplog.at_level(logging.WARNING, logger="spcopyro"), pytest.raises(ValueError) as error:
        check_placement(report, obs, grid)  # the map named by the coarse grid's source
    message = str(error.value)
    assert message.startswith(
        f"20 of 28 observations are left out, 20 of them on occupied cells on map {yaml_path}"
    ), message
    assert [r.getMessage() for r in caplog.records] == []
    assert (
        f"{yaml_path}:4: negate 1 on a map whose free space is drawn white (map_saver's maps "
        "need negate: 0): with negate 0, 6400 cells would be free, not 3600, and 20 of the 20 "
        "observations left out would lie on them"
    ) in message


def test_a_floor_plan_drawn_black_where_the_tour_went_is_not_blamed_on_negate(tmp_path, caplog):
    """Most of the tour outside the drawn room, on its black: refused, but the other negate,
    which frees the outside, would leave the observations in the room out instead: the message
    names the causes on a map that is right and what to do, not negate."""
    image = np.zeros((100, 100), dtype=np.uint8)  # [H, W] black outside, and the walls
    image[30:70, 30:70] = 254  # a 2 m room, x and y 1.5..3.5 m: a drawing, not a robot's map
    grid = load_map(_plan(tmp_path, image))
    inside = np.array([[2.4 + 0.05 * i, 2.5] for i in range(4)])  # [4, 2] mid-room
    outside = np.array([[0.5 + 0.1 * i, 0.5] for i in range(8)])  # [8, 2] on the black
    obs = _observations(np.concatenate([inside, outside]))
    report = cell_counts(grid, obs, warn=False).placement
    assert report.free_space_inverted() and report.num_on_free == 8
    # the warnings naming the lines the message points to: said before it
    with caplog.at_level(logging.WARNING, logger="spcopyro"), pytest.raises(ValueError) as error:
        check_placement(report, obs, grid)  # the map named by default, as a fit names it
    message = str(error.value)
    assert message.startswith(
        f"16 of 24 observations are left out, 16 of them on occupied cells on map {grid.source}: "
    ), message
    assert "negate" not in message
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 2 and said[0].startswith(
        f"8 image(s) and 8 utterance(s) are farther than 0.25 m from free space on map "
        f"{grid.source} and were left out of the cell counts: images of index 4 "
    ), said
    assert "origin and resolution" in message and "unknown grey 205" in message
    assert "--snap-distance, now 0.25 m" in message and "remove them from the data" in message


def _observations(xy: np.ndarray) -> Observations:
    """One image and one utterance at each point ``[n, 2]``."""
    n = len(xy)
    return Observations(
        image_features=np.full((n, 2), 0.5), image_xy=xy, image_trial=np.zeros(n, dtype=int),
        utterances=[("kitchen",)] * n, word_xy=xy, word_trial=np.zeros(n, dtype=int),
    )  # fmt: skip


@pytest.mark.parametrize(
    ("cols", "refused"),
    [
        ([0, 3, 3, 3], True),  # 6 of 8 left out, all on occupied cells
        ([0, 0, 3, 3], False),  # 4 of 8 left out: half, not more
        ([0, 4, 4, 4], False),  # 6 of 8 left out on unknown cells: a map of part of the tour
        ([0, 9, 9, 9], False),  # 6 of 8 off the map
        ([0, 3, 4, 4], False),  # 6 of 8 left out, 2 on occupied cells: not more than half
        ([0, 3, 3, 4], True),  # 4 of the 6 on occupied cells
    ],
)
def test_the_rule_more_than_half_left_out_mostly_on_occupied_cells(cols, refused):
    occupancy = np.array([[FREE, UNKNOWN, UNKNOWN, OCCUPIED, UNKNOWN]], dtype=np.int8)
    grid = OccupancyGrid(occupancy, 1.0, (0.0, 0.0, 0.0))
    xy = np.array([[c + 0.5, 0.5] for c in cols])  # [4, 2] cell centres
    obs = _observations(xy)
    report = cell_counts(grid, obs, snap_distance=0.0, warn=False).placement
    assert report.free_space_inverted() == refused
    if refused:
        with pytest.raises(ValueError, match="observations are left out, .* on occupied cells"):
            check_placement(report, obs, grid)
    else:
        check_placement(report, obs, grid)


def test_check_on_free_and_check_placement_refuse_with_one_rule_and_one_message():
    """check_on_free says only that no observation lands on free space, with check_placement's
    very message; the inverted map is refused by check_placement alone (check_on_free kept an
    older rule and message of its own for it, without the negate line's evidence)."""
    occupancy = np.array([[FREE, UNKNOWN, UNKNOWN, OCCUPIED, UNKNOWN]], dtype=np.int8)
    grid = OccupancyGrid(occupancy, 1.0, (0.0, 0.0, 0.0), source="M")  # named " on map M"
    for cols, said in (
        ([3, 3, 3, 4], "no observation lands on free space: 8 of 8"),  # none on free space
        ([0, 3, 3, 3], "6 of 8 observations are left out, 6 of them on occupied cells"),
    ):
        obs = _observations(np.array([[c + 0.5, 0.5] for c in cols]))  # [4, 2]
        report = cell_counts(grid, obs, snap_distance=0.0, warn=False).placement
        with pytest.raises(ValueError) as by_placement:
            check_placement(report, obs, grid)
        assert str(by_placement.value).startswith(said)
        if report.num_on_free:  # inverted: check_placement's rule, not check_on_free's
            report.check_on_free(" on map M")
            continue
        with pytest.raises(ValueError) as by_free:
            report.check_on_free(" on map M")
        assert str(by_free.value) == str(by_placement.value)


def test_the_counted_and_the_weighed_left_out_positions_are_one_gathering():
    """cell_counts counts the left-out observations on occupied cells from left_out_and_placed,
    the positions inverted_free_space_message weighs: images, utterances, then each further
    modality, left out or placed by the report's indices."""
    from spcopyro.data.observations import ModalityObservations
    from spcopyro.data.placement import count_on_occupied, left_out_and_placed

    occupancy = np.array([[FREE, UNKNOWN, UNKNOWN, OCCUPIED, UNKNOWN]], dtype=np.int8)
    grid = OccupancyGrid(occupancy, 1.0, (0.0, 0.0, 0.0))
    obs = _observations(np.array([[c + 0.5, 0.5] for c in (0, 3, 3, 4)]))  # [4, 2]
    objects = ModalityObservations(
        "objects", ("cup",), np.array([[3.5, 0.5], [0.5, 0.5], [9.5, 0.5]]),
        np.zeros(3, dtype=int), np.ones((3, 1)),
    )  # fmt: skip
    obs = dataclasses.replace(obs, modalities=(objects,))
    report = cell_counts(grid, obs, snap_distance=0.0, warn=False).placement
    left_out, placed = left_out_and_placed(report, obs)  # [n, 2], [m, 2]
    np.testing.assert_array_equal(
        left_out, [[3.5, 0.5], [3.5, 0.5], [4.5, 0.5]] * 2 + [[3.5, 0.5], [9.5, 0.5]]
    )
    np.testing.assert_array_equal(placed, [[0.5, 0.5]] * 3)
    assert report.num_unplaced == len(left_out) and report.num_placed == len(placed)
    assert report.unplaced_on_occupied == count_on_occupied(grid, left_out) == 5


@pytest.mark.parametrize(
    ("edit", "cause"),
    [
        (("negate: 0", "negate: 1"), "the map's free space reads as occupied: {yaml}:4: negate 1 "),
        (("free_thresh: 0.196", "free_thresh: 0"), "the map {yaml} has no free cell, nothing to "),
    ],
)
def test_a_house_s_truth_does_not_hide_the_map_s_own_refusal(tmp_path, capsys, edit, cause):
    """A house with truth.npy on a map whose free space reads as occupied (negate 1 on a map
    drawn white) or that has no free cell: the truth's labels lie off free space, and its
    refusal ("3600 non-free cell(s) carry a category") came first, hiding the map's, which
    names the yaml's lines. The map's refusal (the cause) comes first now."""
    save_house(make_house(seed=0, name="flat"), tmp_path)
    yaml_path = tmp_path / "map" / "flat.yaml"
    text = yaml_path.read_text()
    assert edit[0] in text and (tmp_path / "flat" / "truth.npy").is_file()
    yaml_path.write_text(text.replace(*edit))
    argv = ["fit", str(tmp_path / "flat"), "--out", str(tmp_path / "fit"), "--sweeps", "2"]
    assert main([*argv, "--no-figures"]) == 2
    refusal = capsys.readouterr().err.splitlines()[-1]
    assert refusal.startswith(f"error: house 'flat': {cause.format(yaml=yaml_path)}"), refusal
    assert "carry a category" not in refusal


def _plan_house(tmp_path: Path, xy: np.ndarray, negate: int) -> Path:
    """A 5 m plan drawn with free space white inside 0.5 m thick black walls (the room x and y
    0.5..4.5 m), its yaml saying ``negate``, as house ``plan``'s map (ROOT/map/plan.yaml), with
    one image and one utterance at each point ``[n, 2]``: its room folder."""
    image = np.zeros((100, 100), dtype=np.uint8)  # [H, W] the walls
    image[10:90, 10:90] = 254
    grid = load_map(_plan(tmp_path, image))  # negate 0: the room reads free
    save_house(House("plan", grid, _observations(xy)), tmp_path)
    _plan(tmp_path / "map", image, negate)  # the yaml and image save_house wrote, replaced
    return tmp_path / "plan"


@pytest.mark.parametrize(
    ("xy", "cause"),
    [  # in the room: the other negate places them; off the map: it would not
        ([[1.0 + 0.3 * i, 2.5] for i in range(10)], "the map's free space reads as occupied: "
         "{yaml}:4: negate 1 on a map whose free space is drawn white (map_saver's maps need "
         "negate: 0): with negate 0, 6400 cells would be free, not 3600, and 20 of the 20 "
         "observations left out would lie on them"),
        ([[20.0 + 0.3 * i, 2.5] for i in range(10)], "the map or its origin is wrong, or its "
         "negate flag inverts free space (check {yaml}:4: negate 1)"),
    ],
)  # fmt: skip
def test_no_observation_on_free_space_names_the_yaml_s_negate_line(tmp_path, capsys, xy, cause):
    """negate: 1 on a map drawn with free space white, the whole tour off free space: the
    refusal "no observation lands on free space" said only "its negate flag inverts free space
    (check the map yaml)", where the inverted map's refusal names the yaml's negate line and
    value. It names them too now: as the cause where the other negate would place the tour
    (:func:`~spcopyro.maps.free_space.negate_hint`, the inverted map's evidence), else as what
    to check."""
    room = _plan_house(tmp_path, np.array(xy), negate=1)
    argv = ["fit", str(room), "--out", str(tmp_path / "fit"), "--sweeps", "2", "--no-figures"]
    assert main(argv) == 2
    refusal = capsys.readouterr().err.splitlines()[-1]
    yaml_path = tmp_path / "map" / "plan.yaml"
    assert refusal.startswith("error: no observation lands on free space: 20 of 20 "), refusal
    assert refusal.endswith(f"; {cause.format(yaml=yaml_path)}"), refusal


@pytest.mark.parametrize("room", [True, False])  # the other negate places the tour, or not
def test_the_refusals_naming_the_negate_line_read_the_map_image_once(tmp_path, monkeypatch, room):
    """The refusal "no observation lands on free space" and the truth's map refusal each read
    the map's image once: check_placement read yaml and image again for the negate line
    (negate_line, whose text is used only where negate_hint is ""; now it reads the yaml
    alone, and only then), truth_negate_hint read them again in negate_hint after weighing the
    labels on what it had read."""
    import spcopyro.maps.free_space as free_space

    image = np.zeros((100, 100), dtype=np.uint8)  # [H, W] the walls
    image[10:90, 10:90] = 254  # the room, x and y 0.5..4.5 m
    grid = load_map(_plan(tmp_path, image, negate=1))
    images, yamls = [], []
    read_levels, read_yaml = free_space._read_levels, free_space.read_map_yaml
    monkeypatch.setattr(free_space, "_read_levels", lambda s: images.append(s) or read_levels(s))
    monkeypatch.setattr(
        free_space, "read_map_yaml", lambda p, **k: yamls.append(p) or read_yaml(p, **k)
    )
    obs = _observations(np.array([[1.0 + 0.3 * i, 2.5 if room else 20.0] for i in range(10)]))
    report = cell_counts(grid, obs, warn=False).placement
    with pytest.raises(ValueError, match="no observation lands on free space"):
        check_placement(report, obs, grid)
    assert (len(images), len(yamls)) == (1, 1 if room else 2)  # off the map: the negate line
    if room:  # the truth of the room, drawn for negate 0
        images.clear()
        yamls.clear()
        labelled = np.argwhere(image == 254)  # [6400, 2] (row, col): the room's cells
        assert free_space.truth_negate_hint(grid, labelled).endswith("not 3600")
        assert (len(images), len(yamls)) == (1, 1)
