"""Where the planner can take the robot: frontiers are goals only where it can.

Frontier search (:mod:`.frontiers`) calls a frontier reachable when free cells connect it
to the robot at map resolution, with no clearance. The planner
(:class:`bomc_bt.planner.GridPlanner`) needs the robot's radius of clearance on a coarser
grid and treats unknown cells as walls. Frontiers behind a gap narrower than the robot
(chair legs, a half-seen doorway) were chosen, failed, and were blacklisted: the first
cause ranked in ``docs/exploration.md`` (4.1). This module computes the planner's
traversable component containing the robot, with the same costmap code the planner uses
(:func:`bomc_bt.costmap.grid_clearance`), and says which frontier cells the robot can
be driven to: those within the planner's goal tolerance of that component.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from bomc_bt.costmap import grid_clearance
from bomc_bt.exploration.frontiers import Frontier
from bomc_bt.grid import OccupancyGrid
from bomc_bt.planner import PlannerParams


class Reachability:
    """The planner's reachable area from ``robot_xy`` on one snapshot of ``grid``."""

    def __init__(self, grid: OccupancyGrid, params: PlannerParams, robot_xy: tuple[float, float]):
        self.grid = grid
        self.params = params
        self.factor = max(1, int(round(params.resolution / grid.resolution)))
        res = grid.resolution * self.factor
        clearance, unknown = grid_clearance(grid, self.factor)
        lethal = clearance < params.robot_radius
        if not params.allow_unknown:
            lethal |= unknown
        _, labels = cv2.connectedComponents((~lethal).astype(np.uint8), connectivity=8)
        # Every component within the planner's escape radius: a robot inside the inflated
        # zone (a narrow corridor) is planned from the nearest traversable cell, which may
        # lie in any of them as it moves.
        self.component = np.isin(labels, _near_labels(labels, lethal, grid, self.factor, robot_xy,
                                                      params.escape_radius))
        # A goal within the planner's goal tolerance of a traversable cell is accepted there.
        k = int(math.ceil(params.goal_tolerance / res))
        disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
        self.approach = cv2.dilate(self.component.astype(np.uint8), disk).astype(bool)

    @property
    def empty(self) -> bool:
        return not self.component.any()

    def approachable(self, frontier: Frontier) -> np.ndarray:
        """Bool per frontier cell: the robot can be driven to it."""
        rows, cols = frontier.cells[:, 0] // self.factor, frontier.cells[:, 1] // self.factor
        inside = (rows < self.approach.shape[0]) & (cols < self.approach.shape[1])
        out = np.zeros(len(rows), dtype=bool)
        out[inside] = self.approach[rows[inside], cols[inside]]
        return out

    def split(self, frontiers: list[Frontier]) -> tuple[list[tuple[Frontier, np.ndarray]], list[Frontier]]:
        """(reachable frontiers with their approachable-cell masks, unreachable frontiers)."""
        reachable, unreachable = [], []
        for f in frontiers:
            ok = self.approachable(f)
            if ok.any():
                reachable.append((f, ok))
            else:
                unreachable.append(f)
        return reachable, unreachable

    def contains(self, xy: tuple[float, float]) -> bool:
        """Whether the robot can be driven to ``xy`` (within the goal tolerance)."""
        row, col = (int(v) // self.factor for v in self.grid.world_to_cell(xy[0], xy[1]))
        return (0 <= row < self.approach.shape[0] and 0 <= col < self.approach.shape[1]
                and bool(self.approach[row, col]))


def _near_labels(labels: np.ndarray, lethal: np.ndarray, grid: OccupancyGrid, factor: int,
                 robot_xy: tuple[float, float], radius: float) -> list[int]:
    """Labels of the traversable components within ``radius`` of the robot (its own cell's,
    when traversable, else those the planner's start escape may pick)."""
    start = _start_cell(lethal, grid, factor, robot_xy, radius)
    if start is None:
        return []
    if not lethal[start] and start == tuple(int(v) // factor for v in grid.world_to_cell(*robot_xy)):
        return [int(labels[start])]
    row, col = (int(v) // factor for v in grid.world_to_cell(robot_xy[0], robot_xy[1]))
    k = int(math.ceil(radius / (grid.resolution * factor)))
    h, w = labels.shape
    window = labels[max(row - k, 0):min(row + k + 1, h), max(col - k, 0):min(col + k + 1, w)]
    return [int(v) for v in np.unique(window) if v != 0]


def _start_cell(lethal: np.ndarray, grid: OccupancyGrid, factor: int, robot_xy: tuple[float, float],
                radius: float) -> tuple[int, int] | None:
    """The robot's planning cell, or the nearest traversable one within ``radius`` (the
    planner's escape from a start inside the inflated zone)."""
    row, col = (int(v) // factor for v in grid.world_to_cell(robot_xy[0], robot_xy[1]))
    h, w = lethal.shape
    if 0 <= row < h and 0 <= col < w and not lethal[row, col]:
        return row, col
    k = int(math.ceil(radius / (grid.resolution * factor))) + 1
    r0, r1, c0, c1 = max(row - k, 0), min(row + k + 1, h), max(col - k, 0), min(col + k + 1, w)
    if r0 >= r1 or c0 >= c1:
        return None
    rr, cc = np.nonzero(~lethal[r0:r1, c0:c1])
    if rr.size == 0:
        return None
    d2 = (rr + r0 - row) ** 2 + (cc + c0 - col) ** 2
    i = int(np.argmin(d2))
    if math.sqrt(d2[i]) * grid.resolution * factor > radius + 1e-9:
        return None
    return int(rr[i] + r0), int(cc[i] + c0)
