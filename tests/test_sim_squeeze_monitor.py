"""A monitor pass's robot is not shut in by its own obstacle layer.

On a real building's SLAM map (willow, 0.1 m cells, session 3 of a generated world) the
robot drove through a passage a hand's width wider than itself; the lidar's returns off
walls the saved map draws a cell thinner then closed it behind the robot in the obstacle
layer, the live planner had no way out, and the robot stood still for the last 680 s of
its pass (144 waypoints not reached). The navigator now squeezes (``squeeze_radius``) on
the saved map and obstacle layer too, as it does while building.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import FREE, OCCUPIED, OccupancyGrid
from bomc_bt.robot import Status
from bomc_bt.sim.params import SimParams
from bomc_bt.sim.robot import SimRobot
from bomc_bt.world import World

RES = 0.05


def cell(m: float) -> int:
    return int(round(m / RES))


def two_rooms(gap_low: float, gap_high: float) -> np.ndarray:
    """6 x 3 m, a 0.2 m wall at x = 3 m with a gap from ``gap_low`` to ``gap_high`` (m)."""
    data = np.full((cell(3.0), cell(6.0)), FREE, np.int8)
    data[:2, :] = data[-2:, :] = data[:, :2] = data[:, -2:] = OCCUPIED
    data[:, cell(3.0):cell(3.2)] = OCCUPIED
    data[cell(gap_low):cell(gap_high), cell(3.0):cell(3.2)] = FREE
    return data


def drive_through(squeeze_radius: float) -> tuple[Status, Pose2D]:
    truth = OccupancyGrid(two_rooms(1.2, 1.8), RES, (0.0, 0.0))  # 0.60 m: the base (0.48 m) fits
    saved = OccupancyGrid(two_rooms(1.1, 1.9), RES, (0.0, 0.0))  # the map drew it 0.2 m wider
    start = Pose2D(1.5, 1.5, 0.0)
    world = World("gap", Path("gap.yaml"), Path("gap-map.yaml"), truth, start, 2.5, {}, {}, [])
    params = SimParams()
    params = replace(params, planner=replace(params.planner, squeeze_radius=squeeze_radius))
    robot = SimRobot(world, 1, params=params, seed=0, mode="monitor", start=start)
    robot.use_map(saved)
    relocalizing = robot.relocalize(start)
    while relocalizing.status() is Status.RUNNING:
        robot.step()
    for _ in range(20):  # the obstacle layer fills from a few scans
        robot.step()
    goal = robot.navigate(Pose2D(4.5, 1.5, 0.0))
    for _ in range(900):
        if goal.status() is not Status.RUNNING:
            break
        robot.step()
    return goal.status(), robot.true_pose


def test_a_passage_the_obstacle_layer_narrowed_is_squeezed_through():
    status, pose = drive_through(squeeze_radius=0.25)
    assert status is Status.SUCCEEDED and pose.x > 4.0, (status, pose)


def test_without_squeezing_the_robot_waits_behind_its_own_obstacle_layer():
    """The same passage with squeezing off (``squeeze_radius`` = ``robot_radius``): what the
    pass did before, and what shows the first test is not passing on an open way."""
    status, pose = drive_through(squeeze_radius=0.3)
    assert status is Status.BLOCKED and pose.x < 3.0, (status, pose)
