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
  and safe cells wrongly set in the outer ``room`` band are farther than that.
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
    xs, ys = grid.cell_to_world(rows + r0, cols + c0)
    cx, cy = frontier.centroid
    i = int(np.argmin((xs - cx) ** 2 + (ys - cy) ** 2))
    srows, scols = np.nonzero(safe)
    index = np.zeros(int(labels.max()) + 1, dtype=np.int64)
    index[labels[srows, scols]] = np.arange(srows.size)
    k = index[labels[rows[i], cols[i]]]
    gx, gy = grid.cell_to_world(srows[k] + r0, scols[k] + c0)
    return (float(gx), float(gy)), (float(xs[i]), float(ys[i]))


def _on_component(component: np.ndarray, factor: int, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
    """The planner's reachable area (at ``factor`` map cells per planning cell) over the window."""
    rows, cols = np.arange(r0, r1) // factor, np.arange(c0, c1) // factor
    out = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    rin, cin = rows < component.shape[0], cols < component.shape[1]
    out[np.ix_(rin, cin)] = component[np.ix_(rows[rin], cols[cin])]
    return out
