"""Which map cells are solid, whether a box stands inside a wall, and where a robot can drive.

Used by the loader to reject objects typed into walls and by the simulator, which
treats these cells as solid. "Inside a wall" is defined robustly for real SLAM maps: an
object (or obstacle) is rejected only when its centre cell is a wall *and* not a single
free cell lies within its footprint grown by one cell. A door standing in a doorway, a
cabinet pushed against a wall or a chair whose centre hits a stray occupied pixel all
load; a box typed into the middle of a wall, an unknown pocket or outside the image
does not.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from bomc_bt.grid import OccupancyGrid


def wall_mask(grid: OccupancyGrid) -> np.ndarray:
    """Occupied-or-unknown cells: what a simulator built on this map treats as solid.

    The image's outermost cells count as wall too: everything outside the image is wall,
    and real SLAM maps often run free space out to the edge, where a robot would see
    nothing (its lidar starts inside the wall) and a planner would route along a strip
    that does not exist.
    """
    cached = grid._cache.get("world_walls")
    if cached is None or cached.shape != grid.data.shape:
        cached = grid.occupied_mask() | grid.unknown_mask()
        cached[[0, -1], :] = True
        cached[:, [0, -1]] = True
        grid._cache["world_walls"] = cached
    return cached


def drivable_from(solid: np.ndarray, resolution: float, radius: float, start: tuple[int, int]) -> np.ndarray:
    """Cells a robot of ``radius`` (plus one cell) starting at cell ``start`` (row, col) can drive
    to among ``solid`` cells (4-connected; empty when the start itself is too tight)."""
    dist = cv2.distanceTransform((~solid).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    ok = dist * resolution >= radius + resolution
    _, labels = cv2.connectedComponents(ok.astype(np.uint8), connectivity=4)
    r, c = start
    inside = 0 <= r < ok.shape[0] and 0 <= c < ok.shape[1]
    return labels == labels[r, c] if inside and ok[r, c] else np.zeros_like(ok)


def embedded_in_wall(grid: OccupancyGrid, walls: np.ndarray, position, size, yaw: float) -> bool:
    """True when the centre cell is wall and no free cell lies in the footprint grown by a cell.

    Real SLAM maps have thin, noisy walls: a door in a doorway or a cabinet against a wall
    may have its centre on a wall pixel, so only a box with no free space at all under it
    (one cell of slack for rasterisation) counts as inside a wall.
    """
    x, y = float(position[0]), float(position[1])
    r, c = grid.world_to_cell(x, y)
    if bool(grid.in_bounds(r, c)) and not walls[r, c]:
        return False
    res = grid.resolution
    hx, hy = size[0] / 2.0 + res, size[1] / 2.0 + res
    reach = math.hypot(hx, hy)
    r0, c0 = grid.world_to_cell(x - reach, y - reach)
    r1, c1 = grid.world_to_cell(x + reach, y + reach)
    r0, c0 = max(int(r0), 0), max(int(c0), 0)
    r1, c1 = min(int(r1), grid.height - 1), min(int(c1), grid.width - 1)
    if r0 > r1 or c0 > c1:
        return True  # entirely outside the image
    rows, cols = np.mgrid[r0:r1 + 1, c0:c1 + 1]
    cx, cy = grid.cell_to_world(rows, cols)
    cos, sin = math.cos(yaw), math.sin(yaw)
    lx = (cx - x) * cos + (cy - y) * sin
    ly = -(cx - x) * sin + (cy - y) * cos
    inside = (np.abs(lx) <= hx) & (np.abs(ly) <= hy)
    return not bool(np.any(inside & ~walls[r0:r1 + 1, c0:c1 + 1]))

