"""A scripted fake robot and a mission context for leaf tests, one leaf at a time.

:class:`FakeRobot` implements the robot port with a manual clock and handles whose outcome
the test decides (``robot.last.finish(...)``), so a leaf is ticked tick by tick as py_trees'
own ``tests.tick_tree`` does, without a simulator or a whole mission.
"""

from __future__ import annotations

import numpy as np
import py_trees
from py_trees.common import Status

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import LaserScan, RequestHandle, RGBDFrame
from bomc_bt.tree.leaf import Leaf


def open_room(size_m: float = 10.0, resolution: float = 0.05) -> OccupancyGrid:
    """Free floor inside walls, ``size_m`` square, origin at (0, 0)."""
    n = int(size_m / resolution)
    data = np.zeros((n, n), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    return OccupancyGrid(data, resolution, (0.0, 0.0))


START = Pose2D(5.0, 5.0, 0.0)  # the middle of the open room


class FakeRobot:
    """The robot port, scripted: a manual clock, a settable pose, handles the test finishes."""

    def __init__(self, grid: OccupancyGrid | None = None, pose: Pose2D | None = START):
        self.t = 0.0
        self.dt = 0.1
        self.grid = grid if grid is not None else open_room()
        self._pose = pose
        self.distance_travelled = 0.0
        self.goals: list[Pose2D] = []
        self.relocalizations: list[tuple[Pose2D | None, bool]] = []
        self.handles: list[RequestHandle] = []
        self.frames: list[RGBDFrame] = []
        self.cancelled_all = False
        self.costmap_clears = 0
        self.refreshed_maps = 0
        self.latest_scan: LaserScan | None = None
        self.layer = np.zeros((0, 2))  # the obstacle layer's marked cells (map frame); a clear empties it

    @property
    def last(self) -> RequestHandle:
        """The newest request (navigation or relocalization)."""
        return self.handles[-1]

    def now(self) -> float:
        return self.t

    def step(self) -> None:
        self.t += self.dt

    def advance(self, seconds: float) -> None:
        self.t += seconds

    def pose(self) -> Pose2D | None:
        return self._pose

    def place(self, pose: Pose2D | None) -> None:
        self._pose = pose

    def live_map(self) -> OccupancyGrid:
        return self.grid

    def use_map(self, grid: OccupancyGrid) -> None:
        self.grid = grid

    def refresh_map(self, grid: OccupancyGrid) -> None:
        self.grid = grid
        self.refreshed_maps += 1

    def scan(self) -> LaserScan | None:
        return self.latest_scan

    def frame(self) -> RGBDFrame | None:
        return self.frames.pop(0) if self.frames else None

    def navigate(self, goal: Pose2D) -> RequestHandle:
        self.goals.append(goal)
        self.handles.append(RequestHandle(f"to ({goal.x:.1f}, {goal.y:.1f})"))
        return self.handles[-1]

    def relocalize(self, hint: Pose2D | None, global_search: bool = False) -> RequestHandle:
        self.relocalizations.append((hint, global_search))
        self.handles.append(RequestHandle("matching"))
        return self.handles[-1]

    def clear_costmaps(self) -> None:
        self.costmap_clears += 1
        self.layer = np.zeros((0, 2))

    def obstacle_layer(self) -> np.ndarray:
        return self.layer

    def cancel_all(self) -> None:
        self.cancelled_all = True


def tick(leaf: Leaf, times: int = 1) -> Status:
    """Tick ``leaf`` as its parent would, ``times`` times; its status after the last."""
    for _ in range(times):
        leaf.tick_once()
    return leaf.status


def key(name: str, default=None):
    """What the leaves wrote on the blackboard under ``name``."""
    try:
        return py_trees.blackboard.Blackboard.get("/" + name)
    except KeyError:
        return default


def write_goal(value) -> None:
    py_trees.blackboard.Blackboard.set("/goal", value)
