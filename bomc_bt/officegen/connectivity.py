"""Where a robot of a given radius can get to on the whole floor, with boxes standing on it.

The generator's own safety net (and the tests' yardstick): walls of the map plus every
object and obstacle footprint, rasterised as the simulator's scene rasterises them, are
solid; a cell is passable when it is at least ``radius`` plus one cell from anything
solid; what the robot can reach is the 4-connected passable region around the start.
One distance transform and one labelling over the map: tens of milliseconds at the
paper's 93 x 90 m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from bomc_bt.grid import OccupancyGrid
from bomc_bt.world.walls import drivable_from, wall_mask


def rasterise(shape: tuple[int, int], origin: Sequence[float], res: float, polygons: Sequence[np.ndarray],
              out: np.ndarray | None = None) -> np.ndarray:
    """uint8 mask of polygons (map metres): cells under each plus its centre cell (the scene's rule)."""
    buf = np.zeros(shape, dtype=np.uint8) if out is None else out
    o = np.asarray(origin, dtype=float)
    for corners in polygons:
        cells = (np.asarray(corners) - o) / res - 0.5
        pts = np.rint(cells * 16.0).astype(np.int32).reshape(-1, 1, 2)
        cv2.fillPoly(buf, [pts], 1, lineType=cv2.LINE_8, shift=4)
        cx, cy = np.asarray(corners).mean(axis=0)
        r, c = int(math.floor((cy - o[1]) / res)), int(math.floor((cx - o[0]) / res))
        if 0 <= r < shape[0] and 0 <= c < shape[1]:
            buf[r, c] = 1
    return buf


def passable(grid: OccupancyGrid, footprints: Sequence[np.ndarray], radius: float) -> np.ndarray:
    """Bool mask: cells at least ``radius`` + one cell from walls and from every footprint."""
    solid = wall_mask(grid) | rasterise(grid.data.shape, grid.origin, grid.resolution, footprints).astype(bool)
    dist = cv2.distanceTransform((~solid).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return dist * grid.resolution >= radius + grid.resolution


def reachable(grid: OccupancyGrid, footprints: Sequence[np.ndarray], radius: float,
              start: tuple[float, float]) -> np.ndarray:
    """Bool mask of the passable cells a robot at ``start`` can drive to (empty if start is blocked)."""
    solid = wall_mask(grid) | rasterise(grid.data.shape, grid.origin, grid.resolution, footprints).astype(bool)
    r, c = grid.world_to_cell(start[0], start[1])
    return drivable_from(solid, grid.resolution, radius, (int(r), int(c)))


def distance_to(mask: np.ndarray, res: float) -> np.ndarray:
    """Metres from every cell to the nearest cell of ``mask`` (large where the mask is empty)."""
    return cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * res
