"""The robot port: the one interface behaviours use to reach a robot.

Two implementations stand behind it: the built-in simulator (:mod:`bomc_bt.sim.robot`)
and ROS 1 through rospy (:mod:`bomc_bt.ros.robot`). Nothing here blocks a tick: long
work (navigation, relocalization) runs behind a :class:`Handle` whose status is polled.
Time always comes from :meth:`RobotPort.now` (simulated or ROS time), never wall time.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid


class Status(enum.Enum):
    """What a navigation or relocalization request is doing."""

    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"  # gave up (no path, aborted, not confident)
    BLOCKED = "blocked"  # goal or path obstructed, or no progress within the timeout
    CANCELLED = "cancelled"

    @property
    def done(self) -> bool:
        return self is not Status.RUNNING


@runtime_checkable
class Handle(Protocol):
    """An asynchronous request in flight."""

    def status(self) -> Status: ...

    def cancel(self) -> None: ...

    @property
    def message(self) -> str: ...


class RequestHandle:
    """A plain :class:`Handle`: RUNNING until someone calls :meth:`finish` or :meth:`cancel`."""

    def __init__(self, message: str = "running"):
        self._status = Status.RUNNING
        self._message = message

    @classmethod
    def refused(cls, message: str) -> RequestHandle:
        """A request refused before it started (a goal while not localized): FAILED at once."""
        handle = cls(message)
        handle.finish(Status.FAILED, message)
        return handle

    def status(self) -> Status:
        return self._status

    @property
    def message(self) -> str:
        return self._message

    def cancel(self) -> None:
        self.finish(Status.CANCELLED, "cancelled")

    def finish(self, status: Status, message: str) -> None:
        """The first final status sticks (a late cancel does not undo a success)."""
        if self._status is Status.RUNNING:
            self._status = status
            self._message = message


@dataclass
class LaserScan:
    """A planar scan: ranges (m, inf where nothing was hit) at evenly spaced angles."""

    stamp: float
    angle_min: float  # rad, relative to the robot's heading
    angle_increment: float
    ranges: np.ndarray  # float32 (N,)
    range_max: float

    @property
    def angles(self) -> np.ndarray:
        return self.angle_min + self.angle_increment * np.arange(len(self.ranges))


@dataclass
class RGBDFrame:
    """A registered RGB-D frame with what is needed to put its pixels in the map.

    ``depth`` is float32 metres with NaN where invalid; ``K`` the 3 x 3 intrinsics;
    ``T_map_base`` and ``T_base_camera`` the 4 x 4 transforms at the image stamp (the
    camera frame is the optical frame: z forward, x right, y down). The simulator's
    ground truth (which object each pixel shows) rides on its own subclass,
    :class:`bomc_bt.sim.frame.SimFrame`.
    """

    stamp: float
    rgb: np.ndarray | None  # uint8 (H, W, 3) or None
    depth: np.ndarray  # float32 (H, W), metres, NaN invalid
    K: np.ndarray  # (3, 3)
    T_map_base: np.ndarray  # (4, 4)
    T_base_camera: np.ndarray  # (4, 4)
    depth_range: tuple[float, float] = (0.3, 8.0)

    @property
    def T_map_camera(self) -> np.ndarray:
        return self.T_map_base @ self.T_base_camera

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.depth.shape[0]), int(self.depth.shape[1])


@runtime_checkable
class RobotPort(Protocol):
    """Everything a behaviour needs from a robot, and nothing that blocks."""

    distance_travelled: float
    """Metres the base has driven since the robot was made (odometry; the path length of reports)."""

    def now(self) -> float:
        """Robot time in seconds (simulated or ROS time)."""

    def step(self) -> None:
        """Advance one tick period: the simulator steps the world, ROS sleeps to the rate."""

    def pose(self) -> Pose2D | None:
        """Localized pose in the map frame; None while not localized."""

    def live_map(self) -> OccupancyGrid:
        """The map being built (build mission) or the map in use (monitor mission)."""

    def use_map(self, grid: OccupancyGrid) -> None:
        """Navigate and localize in this saved map from now on (monitor mission)."""

    def refresh_map(self, grid: OccupancyGrid) -> None:
        """Navigate on ``grid`` from now on: the map in use with floor the lidar saw where it
        holds furniture cleared (:mod:`bomc_bt.stale_map`). A stuck pass does this when a
        table gone since the build hems the robot in; the saved map does not change."""

    def scan(self) -> LaserScan | None:
        """Latest laser scan."""

    def frame(self) -> RGBDFrame | None:
        """Latest RGB-D frame not yet returned, or None if there is no new one."""

    def navigate(self, goal: Pose2D) -> Handle:
        """Start driving to ``goal``; a new goal pre-empts the old one."""

    def relocalize(self, hint: Pose2D | None, global_search: bool = False) -> Handle:
        """Start estimating the pose in the map in use, from ``hint`` or globally."""

    def clear_costmaps(self) -> None:
        """Forget the obstacles navigation marked from earlier scans; the next scans rebuild
        them (move_base's ``clear_costmaps``). A pass that keeps failing waypoints clears a
        stale obstacle layer this way (:mod:`bomc_bt.stuck`)."""

    def obstacle_layer(self) -> np.ndarray:
        """(N, 2) map-frame centres of the cells navigation's obstacle layer marks now: what
        the lidar saw since the layer was last cleared, including obstacles out of the
        current scan's sight (a table the robot drove past); the map's walls may be among
        them. Empty when nothing is marked or the robot cannot tell what it marks since the
        last :meth:`clear_costmaps`. A pass that keeps failing waypoints after clearing the
        layer reads it to tell real obstacles from stale ones (:mod:`bomc_bt.stuck`)."""

    def cancel_all(self) -> None:
        """Stop the robot: cancel navigation (Ctrl-C, abort)."""
