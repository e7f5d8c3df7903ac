"""The way the robot came: the last stretch of its path, to back out along.

A robot that stops making progress (a build whose goals keep failing, a monitor pass
boxed in by furniture that moved) backs out along the path it drove: the way it came is
the one place it is known to fit. The explorer (:mod:`bomc_bt.exploration.explorer`) and
the monitor pass's recovery (:mod:`bomc_bt.stuck`) both keep one.
"""

from __future__ import annotations

import math
from collections import deque


class Trail:
    """The robot's recent positions, at least ``spacing`` metres apart, newest last."""

    def __init__(self, spacing: float = 0.25, keep: int = 400):
        self.spacing = spacing
        self.points: deque[tuple[float, float]] = deque(maxlen=keep)

    def add(self, xy: tuple[float, float]) -> None:
        p = (float(xy[0]), float(xy[1]))
        if not self.points or math.dist(self.points[-1], p) >= self.spacing:
            self.points.append(p)

    def back(self, robot_xy: tuple[float, float], distance: float, accept=None) -> tuple[float, float] | None:
        """The first point at least ``distance`` metres back along the trail (and at least
        ``distance / 2`` from the robot) that ``accept`` allows, else None."""
        walked, prev = 0.0, (float(robot_xy[0]), float(robot_xy[1]))
        for p in reversed(self.points):
            walked += math.dist(prev, p)
            prev = p
            if walked >= distance and math.dist(p, robot_xy) >= distance / 2 and (accept is None or accept(p)):
                return p
        return None
