"""What a viewpoint sees: floor within range along a free line of sight, all around.

The coverage plan (:mod:`bomc_bt.coverage_plan`) asks, for thousands of candidate places,
which of tens of thousands of floor samples each one sees. One ray per (place, target)
costs targets x samples per place; here each place casts a fixed fan of rays (one per
degree) once, and a target is seen when the first blocker along the ray of its bearing
lies beyond it. Places and targets sit on one lattice, so the targets in range of any
place are the same window of offsets (their distance and ray computed once), and a batch
of places is a few numpy operations.

The line-of-sight rule is the gap viewpoints' (:mod:`bomc_bt.viewpoints`): no occupied
cell before the target (stopping a cell short, since the target may stand by a wall) and
unknown cells only in its last ``shadow`` metres (furniture's lidar shadow, where the
camera, higher up, sees what stands there). What one place "sees" is all around: the robot
turns in place through the headings that face its floor (see ``headings_for``).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from bomc_bt.grid import OccupancyGrid
from bomc_bt.viewpoints import best_heading

_BATCH = 64  # places per vectorised batch: (64, 360 rays, 50 samples) booleans stay small


class Sight:
    """Visibility of lattice targets from lattice places on one map.

    ``lattice`` is the target raster's step in map cells: target (i, j) is map cell
    (i * lattice, j * lattice). ``floor`` is that raster (True where a target is).
    """

    def __init__(self, grid: OccupancyGrid, floor: np.ndarray, lattice: int, view_range: float,
                 min_range: float, shadow: float, ray_step: float = 0.1, rays: int = 360):
        self.grid, self.floor, self.lattice = grid, floor, lattice
        self.view_range, self.shadow, self.rays = view_range, shadow, rays
        step = grid.resolution * lattice
        n = int(math.floor(view_range / step))
        di, dj = np.mgrid[-n:n + 1, -n:n + 1]
        d = np.hypot(di, dj).ravel() * step
        keep = (d >= min_range) & (d <= view_range)
        self.di, self.dj, self.d = di.ravel()[keep], dj.ravel()[keep], d[keep]
        # rows grow with y, columns with x (OccupancyGrid's layout)
        self.bearing = np.arctan2(self.di, self.dj)
        self.ray = np.round(self.bearing / (2 * math.pi / rays)).astype(np.int64) % rays
        # Blockers thickened by one map cell all round, so samples every ray_step (at most
        # three cells) cannot step over a one-cell wall; the margin is what the 1.5-step
        # stop before a target allows for.
        self.step = max(grid.resolution, min(ray_step, 3 * grid.resolution))
        self.samples = np.arange(1, int(math.ceil(view_range / self.step)) + 1) * self.step
        self.pad = int(math.ceil(self.samples[-1] / grid.resolution)) + 2
        kernel = np.ones((3, 3), np.uint8)
        occupied = cv2.dilate(grid.occupied_mask().astype(np.uint8), kernel)
        blocked = cv2.dilate((~grid.free_mask()).astype(np.uint8), kernel)
        self._occ = np.pad(occupied.astype(bool), self.pad, constant_values=True)
        self._blocked = np.pad(blocked.astype(bool), self.pad, constant_values=True)
        angles = np.arange(rays) * 2 * math.pi / rays
        dr = np.round(np.sin(angles)[:, None] * self.samples[None, :] / grid.resolution).astype(np.int64)
        dc = np.round(np.cos(angles)[:, None] * self.samples[None, :] / grid.resolution).astype(np.int64)
        self._offsets = dr * self._occ.shape[1] + dc  # (rays, samples) flat offsets on the padded map

    def first_blocks(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(B, rays) distances from map cells to the first occupied and the first not-free
        sample along each ray; inf where there is none in range."""
        base = (rows + self.pad) * self._occ.shape[1] + cols + self.pad
        flat = base[:, None, None] + self._offsets[None, :, :]
        return _first(self._occ.ravel()[flat], self.samples), _first(self._blocked.ravel()[flat], self.samples)

    def visible(self, places: np.ndarray, headings: np.ndarray | None = None, hfov: float = 2 * math.pi
                ) -> list[np.ndarray]:
        """For each place (lattice (i, j), shape (K, 2)): flat raster indices of the targets it
        sees, all around or, with ``headings`` (K,), within ``hfov`` of each place's heading."""
        out: list[np.ndarray] = []
        h, w = self.floor.shape
        need_clear = self.d - 1.5 * self.step  # occupied: stop short of the target (it may stand by a wall)
        need_known = self.d - self.shadow - self.step  # unknown: allowed in the target's shadow
        for s in range(0, len(places), _BATCH):
            batch = places[s:s + _BATCH]
            occ, blocked = self.first_blocks(batch[:, 0] * self.lattice, batch[:, 1] * self.lattice)
            ti = batch[:, 0:1] + self.di[None, :]
            tj = batch[:, 1:2] + self.dj[None, :]
            inside = (ti >= 0) & (ti < h) & (tj >= 0) & (tj < w)
            ti, tj = np.clip(ti, 0, h - 1), np.clip(tj, 0, w - 1)
            seen = inside & self.floor[ti, tj]
            seen &= occ[:, self.ray] >= need_clear[None, :]
            seen &= blocked[:, self.ray] >= need_known[None, :]
            if headings is not None:
                off = self.bearing[None, :] - headings[s:s + _BATCH, None]
                seen &= np.abs(np.arctan2(np.sin(off), np.cos(off))) <= hfov / 2
            flat = ti * w + tj
            out.extend(flat[k][seen[k]] for k in range(len(batch)))
        return out


def _first(hit: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Distance of the first True along the last axis; inf where there is none."""
    any_hit = hit.any(axis=-1)
    first = np.where(any_hit, samples[np.argmax(hit, axis=-1)], np.inf)
    return first


def along_paths(sight: Sight, paths: list[np.ndarray], step: float, hfov: float) -> np.ndarray:
    """Flat raster indices of the targets the camera sees while driving ``paths`` facing
    ahead (sampled every ``step`` metres, each sample at its nearest lattice place)."""
    xy, heading = [], []
    for path in paths:
        if path is None or len(path) < 2:
            continue
        seg = np.diff(path, axis=0)
        length = np.hypot(seg[:, 0], seg[:, 1])
        cum = np.concatenate([[0.0], np.cumsum(length)])
        at = np.arange(0.0, cum[-1], step)
        k = np.clip(np.searchsorted(cum, at, side="right") - 1, 0, len(seg) - 1)
        xy.append(np.stack([np.interp(at, cum, path[:, 0]), np.interp(at, cum, path[:, 1])], axis=1))
        heading.append(np.arctan2(seg[k, 1], seg[k, 0]))
    if not xy:
        return np.zeros(0, dtype=np.int64)
    pts, yaw = np.vstack(xy), np.concatenate(heading)
    seen = sight.visible(lattice_places(sight, pts), yaw, hfov)
    return np.unique(np.concatenate(seen)) if seen else np.zeros(0, dtype=np.int64)


def lattice_places(sight: Sight, xy: np.ndarray) -> np.ndarray:
    """(K, 2) lattice (i, j) of map points (K, 2): each at its nearest place on the raster."""
    rows, cols = sight.grid.world_to_cell(xy[:, 0], xy[:, 1])
    h, w = sight.floor.shape
    return np.stack([np.clip(np.round(rows / sight.lattice), 0, h - 1),
                     np.clip(np.round(cols / sight.lattice), 0, w - 1)], axis=1).astype(np.int64)


def faced(sight: Sight, paths: list[np.ndarray], poses: np.ndarray, step: float, hfov: float) -> np.ndarray:
    """Flat raster indices of the targets a tour shows the camera: along ``paths`` facing
    ahead, and at each pose (K, 3: x, y, yaw) only within ``hfov`` of its yaw -- the robot
    turns to a stop's headings, not all around, so this is less than what the stops see."""
    seen = [along_paths(sight, paths, step, hfov)]
    if len(poses):
        seen += sight.visible(lattice_places(sight, poses[:, :2]), poses[:, 2], hfov)
    return np.unique(np.concatenate(seen)).astype(np.int64)


def headings_for(bearings: np.ndarray, hfov: float, min_count: int, max_headings: int) -> list[float]:
    """hfov-wide windows that face the bearings (rad) a viewpoint is to look at.

    Greedy: the window holding most bearings not yet faced; further ones while they hold
    at least ``min_count``; at most ``max_headings``. Turning between headings sweeps the
    camera over what lies between, so a bearing outside every window is rarely unseen.
    """
    left = np.ones(len(bearings), dtype=bool)
    out: list[float] = []
    while len(out) < max_headings and left.any():
        heading, count = best_heading(bearings, left, hfov)
        if out and count < min_count:
            break
        out.append(heading)
        left &= np.abs(np.angle(np.exp(1j * (bearings - heading)))) > hfov / 2 + 1e-9
    return out
