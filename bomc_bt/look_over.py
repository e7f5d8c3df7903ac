"""Looking over furniture: the map cells that hide a first sighting from the camera.

A new object is added once two frames have seen it (:mod:`bomc_bt.graph.tentative`); one
the camera caught in a single frame is worth a turn of the head, and Look Around turns to
it (:func:`~bomc_bt.monitoring.unverified_headings`) when a line from the robot reaches it.
That line used to run over free map cells only. But the chair behind another chair at a
table stands in lidar shadow: the lidar sees the chairs' and the table's outlines and
leaves the floor round them unknown, so no line from the room reached the sighting and
the robot never turned to it. On a generated 93 x 90 m office (seed 8231) pass 1 caught
such a chair (a table against a wall, two chairs on each side, the pair by the wall hidden
behind the pair in front) in one frame from a stop 4.2 m away, turned on to its other
headings and drove off; the chair stayed off the map until pass 2 saw it from 2.7 m over
the table. The camera, at ``camera.mount_height`` (1.1 m), looks over a 0.9 m chair and a
0.75 m table, and the sighting itself shows it saw that place.

So a line to a first sighting is blocked only where the camera cannot see: occupied cells
(:func:`~bomc_bt.node_sight.camera_clear`; unknown cells do not block), and of those not
the lidar outline of an object lower than the camera -- an occupied blob of the map inside
the box of a node lower than ``camera_height``, no longer than :data:`MAX_FURNITURE`, so a
wall never counts as one even where a node's box bled onto it. A node's height is twice its
centroid's (it stands on the floor).

Such a turn is Look Around's one look at the place (no other waypoint turns to it again),
but unlike a turn along free floor it does not settle the sighting for the refresh tour
(``TentativeSightings.mark_looked``, ``past``): from where the robot happens to stand the
object may still be hidden, and the tour plans a look from near and clear of the other
objects. Letting the far turn settle it lost a trash bin caught once behind a chair (36 x 28
m office, seed 8223, pass 6: turned to from 2.95 m, not seen, never looked at again).
"""

from __future__ import annotations

from collections.abc import Iterable

import cv2
import numpy as np

from bomc_bt.grid import OccupancyGrid
from bomc_bt.node_sight import camera_clear

MAX_FURNITURE = 2.0  # m: an occupied blob of the map longer than this (a wall) hides what is behind it
BOX_PAD = 0.1  # m: the lidar outline of an object lies on its box's edge; the box is grown by this
HALF_BOX = 0.25  # m: half the side of the box of a node without a footprint


def object_tops(centroid_heights: np.ndarray) -> np.ndarray:
    """(M,) heights of floor-standing objects (m): twice their centroids' heights."""
    return 2.0 * np.maximum(np.asarray(centroid_heights, dtype=float).reshape(-1), 0.0)


def low_furniture_cells(grid: OccupancyGrid, boxes: np.ndarray, tops: np.ndarray, camera_height: float) -> np.ndarray:
    """(H, W) bool: occupied cells the camera looks over -- inside the box (grown by
    :data:`BOX_PAD`) of an object lower than ``camera_height``, and in an occupied blob
    no longer than :data:`MAX_FURNITURE` (a box that bled onto a wall does not clear it)."""
    occupied = grid.occupied_mask()
    inside = np.zeros(occupied.shape, dtype=bool)
    low = np.asarray(boxes, dtype=float).reshape(-1, 4)[np.asarray(tops, dtype=float).reshape(-1) < camera_height]
    for box in low:
        r0, c0 = grid.world_to_cell(np.array([box[0] - BOX_PAD]), np.array([box[1] - BOX_PAD]))
        r1, c1 = grid.world_to_cell(np.array([box[2] + BOX_PAD]), np.array([box[3] + BOX_PAD]))
        inside[max(r0[0], 0):max(r1[0] + 1, 0), max(c0[0], 0):max(c1[0] + 1, 0)] = True
    candidates = inside & occupied
    if not candidates.any():
        return candidates
    _, labels, stats, _ = cv2.connectedComponentsWithStats(occupied.astype(np.uint8), connectivity=8)
    longest = np.maximum(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT]) * grid.resolution
    small = longest <= MAX_FURNITURE + 1e-9
    small[0] = False  # the label of the cells that are not occupied
    return candidates & small[labels]


def over_furniture_clear(grid: OccupancyGrid, nodes: Iterable, camera_height: float,
                         around: tuple[float, float, float] | None = None) -> np.ndarray:
    """(H, W) bool: the cells a line to a first sighting may cross -- all but occupied ones,
    and of those the lidar outlines of ``nodes`` (the graph's present nodes) lower than
    ``camera_height``. With ``around`` (x, y, radius in m) only outlines within ``radius``
    of (x, y) are cleared (the lines a turn there tests), in a window :data:`MAX_FURNITURE`
    wider, so a wall it cuts still shows longer than any piece of furniture."""
    nodes = list(nodes)
    boxes = np.array([n.footprint if n.footprint is not None else
                      [n.position[0] - HALF_BOX, n.position[1] - HALF_BOX,
                       n.position[0] + HALF_BOX, n.position[1] + HALF_BOX] for n in nodes], dtype=float).reshape(-1, 4)
    tops = object_tops(np.array([n.position[2] for n in nodes], dtype=float))
    clear = camera_clear(grid)
    r0, c0, r1, c1 = 0, 0, grid.height, grid.width
    if around is not None:
        reach = around[2] + MAX_FURNITURE + grid.resolution
        lo_r, lo_c = grid.world_to_cell(np.array([around[0] - reach]), np.array([around[1] - reach]))
        hi_r, hi_c = grid.world_to_cell(np.array([around[0] + reach]), np.array([around[1] + reach]))
        r0, c0 = max(int(lo_r[0]), 0), max(int(lo_c[0]), 0)
        r1, c1 = min(int(hi_r[0]) + 1, grid.height), min(int(hi_c[0]) + 1, grid.width)
        if r0 >= r1 or c0 >= c1:
            return clear
    clear[r0:r1, c0:c1] |= low_furniture_cells(grid.crop(r0, r1, c0, c1), boxes, tops, camera_height)
    return clear
