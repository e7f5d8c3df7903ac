"""How well a laser scan fits a saved map at a pose: the likelihood field of scan matching.

The scoring half of :mod:`bomc_bt.localization` (which searches poses with it). Every
beam endpoint scores ``exp(-d^2 / 2 sigma^2)`` where ``d`` is its distance to the nearest
obstacle *surface* (Olson 2009); a pose scores the mean over its beams. Unknown cells
are not obstacles: a saved map has unknown space beyond its walls, and a beam never ends
there in a correct pose. Fields are precomputed once per map and sigma, so scoring a
grid of thousands of poses is a few numpy gathers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import LaserScan


@dataclass
class Beams:
    """Endpoints of the beams that returned, in the robot frame."""

    xy: np.ndarray  # (B, 2)

    @property
    def count(self) -> int:
        return int(self.xy.shape[0])

    def subsample(self, n: int) -> Beams:
        """Evenly keep ``n`` beams (all of them when there are fewer)."""
        if self.count <= n:
            return self
        return Beams(self.xy[np.unique(np.round(np.linspace(0, self.count - 1, n)).astype(np.int64))])

    @property
    def reach(self) -> float:
        return float(np.hypot(self.xy[:, 0], self.xy[:, 1]).max(initial=0.0))

    def for_grid(self, sigma: float, angular_step: float, min_count: int) -> Beams:
        """The beams a grid with this yaw step can score fairly.

        A yaw off by half a step moves an endpoint at range r by r * step / 2; past the
        range where that exceeds ``sigma`` a beam's likelihood says more about the grid's
        quantisation than about the pose, so a coarse grid ignores those beams (keeping
        at least the ``min_count`` nearest, for large halls).
        """
        r = np.hypot(self.xy[:, 0], self.xy[:, 1])
        keep = r <= sigma / (0.5 * angular_step)
        if np.count_nonzero(keep) < min(min_count, self.count):
            keep = np.zeros(self.count, dtype=bool)
            keep[np.argsort(r, kind="stable")[:min_count]] = True
        return self if keep.all() else Beams(self.xy[keep])


def surface_distance(grid: OccupancyGrid) -> np.ndarray:
    """Distance (m) from each cell centre to the nearest obstacle *surface* a beam can hit.

    Outside obstacles that is the distance to the nearest occupied cell; inside, the
    distance to the nearest free cell, so the field peaks on a wall's face and not all
    through a thick wall (a robot seeing one side of a 20 cm wall must not be free to
    slide 20 cm into it). Both are measured to the cell edge, half a cell nearer than
    the centre, because a beam ends where the wall begins.
    """
    occupied = grid.occupied_mask()
    free = grid.free_mask()
    big = np.float32(1e6)
    d_out = cv2.distanceTransform((~occupied).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    if not occupied.any():
        d_out[:] = big
    d_in = cv2.distanceTransform((~free).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    if not free.any():
        d_in[:] = big
    dist = np.where(occupied, d_in, d_out).astype(np.float64) * grid.resolution
    return np.maximum(dist - 0.5 * grid.resolution, 0.0)


def valid_beams(scan: LaserScan) -> Beams:
    """Endpoints of beams that hit something (finite, positive, below range_max)."""
    r = np.asarray(scan.ranges, dtype=np.float64)
    a = scan.angles
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(r) & (r > 0.0) & (r < scan.range_max)
    return Beams(np.stack([r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])], axis=1))


def to_world(pose: Pose2D, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Robot-frame points (N, 2) seen from ``pose`` in the map frame, as (x, y) arrays."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return pose.x + c * xy[:, 0] - s * xy[:, 1], pose.y + s * xy[:, 0] + c * xy[:, 1]


def crosses(grid: OccupancyGrid, occupied: np.ndarray, pose: Pose2D, wx: np.ndarray, wy: np.ndarray,
            length: np.ndarray) -> np.ndarray:
    """Per ray from ``pose`` towards (wx, wy): a cell of ``occupied`` (a mask over ``grid``)
    within ``length`` metres along it, sampled every half cell?"""
    if len(wx) == 0:
        return np.zeros(0, dtype=bool)
    dx, dy = wx - pose.x, wy - pose.y
    r = np.maximum(np.hypot(dx, dy), 1e-9)
    step = 0.5 * grid.resolution
    t = np.arange(step, max(float(length.max()), step), step)
    px = pose.x + (dx / r)[:, None] * t[None, :]
    py = pose.y + (dy / r)[:, None] * t[None, :]
    rows, cols = grid.world_to_cell(px, py)
    inside = grid.in_bounds(rows, cols) & (t[None, :] < length[:, None])
    occ = np.zeros(rows.shape, dtype=bool)
    occ[inside] = occupied[rows[inside], cols[inside]]
    return occ.any(axis=1)


def small_blobs(mask: np.ndarray, resolution: float, area: float) -> np.ndarray:
    """The cells of ``mask`` in 8-connected blobs of at most ``area`` m² (cells ``resolution`` m
    wide): on a saved map's occupied cells, the furniture, never a stretch of wall."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if count <= 1:
        return np.zeros(mask.shape, dtype=bool)
    small = stats[:, cv2.CC_STAT_AREA] * resolution ** 2 <= area
    small[0] = False  # the background label
    return small[labels]


class LikelihoodField:
    """Likelihood fields of one map (cached per sigma) and the scores of poses against them."""

    def __init__(self, grid: OccupancyGrid):
        self.grid = grid
        self.resolution = float(grid.resolution)
        self.surface_distance = surface_distance(grid)  # m, see surface_distance()
        self.occupied = grid.occupied_mask()
        self._cache: dict = {}

    def crosses_wall(self, pose: Pose2D, wx: np.ndarray, wy: np.ndarray, length: np.ndarray,
                     occupied: np.ndarray | None = None) -> np.ndarray:
        """Per ray from ``pose`` towards (wx, wy): an occupied cell within ``length``?

        ``occupied``: the cells that count (default every occupied cell of the map)."""
        return crosses(self.grid, self.occupied if occupied is None else occupied, pose, wx, wy, length)

    def walls(self, furniture_area: float) -> np.ndarray:
        """Occupied cells without the blobs of at most ``furniture_area`` m^2 (cached).

        A saved map holds the furniture the lidar saw during the build; what a later pass
        finds gone was one of those small blobs, never a stretch of wall."""
        key = ("walls", round(furniture_area, 6))
        if key not in self._cache:
            self._cache[key] = self.occupied & ~small_blobs(self.occupied, self.resolution, furniture_area)
        return self._cache[key]

    def padded(self, sigma: float, pad: int) -> np.ndarray:
        """Likelihood field for ``sigma``, zero-padded by ``pad`` cells (float32, cached)."""
        key = (round(sigma, 6), pad)
        if key not in self._cache:
            lik = np.exp(-0.5 * (self.surface_distance / sigma) ** 2).astype(np.float32)
            self._cache[key] = np.pad(lik, pad)
        return self._cache[key]

    def coarse_scores(self, rows, cols, yaws, beams: Beams, sigma: float) -> np.ndarray:
        """Scores (Y, N) for cell-centred positions: one integer offset per beam and yaw."""
        pad = 64 * int(math.ceil((beams.reach / self.resolution + 2) / 64))
        fld = self.padded(sigma, pad)
        width = fld.shape[1]
        flat = fld.ravel()
        base = (rows.astype(np.int64) + pad) * width + (cols.astype(np.int64) + pad)
        out = np.empty((len(yaws), len(base)), dtype=np.float32)
        bx, by = beams.xy[:, 0], beams.xy[:, 1]
        for i, yaw in enumerate(yaws):
            c, s = math.cos(yaw), math.sin(yaw)
            dc = np.floor((c * bx - s * by) / self.resolution + 0.5).astype(np.int64)
            dr = np.floor((s * bx + c * by) / self.resolution + 0.5).astype(np.int64)
            idx = (dr * width + dc)[:, None] + base[None, :]
            out[i] = flat.take(idx).mean(axis=0)
        return out

    def bilinear_scores(self, yaws, xy, beams: Beams, sigma: float, wall_probe: tuple[float, ...]) -> np.ndarray:
        """Scores (Y, N) for arbitrary positions ``xy`` (N, 2), interpolating the field.

        A beam also scores 0 when a point shortly before its end lies in an occupied
        cell: a cheap stand-in for :meth:`crosses_wall`'s ray test that stops a pose from
        sliding through a thin wall so that endpoints land on its far face.
        """
        yaws = np.asarray(yaws, dtype=float)
        bx, by = beams.xy[:, 0], beams.xy[:, 1]
        c, s = np.cos(yaws)[:, None, None], np.sin(yaws)[:, None, None]
        rx = c * bx[None, :, None] - s * by[None, :, None]  # (Y, B, 1)
        ry = s * bx[None, :, None] + c * by[None, :, None]
        px, py = xy[None, None, :, 0], xy[None, None, :, 1]  # (1, 1, N)
        lik = self.lookup(rx + px, ry + py, sigma)  # (Y, B, N)
        if wall_probe:
            r = np.maximum(np.hypot(bx, by), 1e-9)
            back = np.stack([np.maximum(r - d, 0.0) / r for d in wall_probe])  # (K, B)
            occ = self._occupied_padded()
            h, w = occ.shape
            ox, oy = self.grid.origin
            f = back[:, None, :, None]  # (K, 1, B, 1)
            col = np.clip((f * rx[None] + px[None] - ox) / self.resolution + 1.0, 0, w - 1).astype(np.int64)
            row = np.clip((f * ry[None] + py[None] - oy) / self.resolution + 1.0, 0, h - 1).astype(np.int64)
            blocked = occ.ravel().take(row * w + col).any(axis=0)  # (Y, B, N)
            lik = np.where(blocked, 0.0, lik)
        return lik.mean(axis=1)

    def _occupied_padded(self) -> np.ndarray:
        if "occ" not in self._cache:
            self._cache["occ"] = np.pad(self.occupied, 1)
        return self._cache["occ"]

    def lookup(self, wx: np.ndarray, wy: np.ndarray, sigma: float) -> np.ndarray:
        """Bilinearly interpolated likelihood at map-frame points (0 outside the map)."""
        fld = self.padded(sigma, 1)
        h, w = fld.shape
        flat = fld.ravel()
        ox, oy = self.grid.origin
        # Continuous coordinates with cell centres at integers, in the 1-cell padded field.
        fx = np.clip((wx - ox) / self.resolution + 0.5, 0.0, w - 1.000001)
        fy = np.clip((wy - oy) / self.resolution + 0.5, 0.0, h - 1.000001)
        x0, y0 = fx.astype(np.int64), fy.astype(np.int64)
        tx, ty = fx - x0, fy - y0
        i00 = y0 * w + x0
        return ((1 - ty) * ((1 - tx) * flat.take(i00) + tx * flat.take(i00 + 1))
                + ty * ((1 - tx) * flat.take(i00 + w) + tx * flat.take(i00 + w + 1)))

