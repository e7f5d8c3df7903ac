"""A frontier's safe standoff goal computed on a window of the map around it, not the map.

:class:`.gain.Standoffs` runs two distance transforms over the whole map (how far each
cell is from anything occupied or unknown, then the nearest safe cell to every cell). A
frontier's goal, though, depends only on the map near it, and :mod:`.decision_cache`
keeps it until that part changes. Why a window gives the same goal, bit for bit:

OpenCV's 5x5 distance transform (with or without labels) is two raster passes; each
value is the length of a chain of mask steps from a zero pixel, the minimum over the
chains the passes allow, ties broken by a fixed neighbour order. Every step costs at
least the Chebyshev distance it moves (1, 1.4 and 2.1969 per 1, 1 and 2 cells), so a
chain that leaves a window and comes back to a pixel ``d`` cells inside it is at least
``d`` long. Outside the map the transform sees nothing; cutting a window out of the map
only removes chains, so a window value is never smaller, and it is equal, with the same
label, wherever the full value is shorter than the distance to the window's cut edges
(by induction over the pass order: a neighbour that wins or ties there is itself such a
pixel). Hence, with margins ``room`` (the clearance, plus 3 cells) and ``near`` (the
standoff, plus 2 cells):

* the clearance test ``room >= clearance`` is the same on every cell at least ``room``
  cells from a cut edge (a value that differs is at least that long, so both pass);
* the nearest safe cell within ``max_standoff`` is the same for the frontier's cells,
  which lie ``room + near`` cells inside the window: its chain is shorter than ``near``,
  and safe cells wrongly set in the outer ``room`` band are farther than that;
* the sight line from a frontier cell to its safe cell (:func:`nearest_in_sight`) is
  shorter than ``max_standoff``, so it lies inside the window.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from bomc_bt.exploration.frontiers import Frontier
from bomc_bt.grid import OccupancyGrid

StandoffResult = tuple[tuple[float, float], tuple[float, float]] | None


def standoff_margin(resolution: float, clearance: float, max_standoff: float) -> int:
    """Cells the window reaches beyond the frontier's cells (module docstring)."""
    return int(math.ceil(clearance / resolution)) + 3 + int(math.ceil(max_standoff / resolution)) + 2


def window_standoff(grid: OccupancyGrid, component: np.ndarray, factor: int, clearance: float,
                    max_standoff: float, frontier: Frontier, window: tuple[int, int, int, int]) -> StandoffResult:
    """:meth:`.gain.Standoffs.goal` of ``frontier`` from rows ``r0:r1``, cols ``c0:c1`` of
    the map (``window``, at least :func:`standoff_margin` around the frontier's cells)."""
    r0, r1, c0, c1 = window
    res = grid.resolution
    sub = grid.data[r0:r1, c0:c1]
    blocked = (sub >= 50) | (sub < 0)  # grid.occupied_mask() | grid.unknown_mask()
    room = cv2.distanceTransform((~blocked).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
    room = room * res - 0.5 * res
    safe = _on_component(component, factor, r0, r1, c0, c1) & (room >= clearance)
    if not safe.any():
        return None
    dist, labels = cv2.distanceTransformWithLabels((~safe).astype(np.uint8), cv2.DIST_L2,
                                                   cv2.DIST_MASK_5, labelType=cv2.DIST_LABEL_PIXEL)
    rows, cols = frontier.cells[:, 0] - r0, frontier.cells[:, 1] - c0
    ok = dist[rows, cols] * res <= max_standoff
    if not ok.any():
        return None
    rows, cols = rows[ok], cols[ok]
    srows, scols = np.nonzero(safe)
    index = np.zeros(int(labels.max()) + 1, dtype=np.int64)
    index[labels[srows, scols]] = np.arange(srows.size)
    k = index[labels[rows, cols]]
    i = nearest_in_sight(sub >= 50, rows, cols, srows[k], scols[k], grid.cell_to_world(rows + r0, cols + c0),
                         frontier.centroid)
    if i is None:
        return None
    gx, gy = grid.cell_to_world(srows[k[i]] + r0, scols[k[i]] + c0)
    xs, ys = grid.cell_to_world(rows[i] + r0, cols[i] + c0)
    return (float(gx), float(gy)), (float(xs), float(ys))


def nearest_in_sight(occupied: np.ndarray, rows: np.ndarray, cols: np.ndarray, goal_rows: np.ndarray,
                     goal_cols: np.ndarray, cell_xy: tuple[np.ndarray, np.ndarray],
                     centroid: tuple[float, float]) -> int | None:
    """Of the frontier cells (``rows``, ``cols``, at ``cell_xy`` in the world), the one
    nearest ``centroid`` whose safe cell (``goal_rows``, ``goal_cols``) sees it: no occupied
    cell on the straight line between them. None when no cell's does.

    The nearest safe cell is nearest in a straight line, through walls. A frontier in a
    strip narrower than the robot's standoff clearance (the 0.7 m strip between a building
    and the map's edge) has its nearest safe cell in the room on the other side of the
    wall: the lidar sees nothing of the strip from there, the view's gain is a sliver, and
    the strip was never explored (docs/exploration.md 7.16). Without a safe cell in sight
    the frontier falls back to its own cell (:func:`.explorer.frontier_target`).
    """
    sees = in_sight(occupied, rows, cols, goal_rows, goal_cols)
    if not sees.any():
        return None
    xs, ys = cell_xy
    d2 = (xs - centroid[0]) ** 2 + (ys - centroid[1]) ** 2
    return int(np.argmin(np.where(sees, d2, np.inf)))


def in_sight(occupied: np.ndarray, rows: np.ndarray, cols: np.ndarray, rows_b: np.ndarray,
             cols_b: np.ndarray) -> np.ndarray:
    """Bool per pair of cells: no occupied cell on the straight line between them (sampled
    every quarter cell). The many-pairs, cell-index form of :func:`bomc_bt.node_sight.line_of_sight`,
    and unlike it unknown cells do not block: the frontier cell borders unknown space."""
    span = np.maximum(np.abs(rows_b - rows), np.abs(cols_b - cols))
    steps = int(4 * span.max()) + 1 if span.size else 1
    t = np.linspace(0.0, 1.0, steps + 1)[None, :]
    r = np.floor(rows[:, None] + t * (rows_b - rows)[:, None] + 0.5).astype(np.int64)
    c = np.floor(cols[:, None] + t * (cols_b - cols)[:, None] + 0.5).astype(np.int64)
    return ~occupied[r, c].any(axis=1)


def _on_component(component: np.ndarray, factor: int, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
    """The planner's reachable area (at ``factor`` map cells per planning cell) over the window."""
    rows, cols = np.arange(r0, r1) // factor, np.arange(c0, c1) // factor
    out = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    rin, cin = rows < component.shape[0], cols < component.shape[1]
    out[np.ix_(rin, cin)] = component[np.ix_(rows[rin], cols[cin])]
    return out
