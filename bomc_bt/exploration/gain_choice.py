"""The ``gain`` explorer: the frontier whose view adds the most map per metre driven.

``utility = gain / (path + travel_offset)``: the unknown area the lidar would see from the
frontier's safe standoff goal (:func:`.gain.visible_unknown`), per metre of planned path
(:func:`.gain.path_distances`) plus a fixed ``travel_offset`` that stands for what every
goal costs besides driving (stopping, turning to face it, deciding), so a frontier at the
robot's feet does not win with any gain at all. A ratio, not a difference, because it has
no unit to tune per building: it prefers the nearest frontier of useful size, and leaves
a room only when what is left in it adds less per metre than what lies beyond.

Hysteresis: the frontier the last goal served keeps ``hysteresis`` (a fraction) on top
of its utility, so two frontiers of about equal worth do not pull the robot to and fro.

Termination on remaining gain: frontiers whose view would add less than ``min_gain`` m²
are not goals at all. When none is left the build is done, even with slivers of border
left (behind furniture, in the lidar's shadow, along a glass wall): what is left cannot
add a meaningful area, so no robot time is spent on it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bomc_bt.algorithm_params import ExplorationParams
from bomc_bt.exploration.blacklist import Blacklist
from bomc_bt.exploration.dwfe import Choice
from bomc_bt.exploration.frontiers import Frontier
from bomc_bt.exploration.gain import Heading, path_distances, visible_unknown
from bomc_bt.exploration.reachability import Reachability
from bomc_bt.grid import OccupancyGrid


@dataclass
class Candidate:
    """A reachable frontier with its safe goal, the frontier cell it looks at, and its gain."""

    frontier: Frontier
    goal: tuple[float, float]
    anchor: tuple[float, float]
    gain: float = 0.0  # [m2]
    distance: float = math.inf  # [m] path (or a lower bound of it, for candidates that cannot win)


def choose_by_gain(grid: OccupancyGrid, candidates: list[Candidate], robot_xy: tuple[float, float],
                   reach: Reachability, params: ExplorationParams, blacklist: Blacklist,
                   previous_anchor: tuple[float, float] | None,
                   robot_yaw: float | None = None,
                   gain_of: Callable[[list[tuple[float, float]]], np.ndarray] | None = None,
                   ) -> tuple[Choice, Candidate | None]:
    """The best candidate by gain per metre, or a termination with the reason; with
    ``robot_yaw`` a goal's metres include the turn on the spot before its path.
    ``gain_of`` gives :func:`.gain.visible_unknown` of goals at ``gain_radius`` on ``grid``
    (default: computed here; the explorer passes its :class:`.decision_cache.DecisionCache`)."""
    if not candidates:
        return Choice(None, "none", math.inf, "no frontiers left"), None
    allowed = set(map(id, blacklist.filter([c.frontier for c in candidates])))
    open_ = [c for c in candidates if id(c.frontier) in allowed]
    if not open_:
        return Choice(None, "none", math.inf, f"all {len(candidates)} remaining frontier(s) are blacklisted"), None
    goals = [c.goal for c in open_]
    gains = gain_of(goals) if gain_of is not None else visible_unknown(grid, goals, params.gain_radius)
    for c, g in zip(open_, gains, strict=True):
        c.gain = float(g)
    worth = [c for c in open_ if c.gain >= params.min_gain]
    if not worth:
        best = max(c.gain for c in open_)
        return Choice(None, "none", math.inf,
                      f"remaining gain too small: {len(open_)} frontier(s), the best would add {best:.2f} m² "
                      f"(< min_gain {params.min_gain:g} m²)"), None
    value = [c.gain * (1.0 + (params.hysteresis if previous_anchor is not None
                              and math.dist(c.anchor, previous_anchor) <= params.hysteresis_radius else 0.0))
             for c in worth]
    heading = (Heading(robot_yaw, params.turn_cost, math.radians(params.free_turn_deg))
               if robot_yaw is not None and params.turn_cost > 0 else None)
    distances = path_distances(reach, robot_xy, [c.goal for c in worth], value, params.travel_offset, heading)
    for c, d in zip(worth, distances, strict=True):
        c.distance = d
    scored = [(value[k] / (c.distance + params.travel_offset), -c.distance, -k)
              for k, c in enumerate(worth) if math.isfinite(c.distance)]
    if not scored:
        return Choice(None, "none", math.inf, f"none of {len(worth)} frontier goal(s) has a path"), None
    u, _, k = max(scored)
    best = worth[-k]
    return Choice(best.frontier, "global", -u,
                  f"gain {best.gain:.1f} m² at {best.distance:.1f} m path, best of {len(worth)} "
                  f"({len(open_) - len(worth)} below min_gain)"), best
