"""Ray casting for the simulated camera: per-pixel rays, walls, boxes and people.

:class:`RayTable` holds the per-pixel ray quantities that do not depend on the robot's
pose (the camera only pitches, the robot only yaws); :class:`WallField` sphere-traces
planar rays against the 2.5D walls; :func:`draw_box` and :func:`draw_cylinder` z-buffer
objects, obstacles and people into the depth and label images, each only inside the
image rectangle its corners project to. See :mod:`bomc_bt.sim.camera` for why this is
fast enough to run at the camera rate inside tick simulations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.grid import OccupancyGrid

PERSON_RADIUS = 0.25  # m
PERSON_HEIGHT = 1.7  # m
NEAR = 1e-3  # m: hits closer than this along the ray are ignored (camera inside a box)
_CLIP = 0.5 * NEAR  # m: the plane a solid straddling the camera is clipped at for its screen rectangle
_UNIT_CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
# Every pair of a solid's 8 corners: its edges are among them, whatever the corner order.
_CORNER_PAIRS = np.triu_indices(8, k=1)

# Label codes of the render buffer besides instance ids (> 0).
WALL = -2
FLOOR = -1
NONE = 0


@dataclass
class Box:
    """A renderable oriented box: centre (map), half extents, yaw, and its label."""

    centre: np.ndarray  # (3,)
    half: np.ndarray  # (3,)
    yaw: float
    label: int


class RayTable:
    """Per-pixel ray quantities that do not depend on the robot pose (see module doc).

    A ray is ``origin + t * d`` with ``d`` the pixel's direction scaled to unit optical z,
    so ``t`` is the optical depth directly.
    """

    def __init__(self, K: np.ndarray, T_base_camera: np.ndarray, image_size: tuple[int, int], hfov_deg: float,
                 mount_height: float):
        w, h = image_size
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
            floor = np.where(d_base[..., 2] < 0.0, -mount_height / d_base[..., 2], np.inf)
        self.t_floor = floor.astype(np.float32)
        azimuth = np.arctan2(d_base[..., 1], d_base[..., 0])
        # Bins no coarser than a pixel's angle (and 0.25 deg), so wall edges stay sharp.
        step = min(math.radians(hfov_deg) / w, math.radians(0.25))
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
        depth = np.full(self.shape, np.inf, dtype=np.float32)
        np.copyto(depth, t_wall, where=on_wall)
        np.copyto(depth, self.t_floor, where=below)  # below and on_wall never meet
        label = np.zeros(self.shape, dtype=np.int32)  # NONE
        np.copyto(label, WALL, where=on_wall)
        np.copyto(label, FLOOR, where=below)
        np.copyto(label, NONE, where=~np.isfinite(depth))
        return depth, label


class WallField:
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
        out = np.full(len(azimuths), np.inf)
        # The beams still flying, compacted as they stop: index, direction, distance travelled.
        active = np.arange(len(azimuths))
        du, dv = dirs[:, 0].copy(), dirs[:, 1].copy()
        travelled = np.zeros(len(azimuths))
        h, w = self.solid.shape
        solid, dt = self.solid.ravel(), self.dt.ravel()
        hits: list[tuple[np.ndarray, np.ndarray]] = []  # (azimuth, travelled at hit), refined together
        while active.size:
            pu, pv = start[0] + du * travelled, start[1] + dv * travelled
            cell = (np.minimum(np.maximum(pv.astype(np.intp), 0), h - 1) * w
                    + np.minimum(np.maximum(pu.astype(np.intp), 0), w - 1))
            hit = solid[cell] | (pu < 0) | (pv < 0)
            if hit.any():
                hits.append((active[hit], travelled[hit]))
                keep = ~hit
                active, du, dv, travelled, cell = active[keep], du[keep], dv[keep], travelled[keep], cell[keep]
            travelled = travelled + np.maximum(dt[cell] - self._SAFETY, self._MIN_STEP)
            flying = travelled <= limit
            if not flying.all():
                active, du, dv, travelled = active[flying], du[flying], dv[flying], travelled[flying]
        if hits:
            idx, hit_at = (np.concatenate(parts) for parts in zip(*hits, strict=True))
            out[idx] = self._refine(start, dirs[idx], hit_at) * res
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
def scene_solids(objects: list, obstacles: list, people: list) -> tuple[list[Box], list[tuple[np.ndarray, int]]]:
    """Boxes with their labels (objects 1..N, then obstacles) and people cylinders."""
    boxes = []
    for i, o in enumerate(objects):
        boxes.append(Box(np.asarray(o.position, dtype=float), np.asarray(o.size, dtype=float) / 2.0,
                          float(getattr(o, "yaw", 0.0)), i + 1))
    base = len(objects)
    for j, ob in enumerate(obstacles):
        height = float(ob.height)
        centre = np.array([float(ob.position[0]), float(ob.position[1]), height / 2.0])
        half = np.array([float(ob.size[0]) / 2.0, float(ob.size[1]) / 2.0, height / 2.0])
        boxes.append(Box(centre, half, float(getattr(ob, "yaw", 0.0)), base + j + 1))
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
    if z.max() <= NEAR or z.min() > depth_max:
        return None
    if z.min() <= NEAR:  # straddles the near plane: only its part in front can be hit
        cam = _in_front(cam)
        z = cam[:, 2]
    u = K[0, 0] * cam[:, 0] / z + K[0, 2]
    v = K[1, 1] * cam[:, 1] / z + K[1, 2]
    c0, c1 = max(int(math.floor(u.min())) - 1, 0), min(int(math.ceil(u.max())) + 2, w)
    r0, r1 = max(int(math.floor(v.min())) - 1, 0), min(int(math.ceil(v.max())) + 2, h)
    if c0 >= c1 or r0 >= r1:
        return None
    return r0, r1, c0, c1


def _in_front(cam: np.ndarray) -> np.ndarray:
    """Vertices of a box's part in front of the plane z = ``_CLIP`` (camera frame, (8, 3) in).

    A pixel only takes a hit farther than ``NEAR`` along its ray, so the hit lies in this
    part and its pixel inside the part's projection. Clipping at half of ``NEAR`` keeps the
    rectangle a superset of those pixels with room for rounding; a box beside the camera
    then covers the strip of the image it can reach instead of the whole image.
    """
    z = cam[:, 2] - _CLIP
    a, b = _CORNER_PAIRS
    cross = z[a] * z[b] < 0.0
    a, b = a[cross], b[cross]
    crossing = cam[a] + (z[a] / (z[a] - z[b]))[:, None] * (cam[b] - cam[a])
    return np.concatenate([cam[z >= 0.0], crossing])


def solid_corners(box: Box) -> np.ndarray:
    """The box's 8 map-frame corners, corner i at (bit 2, bit 1, bit 0) of i along (x, y, z)."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    local = _UNIT_CORNERS * box.half
    return local @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T + box.centre


def draw_box(box: Box, depth: np.ndarray, label: np.ndarray, T_map_camera: np.ndarray, rays: RayTable,
              yaw: float, depth_max: float, corners: np.ndarray | None = None) -> int:
    """Slab-test the box in its screen rectangle; z-buffer it in. Returns its unoccluded pixels.

    ``corners``: :func:`solid_corners` of the box, when the caller keeps them.
    """
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    if corners is None:
        corners = solid_corners(box)
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
        hit = (t_near <= t_far) & (t_near > NEAR)
    return _composite(hit, t_near, depth[r0:r1, c0:c1], label[r0:r1, c0:c1], box.label)


def draw_cylinder(centre: np.ndarray, label_id: int, depth: np.ndarray, label: np.ndarray,
                   T_map_camera: np.ndarray, rays: RayTable, yaw: float, depth_max: float) -> int:
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
        side = (disc >= 0) & (t_side > NEAR) & (z_side >= 0.0) & (z_side <= PERSON_HEIGHT)
        t_cap = (np.float32(PERSON_HEIGHT - origin[2])) * rays.inv_bz[r0:r1, c0:c1]
        px, py = rel[0] + t_cap * dx, rel[1] + t_cap * dy
        cap = (t_cap > NEAR) & (px * px + py * py <= r * r) & (origin[2] > PERSON_HEIGHT)
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
