"""Clearance of a planning grid coarser than the map: the costmap's raw material.

:class:`bomc_bt.planner.GridPlanner` turns clearance into lethal cells and an inflation
cost, as a ROS costmap does with ``inflation_radius``. Computing it is the expensive,
once-per-map step, so it runs in OpenCV: one exact Euclidean distance transform on the
fine map, then area-averaging down to the planning resolution.
"""

from __future__ import annotations

import cv2
import numpy as np

from bomc_bt.grid import OccupancyGrid


def clearance_fields(obstacles: np.ndarray, unknown: np.ndarray, res: float,
                     factor: int) -> tuple[np.ndarray, np.ndarray]:
    """Clearance (m) at each planning cell's centre, and which planning cells are unknown.

    The distance transform runs on the fine map (exact walls), then area-averaging down
    to the planning grid reads it at the coarse cell centre. Half a fine cell is taken
    off because the transform measures to obstacle cell centres, not their faces.
    """
    h, w = obstacles.shape
    ph, pw = (-h) % factor, (-w) % factor
    free = np.pad((~obstacles).astype(np.uint8), ((0, ph), (0, pw)), mode="edge")
    if free.all():
        dist = np.full(free.shape, np.inf, dtype=np.float32)
    else:
        dist = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * res
        dist = np.maximum(dist - 0.5 * res, 0.0)
    unk = np.pad(unknown.astype(np.float32), ((0, ph), (0, pw)), constant_values=1.0)
    if factor > 1:
        size = (free.shape[1] // factor, free.shape[0] // factor)
        if np.isfinite(dist).all():
            dist = cv2.resize(dist, size, interpolation=cv2.INTER_AREA)
        else:
            dist = np.full((size[1], size[0]), np.inf, dtype=np.float32)
        unk = cv2.resize(unk, size, interpolation=cv2.INTER_AREA)
    return dist.astype(np.float64), unk > 0.5


def grid_clearance(grid: OccupancyGrid, factor: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`clearance_fields` of a grid's own obstacles, computed once per grid content.

    While exploring, the frontier reachability check and the navigator's planner are both
    built on the same snapshot of the live map, one right after the other; the distance
    transform is the expensive part of each. The result is kept on the grid with a copy
    of its cells, so a grid whose cells were edited in place is recomputed. The arrays
    returned are shared: read them, do not write them.
    """
    cached = grid._cache.get("clearance")
    if cached is not None and cached[0] == factor and np.array_equal(cached[1], grid.data):
        return cached[2], cached[3]
    clearance, unknown = clearance_fields(grid.occupied_mask(), grid.unknown_mask(), grid.resolution, factor)
    clearance.flags.writeable = False
    unknown.flags.writeable = False
    grid._cache["clearance"] = (factor, grid.data.copy(), clearance, unknown)
    return clearance, unknown
