"""What an exploration remembers of its own progress: mapped area over time and the way it came.

:class:`AreaWatch` is the runaway guard that replaces a fixed time limit: a build that has
mapped less than ``min_area`` new square metres for ``window`` seconds of robot time is
not going to finish by itself. It also keeps the (time, area) steps, so a build record can
say when 99 % of the final area was mapped.

:class:`bomc_bt.trail.Trail` (shared with the monitor pass) keeps the last stretch of the
robot's path: a robot that stops making progress backs out along it.
"""

from __future__ import annotations

import math


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
