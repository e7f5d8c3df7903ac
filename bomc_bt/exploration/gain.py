"""Where to stand to see a frontier, how much that view would add, and how far it is to drive.

Three measurements the ``gain`` explorer (:mod:`.choice`) ranks frontiers with:

* **Safe standoff** (:class:`Standoffs`): the goal sent to navigation is a cell of the
  planner's reachable area at least ``clearance`` metres from every occupied *and every
  unknown* cell, as near the frontier as possible and in sight of it. Measured on
  generated offices, every failed exploration goal was "goal is inside an obstacle"
  (issue 16): a goal on the frontier itself, or one only ``clearance`` from known walls,
  lies next to unknown space; when the lidar revealed a wall or a chair there, the goal
  fell inside the planner's lethal zone and failed (75 of 100 failures on a 50 x 45 m office, median
  1.6 m from it), or the planner's coarser clearance already refused it (the other 25).
  A goal kept ``clearance`` from the unknown cannot be invalidated by what the unknown
  hides, and the lidar (25 m) sees into the unknown from there just as well.
* **Information gain** (:func:`visible_unknown`): the unknown area the lidar would see
  from the goal, by casting rays over the live map (unknown is transparent, occupied
  stops a ray) up to ``radius``. Frontier length, which explore_lite and DWFE use, says
  nothing about what lies behind: a long frontier along a shelf's shadow hides a few
  square decimetres, a one-metre doorway hides a room.
* **Path distance** (:func:`path_distances`): Dijkstra over the planner's traversable
  area from the robot, stopped as soon as no unreached goal can beat the best reached one
  (an A*-style bound with the straight line as the optimistic distance). Straight-line
  distance sends the robot to the frontier behind the wall, 30 m away by corridor.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.exploration.frontiers import Frontier
from bomc_bt.exploration.reachability import Reachability
from bomc_bt.exploration.standoff_window import nearest_in_sight
from bomc_bt.grid import OccupancyGrid

_SQRT2 = math.sqrt(2.0)


class Standoffs:
    """Safe goal cells near frontiers on one map snapshot (see module docstring)."""

    def __init__(self, grid: OccupancyGrid, reach: Reachability, clearance: float, max_standoff: float):
        self.grid = grid
        self.max_standoff = max_standoff
        self.occupied = grid.occupied_mask()
        blocked = self.occupied | grid.unknown_mask()
        room = cv2.distanceTransform((~blocked).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
        room = room * grid.resolution - 0.5 * grid.resolution
        f = reach.factor
        on_component = np.kron(reach.component, np.ones((f, f), dtype=bool))[:grid.height, :grid.width]
        safe = np.zeros(grid.data.shape, dtype=bool)
        safe[:on_component.shape[0], :on_component.shape[1]] = on_component
        safe &= room >= clearance
        self.any = bool(safe.any())
        # For every cell, the nearest safe cell (distance and flat index): one pass.
        dist, labels = cv2.distanceTransformWithLabels((~safe).astype(np.uint8), cv2.DIST_L2,
                                                       cv2.DIST_MASK_5, labelType=cv2.DIST_LABEL_PIXEL)
        rows, cols = np.nonzero(safe)
        index = np.zeros(int(labels.max()) + 1, dtype=np.int64)
        index[labels[rows, cols]] = rows * grid.width + cols
        self.dist = dist * grid.resolution
        self.nearest_flat = index[labels]

    def goal(self, frontier: Frontier) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """(goal, anchor): the safe cell nearest the frontier cell closest to its centroid
        among those that have one within ``max_standoff`` in sight
        (:func:`.standoff_window.nearest_in_sight`); None when no cell has."""
        if not self.any:
            return None
        rows, cols = frontier.cells[:, 0], frontier.cells[:, 1]
        ok = self.dist[rows, cols] <= self.max_standoff
        if not ok.any():
            return None
        rows, cols = rows[ok], cols[ok]
        xs, ys = self.grid.cell_to_world(rows, cols)
        flat = self.nearest_flat[rows, cols]
        i = nearest_in_sight(self.occupied, rows, cols, flat // self.grid.width, flat % self.grid.width,
                             (xs, ys), frontier.centroid)
        if i is None:
            return None
        gx, gy = self.grid.cell_to_world(flat[i] // self.grid.width, flat[i] % self.grid.width)
        return (float(gx), float(gy)), (float(xs[i]), float(ys[i]))


def ray_offsets(radius: float, resolution: float, rays: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample offsets (rays, steps) in cells along ``rays`` directions, every two cells, and
    each sample's share of the disc's area in m² (``r * dtheta * dr``), for :func:`visible_unknown`.
    (:func:`visible_unknown` thickens walls by a cell first, so a two-cell step never skips one.)"""
    step = 2.0 * resolution
    r = np.arange(0.5 * step, radius, step)
    theta = np.linspace(0.0, 2.0 * math.pi, rays, endpoint=False)
    dx = np.cos(theta)[:, None] * r[None, :] / resolution
    dy = np.sin(theta)[:, None] * r[None, :] / resolution
    weight = np.broadcast_to(r * (2.0 * math.pi / rays) * step, dx.shape)
    return dy, dx, weight


def _rays(grid: OccupancyGrid, points, radius: float, rays: int):
    """(visible unknown samples, their area weights), samples (points, rays, steps)."""
    dr, dc, weight = ray_offsets(radius, grid.resolution, rays)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    prow, pcol = grid.world_to_cell(pts[:, 0], pts[:, 1])
    rows = np.floor(prow[:, None, None] + 0.5 + dr[None]).astype(np.int64)
    cols = np.floor(pcol[:, None, None] + 0.5 + dc[None]).astype(np.int64)
    inside = (rows >= 0) & (rows < grid.height) & (cols >= 0) & (cols < grid.width)
    rc, cc = np.clip(rows, 0, grid.height - 1), np.clip(cols, 0, grid.width - 1)
    walls = cv2.dilate(grid.occupied_mask().view(np.uint8), np.ones((3, 3), np.uint8))
    values = grid.data[rc, cc]
    blocked = np.maximum.accumulate(~inside | (walls[rc, cc] > 0), axis=2)
    return (values < 0) & ~blocked, weight


def visible_unknown(grid: OccupancyGrid, points: list[tuple[float, float]], radius: float,
                    rays: int = 72) -> np.ndarray:
    """Unknown area (m²) visible within ``radius`` of each point: rays stop at the first
    occupied cell (or the map edge), unknown cells let them pass (the optimistic view)."""
    if not points:
        return np.zeros(0)
    seen, weight = _rays(grid, points, radius, rays)
    return (seen * weight[None]).sum(axis=(1, 2))


def path_distances(reach: Reachability, robot_xy: tuple[float, float], goals: list[tuple[float, float]],
                   value: np.ndarray, offset: float, heading: Heading | None = None) -> list[float]:
    """Cost (m) from the robot to each goal over the planner's reachable area: the path
    length plus, with ``heading``, the turn on the spot before it (:class:`Heading`); as
    far as needed to know the goal with the best ``value / (cost + offset)``; goals not
    needed keep a lower bound of their cost (they are then known not to win), unreachable
    goals get infinity.

    The search stops once even the straight-line distance cannot make an unreached goal
    beat the best reached one (checked every half metre of search radius, vectorised), so
    a decision costs a neighbourhood, not the building.
    """
    res = reach.grid.resolution * reach.factor
    comp = reach.component
    h, w = comp.shape
    value = np.asarray(value, dtype=float)
    cells = [tuple(int(v) // reach.factor for v in reach.grid.world_to_cell(*g)) for g in goals]
    straight = np.array([math.dist(robot_xy, g) for g in goals])
    out = straight.tolist()
    start = _start(comp, reach, robot_xy)
    if start is None or not goals:
        return out
    wp = w + 2
    targets: dict[int, list[int]] = {}  # goals by their cell's index on the padded grid
    for i, (r, c) in enumerate(cells):
        if 0 <= r < h and 0 <= c < w:
            targets.setdefault((r + 1) * wp + c + 1, []).append(i)
    open_goals = np.ones(len(goals), dtype=bool)
    still_open = len(goals)  # open_goals.sum(), kept as a count: the loop tests it at every cell
    best, next_check = -math.inf, 0.0
    ok = np.pad(comp, 1, constant_values=False).ravel().tolist()
    moves = ((1, 1.0), (-1, 1.0), (wp, 1.0), (-wp, 1.0), (wp + 1, _SQRT2), (wp - 1, _SQRT2),
             (-wp + 1, _SQRT2), (-wp - 1, _SQRT2))
    s = (start[0] + 1) * wp + start[1] + 1
    dist = {s: 0.0}
    heap = [(0.0, s)]
    pop, push, known, inf = heapq.heappop, heapq.heappush, dist.get, math.inf  # locals: the loop is hot
    while heap and still_open:
        d, i = pop(heap)
        if d > known(i, inf):
            continue
        metres = d * res
        if best > -math.inf and metres >= next_check:
            next_check = metres + 0.5
            bound = value[open_goals] / (np.maximum(straight[open_goals], metres) + offset)
            if bound.max() <= best:
                heapq.heappush(heap, (d, i))
                break
        for k in targets.get(i, ()):
            out[k] = max(metres, straight[k] - res)
            if heading is not None:
                out[k] += heading.turn_cost(_first_leg(dist, i, s, wp, moves, heading.lead / res), res, wp)
            still_open -= bool(open_goals[k])
            open_goals[k] = False
            best = max(best, value[k] / (out[k] + offset))
        for step, length in moves:
            j = i + step
            if ok[j]:
                nd = d + length
                if nd < known(j, inf):
                    dist[j] = nd
                    push(heap, (nd, j))
    for k in np.flatnonzero(open_goals):
        out[k] = max(out[k], heap[0][0] * res) if heap else math.inf
    return out


@dataclass
class Heading:
    """The robot's heading and what turning costs, for :func:`path_distances`.

    A goal behind the robot costs more than its path: the base turns on the spot before
    it drives (issue 16: on the small shared floors the gain explorer spent 7.6 s of its
    first 95 % turning on the spot against the baseline's 3.4 s, re-deciding towards
    near goals behind it). ``per_radian`` is the path the robot would have driven in the
    time one radian of turn on the spot takes (max speed / max turn rate); only the turn
    beyond ``free_turn`` (what the base turns while driving) costs.
    """

    yaw: float  # [rad] the robot's heading
    per_radian: float  # [m] path-equivalent of one radian turned on the spot
    free_turn: float  # [rad] heading error the base turns away while driving
    lead: float = 1.0  # [m] how far along the path its first direction is taken

    def turn_cost(self, leg: tuple[int, int], res: float, wp: int) -> float:
        dr, dc = leg
        if dr == 0 and dc == 0:
            return 0.0
        error = abs((math.atan2(dr, dc) - self.yaw + math.pi) % (2.0 * math.pi) - math.pi)
        return self.per_radian * max(0.0, error - self.free_turn)


def _first_leg(dist: dict[int, float], goal: int, start: int, wp: int, moves, lead_cells: float) -> tuple[int, int]:
    """(rows, cols) from the start to the point ``lead_cells`` along the shortest path to
    ``goal``, found by descending the search's distances from the goal."""
    i = goal
    while dist[i] > lead_cells:
        j = min((i + step for step, _ in moves if i + step in dist), key=dist.__getitem__)
        if dist[j] >= dist[i]:
            break  # a start cell of the search: the path begins here
        i = j
    return i // wp - start // wp, i % wp - start % wp


def _start(comp: np.ndarray, reach: Reachability, robot_xy: tuple[float, float]) -> tuple[int, int] | None:
    """The robot's planning cell, or the nearest cell of the reachable area within 1 m."""
    row, col = (int(v) // reach.factor for v in reach.grid.world_to_cell(*robot_xy))
    h, w = comp.shape
    if 0 <= row < h and 0 <= col < w and comp[row, col]:
        return row, col
    r0, c0 = max(row - 10, 0), max(col - 10, 0)
    rr, cc = np.nonzero(comp[r0:row + 11, c0:col + 11])
    if rr.size == 0:
        return None
    k = int(np.argmin((rr + r0 - row) ** 2 + (cc + c0 - col) ** 2))
    return int(rr[k] + r0), int(cc[k] + c0)
