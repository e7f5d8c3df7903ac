"""The simulated navigator's planners: a goal near the robot is planned in a window of the
saved map (a distance transform of the whole map per goal was a sixth of a pass's wall
time on an Environment-A-size floor), and the result is the whole map's."""

from __future__ import annotations

import numpy as np

from bomc_bt.grid import OccupancyGrid
from bomc_bt.planner import PlannerParams, path_length
from bomc_bt.sim.mapper import ObstacleLayer
from bomc_bt.sim.planning import SimPlanners, WindowPlanner


def _planners(data: np.ndarray) -> SimPlanners:
    grid = OccupancyGrid(data, 0.05, (0.0, 0.0))
    planners = SimPlanners(PlannerParams(), None)
    planners.use_map(grid, ObstacleLayer(grid))
    return planners


def _open_floor(size_m: float = 60.0) -> np.ndarray:
    n = int(size_m / 0.05)
    data = np.zeros((n, n), dtype=np.int8)
    data[:4], data[-4:], data[:, :4], data[:, -4:] = 100, 100, 100, 100
    return data


def test_a_short_goal_is_planned_in_a_window_and_drives_the_whole_maps_path():
    data = _open_floor()
    data[560:640, 600:606] = 100  # a pillar between start and goal
    planners = _planners(data)
    a, b = np.array([29.0, 30.0]), np.array([32.0, 30.5])
    near = planners.around(a, b)
    assert isinstance(near, WindowPlanner)
    windowed, whole = near.plan(a, b), planners.live().plan(a, b)
    assert windowed is not None and whole is not None
    assert abs(path_length(windowed) - path_length(whole)) < 0.05
    assert near.window.grid.data.size < 0.25 * data.size


def test_a_way_round_outside_the_window_falls_back_on_the_whole_map():
    data = _open_floor()
    data[200:1000, 600:606] = 100  # a 40 m wall: the way round leaves any window near the two ends
    planners = _planners(data)
    a, b = np.array([29.0, 30.0]), np.array([31.5, 30.0])
    path = planners.around(a, b).plan(a, b)
    assert path is not None
    assert path_length(path) > 20.0  # it went round the wall's end, 10 m beyond the ends
    assert planners.around(a, b).window.plan(a, b) is None


def test_a_far_goal_is_planned_on_the_whole_map():
    planners = _planners(_open_floor())
    assert not isinstance(planners.around(np.array([2.0, 2.0]), np.array([58.0, 58.0])), WindowPlanner)


def test_an_obstacle_just_outside_the_window_is_not_driven_through():
    """The window's edge band is occupied: the crop cannot see what stands beyond it."""
    planners = _planners(_open_floor())
    near = planners.around(np.array([30.0, 30.0]), np.array([31.0, 30.0]))
    assert isinstance(near, WindowPlanner)
    x0, y0 = near.window.grid.origin[:2]
    assert not near.window.traversable((x0 + 0.1, y0 + 5.0))
    assert near.window.traversable((30.5, 30.0))
