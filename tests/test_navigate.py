"""`spcopyro navigate` (issue 27): goals from words, shortest paths with clearance, the outputs.

The house: four rooms in a row joined by 0.5 m doorways -- A (bedroom), B (corridor),
C (kitchen), E (bedroom again: the word is ambiguous) -- and D (closet) below them, walled off:
its place can never be reached."""

from __future__ import annotations

import csv
import dataclasses
import math
import re

import numpy as np
import pytest
import yaml
from hand_results import one_word_per_concept

from spcopyro.cli.main import attach_negative_coordinates, main
from spcopyro.maps import FREE, OCCUPIED, OccupancyGrid
from spcopyro.results.result import SpCoResult
from spcopyro.robot.navigation import (
    AmbiguousGoalError,
    NavigationError,
    UnreachableGoalError,
    navigate,
    parse_instruction,
    planning_grid,
)
from spcopyro.robot.navigation.graph import fit_cells_on
from spcopyro.robot.navigation.outputs import write_plan

WORDS = ("bedroom", "corridor", "kitchen", "closet", "the")
RES = 0.1
ROOMS = {"A": (1, 10), "B": (11, 20), "C": (21, 30), "E": (31, 40)}  # columns [start, stop)
CONCEPT = {"A": 0, "B": 1, "C": 2, "E": 0, "D": 3}


def house_grid() -> OccupancyGrid:
    occupancy = np.full((29, 41), OCCUPIED, dtype=np.int8)  # [H, W]
    for c0, c1 in ROOMS.values():
        occupancy[1:19, c0:c1] = FREE
    for wall in (10, 20, 30):
        occupancy[8:13, wall] = FREE  # 0.5 m doorways
    occupancy[20:28, 1:40] = FREE  # D, no door
    return OccupancyGrid(occupancy=occupancy, resolution=RES, origin=(0.0, 0.0, 0.0))


def house_result() -> SpCoResult:
    grid = house_grid()
    image = np.full(grid.shape, -1)
    for room, (c0, c1) in ROOMS.items():
        image[1:19, c0:c1] = CONCEPT[room]
    for wall in (10, 20, 30):
        image[8:13, wall] = CONCEPT["B"] if wall < 30 else CONCEPT["C"]
    image[20:28, 1:40] = CONCEPT["D"]
    labels = image[grid.free]
    return one_word_per_concept(grid, labels, WORDS)


def xy(row: int, col: int) -> tuple[float, float]:
    x, y = house_grid().cell_to_world(np.array([row, col]))
    return float(x), float(y)


START_A = xy(4, 3)  # in room A
START_B = xy(10, 12)  # in the corridor, near A's door


@pytest.fixture(scope="module")
def result():
    return house_result()


@pytest.fixture
def fit(tmp_path, result):
    return result.save(tmp_path / "fit")


def room_of(result, point) -> str:
    row, col = result.grid.world_to_cell(np.array(point))
    label = result.label_image()[row, col]
    if row >= 20:
        return "D"
    return next(r for r, (c0, c1) in ROOMS.items() if c0 <= col < c1) if label >= 0 else "?"


def brute_clearance(grid: OccupancyGrid, cell) -> float:
    blocked = np.argwhere(~np.pad(grid.free, 1, constant_values=False)) - 1  # [B, 2]
    d = np.hypot(*(blocked - np.asarray(cell)).T).min() * grid.resolution
    return d - grid.resolution / 2


@pytest.mark.parametrize("radius", [0.0, 0.1, 0.2])
def test_paths_stay_on_free_cells_and_keep_the_clearance(result, radius):
    plan = navigate(result, "go to the kitchen via the corridor", START_A, radius=radius)
    grid = result.grid
    cells = grid.world_to_cell(plan.path_xy)  # [K, 2]
    assert grid.is_free(cells).all()
    for cell in cells:
        assert brute_clearance(grid, cell) >= radius - 1e-9
    steps = np.diff(cells, axis=0)
    assert np.abs(steps).max() == 1  # 8-neighbours, no jumps
    for (r, c), (dr, dc) in zip(cells[:-1], steps, strict=True):
        if dr and dc:  # no corner cutting: both cells beside a diagonal step are allowed
            for side in ((r + dr, c), (r, c + dc)):
                assert brute_clearance(grid, side) >= radius - 1e-9
    assert room_of(result, plan.goal.xy) == "C"
    assert plan.length == pytest.approx(np.hypot(*np.diff(plan.path_xy, axis=0).T).sum())


def test_a_radius_wider_than_the_doorways_makes_the_kitchen_unreachable(result):
    with pytest.raises(UnreachableGoalError, match="cannot be reached"):
        navigate(result, "kitchen", xy(9, 5), radius=0.3)  # 0.5 m doorways: 0.25 m at most


def test_an_unreachable_place_is_reported_not_returned(result, fit, capsys):
    with pytest.raises(UnreachableGoalError, match="'closet'"):
        navigate(result, "go to the closet", START_A)
    out = fit.parent / "plan"
    code = main(["navigate", str(fit), "go to the closet", f"--start={START_A[0]},{START_A[1]}",
                 "--out", str(out)])  # fmt: skip
    assert code == 3
    assert "no place of 'closet' is reachable" in capsys.readouterr().err
    assert not out.exists()


def test_via_orders_are_kept(result):
    assert parse_instruction("go to the kitchen via the corridor", WORDS).places == (
        "corridor", "kitchen")  # fmt: skip
    assert parse_instruction("via the corridor to the kitchen", WORDS).places == (
        "corridor", "kitchen")  # fmt: skip
    parsed = parse_instruction("to the kitchen via the corridor, then the bedroom", WORDS)
    assert parsed.places == ("corridor", "kitchen", "bedroom")
    assert parsed.via == (True, False, False)
    start_e = xy(10, 35)  # in E: the kitchen is next door, the corridor beyond it
    plan = navigate(result, "go to the kitchen via the corridor", start_e)
    assert [s.word for s in plan.stops] == ["corridor", "kitchen"]
    corridor, kitchen = plan.stops
    assert room_of(result, corridor.xy) == "B" and room_of(result, kitchen.xy) == "C"
    assert 0 < corridor.path_index < kitchen.path_index == len(plan.path_xy) - 1
    assert tuple(plan.path_xy[corridor.path_index]) == pytest.approx(corridor.xy)
    direct = navigate(result, "go to the kitchen", start_e)
    assert plan.length > direct.length + 2.0  # the detour through the corridor is driven


def test_a_place_said_twice_in_a_row_is_one_stop():
    """QA: "kitchen kitchen" planned two identical stops (a path of length 0 to the second);
    a place named again later is visited again."""
    assert parse_instruction("kitchen kitchen", WORDS).places == ("kitchen",)
    parsed = parse_instruction("via the kitchen to the kitchen", WORDS)
    assert (parsed.places, parsed.via) == (("kitchen",), (False,))
    parsed = parse_instruction("the kitchen, then the bedroom, then the kitchen", WORDS)
    assert parsed.places == ("kitchen", "bedroom", "kitchen")


@pytest.mark.parametrize(
    ("text", "places", "via"),
    [
        ("go to the kitchen, then via the corridor to the bedroom",
         ("kitchen", "corridor", "bedroom"), (False, True, False)),
        ("go to the kitchen and after that through the corridor to the bedroom",
         ("kitchen", "corridor", "bedroom"), (False, True, False)),
        ("via the corridor to the kitchen, then via the closet to the bedroom",
         ("corridor", "kitchen", "closet", "bedroom"), (True, False, True, False)),
        ("go to the bedroom via the corridor, then the kitchen",
         ("corridor", "bedroom", "kitchen"), (True, False, False)),
    ],
)  # fmt: skip
def test_a_via_after_then_leads_to_the_next_destination(text, places, via):
    """QA: "go to the kitchen, then via the corridor to the bedroom" visited the corridor
    first: the "via" place went before the destination said before "then"."""
    parsed = parse_instruction(text, WORDS)
    assert (parsed.places, parsed.via) == (places, via)


@pytest.mark.parametrize(
    ("text", "stop"),
    [("go to the kitchen via the hall", "via the hall"),
     ("go to the parlor and then the kitchen", "to the parlor"),
     ("go to the kitchen, then back to the start", "to the start"),
     ("go to the parlor and the kitchen", "to the parlor")],
)  # fmt: skip
def test_a_stop_the_fit_does_not_know_is_refused_not_skipped(text, stop, fit, capsys):
    """QA: "go to the washroom via the corridor" on a fit that never heard "corridor" drove
    straight to the washroom (the waypoint ignored, with a warning); "then back to the start"
    ended in the kitchen."""
    with pytest.raises(ValueError, match=f"names a stop \\('{stop}'\\) that is not in the fit"):
        parse_instruction(text, WORDS)
    assert main(["navigate", str(fit), text, "--start", f"{START_A[0]},{START_A[1]}"]) == 2
    assert "navigate would skip it and drive to" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("text", "places"),
    [("go to the big kitchen", ("kitchen",)), ("go quickly to the kitchen", ("kitchen",)),
     ("then quickly go to the kitchen", ("kitchen",)),
     ("go to the kitchen via the wide corridor", ("corridor", "kitchen")),
     ("go to the bedroom at the end of the hall", ("bedroom",))],
)  # fmt: skip
def test_unknown_words_that_name_no_stop_are_still_ignored(text, places):
    parsed = parse_instruction(text, WORDS)
    assert parsed.places == places and parsed.ignored


def test_instructions_in_other_scripts_find_the_fits_words():
    """QA: the instruction was split on ASCII letters only: "go to the café" said "word 'caf'
    ... did you mean café?", and "go to the 台所" named no place, though the fit's words (and
    `spcopyro where`) hold them."""
    vocabulary = ("bedroom", "corridor", "台所", "café", "ダイニング")
    for text, places in [
        ("go to the 台所", ("台所",)),
        ("Go to the CAFÉ.", ("café",)),
        ("go to the cafe\u0301", ("café",)),  # decomposed: e + combining acute
        ("go to the 台所 via the ダイニング", ("ダイニング", "台所")),
        ("the corridor, then the bedroom", ("corridor", "bedroom")),
    ]:
        assert parse_instruction(text, vocabulary).places == places, text
    with pytest.raises(ValueError, match="word 'cafe' of the instruction .* did you mean café"):
        parse_instruction("go to the cafe", vocabulary)
    grid = house_grid()
    plan = navigate(one_word_per_concept(grid, house_result().labels, ("bedroom", "corridor",
                    "台所", "closet")), "台所 に 行って", START_A)  # fmt: skip
    assert [s.word for s in plan.stops] == ["台所"] and plan.instruction.ignored == ("に", "行って")


@pytest.mark.parametrize(
    ("text", "places"),
    [
        ("go to the kitchen after the corridor", ("corridor", "kitchen")),
        ("go to the kitchen, but first the corridor", ("corridor", "kitchen")),
        ("after the corridor go to the kitchen", ("corridor", "kitchen")),
        ("go to the corridor first, then the kitchen", ("corridor", "kitchen")),
        ("go to the corridor and after that the kitchen", ("corridor", "kitchen")),
        ("go to the corridor before the kitchen", ("corridor", "kitchen")),
        ("go to the kitchen after the corridor, then the bedroom", ("corridor", "kitchen",
                                                                   "bedroom")),
    ],
)  # fmt: skip
def test_after_first_and_before_give_the_order_they_say(text, places):
    """QA: "after", "first" and "before" were skipped as filler words, so "go to the kitchen
    after the corridor" went to the kitchen first, then the corridor."""
    parsed = parse_instruction(text, WORDS)
    assert parsed.places == places and not any(parsed.via)


@pytest.mark.parametrize("text", ["before the kitchen, the corridor", "go to the kitchen, but "
                                  "before that the corridor"])  # fmt: skip
def test_a_before_whose_order_navigate_cannot_tell_is_refused(text):
    with pytest.raises(NavigationError, match="say them in the order to visit them"):
        parse_instruction(text, WORDS)


@pytest.mark.parametrize(
    "text",
    ["go to the bedroom, not the kitchen", "avoid the kitchen", "Don't enter the KITCHEN",
     "Don\u2019t go to the kitchen",  # a typographic apostrophe split it into 'don', 't'
     "you shouldn't enter the kitchen",  # any n't
     "go to the kitchen or the bedroom", "go to the kitchen instead of the bedroom"],
)  # fmt: skip
def test_an_instruction_that_keeps_away_from_a_place_is_refused(text, fit, capsys):
    """QA: "go to the bathroom, not the kitchen" planned bathroom -> kitchen: the negation was
    skipped as a filler word and the robot sent to the place it was told to keep away from; "the
    kitchen or the bedroom" and "the kitchen instead of the bedroom" visited both."""
    with pytest.raises(NavigationError, match="cannot keep the robot away from one"):
        parse_instruction(text, WORDS)
    assert main(["navigate", str(fit), text, "--start", f"{START_A[0]},{START_A[1]}"]) == 2
    assert "--mode keepout" in capsys.readouterr().err


@pytest.mark.parametrize(
    "text, said",
    [("leave the kitchen", "leave"), ("stay away from the kitchen", "away"),
     ("get out of the kitchen", "out of"), ("steer clear of the kitchen", "clear of"),
     ("go anywhere but the kitchen", "anywhere"), ("exit the kitchen", "exit"),
     ("bypass the kitchen on the way to the bedroom", "bypass")],
)  # fmt: skip
def test_an_instruction_that_sends_the_robot_out_of_a_place_is_refused(text, said, fit, capsys):
    """QA: "leave the kitchen", "stay away from the kitchen", "get out of the kitchen" drove
    into the kitchen: "leave", "away", "get" were ignored as words the fit does not know."""
    with pytest.raises(NavigationError, match=f"says '{said}': .*cannot keep the robot away"):
        parse_instruction(text, WORDS)
    assert main(["navigate", str(fit), text, "--start", f"{START_A[0]},{START_A[1]}"]) == 2
    assert "--mode keepout" in capsys.readouterr().err


@pytest.mark.parametrize("vocabulary", [(), ("the", "go")])
def test_a_fit_without_place_words_says_so(vocabulary):
    """It said "known words: " with nothing after."""
    with pytest.raises(ValueError, match="known words: none: the fit has no word that can name"):
        parse_instruction("go to the kitchen", vocabulary)


@pytest.mark.parametrize(
    ("text", "said"), [("", "is empty"), ("  ", "is empty"), (" ?! ", "has no words")]
)
def test_an_empty_instruction_says_so_and_gives_an_example(text, said, fit, capsys):
    """QA: `spcopyro navigate FIT ""` said "the instruction '' names no place the fit knows"."""
    with pytest.raises(
        ValueError, match=f"the instruction '{re.escape(text)}' {said}: .*e\\.g\\. "
    ):
        parse_instruction(text, WORDS)
    assert main(["navigate", str(fit), text, "--start", f"{START_A[0]},{START_A[1]}"]) == 2
    err = capsys.readouterr().err
    assert "names no place" not in err and "e.g. 'go to the bedroom'" in err, err
    assert "known words: bedroom, closet, corridor, kitchen" in err, err


def test_a_place_word_the_fit_knows_is_not_a_leave_word():
    """A house whose exit is a place: "go to the exit" goes there; "out" alone is no "out of"."""
    assert parse_instruction("go to the exit", (*WORDS, "exit")).places == ("exit",)
    assert parse_instruction("go out to the kitchen", WORDS).places == ("kitchen",)


def test_the_route_names_every_stop_in_a_place(result, tmp_path, capsys):
    """QA: "go to the kitchen via the sink" with both words in one place printed "route:
    bedroom -> corridor -> kitchen": the via stop's word vanished from the route (a place's
    word was the last stop's of all that ended there)."""
    images, words = result.emissions
    w = np.full((4, 5), 0.02)  # the vocabulary WORDS, "the" renamed "sink": kitchen's too
    w[[0, 1, 3], [0, 1, 3]] = 0.9
    w[2, [2, 4]] = 0.45
    words = dataclasses.replace(words, items=WORDS[:4] + ("sink",),
                                probabilities=w / w.sum(1, keepdims=True))  # fmt: skip
    result = dataclasses.replace(result, emissions=(images, words))
    plan = navigate(result, "go to the kitchen via the sink", START_A)
    assert plan.stop_places[0] == plan.stop_places[1]
    assert plan.route_words == ("bedroom", "corridor", "sink/kitchen")
    plan = navigate(result, "the sink, then the corridor, then the kitchen", START_A)
    assert plan.route_words == ("bedroom", "corridor", "sink", "corridor", "kitchen")
    fit = result.save(tmp_path / "fit")
    assert main(["navigate", str(fit), "go to the kitchen via the sink", "--start",
                 f"{START_A[0]},{START_A[1]}"]) == 0  # fmt: skip
    assert "route: bedroom -> corridor -> sink/kitchen\n" in capsys.readouterr().out


def test_an_ambiguous_word_takes_the_nearer_unless_strict(result, fit, capsys):
    plan = navigate(result, "bedroom", START_B)
    choice = plan.goal.choice
    assert choice.ambiguous and len(choice.candidates) == 2
    assert room_of(result, plan.goal.xy) == "A"  # nearer to the corridor's left end
    far = navigate(result, "bedroom", xy(10, 28))  # in C, next to E
    assert room_of(result, far.goal.xy) == "E"
    with pytest.raises(AmbiguousGoalError, match="ambiguous: 2 separate regions"):
        navigate(result, "bedroom", START_B, strict=True)
    start = f"--start={START_B[0]},{START_B[1]}"
    assert main(["navigate", str(fit), "go to the bedroom", start]) == 0
    printed = capsys.readouterr().out
    assert "ambiguous: 2 separate regions" in printed and printed.count(" m away") == 2
    assert main(["navigate", str(fit), "go to the bedroom", start, "--strict"]) == 2
    assert "--strict takes none" in capsys.readouterr().err


def test_a_candidate_under_one_square_metre_shows_its_area_to_two_decimals(tmp_path, capsys):
    """navigate wrote a candidate's area to one decimal: a goal of 0.25 m^2 read "0.3 m^2 of
    the place the robot fits in" beside its warning's "the goal is in the largest, 0.25 m^2".
    Below 1 m^2 the stop line, the ambiguous candidates and an unreachable one's warning give
    two decimals, as the place graph's areas."""
    image = house_result().label_image()  # [H, W]
    image[image == CONCEPT["D"]] = CONCEPT["B"]
    for rows, cols in ((slice(20, 28), slice(10, 18)), (slice(6, 14), slice(1, 9)),
                       (slice(6, 14), slice(32, 40))):  # fmt: skip
        image[rows, cols] = CONCEPT["D"]  # 8 x 8 cells, 0.64 m^2: walled off, in A, in E
    fit = one_word_per_concept(house_grid(), image[house_grid().free], WORDS).save(tmp_path / "f")
    start = f"--start={START_B[0]},{START_B[1]}"
    assert main(["navigate", str(fit), "go to the closet", start, "--radius", "0"]) == 0
    out, err = capsys.readouterr()
    assert "0.64 m^2 of the place the robot fits in" in out, out
    assert out.count(" p(cell is the place) = 0.917, 0.64 m^2, ") == 2, out
    assert "(p(cell is the place) = 0.917, 0.64 m^2) cannot be reached" in err, err


def test_an_answer_where_calls_a_guess_is_warned_of_and_refused_when_strict(
    result, capsys, monkeypatch
):
    """'kitchen' nearly as probable under the corridor's concept as under the kitchen's:
    `where` warns that its answer is not clearly more probable than the runner-up, and navigate
    drove there without a word (its own ambiguity is two regions of near-equal p, a laxer
    rule)."""
    import dataclasses

    from spcopyro.results.result import EmissionTable

    w = result.emission("words").probabilities.copy()  # [L, V]
    w[1, WORDS.index("kitchen")] = w[2, WORDS.index("kitchen")] * 0.7
    w /= w.sum(1, keepdims=True)
    emissions = tuple(
        EmissionTable("words", WORDS, w) if e.name == "words" else e for e in result.emissions
    )
    guessed = dataclasses.replace(result, emissions=emissions)
    assert any("not clearly more probable" in x for x in guessed.where("kitchen").warnings)
    plan = navigate(guessed, "go to the kitchen", START_A)
    assert any(n.startswith("where 'kitchen': ") and "not clearly more probable" in n
               for n in plan.goal.choice.notes)  # fmt: skip
    with pytest.raises(AmbiguousGoalError, match="'kitchen' is ambiguous: .*not clearly more"):
        navigate(guessed, "go to the kitchen", START_A, strict=True)
    from spcopyro.robot.navigation.outputs import summary

    (stop,) = summary(plan, "map", None)["stops"]
    assert stop["close_to_guess"] and stop["where_odds"] < 3  # a robot reads a number, not text
    (clear,) = summary(navigate(result, "kitchen", START_A), "map", None)["stops"]
    assert not clear["close_to_guess"] and clear["where_odds"] > 3
    assert not navigate(result, "go to the kitchen", START_A).goal.choice.notes  # a clear answer
    # --strict reads the answer's odds, not its warning's wording
    answer = guessed.where("kitchen")
    assert answer.close_to_guess
    assert answer.odds == pytest.approx(answer.probability / answer.runner_up_probability)
    assert answer.odds < 3
    assert not result.where("kitchen").close_to_guess
    # --strict's refusal spells the odds as where's warning does (where.close_odds), to the byte
    (said,) = [x for x in answer.warnings if x.endswith(": treat the answer with care")]
    with pytest.raises(AmbiguousGoalError) as refused:
        navigate(guessed, "go to the kitchen", START_A, strict=True)
    sentence = said.removesuffix(": treat the answer with care")
    assert (
        str(refused.value)
        == f"'kitchen' is ambiguous: {sentence}: --strict drives to no such answer"
    )
    worded = dataclasses.replace(answer, warnings=("reworded",))
    monkeypatch.setattr(type(guessed), "where", lambda self, word, prior="area": worded)
    with pytest.raises(AmbiguousGoalError, match=f"odds {answer.odds:.2f} < 3"):
        navigate(guessed, "go to the kitchen", START_A, strict=True)


def test_the_goal_lies_in_the_middle_of_a_region_of_equal_probability(result):
    goal = navigate(result, "kitchen", START_A).goal
    row, col = result.grid.world_to_cell(np.array(goal.xy))
    assert 7 <= row <= 11 and 23 <= col <= 27  # room C spans rows 1-18, cols 21-29


def _load(path):
    return yaml.safe_load(path.read_text())


def _check_pose_stamped(message, frame):
    assert set(message) == {"header", "pose"}
    assert message["header"] == {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": frame}
    assert set(message["pose"]["position"]) == {"x", "y", "z"}
    q = message["pose"]["orientation"]
    assert set(q) == {"x", "y", "z", "w"}
    assert q["x"] == q["y"] == 0.0
    assert math.isclose(q["z"] ** 2 + q["w"] ** 2, 1.0)
    return message["pose"]["position"], 2 * math.atan2(q["z"], q["w"])


def test_outputs_load_into_the_fields_of_nav2_messages(fit, tmp_path, capsys):
    out = tmp_path / "plan"
    code = main(["navigate", str(fit), "go to the kitchen via the corridor",
                 f"--start={START_A[0]},{START_A[1]}", "--out", str(out),
                 "--frame", "robot1/map"])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert "corridor (via) -> kitchen" in capsys.readouterr().out
    goal_position, goal_yaw = _check_pose_stamped(_load(out / "goal.yaml"), "robot1/map")
    path = _load(out / "path.yaml")
    assert set(path) == {"header", "poses"} and path["header"]["frame_id"] == "robot1/map"
    poses = [_check_pose_stamped(p, "robot1/map") for p in path["poses"]]
    assert poses[-1][0] == goal_position
    last, before = poses[-1][0], poses[-2][0]
    heading = math.atan2(last["y"] - before["y"], last["x"] - before["x"])
    assert goal_yaw == pytest.approx(heading)  # facing along the path's end
    for (a, yaw), (b, _) in zip(poses[:-1], poses[1:], strict=True):
        assert yaw == pytest.approx(math.atan2(b["y"] - a["y"], b["x"] - a["x"]))
    waypoints = _load(out / "waypoints.yaml")
    assert set(waypoints) == {"poses"} and len(waypoints["poses"]) == 2
    assert _check_pose_stamped(waypoints["poses"][-1], "robot1/map")[0] == goal_position
    with open(out / "path.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(poses) and list(rows[0]) == ["index", "x", "y", "yaw", "distance_m"]
    assert float(rows[-1]["x"]) == pytest.approx(goal_position["x"], abs=1e-4)
    assert (out / "navigate.png").stat().st_size > 0
    summary = yaml.safe_load((out / "navigate.json").read_text())  # JSON is YAML
    assert summary["places"] == ["corridor", "kitchen"] and summary["frame_id"] == "robot1/map"
    # a second run into the folder needs --overwrite, and replaces only a plan
    argv = ["navigate", str(fit), "kitchen", f"--start={START_A[0]},{START_A[1]}", "--out",
            str(out), "--no-figure"]  # fmt: skip
    assert main(argv) == 2
    refused = capsys.readouterr()
    assert "--overwrite" in refused.err
    assert "goal x=" not in refused.out  # refused before a plan is printed
    assert main([*argv, "--overwrite"]) == 0
    assert not (out / "navigate.png").exists()
    assert main([*argv[:4], "--out", str(fit), "--overwrite"]) == 2
    assert "no navigate wrote" in capsys.readouterr().err


def test_a_run_is_reproducible(result, tmp_path):
    files = []
    for k in range(2):
        plan = navigate(result, "go to the bedroom via the kitchen", START_B, radius=0.1)
        written = write_plan(plan, tmp_path / f"plan{k}", figure=False)
        files.append({n: p.read_bytes() for n, p in written.items() if n != "navigate.json"})
    assert files[0] == files[1]


def test_a_seeded_fit_gives_the_same_plan(tmp_path):
    from spcopyro.config import preset
    from spcopyro.fit.house import fit_house
    from spcopyro.synthetic import HouseSpec, make_house

    house = make_house(seed=0, spec=HouseSpec.scaled(45, 60))
    word = house.category_names[0]
    goals = []
    for _ in range(2):
        fitted = fit_house(house, preset("coarse"), sweeps=20, seed=3, progress=False)
        start = house.grid.cell_to_world(house.grid.free_cells[len(house.grid.free_cells) // 2])
        plan = navigate(fitted, word, tuple(start), radius=0.0, grid=house.grid)
        goals.append((plan.goal.xy, plan.path_xy.tolist()))
    assert goals[0] == goals[1]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["go to the kitchn", "--start=0.35,1.45"], "did you mean kitchen"),
        (["go there now", "--start=0.35,1.45"], "names no place the fit knows"),
        (["kitchen", "--start=50,1"], "off the map, which spans x 0.00..4.10"),
        (["kitchen", "--start=1e308,1"], "off the map, which spans x 0.00..4.10"),  # overflowed
        (["kitchen", "--start=0.05,1.45"], "not free (a wall or unknown space)"),
        (["kitchen", "--start=0.15,1.45", "--radius", "0.2"], "closer than the robot's radius"),
        (
            ["kitchen", "--start=0.15,1.45", "--radius", "0.2"],
            "the nearest cell with that clearance is at x=0.35 y=1.45 (0.20 m away)",
        ),
        (["kitchen", "--start=0.35,1.45", "--frame", "map frame"], "a tf frame id"),
        (
            ["kitchen", "--start=0.35,1.45", "--frame", "/map"],  # tf2 refuses a leading /
            "tf2 frame ids cannot start with '/' (tf2 refuses them); use 'map'",
        ),
    ],
)
def test_command_line_errors_are_clear(fit, capsys, argv, message):
    assert main(["navigate", str(fit), *argv]) == 2
    assert message in capsys.readouterr().err


def test_a_start_at_the_goal_is_a_path_of_one_pose(result, fit, capsys):
    """It printed "path: 1 poses"."""
    goal = navigate(result, "kitchen", START_A).goal.xy
    assert main(["navigate", str(fit), "kitchen", f"--start={goal[0]},{goal[1]}"]) == 0
    assert "path: 1 pose, 0.00 m" in capsys.readouterr().out


def test_a_bad_start_value_is_a_usage_error(fit, capsys):
    with pytest.raises(SystemExit):
        main(["navigate", str(fit), "kitchen", "--start", "one,two"])
    assert "give X,Y in metres" in capsys.readouterr().err


def test_a_finer_map_takes_the_fits_probabilities(result):
    grid = result.grid
    fine_occupancy = np.repeat(np.repeat(grid.occupancy, 2, axis=0), 2, axis=1)
    fine = OccupancyGrid(fine_occupancy, RES / 2, grid.origin)
    carried = fit_cells_on(grid, fine)  # [N_fine]
    expected = grid.free_index[fine.free_cells[:, 0] // 2, fine.free_cells[:, 1] // 2]
    np.testing.assert_array_equal(carried, expected)
    plan = navigate(result, "kitchen", START_A, grid=fine, radius=0.1)
    assert room_of(result, plan.goal.xy) == "C"
    assert planning_grid(fine, 0.1).num_allowed < fine.num_free


def test_a_map_that_is_not_the_fits_is_refused(result, fit, tmp_path, capsys):
    """--map of another house (or another origin) in the fit's frame: the fit's places would lie
    across its walls, so the plan is refused with both maps' extents; the fit's own map (and a
    finer copy of it) is taken."""
    from spcopyro.maps import save_map
    from spcopyro.robot.navigation.graph import map_coverage

    grid = result.grid
    shifted = OccupancyGrid(grid.occupancy, RES, (grid.origin[0] + 2.0, *grid.origin[1:]))
    assert map_coverage(grid, grid) == 1.0 and map_coverage(grid, shifted) < 0.8
    save_map(shifted, tmp_path / "other.yaml")
    start = f"--start={START_A[0]},{START_A[1]}"
    argv = ["navigate", str(fit), "go to the kitchen", start, "--map", str(tmp_path / "other.yaml")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "other.yaml is not the fit's map" in err and "pass the map the fit was made on" in err
    with pytest.raises(ValueError, match="not the fit's map"):
        navigate(result, "kitchen", START_A, grid=shifted, radius=0.1)
    save_map(grid, tmp_path / "own.yaml")
    assert main([*argv[:-1], str(tmp_path / "own.yaml")]) == 0


def test_a_coarse_fit_plans_on_the_map_its_data_came_with(result, tmp_path, capsys):
    """A coarse fit's grid thickens walls and can close doorways: without --map, navigate plans
    on DATA/../map/HOUSE.yaml when the fit's provenance names a data folder that still has it,
    and says so; on a fit of the map's own cells, or with the map gone, it uses the fit's grid."""
    import dataclasses

    from spcopyro.config import DataPreparation
    from spcopyro.maps import save_map

    grid = house_grid()  # the fit's grid; the robot's map: the same at half its cell size
    fine = np.repeat(np.repeat(grid.occupancy, 2, axis=0), 2, axis=1)
    save_map(OccupancyGrid(fine, grid.resolution / 2, grid.origin),
             tmp_path / "data" / "map" / "flat.yaml")  # fmt: skip
    source = {"data": str(tmp_path / "data" / "flat"), "house": "flat"}
    coarse = dataclasses.replace(result, preparation=DataPreparation(cell_size=0.2),
                                 provenance={"source": source})  # fmt: skip
    fit = coarse.save(tmp_path / "coarse")
    start = f"--start={START_A[0]},{START_A[1]}"
    assert main(["navigate", str(fit), "go to the kitchen", start]) == 0
    printed = capsys.readouterr().out
    assert f"planning on {tmp_path / 'data' / 'map' / 'flat.yaml'}" in printed
    (tmp_path / "data" / "map" / "flat.yaml").unlink()
    assert main(["navigate", str(fit), "go to the kitchen", start]) == 0
    assert "planning on" not in capsys.readouterr().out
    fine = result.save(tmp_path / "fine")
    assert main(["navigate", str(fine), "go to the kitchen", start]) == 0
    assert "planning on" not in capsys.readouterr().out


def test_a_coarse_fit_plans_on_the_robots_map_it_keeps(result, tmp_path, capsys):
    """`fit` writes a coarse fit's source map as robot_map.yaml; navigate plans on it first."""
    import dataclasses

    from spcopyro.config import DataPreparation
    from spcopyro.maps import save_map

    coarse = dataclasses.replace(result, preparation=DataPreparation(cell_size=0.2))
    fit = coarse.save(tmp_path / "coarse")
    save_map(house_grid(), fit / "robot_map.yaml")
    start = f"--start={START_A[0]},{START_A[1]}"
    assert main(["navigate", str(fit), "go to the kitchen", start]) == 0
    assert f"planning on {fit / 'robot_map.yaml'}" in capsys.readouterr().out


def test_a_coarse_fit_refuses_unknown_words_before_saying_which_map_it_plans_on(
    result, tmp_path, capsys
):
    """An instruction with no known place word is refused before anything is printed: no
    "planning on ..." line ahead of the error, as a fit on the map's own cells prints none."""
    import dataclasses

    from spcopyro.config import DataPreparation
    from spcopyro.maps import save_map

    coarse = dataclasses.replace(result, preparation=DataPreparation(cell_size=0.2))
    fit = coarse.save(tmp_path / "coarse")
    save_map(house_grid(), fit / "robot_map.yaml")
    start = f"--start={START_A[0]},{START_A[1]}"
    assert main(["navigate", str(fit), "go to the zzqx", start]) == 2
    printed = capsys.readouterr()
    assert printed.out == "" and "zzqx" in printed.err


def test_a_coarse_fit_names_the_map_it_plans_on_only_over_a_plan(result, tmp_path, capsys):
    """The "planning on MAP" line heads a plan's output, and only a plan's: a --start off the
    map or an unreachable place is refused with nothing on stdout (the line was printed, then
    the error)."""
    import dataclasses

    from spcopyro.config import DataPreparation
    from spcopyro.maps import save_map

    coarse = dataclasses.replace(result, preparation=DataPreparation(cell_size=0.2))
    fit = coarse.save(tmp_path / "coarse")
    save_map(house_grid(), fit / "robot_map.yaml")
    assert main(["navigate", str(fit), "go to the kitchen", "--start=1000,1000"]) == 2
    printed = capsys.readouterr()
    assert printed.out == "" and "--start 1000,1000 is off the map" in printed.err
    start = f"--start={START_A[0]},{START_A[1]}"
    assert main(["navigate", str(fit), "go to the closet", start]) == 3  # walled off
    printed = capsys.readouterr()
    assert printed.out == "" and "no place of 'closet' is reachable" in printed.err
    assert main(["navigate", str(fit), "go to the kitchen", start]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == (f"planning on {fit / 'robot_map.yaml'}, the map the fit's "
                        f"{result.grid.resolution:g} m cells were coarsened from (--map to "
                        "choose another)")  # fmt: skip
    assert lines[1].startswith("instruction 'go to the kitchen': kitchen")


@pytest.mark.parametrize("refine", ["auto", "never"])
def test_the_embedded_house_fitted_by_the_readme_command_can_be_driven_through(
    tmp_path, capsys, refine
):
    """The README's first command's house: refined, the fit is on the robot's own map; a coarse
    fit (--refine never) keeps the robot's map beside it. Either way a robot of the default
    0.2 m radius passes the doorways, so the kitchen is reached from the entrance."""
    out = tmp_path / "demo"
    argv = ["fit", "--out", str(out), "--sweeps", "30", "--no-figures", "--refine", refine]
    assert main(argv) == 0
    refined = "refining " in capsys.readouterr().out
    assert refined == (refine == "auto")  # the embedded house's images separate its places
    assert (out / "robot_map.yaml").is_file() == (not refined)
    plan = tmp_path / "plan"
    argv = ["navigate", str(out), "go to the kitchen", "--start=-3,0", "--out", str(plan)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert (f"planning on {out / 'robot_map.yaml'}" in printed) == (not refined)
    assert "kitchen: goal" in printed and (plan / "path.yaml").is_file()
    # the area is the part the robot fits in, which reads as a contradiction of `where` unsaid
    assert re.search(r"kitchen: goal .* m\^2 of the place the robot fits in\)", printed)


def test_a_negative_start_needs_no_equals_sign(fit, capsys):
    code = main(["navigate", str(fit), "kitchen", "--start", "-50,1"])  # was "expected one
    assert code == 2  # argument"; now the point itself is judged
    assert "off the map" in capsys.readouterr().err
    assert attach_negative_coordinates(["--start", "-0.5,-1", "--radius", "0.1"]) == [
        "--start=-0.5,-1",
        "--radius",
        "0.1",
    ]
    assert attach_negative_coordinates(["--start", "--radius"]) == ["--start", "--radius"]


def test_the_figures_legend_covers_no_part_of_the_map(result):
    """navigate.png's legend (loc="best", which weighs the path's lines, not the map) could
    cover a room, as the place graph's did: it stands below the map now."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from spcopyro.robot.navigation.figure import plan_figure

    fig = plan_figure(navigate(result, "go to the kitchen via the corridor", START_A))
    renderer = FigureCanvasAgg(fig).get_renderer()
    ax = fig.axes[0]
    legend = ax.get_legend().get_window_extent(renderer)
    assert not legend.overlaps(ax.get_window_extent(renderer))


def test_the_figure_draws_the_destination_apart_from_the_walls_and_as_its_legend_says(result):
    """navigate.png drew room1dk5's bedroom dark slate grey (a 25% orange overlay of the route's
    places on the darkest blue), near the walls' black, and the legend's swatch was tan. The
    probability's darkest colour is now a mid blue far from black, and the route's places are
    an orange outline drawn as the legend shows it."""
    from matplotlib.colors import to_rgb
    from matplotlib.contour import ContourSet

    from spcopyro.maps.palette import delta_e
    from spcopyro.robot.navigation.figure import ROUTE_RGB, plan_figure

    plan = navigate(result, "go to the kitchen via the corridor", START_A)
    fig = plan_figure(plan)
    ax = fig.axes[0]
    probability = [im for im in ax.images if im.get_array().ndim == 2]
    assert len(probability) == 1 and len(ax.images) == 2  # the map and the probability only
    darkest = np.array(probability[0].cmap(1.0)[:3]) * 255
    assert delta_e(darkest, [0, 0, 0]) >= 50
    handles, labels = ax.get_legend_handles_labels()
    if any(leg.corridor is not None for leg in plan.legs):
        route = handles[labels.index("route's places (outline)")]
        outlines = [c for c in ax.collections if isinstance(c, ContourSet)]
        assert len(outlines) == 1
        np.testing.assert_allclose(outlines[0].get_edgecolor()[0][:3], ROUTE_RGB)
        np.testing.assert_allclose(to_rgb(route.get_color()), ROUTE_RGB)
        assert route.get_alpha() in (None, 1.0) and route.get_linewidth() == 2.0
