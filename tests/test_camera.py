"""The simulated head camera: geometry of what it renders, ids, ranges, noise, poses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.sim.camera import CameraParams, SimCamera, category_colour
from bomc_bt.world import Obstacle, WorldObject

RES = 0.05


def empty_world(size_m: float = 20.0) -> tuple[np.ndarray, OccupancyGrid]:
    """A free square centred on the origin (its outer border is wall by convention)."""
    n = int(size_m / RES)
    grid = OccupancyGrid(np.zeros((n, n), dtype=np.int8), RES, (-size_m / 2, -size_m / 2))
    return np.zeros((n, n), dtype=bool), grid


def wall_at_x(walls: np.ndarray, grid: OccupancyGrid, x: float) -> None:
    _, col = grid.world_to_cell(x, 0.0)
    walls[:, int(col):int(col) + 3] = True


def camera(**kw) -> SimCamera:
    kw.setdefault("depth_noise", 0.0)
    return SimCamera(CameraParams(**kw), seed=0)


ORIGIN = Pose2D(0.0, 0.0, 0.0)


def render(cam, walls, grid, objects=(), obstacles=(), people=(), pose=ORIGIN,
           reported=None, stamp=0.0, wall_height=2.5):
    return cam.render(walls, grid, wall_height, list(objects), list(obstacles), list(people), pose,
                      reported or pose, stamp)


def test_box_in_front_renders_at_the_right_pixels_and_depth():
    cam = camera(tilt_deg=0.0, scale=0.5)
    walls, grid = empty_world()
    box = WorldObject("b", "box", (3.0, 0.0, 1.1), (0.2, 0.4, 0.4))  # centred on the optical axis
    f = render(cam, walls, grid, [box])
    K = f.K
    h, w = f.shape
    assert (h, w) == (240, 320)
    cu, cv = int(round(K[0, 2])), int(round(K[1, 2]))
    assert f.instances[cv, cu] == 1
    assert f.depth[cv, cu] == pytest.approx(3.0 - 0.1 - 0.1, abs=1e-4)  # front face minus mount_x
    cols = np.flatnonzero((f.instances == 1).any(axis=0))
    half_px = K[0, 0] * 0.2 / 2.8
    assert cols[0] == pytest.approx(K[0, 2] - half_px, abs=1.0)
    assert cols[-1] == pytest.approx(K[0, 2] + half_px, abs=1.0)
    assert f.instance_categories == {1: "box"}


def test_intrinsics_follow_the_field_of_view_and_scale():
    full, quarter = camera(), camera(scale=0.25)
    assert full.K()[0, 0] == pytest.approx(320.0 / math.tan(math.radians(30.0)))
    assert quarter.K()[0, 0] == pytest.approx(full.K()[0, 0] / 4.0)
    T = full.T_base_camera()
    # The optical axis (z) points forward and down by the tilt; x (image right) is -y of the base.
    assert T[:3, 2] == pytest.approx([math.cos(math.radians(15)), 0.0, -math.sin(math.radians(15))])
    assert T[:3, 0] == pytest.approx([0.0, -1.0, 0.0])
    assert T[:3, 3] == pytest.approx([0.1, 0.0, 1.1])


def test_walls_floor_and_open_sky():
    cam = camera(tilt_deg=0.0, scale=0.25)
    walls, grid = empty_world()
    wall_at_x(walls, grid, 4.0)
    f = render(cam, walls, grid, wall_height=1.5)
    h, w = f.shape
    cu = w // 2
    col = f.depth[:, cu]
    # Mid-height rows see the wall 3.9 m away (camera 0.1 m ahead of base_link).
    assert f.depth[h // 2, cu] == pytest.approx(3.9, abs=RES)
    # Rows looking up past the 1.5 m wall top see nothing.
    assert np.isnan(col[0])
    # The bottom row sees the floor at the depth the ray geometry predicts.
    K = f.K
    slope = (h - 1 - K[1, 2]) / K[1, 1]
    assert col[-1] == pytest.approx(1.1 / slope, rel=1e-3)
    assert f.instances.max() == 0
    # Floor, wall and sky are shaded differently.
    assert len({tuple(f.rgb[0, cu]), tuple(f.rgb[h // 2, cu]), tuple(f.rgb[-1, cu])}) == 3


def test_wall_occludes_object_behind_it_and_outside_the_grid_is_wall():
    cam = camera(tilt_deg=0.0, scale=0.25)
    walls, grid = empty_world(10.0)  # border at x = 5
    wall_at_x(walls, grid, 3.0)
    hidden = WorldObject("h", "chair", (4.0, 0.0, 0.5), (0.5, 0.5, 1.0))
    f = render(cam, walls, grid, [hidden])
    assert not (f.instances == 1).any()
    walls = np.zeros_like(walls)  # a new array: the distance field is cached per walls array
    f = render(cam, walls, grid, [hidden])
    assert (f.instances == 1).any()
    h, w = f.shape
    assert f.depth[h // 2 - 10, w // 2] == pytest.approx(4.9, abs=RES)  # the map border


def test_instance_ids_nearest_hit_and_unlabelled_things():
    cam = camera(scale=0.25, tilt_deg=10.0)
    walls, grid = empty_world()
    front = WorldObject("a", "chair", (2.0, 0.0, 0.45), (0.5, 0.5, 0.9))
    back = WorldObject("b", "cabinet", (3.0, 0.0, 0.6), (0.6, 1.6, 1.2), yaw=0.3)
    obstacle = Obstacle((2.5, -1.2), (0.5, 0.5), 0.8)
    f = render(cam, walls, grid, [front, back], [obstacle], [(2.6, 1.2)])
    ids = set(np.unique(f.instances).tolist())
    assert ids == {0, 1, 2, 3, 4}
    assert f.instance_categories == {1: "chair", 2: "cabinet"}  # obstacle 3, person 4: no category
    # The chair hides part of the cabinet behind it: fewer visible than unoccluded pixels.
    assert np.count_nonzero(f.instances == 2) < f.instance_unoccluded[2]
    assert np.count_nonzero(f.instances == 1) == f.instance_unoccluded[1]
    # The person is a 1.7 m cylinder: visible above the chair's and cabinet's tops.
    rows = np.flatnonzero((f.instances == 4).any(axis=1))
    rows_cab = np.flatnonzero((f.instances == 2).any(axis=1))
    assert rows[0] < rows_cab[0]
    # Colours follow categories: the chair's pixels share one hue family, unlike the cabinet.
    assert not np.array_equal(f.rgb[f.instances == 1][0], f.rgb[f.instances == 2][0])


def test_depth_range_limits():
    cam = camera(scale=0.25, tilt_deg=0.0, depth_max=5.0)
    walls, grid = empty_world(30.0)
    near = WorldObject("n", "box", (0.35, 0.0, 1.1), (0.05, 0.1, 0.1))  # 0.225 m from the camera
    far = WorldObject("f", "box", (7.0, 3.0, 1.1), (0.5, 0.5, 0.5))
    f = render(cam, walls, grid, [near, far])
    assert np.isnan(f.depth[f.instances == 1]).all()  # too close: seen, but no depth
    assert not (f.instances == 2).any()  # beyond depth_max: not rendered
    finite = f.depth[np.isfinite(f.depth)]
    assert finite.max() <= 5.0 and f.depth_range == (0.3, 5.0)


def test_frame_carries_reported_pose_but_renders_true_pose():
    cam = camera(scale=0.25)
    walls, grid = empty_world()
    obj = WorldObject("o", "box", (2.5, 0.0, 0.5), (0.4, 0.4, 1.0))
    true, reported = Pose2D(0.0, 0.0, 0.0), Pose2D(0.3, -0.2, 0.1)
    f = render(cam, walls, grid, [obj], pose=true, reported=reported)
    g = render(cam, walls, grid, [obj], pose=true)
    assert np.array_equal(f.instances, g.instances)
    assert f.T_map_base == pytest.approx(reported.to_matrix())
    assert f.T_base_camera == pytest.approx(cam.T_base_camera())


def test_rotating_the_robot_rotates_the_view():
    cam = camera(scale=0.25)
    walls, grid = empty_world()
    obj = WorldObject("o", "box", (0.0, 2.5, 0.5), (0.4, 0.4, 1.0))  # to the robot's left
    assert not (render(cam, walls, grid, [obj]).instances == 1).any()
    f = render(cam, walls, grid, [obj], pose=Pose2D(0.0, 0.0, math.pi / 2))
    cols = np.flatnonzero((f.instances == 1).any(axis=0))
    assert abs(cols.mean() - f.K[0, 2]) < 2.0


def test_noise_grows_with_depth_and_is_deterministic_per_stamp():
    cam = SimCamera(CameraParams(scale=0.25, depth_noise=0.01), seed=4)
    clean = camera(scale=0.25)
    walls, grid = empty_world()
    f1 = render(cam, walls, grid, stamp=1.0)
    f1_again = render(SimCamera(CameraParams(scale=0.25, depth_noise=0.01), seed=4), walls, grid, stamp=1.0)
    f2 = render(cam, walls, grid, stamp=1.5)
    ref = render(clean, walls, grid)
    assert np.array_equal(f1.depth, f1_again.depth, equal_nan=True)
    assert not np.array_equal(f1.depth, f2.depth, equal_nan=True)
    err = f1.depth - ref.depth
    near, far = ref.depth < 2.5, (ref.depth > 5.0) & (ref.depth < 8.0)
    assert np.nanstd(err[far]) > 3.0 * np.nanstd(err[near])


def _draw_everything(monkeypatch) -> None:
    """Make the camera slab-test every box over the whole image (no cull, no screen rectangle)
    except the two cases where no pixel can be drawn: all corners behind the camera or all
    beyond depth_max."""
    from bomc_bt.sim import raycast, solids

    def whole_image(corners, T_map_camera, shape, K, depth_max):
        z = ((corners - T_map_camera[:3, 3]) @ T_map_camera[:3, :3])[:, 2]
        if z.max() <= raycast.NEAR or z.min() > depth_max:
            return None
        return 0, shape[0], 0, shape[1]

    monkeypatch.setattr(raycast, "_screen_rect", whole_image)
    monkeypatch.setattr(solids.SceneSolids, "candidates", lambda self, *a: list(range(len(self.boxes))))


def test_culling_boxes_out_of_view_changes_no_pixel(monkeypatch):
    """The per-frame cull and the screen rectangles (also of boxes beside or around the camera)
    give the same frames as testing every box against every pixel."""
    rng = np.random.default_rng(4)
    walls, grid = empty_world(30.0)
    objects = [WorldObject(f"o{i}", "chair", (*rng.uniform(-12, 12, 2), 0.5), tuple(rng.uniform(0.2, 2.5, 3)),
                           float(rng.uniform(-3, 3))) for i in range(60)]
    obstacles = [Obstacle(tuple(rng.uniform(-12, 12, 2)), tuple(rng.uniform(0.3, 3.0, 2)), 1.0) for _ in range(10)]
    poses = [Pose2D(*rng.uniform(-12, 12, 2), float(rng.uniform(-3, 3))) for _ in range(10)]
    # Standing inside, at the side of and right behind a box: its corners straddle the camera.
    poses += [Pose2D(o.position[0] + dx, o.position[1] + dy, yaw) for o in objects[:4]
              for dx, dy, yaw in ((0.0, 0.0, 0.3), (0.6, 0.4, 2.0), (-0.9, 0.1, 0.0))]
    people = [(p.x + 1.0, p.y - 0.2) for p in poses[:3]]
    fast = [render(camera(scale=0.25), walls, grid, objects, obstacles, people, pose) for pose in poses]
    _draw_everything(monkeypatch)
    slow = [render(camera(scale=0.25), walls, grid, objects, obstacles, people, pose) for pose in poses]
    assert sum(len(f.instance_unoccluded) for f in slow) > len(poses)  # the scenes show boxes
    for a, b in zip(fast, slow, strict=True):
        assert np.array_equal(a.depth, b.depth, equal_nan=True)
        assert np.array_equal(a.instances, b.instances)
        assert np.array_equal(a.rgb, b.rgb)
        assert a.instance_unoccluded == b.instance_unoccluded


def test_an_object_is_drawn_in_its_own_colour_and_without_one_in_its_categorys():
    cam = camera(tilt_deg=0.0, scale=0.5)
    walls, grid = empty_world()
    red = WorldObject("r", "chair", (3.0, 0.6, 1.1), (0.4, 0.4, 0.4), colour=(160, 45, 40))
    plain = WorldObject("p", "chair", (3.0, -0.6, 1.1), (0.4, 0.4, 0.4))
    f = render(cam, walls, grid, [red, plain])
    rgb = f.rgb.reshape(-1, 3).astype(float)
    ids = f.instances.ravel()
    chroma = rgb[ids == 1] / rgb[ids == 1].sum(axis=1, keepdims=True)
    assert np.allclose(chroma[:, :2], [160 / 245, 45 / 245], atol=0.01)  # darkened with distance, same hue
    other = rgb[ids == 2] / rgb[ids == 2].sum(axis=1, keepdims=True)
    r, g, b = category_colour("chair")
    assert np.allclose(other, np.array([r, g, b]) / (r + g + b), atol=0.01)


def test_an_object_repainted_or_replaced_between_frames_of_one_camera_is_drawn_as_it_is_now():
    """The camera keeps the objects' colours while the records are the same; a changed world
    (new records: a chair repainted, another carried in) is drawn and labelled anew."""
    cam = camera(tilt_deg=0.0, scale=0.5)
    walls, grid = empty_world()
    red = WorldObject("r", "chair", (3.0, 0.6, 1.1), (0.4, 0.4, 0.4), colour=(160, 45, 40))
    first = render(cam, walls, grid, [red])
    blue = WorldObject("r", "chair", (3.0, 0.6, 1.1), (0.4, 0.4, 0.4), colour=(40, 45, 160))
    bin_ = WorldObject("b", "trash bin", (3.0, -0.6, 1.1), (0.4, 0.4, 0.4))
    second = render(cam, walls, grid, [blue, bin_])
    def mean(frame, instance):
        return frame.rgb.reshape(-1, 3)[frame.instances.ravel() == instance].mean(axis=0)
    assert mean(first, 1)[0] > 2 * mean(first, 1)[2] and mean(second, 1)[2] > 2 * mean(second, 1)[0]
    assert second.instance_categories == {1: "chair", 2: "trash bin"} and first.instance_categories == {1: "chair"}
    again = render(cam, walls, grid, [red])
    assert np.array_equal(again.rgb, first.rgb)
