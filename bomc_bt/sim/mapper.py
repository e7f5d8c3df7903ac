"""Occupancy mapping from scans: the simulator's stand-in for GMapping, and a costmap layer.

Both classes rasterise a scan as :mod:`bomc_bt.scan_raster` does.

* :class:`Mapper` accumulates log-odds like GMapping's grid and, like GMapping, only
  integrates a scan after the robot moved ``linear_update`` or turned ``angular_update``.
  The pose it is given is the SLAM estimate (the simulator passes the true pose: SLAM
  drift is out of scope).
* :class:`ObstacleLayer` is the local obstacle layer of a monitor-mode costmap: cells
  hit by recent scans are obstacles until a later scan sees through them.
"""

from __future__ import annotations

import numpy as np

from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from bomc_bt.pass_resume import pack_mask, unpack_mask
from bomc_bt.robot import LaserScan
from bomc_bt.scan_raster import rasterise
from bomc_bt.sim.params import MapperParams, ObstacleLayerParams


class Mapper:
    """A log-odds occupancy grid over the world map's extent, updated from scans."""

    def __init__(self, width: int, height: int, resolution: float, origin: tuple[float, float],
                 params: MapperParams | None = None):
        self.params = params or MapperParams()
        self.log_odds = np.zeros((height, width), dtype=np.float32)
        self._cells = np.full((height, width), UNKNOWN, dtype=np.int8)  # log_odds thresholded, kept in step
        self.geometry = OccupancyGrid.unknown(width, height, resolution, origin)
        self.updates = 0
        self._last_pose: Pose2D | None = None
        self._map: OccupancyGrid | None = None

    @classmethod
    def like(cls, grid: OccupancyGrid, params: MapperParams | None = None) -> Mapper:
        """A mapper covering ``grid``'s extent at ``params.resolution``."""
        params = params or MapperParams()
        scale = grid.resolution / params.resolution
        width = max(1, int(round(grid.width * scale)))
        height = max(1, int(round(grid.height * scale)))
        return cls(width, height, params.resolution, tuple(grid.origin), params)

    def needs_update(self, pose: Pose2D) -> bool:
        """True when the robot moved or turned enough since the last integrated scan."""
        last = self._last_pose
        if last is None:
            return True
        p = self.params
        return (pose.distance_to(last) >= p.linear_update
                or abs(wrap_angle(pose.yaw - last.yaw)) >= p.angular_update)

    def integrate(self, scan: LaserScan, pose: Pose2D) -> bool:
        """Add a scan taken at ``pose``; returns whether the map changed."""
        self._last_pose = pose
        p = self.params
        raster = rasterise(scan, pose, self.geometry, p.max_free_range)
        if raster is None:
            return False
        delta = np.where(raster.free, np.float32(p.miss_log_odds), np.float32(0.0))
        delta[raster.hits] = p.hit_log_odds
        h, w = delta.shape
        view = self.log_odds[raster.r0:raster.r0 + h, raster.c0:raster.c0 + w]
        np.clip(view + delta, -p.clamp_log_odds, p.clamp_log_odds, out=view)
        cells = self._cells[raster.r0:raster.r0 + h, raster.c0:raster.c0 + w]
        cells[...] = UNKNOWN
        cells[view < p.free_threshold] = FREE
        cells[view > p.occupied_threshold] = OCCUPIED
        self.updates += 1
        self._map = None
        return True

    def grid(self) -> OccupancyGrid:
        """The current map (cached until the next integrated scan).

        Each integrated scan re-thresholds only the cells it touched, so a new map is a
        copy of those cells, not a pass over the whole log-odds grid; a map handed out
        earlier keeps its own cells.
        """
        if self._map is None:
            self._map = OccupancyGrid(self._cells.copy(), self.geometry.resolution, tuple(self.geometry.origin))
        return self._map


_KEPT_WINDOWS = 64  # [count] scan windows an obstacle layer remembers for its checkpoint


class ObstacleLayer:
    """Obstacles seen by recent scans, on a saved map's grid (a costmap obstacle layer)."""

    def __init__(self, grid: OccupancyGrid, params: ObstacleLayerParams | None = None):
        self.params = params or ObstacleLayerParams()
        self.geometry = OccupancyGrid.unknown(grid.width, grid.height, grid.resolution, grid.origin)
        self.mask = np.zeros(grid.data.shape, dtype=bool)
        self.version = 0
        self._packed: tuple[int, str] | None = None  # (version, packed mask) of the last checkpoint
        self._windows: list[tuple[int, tuple[int, int, int, int]]] = []  # (version, window) of recent scans

    def update(self, scan: LaserScan, pose: Pose2D) -> None:
        p = self.params
        raster = rasterise(scan, pose, self.geometry, p.raytrace_range, p.obstacle_range)
        if raster is None:
            return
        h, w = raster.free.shape
        view = self.mask[raster.r0:raster.r0 + h, raster.c0:raster.c0 + w]
        before = view.copy()
        view &= ~raster.free
        view |= raster.hits
        if not np.array_equal(before, view):
            self.version += 1
            self._windows = self._windows[-(_KEPT_WINDOWS - 1):] + [
                (self.version, (raster.r0, raster.r0 + h, raster.c0, raster.c0 + w))]

    def changed_since(self, version: int) -> list[tuple[int, int, int, int]] | None:
        """The windows (rows r0:r1, columns c0:c1) of the mask that scans changed after
        ``version``; None where something else changed it since, or too long ago (the
        checkpoint's tile encoder then looks at the whole mask: :mod:`bomc_bt.sim.tiled_mask`)."""
        after = [(v, window) for v, window in self._windows if v > version]
        if [v for v, _ in after] != list(range(version + 1, self.version + 1)):
            return None
        return [window for _, window in after]

    def clear(self) -> None:
        self.mask[:] = False
        self.version += 1
        self._windows = []

    def points(self) -> np.ndarray:
        """(N, 2) map-frame centres of the marked cells."""
        return self.geometry.cell_centres(self.mask)

    def packed(self) -> str:
        """The mask as a checkpoint saves it, packed once per version: a pass commits with
        every frame, and packing an Environment-A-size mask costs milliseconds while the
        layer rarely changes between two frames."""
        if self._packed is None or self._packed[0] != self.version:
            self._packed = (self.version, pack_mask(self.mask))
        return self._packed[1]

    def load(self, packed: str, version: int) -> None:
        """Put back a checkpoint's mask (:meth:`packed`) and version."""
        self.mask[:] = unpack_mask(packed, self.mask.shape).astype(bool)
        self.version = int(version)
        self._windows = []
        self._packed = (self.version, packed)
