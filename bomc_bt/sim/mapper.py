"""Occupancy mapping from scans: the simulator's stand-in for GMapping, and a costmap layer.

Both classes rasterise one scan the same way, with OpenCV instead of per-beam Python:
a polygon star-shaped around the sensor is filled as "seen free", and the end points of
beams that hit something are "occupied" (written after the free fill, so a return is
never cleared by its own scan). The polygon is the area a ray-casting mapper (GMapping)
would clear, without casting each beam: every beam out to half a cell short of its
return, and between two neighbouring beams the wedge out to the *nearer* of their two
ranges. Joining neighbouring end points instead (the scan's outline) lays the outline
along any wall seen at a grazing angle, and filling it carves that wall's cells free
between two returns, scan after scan, until no hit survives and the map shows a gap
into whatever lies behind the wall. Work is confined to the scan's bounding box, so an
update costs the area the scan covers, not the whole map.

* :class:`Mapper` accumulates log-odds like GMapping's grid and, like GMapping, only
  integrates a scan after the robot moved ``linear_update`` or turned ``angular_update``.
  The pose it is given is the SLAM estimate (the simulator passes the true pose: SLAM
  drift is out of scope).
* :class:`ObstacleLayer` is the local obstacle layer of a monitor-mode costmap: cells
  hit by recent scans are obstacles until a later scan sees through them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from bomc_bt.pass_resume import pack_mask, unpack_mask
from bomc_bt.robot import LaserScan
from bomc_bt.sim.params import MapperParams, ObstacleLayerParams


@dataclass
class RasterisedScan:
    """One scan in grid cells: a bounding box and the free / hit masks inside it."""

    r0: int
    c0: int
    free: np.ndarray  # bool (h, w), includes the hit cells' rays
    hits: np.ndarray  # bool (h, w)


def rasterise(scan: LaserScan, pose: Pose2D, grid: OccupancyGrid, free_range: float,
              hit_range: float | None = None) -> RasterisedScan | None:
    """Free polygon and hit cells of ``scan`` taken at ``pose``, clipped to ``grid``.

    ``hit_range`` limits which returns count as hits (a costmap's obstacle_range); beams
    without a return, or beyond it, clear up to ``free_range``.
    """
    ranges = np.asarray(scan.ranges, dtype=float)
    angles = scan.angles + pose.yaw
    finite = np.isfinite(ranges)
    reach = np.where(finite, np.minimum(ranges, free_range), free_range)
    is_hit = finite & (ranges <= (hit_range if hit_range is not None else scan.range_max))
    res, (ox, oy) = grid.resolution, grid.origin
    cos, sin = np.cos(angles), np.sin(angles)
    ex = (pose.x + reach * cos - ox) / res
    ey = (pose.y + reach * sin - oy) / res
    sx, sy = (pose.x - ox) / res, (pose.y - oy) / res
    c0 = max(int(math.floor(min(ex.min(), sx))) - 1, 0)
    r0 = max(int(math.floor(min(ey.min(), sy))) - 1, 0)
    c1 = min(int(math.ceil(max(ex.max(), sx))) + 2, grid.width)
    r1 = min(int(math.ceil(max(ey.max(), sy))) + 2, grid.height)
    if c0 >= c1 or r0 >= r1:
        return None
    h, w = r1 - r0, c1 - c0
    # Half a cell short of a return (the range noise), then a tenth of a cell inset.
    ends_on_surface = finite & (ranges <= free_range)
    cleared = np.maximum(reach - np.where(ends_on_surface, 0.5 * res, 0.0), 0.0)
    dx, dy = free_outline(cleared, cos, sin, 0.1 * res)
    outline = np.stack([pose.x + dx - ox, pose.y + dy - oy], axis=1) / res
    poly = np.concatenate([[[sx, sy]], outline]) - [c0 + 0.5, r0 + 0.5]
    free = np.zeros((h, w), dtype=np.uint8)
    cv2.fillPoly(free, [np.rint(poly * 16.0).astype(np.int32).reshape(-1, 1, 2)], 1,
                 lineType=cv2.LINE_8, shift=4)
    hits = np.zeros((h, w), dtype=bool)
    if is_hit.any():
        # Half a cell past the return, so the hit lands in the cell that was hit.
        push = ranges[is_hit] + 0.5 * res
        hc = np.floor((pose.x + push * cos[is_hit] - ox) / res).astype(np.int64) - c0
        hr = np.floor((pose.y + push * sin[is_hit] - oy) / res).astype(np.int64) - r0
        ok = (hr >= 0) & (hr < h) & (hc >= 0) & (hc < w)
        hits[hr[ok], hc[ok]] = True
    return RasterisedScan(r0, c0, free.astype(bool), hits)


def free_outline(reach: np.ndarray, cos: np.ndarray, sin: np.ndarray,
                 inset: float) -> tuple[np.ndarray, np.ndarray]:
    """Outline (x, y offsets from the sensor, metres) of the area a scan clears.

    Beam ``i`` goes out to ``reach[i]``; between beams ``i`` and ``i + 1`` the outline
    runs at ``min(reach[i], reach[i + 1])``, so per beam three vertices: in at the
    nearer of its left neighbour and itself, out along the beam to its own reach, back
    in to the nearer of itself and its right neighbour. The chord between two beams then
    lies inside the circle through the nearer return and never cuts into the surface
    the farther beam ran along.

    Every vertex then moves ``inset`` towards the sensor along each axis: a return lies
    on a cell face, and OpenCV fills every cell a vertex rounds into, ties upwards, so
    a beam grazing a wall on its +x or +y side would otherwise end (and run its last
    cells) in the wall's cells. Pulling back along the beam does not help there: at a
    grazing angle it barely moves the end away from the wall.
    """
    nearer = np.minimum(reach[:-1], reach[1:])
    before = np.concatenate([reach[:1], nearer])
    after = np.concatenate([nearer, reach[-1:]])
    radius = np.stack([before, reach, after], axis=1).ravel()
    dx, dy = radius * np.repeat(cos, 3), radius * np.repeat(sin, 3)
    return (np.sign(dx) * np.maximum(np.abs(dx) - inset, 0.0),
            np.sign(dy) * np.maximum(np.abs(dy) - inset, 0.0))


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


class ObstacleLayer:
    """Obstacles seen by recent scans, on a saved map's grid (a costmap obstacle layer)."""

    def __init__(self, grid: OccupancyGrid, params: ObstacleLayerParams | None = None):
        self.params = params or ObstacleLayerParams()
        self.geometry = OccupancyGrid.unknown(grid.width, grid.height, grid.resolution, grid.origin)
        self.mask = np.zeros(grid.data.shape, dtype=bool)
        self.version = 0
        self._packed: tuple[int, str] | None = None  # (version, packed mask) of the last checkpoint

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

    def clear(self) -> None:
        self.mask[:] = False
        self.version += 1

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
        self._packed = (self.version, packed)
