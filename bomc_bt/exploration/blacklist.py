"""Goals that failed, and when to try them again.

A frontier whose goal failed (no path, no progress) is skipped while its entry is active.
Giving up on it for good is what ended explorations early (issue 16): the goal often
failed because the map around it was still half-built (a doorway seen at a glancing
angle, a corridor not yet cleared), and the robot drove past it later with a map on
which the way was plain. So an entry made by a *failure* is re-admitted

* when the map around it changed: the known area within ``readmit_radius`` of the goal
  grew or shrank by more than ``readmit_area`` since it failed, or
* when the robot comes within ``near_radius`` of it, having been farther than that when
  it failed (it is now next to it: a retry is cheap),

at most ``max_retries`` times per place, so an exploration always ends. A goal that was
*reached* but stayed open (it looks into a glass wall or a pocket behind furniture) is
not re-admitted: the robot stood there and saw what can be seen from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bomc_bt.algorithm_params import ExplorationParams
from bomc_bt.exploration.frontiers import Frontier
from bomc_bt.grid import OccupancyGrid


@dataclass
class Entry:
    """One blacklisted goal: its points and what the map and robot looked like then."""

    points: list[tuple[float, float]]
    known: int = -1  # known cells around points[0] when it was blacklisted (-1: not measured)
    robot_far: bool = False  # the robot was farther than near_radius from points[0] then
    retries: int = 0  # times re-admitted so far
    permanent: bool = False  # never re-admitted (reached but still open, or out of retries)
    active: bool = True


@dataclass
class Blacklist:
    """Failed goals; frontiers whose nearest cell or centroid is within ``radius`` of an
    active entry's point are skipped.

    Checking both points matters: a frontier that shrinks after a failed attempt moves
    its centroid, but the unreachable part of it (usually near its nearest cell) stays.
    """

    radius: float = 0.5  # [m]
    readmit_radius: float = 1.0  # [m]
    readmit_area: float = 0.25  # [m2]
    near_radius: float = 1.5  # [m]
    max_retries: int = 2
    entries: list[Entry] = field(default_factory=list)
    readmitted: int = 0  # re-admissions so far (for the build record)

    @classmethod
    def for_params(cls, params: ExplorationParams) -> Blacklist:
        """An empty blacklist with the re-admission rules of ``params``."""
        return cls(params.blacklist_radius, params.blacklist_readmit_radius, params.blacklist_readmit_area,
                   params.blacklist_near_radius, int(params.blacklist_max_retries))

    @property
    def points(self) -> list[tuple[float, float]]:
        """The points of the active entries (what the viewer draws)."""
        return [p for e in self.entries if e.active for p in e.points]

    def add(self, xy: tuple[float, float], *more: tuple[float, float], grid: OccupancyGrid | None = None,
            robot_xy: tuple[float, float] | None = None, permanent: bool = False) -> Entry:
        """Blacklist a goal at ``xy`` (and its other points, e.g. the frontier's centroid).

        A place blacklisted before (an inactive entry within ``radius``) keeps its retry
        count, so re-admissions of one place are bounded.
        """
        pts = [(float(xy[0]), float(xy[1]))] + [(float(p[0]), float(p[1])) for p in more]
        old = next((e for e in self.entries if not e.active and math.dist(e.points[0], pts[0]) <= self.radius),
                   None)
        entry = old or Entry(pts)
        entry.points, entry.active = pts, True
        entry.permanent = entry.permanent or permanent or entry.retries >= self.max_retries
        entry.known = known_cells(grid, pts[0], self.readmit_radius) if grid is not None else -1
        entry.robot_far = robot_xy is not None and math.dist(robot_xy, pts[0]) > self.near_radius
        if old is None:
            self.entries.append(entry)
        return entry

    def readmit(self, grid: OccupancyGrid, robot_xy: tuple[float, float]) -> int:
        """Re-admit the entries whose surroundings changed or that the robot came near; how many."""
        cell_area = grid.resolution**2
        count = 0
        for e in self.entries:
            if not e.active or e.permanent:
                continue
            changed = (e.known >= 0 and abs(known_cells(grid, e.points[0], self.readmit_radius) - e.known) * cell_area
                       > self.readmit_area)
            near = e.robot_far and math.dist(robot_xy, e.points[0]) <= self.near_radius
            if changed or near:
                e.active = False
                e.retries += 1
                count += 1
        self.readmitted += count
        return count

    def contains(self, xy: tuple[float, float]) -> bool:
        x, y = float(xy[0]), float(xy[1])
        return any(math.hypot(x - px, y - py) <= self.radius for px, py in self.points)

    def filter(self, frontiers: list[Frontier]) -> list[Frontier]:
        points = self.points
        if not points:
            return list(frontiers)
        pts = np.asarray(points)

        def hit(xy: tuple[float, float]) -> bool:
            return bool((np.hypot(pts[:, 0] - xy[0], pts[:, 1] - xy[1]) <= self.radius).any())

        return [f for f in frontiers if not (hit(f.nearest) or hit(f.centroid))]

    def __len__(self) -> int:
        return len(self.points)


def known_cells(grid: OccupancyGrid, xy: tuple[float, float], radius: float) -> int:
    """Known (free or occupied) cells in the square of half-side ``radius`` around ``xy``."""
    r = int(math.ceil(radius / grid.resolution))
    row, col = (int(v) for v in grid.world_to_cell(xy[0], xy[1]))
    window = grid.data[max(0, row - r):max(0, row + r + 1), max(0, col - r):max(0, col + r + 1)]
    return int(np.count_nonzero(window >= 0))
