"""What an exploration remembers of its own progress: mapped area over time and the way it came.

:class:`AreaWatch` is the runaway guard that replaces a fixed time limit: a build that has
mapped less than ``min_area`` new square metres for ``window`` seconds of robot time is
not going to finish by itself. It also keeps the (time, area) steps, so a build record can
say when 99 % of the final area was mapped.

:class:`Trail` keeps the last stretch of the robot's path: a robot that stops making
progress backs out along it (the way it came is the one place it is known to fit).
"""

from __future__ import annotations

import math
from collections import deque


class AreaWatch:
    """Mapped area against robot time; :meth:`stalled` when it stopped growing."""

    def __init__(self, window: float, min_area: float, start_time: float):
        self.window = window
        self.min_area = min_area
        self.mark_time = start_time  # when the area last grew by min_area
        self.mark_area = -math.inf
        self.steps: list[tuple[float, float]] = []  # (time, area) whenever the area grew

    def update(self, area: float, now: float) -> bool:
        """Record the mapped area at ``now``; True when it grew by ``min_area`` since the mark."""
        if not self.steps or area > self.steps[-1][1]:
            self.steps.append((now, area))
        if area >= self.mark_area + self.min_area:
            self.mark_area, self.mark_time = area, now
            return True
        return False

    def stalled(self, now: float) -> bool:
        return now - self.mark_time >= self.window

    def time_to(self, fraction: float) -> float | None:
        """Robot time at which ``fraction`` of the largest area recorded was first reached."""
        if not self.steps:
            return None
        target = fraction * self.steps[-1][1]
        return next(t for t, a in self.steps if a >= target)


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
