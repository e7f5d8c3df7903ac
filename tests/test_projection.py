"""Perception geometry: back-projection through full SE(3), robust centroid, FoV, visibility."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.perception.frames import Detection
from bomc_bt.perception.projection import (
    ProjectionParams,
    ProjectionStats,
    backproject,
    detections_to_observations,
    fov_polygon,
    in_polygon,
    robust_centroid,
    truncated,
    visible,
)
from bomc_bt.robot import RGBDFrame
from bomc_bt.sim.camera import CameraParams, SimCamera
from bomc_bt.sim.detector import SimDetector, SimDetectorParams
from bomc_bt.world import WorldObject

RES = 0.05


def empty_world(size_m: float = 30.0):
    n = int(size_m / RES)
    grid = OccupancyGrid(np.zeros((n, n), dtype=np.int8), RES, (-size_m / 2, -size_m / 2))
    return np.zeros((n, n), dtype=bool), grid


def see(objects, pose, tilt=15.0, walls=None, grid=None, scale=0.5):
    cam = SimCamera(CameraParams(scale=scale, tilt_deg=tilt, depth_noise=0.0), seed=0)
    if walls is None:
        walls, grid = empty_world()
    return cam.render(walls, grid, 2.5, list(objects), [], [], pose, pose, 0.0)


def perfect_observations(frame, categories, params=None):
    det = SimDetector(SimDetectorParams(preset="perfect"))
    detections = det.segment(frame, det.detect(frame, categories))
    return detections, detections_to_observations(frame, detections, params or ProjectionParams())


def facing_panel(pose: Pose2D, distance: float, bearing: float, height: float) -> WorldObject:
    """A thin square panel facing the camera: its visible points' mean is its centre."""
    yaw = pose.yaw + bearing
    x, y = pose.x + distance * math.cos(yaw), pose.y + distance * math.sin(yaw)
    return WorldObject("p", "panel", (x, y, height), (0.01, 0.3, 0.3), yaw)


def box_distance(points: np.ndarray, obj: WorldObject) -> np.ndarray:
    """Distance of each point from the surface of an oriented box (0 on it)."""
    c, s = math.cos(obj.yaw), math.sin(obj.yaw)
    rel = points - np.asarray(obj.position)
    local = np.stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1], rel[:, 2]], axis=1)
    q = np.abs(local) - np.asarray(obj.size) / 2.0
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = np.minimum(q.max(axis=1), 0.0)
    return np.abs(outside + inside)


def test_backproject_inverts_the_pinhole_model():
    K = np.array([[100.0, 0, 19.5], [0, 100.0, 14.5], [0, 0, 1]])
    depth = np.full((30, 40), 2.0, dtype=np.float32)
    depth[0, 0] = np.nan
    depth[1, 1] = 9.0
    mask = np.zeros((30, 40), dtype=bool)
    mask[:4, :4] = True
    mask[20, 30] = True
    pts = backproject(depth, mask, K, stride=1, depth_range=(0.3, 8.0))
    assert len(pts) == 16 - 2 + 1  # the block without its NaN and out-of-range pixels, and (20, 30)
    assert pts[-1] == pytest.approx([(30 - 19.5) / 100.0 * 2.0, (20 - 14.5) / 100.0 * 2.0, 2.0])
    strided = backproject(depth, mask, K, stride=2)
    assert len(strided) == 4  # lattice pixels (0, 2), (2, 0), (2, 2) ((0, 0) is NaN) and (20, 30)
    with pytest.raises(BomcError, match="mask"):
        backproject(depth, mask[:10], K)


VIEWS = {  # tilt -> (bearing, height, distance) of panels fully inside that view
    0.0: [(0.0, 1.1, 3.0), (0.3, 0.6, 3.0), (-0.35, 1.5, 3.5)],
    15.0: [(0.0, 1.0, 3.0), (0.3, 0.5, 3.0), (-0.35, 1.2, 3.5)],
    30.0: [(0.0, 0.3, 2.5), (0.3, 0.5, 3.0), (-0.35, 0.15, 2.0)],
}


@pytest.mark.parametrize("pose", [Pose2D(0.0, 0.0, 0.0), Pose2D(3.0, -2.0, 2.3), Pose2D(-4.0, 5.0, -1.1)])
@pytest.mark.parametrize("tilt", sorted(VIEWS))
def test_detection_lands_at_the_object_map_position(pose, tilt):
    for bearing, height, distance in VIEWS[tilt]:
        panel = facing_panel(pose, distance, bearing, height)
        frame = see([panel], pose, tilt)
        dets, obs = perfect_observations(frame, ["panel"])
        assert len(obs) == 1, (pose, tilt, bearing, height)
        rows, cols = np.nonzero(dets[0].mask)
        h, w = frame.shape
        assert rows.min() > 0 and cols.min() > 0 and rows.max() < h - 1 and cols.max() < w - 1
        assert np.linalg.norm(obs[0].position - np.asarray(panel.position)) < 0.03


def test_every_backprojected_point_lies_on_the_box_surface():
    pose = Pose2D(1.0, 2.0, 0.7)
    box = WorldObject("t", "table", (3.0, 4.3, 0.375), (1.2, 0.8, 0.75), yaw=0.4)
    frame = see([box], pose, tilt=20.0)
    dets, obs = perfect_observations(frame, ["table"])
    cam = backproject(frame.depth, dets[0].mask, frame.K)
    T = frame.T_map_camera
    pts = cam @ T[:3, :3].T + T[:3, 3]
    assert box_distance(pts, box).max() < 0.005
    # Objects at different heights keep different centroids (full 3D).
    assert 0.3 < obs[0].position[2] < 0.75


def test_localization_error_moves_observations_with_the_reported_pose():
    true = Pose2D(0.0, 0.0, 0.0)
    reported = Pose2D(0.2, 0.0, 0.0)
    panel = facing_panel(true, 2.5, 0.0, 1.0)
    cam = SimCamera(CameraParams(scale=0.5, depth_noise=0.0))
    walls, grid = empty_world()
    frame = cam.render(walls, grid, 2.5, [panel], [], [], true, reported, 0.0)
    _, obs = perfect_observations(frame, ["panel"])
    assert obs[0].position[0] == pytest.approx(panel.position[0] + 0.2, abs=0.03)


def bleed_mask(mask: np.ndarray, fraction: float) -> np.ndarray:
    """Dilate until the mask grew by ``fraction`` of its area."""
    grown = mask.copy()
    target = mask.sum() * (1.0 + fraction)
    while grown.sum() < target:
        grown = cv2.dilate(grown.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    return grown


def test_robust_centroid_survives_mask_bleed_onto_a_far_wall():
    walls, grid = empty_world()
    _, col = grid.world_to_cell(5.0, 0.0)
    walls[:, int(col):int(col) + 3] = True  # a wall 2.5 m behind the object
    pose = Pose2D(0.0, 0.0, 0.0)
    panel = WorldObject("p", "panel", (2.5, 0.0, 1.2), (0.05, 0.4, 0.4))
    frame = see([panel], pose, walls=walls, grid=grid)
    dets, _ = perfect_observations(frame, ["panel"])
    bled = bleed_mask(dets[0].mask, 0.3)
    assert np.isfinite(frame.depth[bled & ~dets[0].mask]).all()  # the bleed sees the wall
    T = frame.T_map_camera
    pts = backproject(frame.depth, bled, frame.K) @ T[:3, :3].T + T[:3, 3]
    truth = np.array([2.475, 0.0, 1.2])  # the face towards the camera
    assert np.linalg.norm(pts.mean(axis=0) - truth) > 0.3  # a plain mean is dragged away
    assert np.linalg.norm(robust_centroid(pts, origin=T[:3, 3]) - truth) < 0.1
    assert np.linalg.norm(robust_centroid(pts) - truth) < 0.1  # without the camera position too
    obs = detections_to_observations(frame, [dets[0].with_mask(bled)], ProjectionParams())
    assert np.linalg.norm(obs[0].position - truth) < 0.1


def test_robust_centroid_keeps_a_deep_object_whole():
    rng = np.random.default_rng(0)
    pts = rng.uniform([2.0, -0.3, 0.0], [3.2, 0.3, 0.75], size=(2000, 3))  # a 1.2 m deep table
    centre = robust_centroid(pts, origin=np.zeros(3))
    assert np.linalg.norm(centre - pts.mean(axis=0)) < 0.05
    assert robust_centroid(np.empty((0, 3))) is None
    assert robust_centroid(np.full((5, 3), np.nan)) is None


def test_unusable_detections_are_counted_not_raised():
    pose = Pose2D(0.0, 0.0, 0.0)
    panel = facing_panel(pose, 2.5, 0.0, 1.1)
    frame = see([panel], pose)
    dets, _ = perfect_observations(frame, ["panel"])
    good = dets[0]
    h, w = frame.shape
    empty = good.with_mask(np.zeros((h, w), dtype=bool))
    no_mask = Detection("panel", good.box, 0.9)
    tiny = np.zeros((h, w), dtype=bool)
    tiny[np.nonzero(good.mask)[0][0], np.nonzero(good.mask)[1][0]] = True
    nan_frame = RGBDFrame(frame.stamp, None, np.full((h, w), np.nan, np.float32), frame.K,
                          frame.T_map_base, frame.T_base_camera)
    stats = ProjectionStats()
    obs = detections_to_observations(frame, [empty, no_mask, good.with_mask(tiny), good],
                                     ProjectionParams(), stats)
    assert len(obs) == 1 and obs[0].category == "panel" and obs[0].confidence == 1.0
    assert (stats.no_mask, stats.few_points, stats.observations, stats.detections) == (2, 1, 1, 4)
    assert detections_to_observations(nan_frame, [good], ProjectionParams(), stats) == []
    assert stats.no_depth == 1


def test_params_scale_with_the_image():
    p = ProjectionParams(min_points=30, stride=2)
    assert p.scaled((480, 640)) == (2, 30)
    stride, min_points = p.scaled((120, 160))
    assert stride == 1 and min_points == 8  # same apparent size passes at a quarter resolution


def test_fov_polygon_contains_what_is_in_view_and_not_what_is_behind():
    walls, grid = empty_world()
    _, col = grid.world_to_cell(4.0, 0.0)
    walls[:, int(col):int(col) + 3] = True
    pose = Pose2D(0.0, 0.0, 0.0)
    frame = see([], pose, walls=walls, grid=grid)
    poly = fov_polygon(frame, ProjectionParams())
    assert poly.shape[1] == 2 and len(poly) >= 10
    inside = in_polygon(poly, [[2.5, 0.3], [-1.5, 0.0], [6.0, 0.0], [2.5, 4.0], [3.8, -0.5]])
    assert inside.tolist() == [True, False, False, False, True]
    # Counter-clockwise, and capped at max_depth when nothing is in the way.
    x, y = poly[:, 0], poly[:, 1]
    assert np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)) > 0
    open_frame = see([], Pose2D(0.0, 0.0, 1.0))
    camera_xy = open_frame.T_map_camera[:2, 3]
    near = np.linalg.norm(fov_polygon(open_frame, ProjectionParams(max_depth=3.0)) - camera_xy, axis=1)
    far = np.linalg.norm(fov_polygon(open_frame, ProjectionParams(max_depth=6.0)) - camera_xy, axis=1)
    assert 2.5 < near.max() < 3.0 * 1.23  # optical depth 3 m on the most oblique ray
    assert far.max() > 5.0


def test_fov_polygon_of_a_blind_frame_is_empty():
    frame = see([], Pose2D(0.0, 0.0, 0.0))
    frame.depth[:] = np.nan
    assert fov_polygon(frame).shape == (0, 2)


def test_visible_tells_seen_from_hidden():
    walls, grid = empty_world()
    _, col = grid.world_to_cell(3.0, 0.0)
    walls[:, int(col):int(col) + 3] = True
    pose = Pose2D(0.0, 0.0, 0.0)
    chair = WorldObject("c", "chair", (2.0, 0.4, 0.45), (0.5, 0.5, 0.9))
    frame = see([chair], pose, walls=walls, grid=grid)
    _, obs = perfect_observations(frame, ["chair"])
    points = np.array([
        obs[0].position,  # the chair as observed
        [4.5, 0.0, 0.5],  # behind the wall
        [-2.0, 0.0, 0.5],  # behind the robot
        [2.6, 0.4, 0.3],  # behind the chair
        [2.5, -0.6, 0.05],  # on the free floor in view
        [1.5, 3.0, 0.5],  # out of the image to the left
    ])
    assert visible(frame, points).tolist() == [True, False, False, False, True, False]
    # Once the chair is gone, its old position is seen through: it is expected and missing.
    empty = see([], pose, walls=walls, grid=grid)
    assert visible(empty, points[:1]).tolist() == [True]
    assert visible(empty, points[:1], max_depth=1.0).tolist() == [False]
    assert visible(empty, np.empty((0, 3))).shape == (0,)


def test_truncated_tells_a_cut_off_view_from_a_whole_one():
    depth = np.full((48, 64), 4.0, np.float32)  # a wall 4 m away
    depth[20:30, 20:40] = 2.0  # the object, 2 m away, whole and in the open
    whole = np.zeros(depth.shape, bool)
    whole[20:30, 20:40] = True
    assert not truncated(depth, whole, 2.0)
    occluded = depth.copy()
    occluded[18:32, 30:34] = 1.2  # a chair leg in front cuts it in two
    left = whole.copy()
    left[:, 30:] = False
    assert truncated(occluded, left, 2.0)
    at_edge = np.zeros(depth.shape, bool)
    at_edge[20:30, 0:10] = True  # cut by the image border
    assert truncated(depth, at_edge, 2.0)
    nan = depth.copy()
    nan[19, :] = np.nan  # no depth next to it is no evidence of an occluder
    assert not truncated(nan, whole, 2.0)


def test_observations_carry_their_floor_box_and_truncation():
    table = WorldObject("t", "table", (3.0, 0.0, 0.375), (0.8, 1.2, 0.75), 0.0)
    _, (o,) = perfect_observations(see([table], Pose2D(0.0, 0.0, 0.0)), ["table"])
    x0, y0, x1, y1 = o.box
    assert x0 <= o.position[0] <= 3.1 and y0 <= o.position[1] <= y1  # its far part moves the centre, not the box
    assert 2.5 < x0 < 2.7 and 1.0 < y1 - y0 < 1.3  # from its near edge; its whole width
    assert not o.truncated
    chair = WorldObject("c", "chair", (2.0, 0.0, 0.45), (0.5, 0.5, 0.9), 0.0)  # in front of its middle
    _, observations = perfect_observations(see([table, chair], Pose2D(0.0, 0.0, 0.0)), ["table"])
    assert observations and all(o.truncated for o in observations)


def test_a_detection_on_bare_floor_is_no_object_but_an_object_keeps_the_floor_its_mask_spilled_onto():
    """A box standing on the floor and, beside it, a "detection" whose mask holds only the
    floor in front of it: the second gives no observation (it is counted as on the floor);
    the box's own mask widened by a band of floor is kept, as a whole."""
    pose = Pose2D(0.0, 0.0, 0.0)
    box = WorldObject("b", "bin", (2.5, 0.0, 0.3), (0.4, 0.4, 0.6), 0.0)
    frame = see([box], pose, 15.0)
    dets, _ = perfect_observations(frame, ["bin"])
    rows, cols = np.nonzero(dets[0].mask)
    spilled = dets[0].mask.copy()
    spilled[rows.max() + 1:rows.max() + 6, cols.min():cols.max() + 1] = True  # floor just below its foot
    floor_only = np.zeros_like(spilled)
    floor_only[rows.max() + 2:rows.max() + 14, cols.min():cols.max() + 1] = True
    assert np.isfinite(frame.depth[floor_only]).all()
    stats = ProjectionStats()
    views = [replace(dets[0], mask=spilled), replace(dets[0], mask=floor_only)]
    kept = detections_to_observations(frame, views, ProjectionParams(), stats)
    assert len(kept) == 1 and stats.on_floor == 1 and stats.observations == 1
    unfiltered = detections_to_observations(frame, views, ProjectionParams(floor_height=0.0))
    assert len(unfiltered) == 2 and unfiltered[1].position[2] < 0.02  # what it was: a floor "object"
    assert np.allclose(kept[0].position, unfiltered[0].position)  # the object's view is untouched


def map_heights_and_x(frame) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel, the map-frame height and x of what its depth sees (NaN without depth)."""
    rows, cols = np.indices(frame.depth.shape)
    K, z = frame.K, frame.depth.astype(float)
    cam = np.stack([(cols - K[0, 2]) / K[0, 0] * z, (rows - K[1, 2]) / K[1, 1] * z, z], axis=-1)
    world = cam @ frame.T_map_camera[:3, :3].T + frame.T_map_camera[:3, 3]
    return world[..., 2], world[..., 0]


def test_a_shadow_whose_mask_reaches_up_the_wall_behind_is_no_object():
    """A "chair" the detector takes a shadow on the floor for, its mask reaching up the wall
    1.6 m behind: enough of the mask lies above the floor (on the wall), but the surface
    the view is of, the nearest dominant range, is all floor. No observation (counted as on
    the floor); before, it was a chair at floor height, kept pass after pass."""
    walls, grid = empty_world()
    _, col = grid.world_to_cell(4.2, 0.0)
    walls[:, int(col):int(col) + 4] = True  # a wall facing the camera, 4.2 m ahead
    frame = see([], Pose2D(0.0, 0.0, 0.0), 15.0, walls=walls, grid=grid)
    height, x = map_heights_and_x(frame)
    cols = np.zeros(frame.depth.shape, dtype=bool)
    cols[:, frame.depth.shape[1] // 2 - 12:frame.depth.shape[1] // 2 + 12] = True
    floor = cols & (height < 0.02) & (x > 2.0) & (x < 2.6)
    wall = cols & (x > 4.1) & (height > 0.1) & (height < 0.2)
    shadow = floor | wall
    params = ProjectionParams()
    stride, min_points = params.scaled(frame.shape)
    points = backproject(frame.depth, wall, frame.K, stride)
    assert len(points) >= min_points  # the mask's wall part alone passes the whole-mask floor test
    assert floor.sum() > 3 * wall.sum()
    detection = Detection("chair", (0.0, 0.0, 1.0, 1.0), 0.6, mask=shadow)
    stats = ProjectionStats()
    assert detections_to_observations(frame, [detection], params, stats) == []
    assert stats.on_floor == 1
    assert len(detections_to_observations(frame, [detection], ProjectionParams(floor_height=0.0))) == 1  # off
    # the wall part alone stands above the floor: a patch of the wall (surface_patch.py), and
    # with that test off a view of something standing (the wall)
    assert detections_to_observations(frame, [replace(detection, mask=wall)], params, stats) == []
    assert stats.on_wall == 1
    [on_wall] = detections_to_observations(frame, [replace(detection, mask=wall)], replace(params, patch_share=1.1))
    assert on_wall.position[2] > 0.1


def test_a_far_object_is_not_made_of_what_its_mask_bled_onto_in_front_of_it():
    """A cabinet 7.5 m away, its mask bled onto the bin in front of it. Beyond max_depth (6 m)
    the cabinet's own pixels are cut away; the bin's rim would be all that was left, a
    "cabinet" 2 m too near (PAL's Willow Garage map: two phantom cabinets in one pass).
    A mask mostly beyond the range is a far object's and gives no observation; a near
    object whose mask bled onto a wall beyond the range is kept, at its place."""
    pose = Pose2D(0.0, 0.0, 0.0)
    cabinet = WorldObject("c", "cabinet", (7.5, 0.0, 0.6), (0.5, 0.9, 1.2))
    bin_ = WorldObject("b", "bin", (5.3, 0.25, 0.3), (0.4, 0.4, 0.6))
    frame = see([cabinet, bin_], pose, 5.0)
    dets, _ = perfect_observations(frame, ["cabinet"])
    bled = bleed_mask(dets[0].mask, 0.3)
    assert (frame.depth[bled & ~dets[0].mask] < 6.0).any()  # some of the bleed lies on the bin
    stats = ProjectionStats()
    assert detections_to_observations(frame, [dets[0].with_mask(bled)], ProjectionParams(), stats) == []
    assert stats.too_far == 1 and stats.observations == 0

    walls, grid = empty_world()
    _, col = grid.world_to_cell(7.5, 0.0)
    walls[:, int(col):int(col) + 3] = True  # a wall beyond the range, 3 m behind the object
    near = WorldObject("c", "cabinet", (4.5, 0.0, 0.6), (0.5, 0.9, 1.2))
    frame = see([near], pose, 5.0, walls=walls, grid=grid)
    dets, _ = perfect_observations(frame, ["cabinet"])
    bled = bleed_mask(dets[0].mask, 0.3)
    assert (frame.depth[bled & ~dets[0].mask] > 6.0).any()  # the bleed sees the far wall
    [obs] = detections_to_observations(frame, [dets[0].with_mask(bled)], ProjectionParams())
    assert np.linalg.norm(obs.position[:2] - [4.25, 0.0]) < 0.15  # its face towards the camera
