"""The simulated head camera: a vectorised 2.5D RGB-D renderer.

The world is what the simulator knows: a walls mask extruded to ``wall_height``, the
labelled objects and the unlabelled obstacles as oriented boxes standing in the map, and
people as vertical cylinders. Every pixel ray of a pinhole camera (Fetch's head camera,
about 60 degrees horizontal field of view, tilted down) is intersected with all of them and
the nearest hit wins, giving a depth image, an instance-id image and a flat-shaded colour
image.

Why it is fast enough to run at the camera rate inside tick simulations:

* The camera is only tilted (pitched), never rolled, and the robot only yaws, so in the
  base frame every pixel ray is constant: its azimuth, its horizontal length and its
  vertical component are computed once. The floor depth of each pixel is constant too.
* Walls are 2.5D: rays are cast in the plane once per *azimuth bin* (about one per image
  column; with tilt, image columns are not vertical planes, so the bins follow azimuth
  rather than columns), by sphere tracing on a distance transform of the walls mask that
  is cached per walls array. Each pixel then compares its ray's height at the wall with
  the floor and the wall top: floor hit, wall hit, or nothing (above the wall, NaN).
* Boxes and cylinders are intersected (slab test / quadratic) only inside the image
  rectangle their corners project to, and only when they are in front of the camera and
  within ``depth_max``.

Depth is the optical-axis depth (z in the optical frame), the convention of registered
depth images. It is rendered from the *true* pose while ``T_map_base`` carries the pose the
robot *reports*, so localization error reaches the object map as it does on a robot.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.geometry import Pose2D, rotation_y, se3
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import RGBDFrame
from bomc_bt.sim.params import CameraParams

PERSON_RADIUS = 0.25  # m
PERSON_HEIGHT = 1.7  # m
_NEAR = 1e-3  # m: hits closer than this along the ray are ignored (camera inside a box)

# Label codes of the render buffer besides instance ids (> 0).
_WALL = -2
_FLOOR = -1
_NONE = 0

# Optical frame (z forward, x right, y down) expressed in base_link (x forward, y left, z up).
_R_BASE_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass
class _Box:
    """A renderable oriented box: centre (map), half extents, yaw, and its label."""

    centre: np.ndarray  # (3,)
    half: np.ndarray  # (3,)
    yaw: float
    label: int


class SimCamera:
    """Renders RGB-D frames of the simulated world from the robot's true pose."""

    def __init__(self, params: CameraParams | None = None, seed: int = 0):
        self.params = params or CameraParams()
        self.seed = int(seed)
        self.rate = float(self.params.rate)
        self._K = _intrinsics(self.params)
        self._T_base_camera = _base_camera(self.params)
        self._rays = _RayTable(self._K, self._T_base_camera, self.params)
        self._walls_key: np.ndarray | None = None
        self._walls_field: _WallField | None = None

    # -- calibration -----------------------------------------------------------------
    def T_base_camera(self) -> np.ndarray:
        """base_link -> optical frame (z forward, x right, y down), tilted down."""
        return self._T_base_camera.copy()

    def K(self) -> np.ndarray:
        """3 x 3 intrinsics of the rendered (scaled) image."""
        return self._K.copy()

    # -- rendering -------------------------------------------------------------------
    def render(self, walls: np.ndarray, grid: OccupancyGrid, wall_height: float, objects: list,
               obstacles: list, people: list[tuple[float, float]], true_pose: Pose2D,
               reported_pose: Pose2D, stamp: float) -> RGBDFrame:
        """One frame seen from ``true_pose``, registered with ``reported_pose``.

        ``objects`` are :class:`bomc_bt.world.WorldObject`-like (name, category, position,
        size, yaw); they get instance ids 1..N in the given order and a category. Obstacles
        (position, size, height, yaw) and people (x, y) get the next ids and no category,
        so the simulated detector never reports them.
        """
        p = self.params
        rays = self._rays
        T_map_camera = true_pose.to_matrix() @ self._T_base_camera
        origin = T_map_camera[:3, 3]
        field_ = self._wall_field(walls, grid)
        dist = field_.cast(origin[:2], rays.bin_azimuths + true_pose.yaw, rays.max_horizontal(p.depth_max))
        depth, label = rays.walls_and_floor(dist, origin[2], wall_height)
        boxes, cylinders = _scene(objects, obstacles, people)
        unoccluded: dict[int, int] = {}
        for box in boxes:
            n = _draw_box(box, depth, label, T_map_camera, rays, true_pose.yaw, p.depth_max)
            if n:
                unoccluded[box.label] = n
        for centre, label_id in cylinders:
            n = _draw_cylinder(centre, label_id, depth, label, T_map_camera, rays, true_pose.yaw, p.depth_max)
            if n:
                unoccluded[label_id] = n
        return self._finish(depth, label, objects, unoccluded, reported_pose, stamp)

    def _finish(self, depth: np.ndarray, label: np.ndarray, objects: list, unoccluded: dict[int, int],
                reported_pose: Pose2D, stamp: float) -> RGBDFrame:
        """Range limits, noise, instance and colour images, and the frame record."""
        p = self.params
        beyond = ~(depth <= p.depth_max)  # includes inf (nothing hit)
        label[beyond] = _NONE
        rgb = _shade(label, depth, objects)
        depth[beyond | (depth < p.depth_min)] = np.nan
        if p.depth_noise > 0.0:
            depth += _depth_noise(depth.shape, self.seed, stamp) * (np.float32(p.depth_noise) * depth * depth)
        instances = np.maximum(label, 0).astype(np.int32, copy=False)
        categories = {i + 1: str(o.category) for i, o in enumerate(objects)}
        return RGBDFrame(
            stamp=float(stamp), rgb=rgb, depth=depth, K=self._K.copy(),
            T_map_base=reported_pose.to_matrix(), T_base_camera=self._T_base_camera.copy(),
            depth_range=(p.depth_min, p.depth_max), instances=instances,
            instance_categories=categories, instance_unoccluded=unoccluded,
        )

    def _wall_field(self, walls: np.ndarray, grid: OccupancyGrid) -> _WallField:
        """The distance field of ``walls``, rebuilt only when the walls change.

        The cache is keyed on the array's identity, with an equality check as fallback so
        callers that rebuild an identical mask every frame still hit the cache. Changing
        walls means passing a new array: an in-place edit of the cached one is not seen.
        """
        same = self._walls_key is not None and (
            walls is self._walls_key
            or (walls.shape == self._walls_key.shape and np.array_equal(walls, self._walls_key)))
        if not same or self._walls_field is None or not self._walls_field.matches(grid):
            self._walls_field = _WallField(np.asarray(walls, dtype=bool), grid.resolution, grid.origin)
            self._walls_key = walls
        return self._walls_field


# -- calibration ---------------------------------------------------------------------------
def _intrinsics(p: CameraParams) -> np.ndarray:
    w, h = p.image_size
    fx = (w / 2.0) / math.tan(math.radians(p.hfov_deg) / 2.0)
    return np.array([[fx, 0.0, (w - 1) / 2.0], [0.0, fx, (h - 1) / 2.0], [0.0, 0.0, 1.0]])


def _base_camera(p: CameraParams) -> np.ndarray:
    rotation = rotation_y(math.radians(p.tilt_deg)) @ _R_BASE_OPTICAL
    return se3(rotation, np.array([p.mount_x, 0.0, p.mount_height]))


def _depth_noise(shape: tuple[int, int], seed: int, stamp: float) -> np.ndarray:
    """Unit Gaussian noise correlated over 2 x 2 pixel blocks.

    Structured-light and stereo depth noise is spatially correlated over a few pixels, and
    drawing a quarter of the samples halves the render time at full resolution.
    """
    h, w = shape
    rng = np.random.default_rng([seed, _stamp_key(stamp)])
    coarse = rng.standard_normal(((h + 1) // 2, (w + 1) // 2), dtype=np.float32)
    return cv2.resize(coarse, ((w + 1) // 2 * 2, (h + 1) // 2 * 2), interpolation=cv2.INTER_NEAREST)[:h, :w]


def _stamp_key(stamp: float) -> int:
    """A non-negative integer per millisecond of stamp, for per-frame seeding."""
    return int(round(float(stamp) * 1000.0)) % (2**63)


class _RayTable:
    """Per-pixel ray quantities that do not depend on the robot pose (see module doc).

    A ray is ``origin + t * d`` with ``d`` the pixel's direction scaled to unit optical z,
    so ``t`` is the optical depth directly.
    """

    def __init__(self, K: np.ndarray, T_base_camera: np.ndarray, p: CameraParams):
        w, h = p.image_size
        self.K = K
        u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
        d_cam = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)
        d_base = d_cam @ T_base_camera[:3, :3].T
        self.bx = np.ascontiguousarray(d_base[..., 0], dtype=np.float32)
        self.by = np.ascontiguousarray(d_base[..., 1], dtype=np.float32)
        self.bz = np.ascontiguousarray(d_base[..., 2], dtype=np.float32)
        hnorm = np.hypot(d_base[..., 0], d_base[..., 1])
        self.hnorm = np.maximum(hnorm, 1e-9).astype(np.float32)
        with np.errstate(divide="ignore"):
            self.inv_bz = (1.0 / d_base[..., 2]).astype(np.float32)
            floor = np.where(d_base[..., 2] < 0.0, -p.mount_height / d_base[..., 2], np.inf)
        self.t_floor = floor.astype(np.float32)
        azimuth = np.arctan2(d_base[..., 1], d_base[..., 0])
        # Bins no coarser than a pixel's angle (and 0.25 deg), so wall edges stay sharp.
        step = min(math.radians(p.hfov_deg) / w, math.radians(0.25))
        lo, hi = float(azimuth.min()), float(azimuth.max())
        n = int(math.ceil((hi - lo) / step)) + 1
        self.bin_azimuths = lo + step * np.arange(n)
        self.bin_index = np.clip(np.rint((azimuth - lo) / step), 0, n - 1).astype(np.intp)
        self._max_hnorm = float(hnorm.max())
        self.shape = (h, w)

    def max_horizontal(self, depth_max: float) -> float:
        """Horizontal reach of the longest ray within ``depth_max`` optical depth."""
        return depth_max * self._max_hnorm

    def walls_and_floor(self, dist: np.ndarray, camera_z: float, wall_height: float):
        """Depth and label images of the empty building: floor, walls, or nothing."""
        t_wall = np.take(dist.astype(np.float32), self.bin_index) / self.hnorm
        with np.errstate(invalid="ignore", over="ignore"):
            z_wall = np.float32(camera_z) + t_wall * self.bz
            below = z_wall < 0.0  # the ray meets the floor before the wall (inf, -inf too)
            on_wall = (z_wall >= 0.0) & (z_wall <= wall_height)
        depth = np.where(below, self.t_floor, np.where(on_wall, t_wall, np.float32(np.inf)))
        label = np.where(below, _FLOOR, np.where(on_wall, _WALL, _NONE)).astype(np.int32)
        label[~np.isfinite(depth)] = _NONE
        return depth.astype(np.float32, copy=False), label


class _WallField:
    """Sphere tracing of planar rays against a walls mask (outside the grid is wall)."""

    _MIN_STEP = 0.35  # cells: fine steps near walls (thin diagonal walls are not tunnelled)
    _SAFETY = 1.42  # cells: a cell-centre distance overestimates free space by up to sqrt(2)

    def __init__(self, walls: np.ndarray, resolution: float, origin: tuple[float, float]):
        padded = np.pad(walls, 1, constant_values=True)
        self.solid = padded
        free = (~padded).astype(np.uint8)
        self.dt = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE).astype(np.float32)
        self.resolution = float(resolution)
        self.origin = (float(origin[0]), float(origin[1]))
        self.shape = walls.shape

    def matches(self, grid: OccupancyGrid) -> bool:
        return (grid.data.shape == self.shape and float(grid.resolution) == self.resolution
                and (float(grid.origin[0]), float(grid.origin[1])) == self.origin)

    def cast(self, xy: np.ndarray, azimuths: np.ndarray, max_range: float) -> np.ndarray:
        """Horizontal distance (m) from ``xy`` to the first wall per azimuth (inf beyond range)."""
        res = self.resolution
        start = np.array([(xy[0] - self.origin[0]) / res + 1.0, (xy[1] - self.origin[1]) / res + 1.0])
        dirs = np.stack([np.cos(azimuths), np.sin(azimuths)], axis=1)
        limit = max_range / res
        travelled = np.zeros(len(azimuths))
        out = np.full(len(azimuths), np.inf)
        active = np.arange(len(azimuths))
        h, w = self.solid.shape
        while active.size:
            pos = start + dirs[active] * travelled[active, None]
            col = np.clip(pos[:, 0].astype(np.intp), 0, w - 1)
            row = np.clip(pos[:, 1].astype(np.intp), 0, h - 1)
            outside = (pos[:, 0] < 0) | (pos[:, 1] < 0)
            hit = self.solid[row, col] | outside
            if hit.any():
                idx = active[hit]
                out[idx] = self._refine(start, dirs[idx], travelled[idx]) * res
            keep = ~hit
            active, row, col = active[keep], row[keep], col[keep]
            step = np.maximum(self.dt[row, col] - self._SAFETY, self._MIN_STEP)
            travelled[active] += step
            far = travelled[active] > limit
            active = active[~far]
        return out

    def _refine(self, start: np.ndarray, dirs: np.ndarray, hit_at: np.ndarray) -> np.ndarray:
        """Bisect between the last free sample and the wall sample (to ~1/50 cell)."""
        lo = np.maximum(hit_at - self._MIN_STEP, 0.0)
        hi = hit_at.copy()
        h, w = self.solid.shape
        for _ in range(5):
            mid = 0.5 * (lo + hi)
            pos = start + dirs * mid[:, None]
            col = np.clip(pos[:, 0].astype(np.intp), 0, w - 1)
            row = np.clip(pos[:, 1].astype(np.intp), 0, h - 1)
            solid = self.solid[row, col] | (pos[:, 0] < 0) | (pos[:, 1] < 0)
            hi = np.where(solid, mid, hi)
            lo = np.where(solid, lo, mid)
        return hi


# -- boxes and cylinders ---------------------------------------------------------------------
def _scene(objects: list, obstacles: list, people: list) -> tuple[list[_Box], list[tuple[np.ndarray, int]]]:
    """Boxes with their labels (objects 1..N, then obstacles) and people cylinders."""
    boxes = []
    for i, o in enumerate(objects):
        boxes.append(_Box(np.asarray(o.position, dtype=float), np.asarray(o.size, dtype=float) / 2.0,
                          float(getattr(o, "yaw", 0.0)), i + 1))
    base = len(objects)
    for j, ob in enumerate(obstacles):
        height = float(ob.height)
        centre = np.array([float(ob.position[0]), float(ob.position[1]), height / 2.0])
        half = np.array([float(ob.size[0]) / 2.0, float(ob.size[1]) / 2.0, height / 2.0])
        boxes.append(_Box(centre, half, float(getattr(ob, "yaw", 0.0)), base + j + 1))
    base += len(obstacles)
    cylinders = [(np.array([float(x), float(y)]), base + k + 1) for k, (x, y) in enumerate(people)]
    return boxes, cylinders


def _screen_rect(corners: np.ndarray, T_map_camera: np.ndarray, shape: tuple[int, int], K: np.ndarray,
                 depth_max: float) -> tuple[int, int, int, int] | None:
    """Image rectangle (r0, r1, c0, c1) covering a convex solid's corners; None if unseen."""
    R, t = T_map_camera[:3, :3], T_map_camera[:3, 3]
    cam = (corners - t) @ R
    z = cam[:, 2]
    h, w = shape
    if z.max() <= _NEAR or z.min() > depth_max:
        return None
    if z.min() <= _NEAR:  # straddles the image plane: its projection is unbounded
        return 0, h, 0, w
    u = K[0, 0] * cam[:, 0] / z + K[0, 2]
    v = K[1, 1] * cam[:, 1] / z + K[1, 2]
    c0, c1 = max(int(math.floor(u.min())) - 1, 0), min(int(math.ceil(u.max())) + 2, w)
    r0, r1 = max(int(math.floor(v.min())) - 1, 0), min(int(math.ceil(v.max())) + 2, h)
    if c0 >= c1 or r0 >= r1:
        return None
    return r0, r1, c0, c1


def _draw_box(box: _Box, depth: np.ndarray, label: np.ndarray, T_map_camera: np.ndarray, rays: _RayTable,
              yaw: float, depth_max: float) -> int:
    """Slab-test the box in its screen rectangle; z-buffer it in. Returns its unoccluded pixels."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    local = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * box.half
    corners = local @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T + box.centre
    rect = _screen_rect(corners, T_map_camera, rays.shape, rays.K, depth_max)
    if rect is None:
        return 0
    r0, r1, c0, c1 = rect
    # Ray origin and directions in the box frame: directions rotate by (robot yaw - box yaw).
    rel = T_map_camera[:3, 3] - box.centre
    o = np.array([c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1], rel[2]])
    a = yaw - box.yaw
    ca, sa = np.float32(math.cos(a)), np.float32(math.sin(a))
    bx, by = rays.bx[r0:r1, c0:c1], rays.by[r0:r1, c0:c1]
    dirs = (ca * bx - sa * by, sa * bx + ca * by, rays.bz[r0:r1, c0:c1])
    t_near = np.full(bx.shape, -np.inf, dtype=np.float32)
    t_far = np.full(bx.shape, np.inf, dtype=np.float32)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for axis in range(3):
            inv = (rays.inv_bz[r0:r1, c0:c1] if axis == 2 else np.float32(1.0) / dirs[axis])
            t1 = (np.float32(-box.half[axis] - o[axis])) * inv
            t2 = (np.float32(box.half[axis] - o[axis])) * inv
            np.maximum(t_near, np.minimum(t1, t2), out=t_near)
            np.minimum(t_far, np.maximum(t1, t2), out=t_far)
        hit = (t_near <= t_far) & (t_near > _NEAR)
    return _composite(hit, t_near, depth[r0:r1, c0:c1], label[r0:r1, c0:c1], box.label)


def _draw_cylinder(centre: np.ndarray, label_id: int, depth: np.ndarray, label: np.ndarray,
                   T_map_camera: np.ndarray, rays: _RayTable, yaw: float, depth_max: float) -> int:
    """A vertical person cylinder (side and top cap). Returns its unoccluded pixels."""
    r = PERSON_RADIUS
    corners = np.array([[centre[0] + dx, centre[1] + dy, z] for dx in (-r, r) for dy in (-r, r)
                        for z in (0.0, PERSON_HEIGHT)])
    rect = _screen_rect(corners, T_map_camera, rays.shape, rays.K, depth_max)
    origin = T_map_camera[:3, 3]
    rel = origin[:2] - centre
    if rect is None or float(rel @ rel) <= r * r:
        return 0
    r0, r1, c0, c1 = rect
    cy_, sy_ = np.float32(math.cos(yaw)), np.float32(math.sin(yaw))
    bx, by, bz = rays.bx[r0:r1, c0:c1], rays.by[r0:r1, c0:c1], rays.bz[r0:r1, c0:c1]
    dx, dy = cy_ * bx - sy_ * by, sy_ * bx + cy_ * by
    a = rays.hnorm[r0:r1, c0:c1] ** 2
    b = 2.0 * (np.float32(rel[0]) * dx + np.float32(rel[1]) * dy)
    cc = np.float32(rel @ rel - r * r)
    disc = b * b - 4.0 * a * cc
    with np.errstate(invalid="ignore", divide="ignore"):
        t_side = (-b - np.sqrt(disc)) / (2.0 * a)
        z_side = np.float32(origin[2]) + t_side * bz
        side = (disc >= 0) & (t_side > _NEAR) & (z_side >= 0.0) & (z_side <= PERSON_HEIGHT)
        t_cap = (np.float32(PERSON_HEIGHT - origin[2])) * rays.inv_bz[r0:r1, c0:c1]
        px, py = rel[0] + t_cap * dx, rel[1] + t_cap * dy
        cap = (t_cap > _NEAR) & (px * px + py * py <= r * r) & (origin[2] > PERSON_HEIGHT)
    t = np.where(side, t_side, np.where(cap, t_cap, np.inf)).astype(np.float32)
    return _composite(side | cap, t, depth[r0:r1, c0:c1], label[r0:r1, c0:c1], label_id)


def _composite(hit: np.ndarray, t: np.ndarray, depth_view: np.ndarray, label_view: np.ndarray,
               label_id: int) -> int:
    """Nearest hit wins; returns how many pixels the solid covers ignoring occlusion."""
    n = int(np.count_nonzero(hit))
    if n:
        closer = hit & (t < depth_view)
        depth_view[closer] = t[closer]
        label_view[closer] = label_id
    return n


# -- colour --------------------------------------------------------------------------------
def category_colour(category: str) -> tuple[int, int, int]:
    """A stable, saturated RGB colour per category name (crc32 hue)."""
    hue = zlib.crc32(category.encode("utf-8")) % 180
    hsv = np.array([[[hue, 200, 230]]], dtype=np.uint8)
    r, g, b = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0, 0]
    return int(r), int(g), int(b)


_WALL_RGB = (200, 200, 195)
_FLOOR_RGB = (125, 115, 100)
_NONE_RGB = (235, 235, 245)
_OTHER_RGB = (110, 95, 80)  # obstacles and people: unlabelled


def _shade(label: np.ndarray, depth: np.ndarray, objects: list) -> np.ndarray:
    """Flat colour per surface (category colour for objects), darkened with distance."""
    n_labels = max(int(label.max(initial=0)), len(objects))
    palette = np.empty((n_labels + 3, 3), dtype=np.uint8)
    palette[0], palette[1], palette[2] = _WALL_RGB, _FLOOR_RGB, _NONE_RGB
    palette[3:] = _OTHER_RGB
    for i, o in enumerate(objects):
        palette[i + 3] = category_colour(str(o.category))
    rgb = np.take(palette, label + 2, axis=0)
    with np.errstate(invalid="ignore"):  # depth is inf (not NaN) where nothing was hit
        shade = (np.clip(np.float32(1.1) - np.float32(0.06) * depth, 0.5, 1.0) * 255.0).astype(np.uint8)
    return cv2.multiply(rgb, cv2.merge([shade, shade, shade]), scale=1.0 / 255.0)
