"""A turn on the spot towards a frontier at the robot's feet, when nothing else is left.

Goals nearer than the explorer's ``min_goal_distance`` are not chosen
(:meth:`.explorer.Explorer.next_goal`): such a frontier lies in the blind sector behind
the robot (the lidar sees 220 degrees), and the turn towards any other goal maps it on
the way. When no other goal is left, though, nothing turns the robot. A build that
started facing a wall ended "done" at 0 s with 5 m² of a 924 m² floor mapped (generated
office 36 x 28 m, seed 5151, start 3 of ``bench_exploration.py``), both explorers alike;
issue 16 asks that "done" mean no reachable frontier is left.

So the last resort before "done" is a goal at the robot's own position facing the
frontier there, turned the way the robot's back faced: navigation turns on the spot,
the lidar sweeps the blind sector, and exploration goes on from what it shows. At most one turn per place (within
``radius``), so a frontier the turn cannot close (glass, a pocket out of the lidar's
plane) does not turn the robot forever.
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
