"""Gap viewpoints: where the monitor pass goes to see the floor its camera has not seen."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bomc_bt.algorithm_params import TraversalParams
from bomc_bt.coverage_plan import order_stops
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.planner import GridPlanner
from bomc_bt.viewpoints import GapParams, _nearest_neighbour_order, gap_targets, gap_viewpoints

RES = 0.05


def two_rooms(door: bool = True) -> OccupancyGrid:
    """15 x 10 m, split by a wall at x = 7.5 m with a 2 m door (y 4-6 m) when ``door``."""
    data = np.zeros((200, 300), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[:, 150] = 100
    if door:
        data[80:120, 150] = 0
    return OccupancyGrid(data, RES, (0.0, 0.0))


def seen_left_room(grid: OccupancyGrid) -> np.ndarray:
    seen = np.zeros(grid.data.shape, np.uint8)
    seen[:, :150] = 1
    return seen


def sees(grid: OccupancyGrid, view: Pose2D, point: np.ndarray, params: GapParams) -> bool:
    """Independent check: in range, inside the planned cone, and a 1 cm-sampled clear line."""
    dx, dy = point[0] - view.x, point[1] - view.y
    d = math.hypot(dx, dy)
    if not params.min_range <= d <= params.view_range:
        return False
    if abs(math.remainder(math.atan2(dy, dx) - view.yaw, 2 * math.pi)) > math.radians(params.hfov_deg) / 2:
        return False
    t = np.linspace(0.0, 1.0, max(2, int(d / 0.01)))[:-10]
    rows, cols = grid.world_to_cell(view.x + t * dx, view.y + t * dy)
    return bool(grid.free_mask()[rows, cols].all())


def test_viewpoints_look_into_the_unseen_room_through_its_door():
    grid, params = two_rooms(), GapParams(max_viewpoints=20)
    seen = seen_left_room(grid)
    views = gap_viewpoints(grid, seen, Pose2D(2.0, 5.0, 0.0), params)
    assert 4 <= len(views) <= 20
    assert all(v.x > 7.0 for v in views)  # a wall is between the left room and most of the right
    targets = gap_targets(grid, seen, params)
    covered = np.array([any(sees(grid, v, p, params) for v in views) for p in targets])
    assert covered.mean() >= 0.9, covered.mean()  # the unseen room is now (nearly) all in view
    first = views[0]
    assert math.hypot(first.x - 2.0, first.y - 5.0) <= min(math.hypot(v.x - 2.0, v.y - 5.0) for v in views) + 1e-9


def test_nothing_to_see_means_no_viewpoints():
    grid = two_rooms()
    everything = np.ones(grid.data.shape, np.uint8)
    assert gap_viewpoints(grid, everything, Pose2D(2.0, 5.0, 0.0)) == []
    seen = everything.copy()
    seen[100:110, 200:210] = 0  # 0.25 m²: below min_area
    assert gap_viewpoints(grid, seen, Pose2D(2.0, 5.0, 0.0), GapParams(min_area=1.0)) == []


def test_a_room_without_a_door_cannot_be_seen_from_outside():
    grid = two_rooms(door=False)
    assert gap_viewpoints(grid, seen_left_room(grid), Pose2D(2.0, 5.0, 0.0)) == []


def test_max_viewpoints_and_min_gain_bound_the_extra_driving():
    grid = two_rooms()
    seen = seen_left_room(grid)
    assert len(gap_viewpoints(grid, seen, Pose2D(2.0, 5.0, 0.0), GapParams(max_viewpoints=3))) == 3
    assert gap_viewpoints(grid, seen, Pose2D(2.0, 5.0, 0.0), GapParams(min_gain=100.0)) == []


@pytest.mark.parametrize("field,value", [("max_viewpoints", -1), ("min_range", 5.0), ("hfov_deg", 0.0)])
def test_bad_params_are_refused(field, value):
    with pytest.raises(ValueError):
        GapParams(**{field: value})


def test_the_lidar_shadow_of_furniture_is_worth_a_look():
    """A room the camera has seen, but for the unknown block where a table's legs kept the
    lidar out: the camera, higher up, can see what stands there."""
    data = np.zeros((200, 200), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[86:114, 86:114] = -1  # 1.4 m square of unknown in the middle of the room
    grid = OccupancyGrid(data, RES, (0.0, 0.0))
    seen = (data == 0).astype(np.uint8)  # every free cell seen; the shadow never
    views = gap_viewpoints(grid, seen, Pose2D(1.0, 1.0, 0.0), GapParams(shadow=0.75))
    assert views
    for v in views:  # each looks at the block's centre (5, 5) within half its field of view
        bearing = math.atan2(5.0 - v.y, 5.0 - v.x)
        assert abs(math.remainder(bearing - v.yaw, 2 * math.pi)) <= math.radians(25) + 0.35
    assert gap_viewpoints(grid, seen, Pose2D(1.0, 1.0, 0.0), GapParams(shadow=0.0)) == []


def test_gap_viewpoints_are_driven_as_one_tour_along_the_walls_not_by_straight_line():
    """A 20 x 10 m floor split by a wall at y = 5 m, open only at its right end: the
    viewpoint nearest the dock in a straight line lies behind the wall. Nearest-neighbour
    by straight lines goes there first and drives round the wall twice; ordered over path
    lengths, the robot goes round once."""
    data = np.zeros((200, 400), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[98:102, :340] = 100
    grid = OccupancyGrid(data, RES, (0.0, 0.0))
    planner = GridPlanner(grid)
    dock = (1.5, 2.5)
    views = [Pose2D(x, y, 0.0) for x, y in ((1.5, 7.5), (9.0, 2.5), (16.0, 2.5), (16.0, 7.5), (9.0, 7.5))]
    ordered = order_stops(planner, dock, views, TraversalParams())
    assert [(v.x, v.y) for v in ordered] == [(9.0, 2.5), (16.0, 2.5), (16.0, 7.5), (9.0, 7.5), (1.5, 7.5)]

    def driven(order: list[Pose2D]) -> float:
        stops = [dock] + [(v.x, v.y) for v in order]
        return sum(planner.lookup(planner.distances_from(a), b) for a, b in zip(stops[:-1], stops[1:], strict=True))

    straight = _nearest_neighbour_order(views, Pose2D(*dock, 0.0))
    assert (straight[0].x, straight[0].y) == (1.5, 7.5)
    assert driven(ordered) < 0.7 * driven(straight)
