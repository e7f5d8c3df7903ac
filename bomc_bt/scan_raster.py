"""One laser scan as grid cells: the floor it sees free and the cells its returns hit.

The simulator's mapper and obstacle layer (:mod:`bomc_bt.sim.mapper`) and the recovery's
look for furniture gone since the build (:mod:`bomc_bt.stale_map`) rasterise a scan the same
way, with OpenCV instead of per-beam Python:
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
