"""The ``hard`` preset's failure modes: errors tied to places and views, not to frames.

The ``realistic`` preset draws its misses and false positives independently per frame, and
an object seen in many frames of a pass survives them. The failures the paper reports are
not like that: they come back whenever the robot looks from the same place. This module
models four of them on top of ``realistic``:

* **Look-alikes** (a shadow taken for a door or a table, a box for a trash bin). The floor
  is cut into ``lookalike_cell`` squares; a hash of (world, square) decides whether the
  square holds a look-alike, where, and what it is mistaken for, and a hash of (world,
  square, viewing sector) whether it is mistaken from that side. Seen from one of its
  sectors within ``lookalike_range``, on visible floor, it is reported with
  ``lookalike_rate`` per frame: the same false object from similar poses, pass after pass.
* **Grazing-angle misses** for thin, flat objects (doors): the normal of the object's
  visible surface is fitted to its depth points; the miss probability rises with the angle
  between the view ray and that normal, and with how close the camera is to the object's
  plane (a narrow corridor, where a door on the side wall is only ever seen edge-on).
* **Dark zones**: a hash of (world, ``dark_cell`` square) places at most one dark disc per
  square; an object whose depth points lie inside one is missed more and scores lower.
* **People** are rendered by the camera as opaque cylinders with no category: an object
  behind a person loses those pixels (its box and mask cover only what is visible, and its
  occluded fraction raises the ``realistic`` miss rate); one hidden entirely is not a
  candidate at all. Nothing here adds to that.

The world is identified by :attr:`SimFrame.world_key`, not by the pass's seed, so the
look-alikes and dark zones stay where they are across passes run with different seeds;
frames without a key (0) share one layout. Geometry uses the frame's reported pose, as the
pipeline does.
"""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.sim.frame import SimFrame
from bomc_bt.sim.params import HardDetectorParams

_LOOKALIKE, _SECTOR, _DARK = 1, 2, 3  # hash salts: one stream per kind of place
_MAX_POINTS = 400  # depth points per candidate used for its position and surface normal
_MIN_RANGE = 0.5  # [m] a look-alike nearer than this is under the camera, not in the image


def unit_hash(*keys) -> np.ndarray:
    """Uniform numbers in [0, 1) from integer keys (arrays broadcast): splitmix64, vectorised.

    Same keys, same number, on every machine: what fixes look-alikes and dark zones to places.
    """
    arrays = np.broadcast_arrays(*(np.atleast_1d(np.asarray(k, dtype=np.int64)) for k in keys))
    h = np.zeros(arrays[0].shape, dtype=np.uint64)
    with np.errstate(over="ignore"):
        for k in arrays:
            h = h ^ k.astype(np.uint64)
            h = h + np.uint64(0x9E3779B97F4A7C15)
            h = (h ^ (h >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
            h = (h ^ (h >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
            h = h ^ (h >> np.uint64(31))
    return (h >> np.uint64(11)).astype(np.float64) / float(2**53)


def camera_pose(frame: SimFrame) -> np.ndarray:
    """map -> optical frame of the camera, from the frame's reported pose."""
    return np.asarray(frame.T_map_base, dtype=float) @ np.asarray(frame.T_base_camera, dtype=float)


# -- dark zones ------------------------------------------------------------------------------
def in_dark_zone(world_key: int, xy: np.ndarray, p: HardDetectorParams) -> np.ndarray:
    """Which map points (N x 2) lie inside one of the world's dark zones."""
    xy = np.atleast_2d(np.asarray(xy, dtype=float))
    inside = np.zeros(len(xy), dtype=bool)
    if p.dark_share <= 0.0 or p.dark_radius <= 0.0:
        return inside
    home = np.floor(xy / p.dark_cell).astype(np.int64)
    for dx in (-1, 0, 1):  # dark_radius <= dark_cell: a disc reaches one square around its own
        for dy in (-1, 0, 1):
            cx, cy = home[:, 0] + dx, home[:, 1] + dy
            exists = unit_hash(world_key, _DARK, cx, cy, 0) < p.dark_share
            centre = np.stack([cx + unit_hash(world_key, _DARK, cx, cy, 1),
                               cy + unit_hash(world_key, _DARK, cx, cy, 2)], axis=1) * p.dark_cell
            inside |= exists & (np.hypot(*(xy - centre).T) < p.dark_radius)
    return inside


# -- per-candidate penalties -----------------------------------------------------------------
def candidate_points(frame: SimFrame, instance: int) -> np.ndarray:
    """Map-frame points (N x 3) of an instance's valid depth pixels, at most ``_MAX_POINTS``."""
    rows, cols = np.nonzero((frame.instances == instance) & np.isfinite(frame.depth))
    if rows.size > _MAX_POINTS:
        pick = np.linspace(0, rows.size - 1, _MAX_POINTS).astype(int)
        rows, cols = rows[pick], cols[pick]
    z = frame.depth[rows, cols].astype(float)
    K = frame.K
    optical = np.stack([(cols - K[0, 2]) * z / K[0, 0], (rows - K[1, 2]) * z / K[1, 1], z, np.ones_like(z)])
    return (camera_pose(frame) @ optical)[:3].T


def grazing_angle(points_xy: np.ndarray, camera_xy: np.ndarray) -> tuple[float, float] | None:
    """(angle between the view ray and the surface normal in deg, camera's distance to the
    surface's plane in m) for a flat object's points, or None when they show no clear plane."""
    if len(points_xy) < 10:
        return None
    centre = points_xy.mean(axis=0)
    values, vectors = np.linalg.eigh(np.cov((points_xy - centre).T))
    if values[1] < 0.05**2 or values[1] < 9.0 * values[0]:  # too small, or no long axis: no plane to graze
        return None
    normal = vectors[:, 0]
    ray = centre - camera_xy
    distance = float(np.hypot(*ray))
    if distance < 1e-6:
        return None
    lateral = abs(float(ray @ normal))
    return math.degrees(math.acos(min(1.0, lateral / distance))), lateral


def grazing_miss(angle_deg: float, lateral: float, p: HardDetectorParams) -> float:
    """Added miss probability: rises past ``grazing_start_deg``, full when the camera is
    within ``grazing_lateral`` of the plane, none at twice that."""
    graze = min(max((angle_deg - p.grazing_start_deg) / (90.0 - p.grazing_start_deg), 0.0), 1.0)
    narrow = min(max(2.0 - lateral / p.grazing_lateral, 0.0), 1.0)
    return p.grazing_miss * graze * narrow


def penalties(frame: SimFrame, candidates: list, p: HardDetectorParams) -> dict[int, tuple[float, float]]:
    """Per candidate instance: (added miss probability, score lost) from grazing and darkness."""
    camera_xy = camera_pose(frame)[:2, 3]
    out = {}
    for c in candidates:
        points = candidate_points(frame, c.instance)
        if len(points) == 0:
            continue
        miss, loss = 0.0, 0.0
        if c.category in p.grazing_categories:
            view = grazing_angle(points[:, :2], camera_xy)
            if view is not None:
                miss += grazing_miss(*view, p)
        if in_dark_zone(frame.world_key, np.median(points[:, :2], axis=0), p)[0]:
            miss += p.dark_miss
            loss += p.dark_score_drop
        out[c.instance] = (miss, loss)
    return out


# -- look-alikes -----------------------------------------------------------------------------
def lookalike_sites(world_key: int, camera_xy: np.ndarray, p: HardDetectorParams,
                    prompts: list[str]) -> list[tuple[np.ndarray, str]]:
    """Look-alikes mistaken from where the camera stands: (floor point, category) each."""
    if p.lookalike_density <= 0.0 or not prompts:
        return []
    lo = np.floor((camera_xy - p.lookalike_range) / p.lookalike_cell).astype(np.int64)
    hi = np.floor((camera_xy + p.lookalike_range) / p.lookalike_cell).astype(np.int64)
    cx, cy = (a.ravel() for a in np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1)))
    exists = unit_hash(world_key, _LOOKALIKE, cx, cy, 0) < p.lookalike_density
    cx, cy = cx[exists], cy[exists]
    sites = np.stack([cx + unit_hash(world_key, _LOOKALIKE, cx, cy, 1),
                      cy + unit_hash(world_key, _LOOKALIKE, cx, cy, 2)], axis=1) * p.lookalike_cell
    away = camera_xy - sites
    distance = np.hypot(away[:, 0], away[:, 1])
    bearing = np.arctan2(away[:, 1], away[:, 0])
    sector = np.floor((bearing + math.pi) / (2.0 * math.pi) * p.lookalike_sectors).astype(np.int64)
    sector %= p.lookalike_sectors
    seen = unit_hash(world_key, _SECTOR, cx, cy, sector) < p.lookalike_sector_share
    keep = seen & (distance <= p.lookalike_range) & (distance >= _MIN_RANGE)
    ordered = sorted(prompts)
    picks = unit_hash(world_key, _LOOKALIKE, cx, cy, 3)
    return [(sites[i], ordered[int(picks[i] * len(ordered)) % len(ordered)]) for i in np.flatnonzero(keep)]


def lookalike_box(frame: SimFrame, site: np.ndarray, p: HardDetectorParams,
                  min_pixels: int) -> tuple[float, float, float, float] | None:
    """The image box of a look-alike at floor point ``site``, or None when its spot on the
    floor is not what the camera sees there (behind a wall or an object, out of view)."""
    T_camera_map = np.linalg.inv(camera_pose(frame))
    h, w = frame.instances.shape
    centre = _project(frame.K, T_camera_map, np.array([[site[0], site[1], 0.0]]))
    if centre is None:
        return None
    (u, v), z = centre[0][0], centre[1][0]
    col, row = int(round(u)), int(round(v))
    if not (0 <= col < w and 0 <= row < h) or frame.instances[row, col] != 0:
        return None
    seen = float(frame.depth[row, col])
    if not math.isfinite(seen) or abs(seen - z) > max(0.15, 0.05 * z):  # the floor there is not what shows
        return None
    s, t = p.lookalike_size / 2.0, p.lookalike_height
    corners = np.array([[site[0] + dx, site[1] + dy, dz] for dx in (-s, s) for dy in (-s, s) for dz in (0.0, t)])
    projected = _project(frame.K, T_camera_map, corners)
    if projected is None:
        return None
    uv = projected[0]
    x0, y0 = max(float(uv[:, 0].min()), 0.0), max(float(uv[:, 1].min()), 0.0)
    x1, y1 = min(float(uv[:, 0].max()) + 1.0, float(w)), min(float(uv[:, 1].max()) + 1.0, float(h))
    if (x1 - x0) * (y1 - y0) < min_pixels:
        return None
    return x0, y0, x1, y1


def _project(K: np.ndarray, T_camera_map: np.ndarray, points: np.ndarray):
    """Pixels (N x 2) and depths (N) of map points, or None if any is behind the camera."""
    cam = (T_camera_map @ np.c_[points, np.ones(len(points))].T)[:3]
    if (cam[2] <= 0.05).any():
        return None
    uv = np.stack([K[0, 0] * cam[0] / cam[2] + K[0, 2], K[1, 1] * cam[1] / cam[2] + K[1, 2]], axis=1)
    return uv, cam[2]
