"""How much of a building a saved map covers: the build mission's acceptance measure.

The reference is the true free space *reachable from the start*: free cells of the true
map, less the footprints of the objects standing there (a closed door shuts a room, the
floor under a table is never seen), connected to the start cell (4-connected). A saved
map covers a reachable cell when it marks that cell free.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid


@dataclass
class MapCoverage:
    reachable_m2: float
    covered_m2: float
    extra_m2: float  # free in the saved map but not free in the truth (false free)

    @property
    def fraction(self) -> float:
        return self.covered_m2 / self.reachable_m2 if self.reachable_m2 else 0.0


def solid_mask(truth: OccupancyGrid, walls: np.ndarray, footprints: list[np.ndarray]) -> np.ndarray:
    """Walls plus the given (K, 2) map-frame footprints (objects, obstacles) rasterised."""
    mask = walls.astype(np.uint8)
    for corners in footprints:
        rows, cols = truth.world_to_cell(corners[:, 0], corners[:, 1])
        cv2.fillPoly(mask, [np.stack([cols, rows], axis=1).astype(np.int32)], 1)
    return mask.astype(bool)


def reachable_free(truth: OccupancyGrid, walls: np.ndarray, start: Pose2D) -> np.ndarray:
    """Bool mask of true free cells 4-connected to the start cell."""
    free = (~walls).astype(np.uint8)
    _, labels = cv2.connectedComponents(free, connectivity=4)
    row, col = truth.world_to_cell(start.x, start.y)
    if not truth.in_bounds(row, col) or labels[row, col] == 0:
        return np.zeros(walls.shape, dtype=bool)
    return labels == labels[row, col]


def map_coverage(saved: OccupancyGrid, truth: OccupancyGrid, walls: np.ndarray, start: Pose2D) -> MapCoverage:
    """Compare a saved map with the true map (both in the map frame, any origin)."""
    reach = reachable_free(truth, walls, start)
    rows, cols = np.nonzero(reach)
    xs, ys = truth.cell_to_world(rows, cols)
    srows, scols = saved.world_to_cell(xs, ys)
    inside = saved.in_bounds(srows, scols)
    covered = np.zeros(len(rows), dtype=bool)
    covered[inside] = saved.data[srows[inside], scols[inside]] == 0
    cell = truth.resolution**2
    srows_all, scols_all = np.nonzero(saved.data == 0)
    fx, fy = saved.cell_to_world(srows_all, scols_all)
    trows, tcols = truth.world_to_cell(fx, fy)
    tin = truth.in_bounds(trows, tcols)
    false_free = np.count_nonzero(~tin) + np.count_nonzero(walls[trows[tin], tcols[tin]])
    return MapCoverage(float(len(rows)) * cell, float(np.count_nonzero(covered)) * cell,
                       float(false_free) * saved.resolution**2)
