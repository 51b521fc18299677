"""From an instruction to a goal and a path (``spcopyro navigate``, issue 27).

* :mod:`~spcopyro.robot.navigation.graph`: clearance from walls, the cells a robot fits on and the
  8-connected graph between them (shortest paths).
* :mod:`~spcopyro.robot.navigation.goals`: an instruction's place words in visiting order; a word's
  goal (candidate regions, ambiguity, reachability).
* :mod:`~spcopyro.robot.navigation.planning`: :func:`navigate`, the plan through every stop.
* :mod:`~spcopyro.robot.navigation.places`: the place graph (regions as nodes, shared borders and
  doorways as edges) and the shortest route over it.
* :mod:`~spcopyro.robot.navigation.hierarchy`: hierarchical planning (SpCoTMHP): each leg's
  route over the place graph, then the grid path kept to the route's places, or the shortest
  grid path with the reason.
* :mod:`~spcopyro.robot.navigation.outputs`: the plan as ROS message YAML, CSV, JSON
  (:func:`write_plan`); :mod:`~spcopyro.robot.navigation.figure`: its PNG.
"""

from spcopyro.robot.navigation.goals import (
    AmbiguousGoalError,
    NavigationError,
    UnreachableGoalError,
    parse_instruction,
)
from spcopyro.robot.navigation.graph import clearance_map, planning_grid
from spcopyro.robot.navigation.planning import DEFAULT_RADIUS, NavigationPlan, navigate

__all__ = [
    "DEFAULT_RADIUS",
    "AmbiguousGoalError",
    "NavigationError",
    "NavigationPlan",
    "UnreachableGoalError",
    "clearance_map",
    "navigate",
    "parse_instruction",
    "planning_grid",
]
