"""The floor a frame looked at (first seen vs added, issue 17): furniture hides what is behind it."""

from __future__ import annotations

import numpy as np

from bomc_bt.algorithm_params import ProjectionParams
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.perception.looked import looked_polygon
from bomc_bt.perception.projection import fov_polygon, in_polygon
from bomc_bt.sim.camera import CameraParams, SimCamera
from bomc_bt.world import WorldObject

RES = 0.05
REACH = 5.0


def room_with_far_wall(size_m: float = 30.0, wall_x: float = 6.0):
    n = int(size_m / RES)
    grid = OccupancyGrid(np.zeros((n, n), dtype=np.int8), RES, (-size_m / 2, -size_m / 2))
    walls = np.zeros((n, n), dtype=bool)
    _, col = grid.world_to_cell(wall_x, 0.0)
    walls[:, int(col):int(col) + 3] = True
    return walls, grid


def frame_of(objects, noise: float = 0.0):
    walls, grid = room_with_far_wall()
    cam = SimCamera(CameraParams(scale=0.5, depth_noise=noise), seed=3)
    pose = Pose2D(0.0, 0.0, 0.0)
    return cam.render(walls, grid, 2.5, list(objects), [], [], pose, pose, 0.0)


TABLE = WorldObject("table-1", "table", (2.0, 0.0, 0.375), (0.8, 1.0, 0.75), 0.0)
MAT = WorldObject("mat-1", "mat", (2.0, 0.0, 0.04), (0.8, 1.0, 0.08), 0.0)
BEHIND_TABLE, BESIDE_TABLE, BEFORE_TABLE = [3.4, 0.0], [3.0, 1.2], [1.2, 0.0]


def test_the_floor_behind_a_table_was_not_looked_at_though_the_view_fan_covers_it():
    frame = frame_of([TABLE])
    params = ProjectionParams()
    looked = looked_polygon(frame, params, REACH)
    fan = fov_polygon(frame, params)
    points = [BEHIND_TABLE, BESIDE_TABLE, BEFORE_TABLE]
    assert in_polygon(fan, points).tolist() == [True, True, True]  # the fan reaches the wall behind
    assert in_polygon(looked, points).tolist() == [False, True, True]


def test_with_nothing_standing_the_look_reaches_the_wall_or_the_reach_whichever_is_nearer():
    params = ProjectionParams()
    for noise in (0.0, 0.005):  # floor pixels with depth noise do not cut the columns short
        looked = looked_polygon(frame_of([], noise), params, REACH)
        ranges = np.hypot(*(looked[1:] - looked[0]).T)
        assert np.median(ranges) > 4.9 and ranges.max() <= REACH + 1e-9
        assert in_polygon(looked, [BEHIND_TABLE, [4.8, 0.0]]).tolist() == [True, True]
    looked_short = looked_polygon(frame_of([]), params, 3.0)
    assert in_polygon(looked_short, [[2.8, 0.0], [3.4, 0.0]]).tolist() == [True, False]


def test_a_thing_lower_than_an_object_does_not_hide_the_floor_behind_it():
    looked = looked_polygon(frame_of([MAT]), ProjectionParams(), REACH)
    assert in_polygon(looked, [BEHIND_TABLE]).tolist() == [True]


def test_a_blind_frame_looked_at_nothing():
    frame = frame_of([])
    frame.depth[:] = np.nan
    assert looked_polygon(frame, ProjectionParams(), REACH).shape == (0, 2)


def test_the_camera_is_vertex_0_so_the_near_coverage_is_cut_from_the_camera():
    """A budget's looks count only the floor within ``near_range`` of the camera; with the
    fan's vertices reversed to make it counter-clockwise, the camera used to be the *last*
    vertex and the cut was measured from a far corner of the fan."""
    from bomc_bt.monitoring import Coverage
    frame = frame_of([])
    camera = frame.T_map_camera[:2, 3]
    fan = fov_polygon(frame, ProjectionParams())
    assert np.allclose(fan[0], camera) and np.allclose(looked_polygon(frame, ProjectionParams(), REACH)[0], camera)
    _, grid = room_with_far_wall()
    coverage = Coverage(grid, near_range=3.0)
    coverage.add(fan)
    rows, cols = np.nonzero(coverage.near)
    x, y = grid.cell_to_world(rows, cols)
    assert np.hypot(x - camera[0], y - camera[1]).max() <= 3.0 + 2 * RES
    assert coverage.near[grid.world_to_cell(2.5, 0.0)] and not coverage.near[grid.world_to_cell(4.0, 0.0)]
    assert coverage.seen[grid.world_to_cell(4.0, 0.0)]
