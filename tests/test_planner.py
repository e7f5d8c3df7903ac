"""The grid planner: paths around walls with clearance, unreachable goals, lethal ends."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from bomc_bt.planner import DrivenLengths, GridPlanner, PlannerParams
from bomc_bt.polyline import path_clear_of, path_length

RES = 0.05


def room(width_m: float, height_m: float) -> np.ndarray:
    """Free room with a 0.1 m wall all round (rows = y)."""
    data = np.full((int(round(height_m / RES)), int(round(width_m / RES))), FREE, dtype=np.int8)
    data[:2, :] = data[-2:, :] = OCCUPIED
    data[:, :2] = data[:, -2:] = OCCUPIED
    return data


def block(data: np.ndarray, x0: float, x1: float, y0: float, y1: float, value: int = OCCUPIED) -> None:
    data[int(round(y0 / RES)):int(round(y1 / RES)), int(round(x0 / RES)):int(round(x1 / RES))] = value


def grid(data: np.ndarray) -> OccupancyGrid:
    return OccupancyGrid(data, RES, (0.0, 0.0))


def clearance_along(g: OccupancyGrid, path: np.ndarray) -> float:
    """Smallest distance (m) from densely sampled path points to an occupied cell's face."""
    dist = cv2.distanceTransform((~g.occupied_mask()).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    lengths = np.hypot(*np.diff(path, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    s = np.linspace(0.0, cum[-1], 400)
    r, c = g.world_to_cell(np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1]))
    return float((dist[r, c] * RES - 0.5 * RES).min())


def test_path_goes_around_a_wall_and_keeps_clearance():
    data = room(10, 10)
    block(data, 4.9, 5.1, 0.0, 7.0)  # a wall from the bottom up to y = 7
    g = grid(data)
    planner = GridPlanner(g, PlannerParams())
    path = planner.plan((2.0, 2.0), (8.0, 2.0))
    assert path is not None
    assert np.allclose(path[0], (2.0, 2.0)) and np.allclose(path[-1], (8.0, 2.0))
    assert path[:, 1].max() > 7.0  # went over the top of the wall
    assert path_length(path) > 2 * (7.0 - 2.0)
    assert clearance_along(g, path) >= 0.3 - 0.05
    assert len(path) < 20  # smoothed, not a staircase of cells
    assert planner.distance((2.0, 2.0), (8.0, 2.0)) == pytest.approx(path_length(path))


def test_prefers_the_middle_of_a_corridor():
    data = room(10, 1.8)  # inner width 1.6 m
    g = grid(data)
    path = GridPlanner(g, PlannerParams()).plan((0.6, 0.55), (9.4, 0.55))
    assert path is not None
    assert np.all(np.diff(path[:, 0]) > 0)
    middle = np.interp(np.linspace(3.0, 7.0, 9), path[:, 0], path[:, 1])
    assert middle.min() > 0.75  # moved off the wall towards the centre (0.9)
    no_cost = GridPlanner(g, PlannerParams(cost_weight=0.0)).plan((0.6, 0.55), (9.4, 0.55))
    assert no_cost is not None and abs(no_cost[:, 1] - 0.55).max() < 0.1  # cost is what moved it


def test_enclosed_goal_is_unreachable():
    data = room(10, 10)
    block(data, 6.0, 9.0, 6.0, 6.2)
    block(data, 6.0, 9.0, 8.8, 9.0)
    block(data, 6.0, 6.2, 6.0, 9.0)
    block(data, 8.8, 9.0, 6.0, 9.0)
    planner = GridPlanner(grid(data))
    assert planner.plan((2.0, 2.0), (7.5, 7.5)) is None
    assert planner.distance((2.0, 2.0), (7.5, 7.5)) == math.inf
    field = planner.distances_from((2.0, 2.0))
    assert planner.lookup(field, (7.5, 7.5)) == math.inf
    assert planner.lookup(field, (5.0, 5.0)) == pytest.approx(math.hypot(3, 3), rel=0.1)


def test_lethal_goal_snaps_within_tolerance_else_fails():
    data = room(6, 6)
    block(data, 2.9, 3.1, 0.0, 6.0)  # splits the room; x in [2.9, 3.1) is wall
    planner = GridPlanner(grid(data), PlannerParams(goal_tolerance=0.3))
    near_wall = planner.plan((1.0, 3.0), (2.65, 3.0))  # 0.25 m from the wall: lethal, but close to free
    assert near_wall is not None
    assert np.hypot(*(near_wall[-1] - (2.65, 3.0))) <= 0.3 + 1e-9
    assert planner.traversable(near_wall[-1])
    assert planner.plan((1.0, 3.0), (3.0, 3.0)) is None  # in the wall, nothing traversable near
    assert planner.nearest_traversable((3.0, 3.0), 0.3) is None


def test_start_hugging_a_wall_escapes():
    data = room(6, 6)
    planner = GridPlanner(grid(data))
    start = (0.2, 3.0)  # 0.1 m from the wall face: lethal
    assert not planner.traversable(start)
    path = planner.plan(start, (4.0, 3.0))
    assert path is not None and np.allclose(path[0], start)
    assert planner.traversable(path[1])


def test_a_robot_standing_on_the_tip_of_a_tables_lidar_shadow_plans_out_of_it():
    # Traced on a generated 36 x 28 m office (seed 7911, pass 8): a viewpoint reached at the
    # tip of the shadow a table cast on the saved map while it was built; the robot stood
    # on unknown cells, every later goal failed at once, and the pass ended there.
    data = room(6, 6)
    block(data, 3.0, 5.0, 2.0, 4.0, UNKNOWN)  # the table's shadow
    planner = GridPlanner(grid(data))
    start = (3.1, 3.0)  # two map cells into the shadow
    assert not planner.traversable(start)
    path = planner.plan(start, (1.0, 5.0))
    assert path is not None and np.allclose(path[0], start) and planner.traversable(path[1])
    assert planner.plan((3.6, 3.0), (1.0, 5.0)) is None  # deep inside: not under the robot
    # standing on free floor, the line out never crosses unknown cells: a one-cell hole in
    # a wall is no way through it
    data = room(6, 6)
    block(data, 3.0, 3.1, 0.0, 6.0)  # a wall across the room ...
    block(data, 3.0, 3.1, 2.95, 3.05, UNKNOWN)  # ... with a hole the lidar left at a grazing angle
    planner = GridPlanner(grid(data))
    assert planner.plan((2.95, 3.0), (5.0, 3.0)) is None


def test_unknown_space_only_with_allow_unknown():
    data = room(10, 4)
    block(data, 4.0, 6.0, 0.1, 3.9, UNKNOWN)  # an unexplored band across the room
    g = grid(data)
    assert GridPlanner(g, PlannerParams(allow_unknown=False)).plan((1.0, 2.0), (9.0, 2.0)) is None
    path = GridPlanner(g, PlannerParams(allow_unknown=True)).plan((1.0, 2.0), (9.0, 2.0))
    assert path is not None and path_length(path) == pytest.approx(8.0, rel=0.05)


def test_extra_obstacles_block_and_path_check_notices():
    data = room(10, 3)
    g = grid(data)
    path = GridPlanner(g).plan((1.0, 1.5), (9.0, 1.5))
    assert path is not None
    extra = np.zeros(data.shape, dtype=bool)
    extra[:, int(5.0 / RES):int(5.4 / RES)] = True  # a barrier across the corridor
    assert not path_clear_of(extra, g, path, 0.3)
    assert path_clear_of(np.zeros_like(extra), g, path, 0.3)
    blocked = GridPlanner(g, extra_obstacles=extra)
    assert blocked.plan((1.0, 1.5), (9.0, 1.5)) is None
    assert not blocked.path_is_clear(path) and GridPlanner(g).path_is_clear(path)


def test_distance_field_agrees_with_planned_lengths():
    data = room(10, 10)
    block(data, 4.9, 5.1, 0.0, 7.0)
    planner = GridPlanner(grid(data), PlannerParams(cost_weight=0.0, heuristic_weight=1.0))
    field = planner.distances_from((2.0, 2.0))
    for goal in [(8.0, 2.0), (2.0, 8.0), (8.0, 8.0)]:
        planned = planner.distance((2.0, 2.0), goal)
        assert planner.lookup(field, goal) == pytest.approx(planned, rel=0.08)


def room_behind_a_narrow_door(door_m: float = 0.56) -> OccupancyGrid:
    """A 10 x 10 m room split by a wall at x = 7 m with one doorway, ``door_m`` wide, at y = 5 m:
    narrower than the default robot_radius (0.3 m) lets a plan through, not squeeze_radius (0.25 m)."""
    data = room(10, 10)
    block(data, 7.0, 7.1, 0.0, 5.0 - door_m / 2)
    block(data, 7.0, 7.1, 5.0 + door_m / 2, 10.0)
    return grid(data)


def test_path_lengths_from_a_room_the_robot_squeezed_into_are_measured_out_through_its_door():
    """The robot drove into the small room by squeezing (the navigator's last resort); a
    planner with its full clearance sees it shut in, and every place the pass has reached in
    the big room was unreachable from there. Driven lengths leave the pocket on squeeze_radius."""
    g = room_behind_a_narrow_door()
    planner, driven = GridPlanner(g), DrivenLengths(g, PlannerParams())
    places = np.array([[3.0, 5.0], [2.0, 8.0], [8.5, 2.0]])
    assert planner.shut_in((8.5, 5.0)) and not planner.shut_in((3.0, 5.0))
    assert np.isinf(planner.path_lengths_from((8.5, 5.0))(places[:2])).all()
    out = driven((8.5, 5.0))(places)
    assert out[0] == pytest.approx(5.5, abs=0.2) and out[1] == pytest.approx(math.hypot(6.5, 3.0), rel=0.15)
    assert out[2] == pytest.approx(3.0, abs=0.2)
    # from the big room, lengths are the planner's own: the pocket stays unreachable, as plans there are
    assert np.array_equal(driven((3.0, 5.0))(places), planner.path_lengths_from((3.0, 5.0))(places))
    assert np.isinf(driven((3.0, 5.0))(places[2:])).all()
    # a doorway no robot passes is no way out either, and a robot that may not squeeze never does
    assert np.isinf(DrivenLengths(room_behind_a_narrow_door(0.4), PlannerParams())((8.5, 5.0))(places[:2])).all()
    strict = PlannerParams(squeeze_radius=0.3)
    assert np.isinf(DrivenLengths(g, strict)((8.5, 5.0))(places[:2])).all()


def test_bad_parameters_are_rejected():
    with pytest.raises(ValueError):
        PlannerParams(robot_radius=0.8, inflation_radius=0.5)
    with pytest.raises(ValueError):
        PlannerParams(heuristic_weight=0.5)


def test_a_grid_edited_in_place_is_planned_on_as_it_is_now():
    """Clearance is computed once per map snapshot and shared; a grid whose cells were
    changed in place must not be planned on with the clearance of its old cells."""
    data = room(8.0, 4.0)
    g = grid(data)
    before = GridPlanner(g).plan((1.0, 2.0), (7.0, 2.0))
    assert before is not None
    block(data, 3.9, 4.1, 0.0, 4.0)  # a wall across the whole room, written into g.data
    assert GridPlanner(g).plan((1.0, 2.0), (7.0, 2.0)) is None
    data[:, :] = room(8.0, 4.0)
    assert np.array_equal(GridPlanner(g).plan((1.0, 2.0), (7.0, 2.0)), before)
