"""Where the saved map still holds furniture that has gone: the floor the lidar sees through it.

A saved map is the building as the build found it, chairs and tables included, and
navigation plans on it as move_base's static layer does: no scan ever clears it. Where a
table stood at the build, and something brought in since stands beside that spot, the
planner sees a wall where the robot can drive; a pass hemmed in this way failed waypoint
after waypoint and ended early "boxed in" while the way was open (issue 15 item 6).

:func:`floor_seen` finds the cells one scan sees free that the map holds as furniture (an
occupied blob no larger than ``furniture_area``, never a stretch of wall) or as unknown (the
floor under a table, never seen at the build). :class:`FloorSeen` keeps them over a pass:
the spot that hems the robot in is seldom in the scan at the moment it is found stuck (it
drove past it minutes before). :func:`with_floor` is the map with them free. The recovery
diagnoses ``stale_map`` with them (:mod:`bomc_bt.stuck`) and the robot navigates on the
refreshed map for the rest of the pass (``RobotPort.refresh_map``); the saved map itself
never changes.
"""

from __future__ import annotations

import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import FREE, OccupancyGrid
from bomc_bt.robot import LaserScan
from bomc_bt.scan_likelihood import small_blobs
from bomc_bt.scan_raster import rasterise


def furniture_cells(grid: OccupancyGrid, furniture_area: float) -> np.ndarray:
    """Bool mask of the occupied cells in 8-connected blobs of at most ``furniture_area`` m²
    (as relocalization tells furniture from walls, :meth:`~bomc_bt.scan_likelihood.LikelihoodField.walls`)."""
    return small_blobs(grid.occupied_mask(), grid.resolution, furniture_area)


def _raster_window(grid: OccupancyGrid, pose: Pose2D, scan: LaserScan | None, max_range: float):
    raster = None if scan is None else rasterise(scan, pose, grid, max_range)
    if raster is None:
        return None, None
    h, w = raster.free.shape
    return raster, (slice(raster.r0, raster.r0 + h), slice(raster.c0, raster.c0 + w))


def floor_seen(grid: OccupancyGrid, pose: Pose2D, scan: LaserScan | None, furniture_area: float,
               max_range: float) -> np.ndarray:
    """(K, 2) rows and columns of the cells ``scan`` (taken at ``pose``) sees as floor out to
    ``max_range`` m that ``grid`` holds as furniture or unknown. Empty without a scan or
    with ``furniture_area`` 0 (off)."""
    raster, window = _raster_window(grid, pose, scan, max_range) if furniture_area > 0 else (None, None)
    if raster is None:
        return np.zeros((0, 2), dtype=np.int64)
    stale = furniture_cells(grid, furniture_area)[window] | grid.unknown_mask()[window]
    rows, cols = np.nonzero(raster.free & ~raster.hits & stale)
    return np.stack([rows + raster.r0, cols + raster.c0], axis=1)


def with_floor(grid: OccupancyGrid, floor: np.ndarray) -> OccupancyGrid:
    """A copy of ``grid`` with the ``floor`` cells (rows, columns) free."""
    data = grid.data.copy()
    if len(floor):
        data[floor[:, 0], floor[:, 1]] = FREE
    return OccupancyGrid(data, grid.resolution, tuple(grid.origin))


class FloorSeen:
    """How many scans of this pass saw each cell of the saved map that holds furniture or is
    unknown as floor; a return off such a cell starts its count again (the object is back).

    ``min_seen`` scans must agree before a cell counts (one scan taken at a pose a few
    centimetres off sees through the edge of a cabinet that is still there).
    """

    def __init__(self, grid: OccupancyGrid, furniture_area: float, max_range: float, min_seen: int):
        self.grid, self.max_range, self.min_seen = grid, max_range, min_seen
        self.candidates = (furniture_cells(grid, furniture_area) | grid.unknown_mask()) if furniture_area > 0 else None
        self.counts = np.zeros(grid.data.shape, dtype=np.uint8)
        self.scans = 0

    def add(self, pose: Pose2D, scan: LaserScan | None) -> None:
        """Fold one scan taken at ``pose`` in."""
        if self.candidates is None:
            return
        raster, window = _raster_window(self.grid, pose, scan, self.max_range)
        if raster is None:
            return
        counts = self.counts[window]
        seen = raster.free & ~raster.hits & self.candidates[window] & (counts < 255)
        counts[seen] += 1
        counts[raster.hits] = 0
        self.scans += 1

    def cells(self) -> np.ndarray:
        """(K, 2) rows and columns seen as floor by at least ``min_seen`` scans."""
        rows, cols = np.nonzero(self.counts >= self.min_seen)
        return np.stack([rows, cols], axis=1)
