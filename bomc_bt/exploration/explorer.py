"""The state of one exploration run: what the Explore leaves ask between ticks.

Frontier search (:mod:`.frontiers`) and the DWFE choice (:mod:`.dwfe`) are pure
functions of a map; an exploration also remembers things across goals: goals that
failed (the blacklist), how many failed in a row (a robot that cannot reach anything is
*stuck*, and stops rather than spinning), the time limit, and why it ended. Keeping that
here leaves the behaviours thin and lets tests drive an exploration without a tree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.exploration.dwfe import Blacklist, Choice, ExplorationParams, choose_frontier
from bomc_bt.exploration.frontiers import Frontier, find_frontiers
from bomc_bt.grid import OccupancyGrid

EXPLORING = "exploring"
DONE = "done"
TIME_LIMIT = "time limit"
STUCK = "stuck"


@dataclass
class Goal:
    """A frontier chosen as a navigation goal."""

    xy: tuple[float, float]
    frontier: Frontier
    window: str
    chosen_at: float


class Explorer:
    """Chooses frontier goals until none are left, time runs out, or the robot is stuck."""

    def __init__(self, params: ExplorationParams, start_time: float, max_time: float | None = None,
                 max_consecutive_failures: int = 5, clearance: float = 0.35, min_goal_distance: float = 0.6):
        self.params = params
        self.start_time = start_time
        self.max_time = params.max_time if max_time is None else max_time
        self.max_consecutive_failures = max_consecutive_failures
        self.clearance = clearance
        self.min_goal_distance = min_goal_distance
        self.blacklist = Blacklist(params.blacklist_radius)
        self.status = EXPLORING
        self.reason = ""
        self.goals = 0
        self.failures = 0
        self.consecutive_failures = 0
        self.last_choice: Choice | None = None
        self._streak_start: tuple[float, float] | None = None
        self.frontiers: list[Frontier] = []

    def time_up(self, now: float) -> bool:
        return self.max_time is not None and now - self.start_time >= self.max_time

    def next_goal(self, grid: OccupancyGrid, robot_xy: tuple[float, float], now: float) -> Goal | None:
        """The next frontier to drive to, or None with :attr:`status` saying why not."""
        if self.time_up(now):
            return self._finish(TIME_LIMIT, f"time limit of {self.max_time:.0f} s reached")
        min_cells = self.params.min_size_cells(grid.resolution)
        self.frontiers = find_frontiers(grid, robot_xy, min_size=min_cells)
        distance = obstacle_distance(grid)
        targets = {id(f): frontier_target(grid, f, distance, self.clearance) for f in self.frontiers}
        # A frontier whose best target is where the robot already stands (the blind sector
        # behind a 220-degree lidar) is mapped by the turn towards any other goal.
        far = [f for f in self.frontiers
               if math.dist(targets[id(f)], robot_xy) >= self.min_goal_distance]
        choice = choose_frontier(far, robot_xy, self.params, self.blacklist)
        self.last_choice = choice
        if choice.frontier is None:
            return self._finish(DONE, choice.reason or "no frontiers left")
        self.goals += 1
        return Goal(targets[id(choice.frontier)], choice.frontier, choice.window, now)

    def goal_reached(self, goal: Goal | None = None, still_open: bool = False) -> None:
        """A goal was reached; one reached but still unmapped (e.g. it looks into a glass
        wall or an unreachable pocket) is not chosen again."""
        self.consecutive_failures = 0
        if goal is not None and still_open:
            self._blacklist(goal)

    def goal_failed(self, goal: Goal, why: str, robot_xy: tuple[float, float] | None = None,
                    now: float | None = None) -> None:
        """Blacklist an unreachable goal; many failures in a row *without moving* is stuck.

        Failures alone are not enough: near the end of an exploration the frontiers left
        are often shadows behind furniture that no goal reaches, and those are simply
        blacklisted until none remain ("done"). A robot that fails goal after goal while
        staying where it is, though, cannot get anywhere: that is "stuck".
        """
        self._blacklist(goal)
        self.failures += 1
        if now is not None and now - goal.chosen_at < 2.0:
            return  # refused at once (no path, goal in a wall): a bad goal, not a stuck robot
        self.consecutive_failures += 1
        if robot_xy is not None:
            if self.consecutive_failures == 1 or self._streak_start is None:
                self._streak_start = robot_xy
            moved = math.dist(self._streak_start, robot_xy)
        else:
            moved = 0.0
        if self.consecutive_failures >= self.max_consecutive_failures and moved < 1.0:
            self._finish(STUCK, f"{self.consecutive_failures} goals failed in a row without moving (last: {why})")

    def _blacklist(self, goal: Goal) -> None:
        # The target and the frontier's centroid: the blacklist matches frontiers by their
        # nearest cell or centroid, and a target may lie away from both on a long frontier.
        self.blacklist.add(goal.xy)
        self.blacklist.add(goal.frontier.centroid)

    def _finish(self, status: str, reason: str) -> None:
        self.status = status
        self.reason = reason
        return None


def obstacle_distance(grid: OccupancyGrid) -> np.ndarray:
    """Metres from each cell to the nearest occupied cell (unknown is not an obstacle)."""
    return cv2.distanceTransform((~grid.occupied_mask()).astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution


def frontier_target(grid: OccupancyGrid, frontier: Frontier, distance: np.ndarray | None = None,
                    clearance: float = 0.0) -> tuple[float, float]:
    """The frontier cell closest to the cluster's centroid among those the robot fits on.

    The centroid of a curved frontier can lie in unknown space or inside a wall; a cell
    of the frontier is a known free cell on the boundary, so the robot sees into the
    unknown from there. Cells nearer a wall than ``clearance`` would be refused by the
    planner as lethal, so they are used only when the whole frontier hugs a wall (then
    the roomiest cell is taken).
    """
    rows, cols = frontier.cells[:, 0], frontier.cells[:, 1]
    xs, ys = grid.cell_to_world(rows, cols)
    cx, cy = frontier.centroid
    d2 = (xs - cx) ** 2 + (ys - cy) ** 2
    if distance is None or clearance <= 0:
        i = int(np.argmin(d2))
        return float(xs[i]), float(ys[i])
    room = distance[rows, cols]
    fits = room >= clearance
    if fits.any():
        i = int(np.argmin(np.where(fits, d2, np.inf)))
        return float(xs[i]), float(ys[i])
    i = int(np.argmin(d2))
    return standoff(grid, distance, rows[i], cols[i], clearance, search=1.0) or (float(xs[i]), float(ys[i]))


def standoff(grid: OccupancyGrid, distance: np.ndarray, row: int, col: int, clearance: float,
             search: float) -> tuple[float, float] | None:
    """The known free cell nearest (row, col), within ``search`` m, where the robot fits.

    A frontier squeezed between walls (a half-seen doorway) has no cell the robot can
    stand on; a cell a little back in the open still looks through it.
    """
    r = int(math.ceil(search / grid.resolution))
    r0, r1 = max(0, row - r), min(grid.height, row + r + 1)
    c0, c1 = max(0, col - r), min(grid.width, col + r + 1)
    ok = (distance[r0:r1, c0:c1] >= clearance) & (grid.data[r0:r1, c0:c1] == 0)
    if not ok.any():
        return None
    rr, cc = np.nonzero(ok)
    k = int(np.argmin((rr + r0 - row) ** 2 + (cc + c0 - col) ** 2))
    x, y = grid.cell_to_world(rr[k] + r0, cc[k] + c0)
    return float(x), float(y)


def still_open(grid: OccupancyGrid, xy: tuple[float, float], radius: float, min_unknown: int) -> bool:
    """Whether unknown space still borders ``xy``: once it is mapped, drive elsewhere."""
    r = int(math.ceil(radius / grid.resolution))
    row, col = grid.world_to_cell(xy[0], xy[1])
    r0, r1 = max(0, int(row) - r), min(grid.height, int(row) + r + 1)
    c0, c1 = max(0, int(col) - r), min(grid.width, int(col) + r + 1)
    window = grid.data[r0:r1, c0:c1]
    return int(np.count_nonzero(window < 0)) >= min_unknown
