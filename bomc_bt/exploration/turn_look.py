"""Turns on the spot in exploration: one made when nothing else is left, one skipped on arrival.

**A frontier at the robot's feet.** Goals nearer than the explorer's ``min_goal_distance``
are not chosen (:meth:`.explorer.Explorer.next_goal`): such a frontier lies in the blind
sector behind the robot (the lidar sees 220 degrees), and the turn towards any other goal
maps it on the way. When no other goal is left, though, nothing turns the robot. A build
that started facing a wall ended "done" at 0 s with 5 m² of a 924 m² floor mapped
(generated office 36 x 28 m, seed 5151, start 3 of ``bench_exploration.py``), both
explorers alike; issue 16 asks that "done" mean no reachable frontier is left. So the last
resort before "done" is a goal at the robot's own position facing the way its back faced:
navigation turns on the spot, the lidar sweeps the blind sector, and exploration goes on
from what it shows. At most one turn per place (within ``radius``), so a frontier the turn
cannot close (glass, a pocket out of the lidar's plane) does not turn the robot forever.

**A frontier in view on arrival.** Every goal's heading faces its frontier, for a robot
that arrives with it in the blind sector. One that arrives with the frontier already in
view need not turn (:meth:`TurnLooks.skip_arrival_turn`; docs/exploration.md 7.14). Only
the first arrival at a frontier is spared so: the next one turns, and a frontier still open
then is blacklisted, so two frontiers no lidar closes do not pull the robot to and fro.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from bomc_bt.exploration.blacklist import Blacklist
from bomc_bt.exploration.gain_choice import Candidate


@dataclass
class TurnLooks:
    """Where the robot already turned to look, and the pick of the next turn."""

    radius: float = 0.5  # [m] a place this near an earlier turn's gets no turn of its own
    places: list[tuple[float, float]] = field(default_factory=list)
    spared: list[tuple[float, float]] = field(default_factory=list)  # frontiers whose arrival turn was skipped

    def pick(self, candidates: list[Candidate], robot_xy: tuple[float, float], near: float,
             blacklist: Blacklist, gain_of: Callable[[list[tuple[float, float]]], np.ndarray] | None = None,
             min_gain: float = 0.0) -> Candidate | None:
        """The frontier to turn towards among ``candidates`` whose goal is nearer than
        ``near`` (m) and not blacklisted, or None: none, the robot turned here already, or
        (with ``gain_of``) none whose view would add ``min_gain`` m². The largest view wins,
        else the longest frontier."""
        if any(math.dist(p, robot_xy) <= self.radius for p in self.places):
            return None
        close = [c for c in candidates if math.dist(c.goal, robot_xy) < near]
        allowed = {id(f) for f in blacklist.filter([c.frontier for c in close])}
        close = [c for c in close if id(c.frontier) in allowed]
        if gain_of is not None and close:
            for c, g in zip(close, gain_of([c.goal for c in close]), strict=True):
                c.gain = float(g)
            close = [c for c in close if c.gain >= min_gain]
        if not close:
            return None
        best = max(close, key=lambda c: (c.gain, c.frontier.length))
        self.places.append(robot_xy)
        return best

    @staticmethod
    def behind(robot_xy: tuple[float, float], robot_yaw: float | None, frontier: Candidate) -> tuple[float, float]:
        """The point the turn faces: 1 m behind the robot (the middle of the lidar's blind
        sector), or the frontier's anchor when the heading is not known."""
        if robot_yaw is None:
            return frontier.anchor
        return (robot_xy[0] - math.cos(robot_yaw), robot_xy[1] - math.sin(robot_yaw))

    def skip_arrival_turn(self, anchor: tuple[float, float], pose: tuple[float, float, float], in_view_deg: float,
                          same: float) -> bool:
        """Whether a robot at ``pose`` (x, y, yaw) that arrived at the goal of an open frontier
        (its cell ``anchor``) may skip the turn to face it: the frontier lies within
        ``in_view_deg`` of its heading, and no arrival within ``same`` (m) of it was spared yet."""
        if any(math.dist(anchor, xy) <= same for xy in self.spared):
            return False
        x, y, yaw = pose
        bearing = math.remainder(math.atan2(anchor[1] - y, anchor[0] - x) - yaw, 2 * math.pi)
        if abs(bearing) > math.radians(in_view_deg):
            return False
        self.spared.append(anchor)
        return True
