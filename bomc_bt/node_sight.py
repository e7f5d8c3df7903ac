"""Whether a place sees a node of the graph: a line the camera sees along, to a face of its object.

The pass asks it wherever it plans a look at a node it already knows: the headings Look
Around turns to (:func:`~bomc_bt.monitoring.unverified_headings`), whether a missed node is
in front of the robot (:func:`~bomc_bt.look_around.pending_in_front`), which reached
places a refresh stop may stand at (:mod:`bomc_bt.refresh`), and which floor shows a known
node to the coverage plan (:mod:`bomc_bt.coverage_known`).

A node's centre is inside its object, whose own cells (occupied, or unknown in its lidar
shadow) would hide it, so the first rule tested the line only up to half a metre short of
the centre (:func:`sees_node`). Objects stand against walls: a door on one face of a
wall, a table pushed against one. Half a metre short of such a centre lies on the wall's
other side, so every place behind the wall "saw" it. Planned against the nodes of five
36 x 28 m offices after twelve passes, on their built maps (reached places 0.5 m apart,
nodes within 5 m; ``benchmarks/bench_node_sight.py``), 15-20 % of the
pairs that rule counted as in sight had a wall between the place and every face of the
object, four in five of them doors; a refresh stop planned there looked at a wall and
counted nothing (session 80: a table carried off stayed on the map for a pass), and Look
Around turned to walls.

With the node's floor footprint (robust association keeps one: the box the object's
points covered, padded by noise and by depth that bled onto the wall behind) the line
goes instead to points on the outline of that box shrunk by :data:`FACE_INSET`, and
must be clear up to where it enters the box: the cells inside are the object's own (its
lidar outline). The node is in sight when one such line is: the camera sees a face. On
the same offices 3-8 % of the pairs in sight are walled off, and a fifth as many pairs
with a face in plain view are counted out of sight. A node without a footprint
(``association.mode: paper``, a first sighting) keeps the old rule.
"""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.grid import OccupancyGrid

FACE_INSET = 0.05  # m: how far inside a node's footprint the points a look must reach lie
_SIDE_POINTS = 4  # points per side of the footprint, corners included (12 in all)


def camera_clear(grid: OccupancyGrid) -> np.ndarray:
    """Cells the camera sees through on ``grid``: all but occupied ones. Furniture leaves its
    lidar shadow unknown on a map (the floor round a table pushed against a wall and the
    chair at it), and the camera, higher than the lidar, looks over what casts it; a
    look planned only along known free cells never faces such a table, and a table
    taken away from there is not seen gone."""
    return ~grid.occupied_mask()


def line_of_sight(grid: OccupancyGrid, free: np.ndarray, a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Every cell on the segment from ``a`` to ``b`` (both ends included) is in ``free``."""
    n = max(2, int(math.hypot(b[0] - a[0], b[1] - a[1]) / (grid.resolution * 0.5)))
    t = np.linspace(0.0, 1.0, n)
    rows, cols = grid.world_to_cell(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))
    inside = grid.in_bounds(rows, cols)
    return bool(inside.all() and free[rows, cols].all())


def sees_node(grid: OccupancyGrid, clear: np.ndarray, a: tuple[float, float], b: tuple[float, float],
              short: float = 0.5) -> bool:
    """:func:`line_of_sight` from ``a`` to ``short`` metres before the node at ``b``: the
    node's own cells (occupied, or unknown in its shadow) do not hide it. The rule for a
    place without a footprint; see :func:`sees_target`."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    d = math.hypot(dx, dy)
    stop = (a[0] + dx * (1 - short / d), a[1] + dy * (1 - short / d)) if d > short else a
    return line_of_sight(grid, clear, a, stop)


def face_points(footprint, inset: float = FACE_INSET) -> np.ndarray:
    """(12, 2): points on the outline of ``footprint`` (x0, y0, x1, y1) shrunk by ``inset``
    on every side (a side shorter than twice that shrinks to its middle; a negative ``inset``
    grows it, as ``benchmarks/bench_node_sight.py`` does for points just off an object's faces)."""
    x0, y0, x1, y1 = (float(v) for v in footprint)
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    x0, x1 = min(x0 + inset, cx), max(x1 - inset, cx)
    y0, y1 = min(y0 + inset, cy), max(y1 - inset, cy)
    xs, ys = np.linspace(x0, x1, _SIDE_POINTS), np.linspace(y0, y1, _SIDE_POINTS)[1:-1]
    return np.concatenate([np.stack([xs, np.full_like(xs, y0)], 1), np.stack([xs, np.full_like(xs, y1)], 1),
                           np.stack([np.full_like(ys, x0), ys], 1), np.stack([np.full_like(ys, x1), ys], 1)])


def sees_faces(grid: OccupancyGrid, clear: np.ndarray, a: tuple[float, float], footprint) -> bool:
    """Some point of :func:`face_points` has a line from ``a`` clear on ``clear`` up to where
    it enters the footprint: the cells inside are the object's own (its lidar outline,
    where the footprint is no wider than the object)."""
    ends = face_points(footprint)
    n = max(2, int(np.hypot(ends[:, 0] - a[0], ends[:, 1] - a[1]).max() / (grid.resolution * 0.5)))
    t = np.linspace(0.0, 1.0, n)[None, :]
    xs, ys = a[0] + t * (ends[:, :1] - a[0]), a[1] + t * (ends[:, 1:] - a[1])
    rows, cols = grid.world_to_cell(xs, ys)
    ok = grid.in_bounds(rows, cols).all(axis=1)
    if not ok.any():
        return False
    x0, y0, x1, y1 = (float(v) for v in footprint)
    own = (xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)
    return bool((clear[rows[ok], cols[ok]] | own[ok]).all(axis=1).any())


def sees_target(grid: OccupancyGrid, clear: np.ndarray, a: tuple[float, float], position,
                footprint=None) -> bool:
    """Whether a place at ``a`` sees the node at ``position``: a face of its ``footprint``
    (:func:`sees_faces`), or without one, :func:`sees_node`. A footprint that does not hold
    the node's own place describes some other view (93 x 90 m, one table in 400 nodes had
    its box a metre off its centre) and is not used."""
    x, y = float(position[0]), float(position[1])
    if footprint is None or not (footprint[0] <= x <= footprint[2] and footprint[1] <= y <= footprint[3]):
        return sees_node(grid, clear, a, (x, y))
    return sees_faces(grid, clear, a, footprint)
