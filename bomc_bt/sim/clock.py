"""The simulated clock: session time that advances only when the simulation steps.

Every timeout and rate in the simulator reads this clock, never wall time, so a run is
reproducible and an hour of robot time takes as long as the computer needs for it.
Time is kept as an integer step count so that repeated additions of ``dt`` never drift.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class SimClock:
    """Session time in seconds, starting at 0."""

    dt: float = 0.1
    steps: int = 0

    def __post_init__(self) -> None:
        if not self.dt > 0:
            raise ValueError("dt must be > 0")

    def now(self) -> float:
        return self.steps * self.dt

    def tick(self) -> float:
        """Advance one step; returns the new time."""
        self.steps += 1
        return self.now()

    def every(self, period: float) -> int:
        """Index of the ``period``-long slot the clock is in (changes once per period)."""
        return int(self.now() / period + 1e-9)
