"""Global path planning on an occupancy grid: A* with clearance costs, like navfn.

Why this shape: the planner runs inside the simulator's step loop and inside behaviours
(reachability, traversal plans), so it must be fast in pure Python + numpy. Everything
per cell is precomputed once per map with OpenCV (a Euclidean distance transform gives
clearance, from which lethal cells and a decaying inflation cost follow, as in a ROS
costmap with ``inflation_radius``); the search itself walks flat Python lists on a
planning grid coarser than the map (0.1 m by default), with a one-cell blocked border
so neighbour indices never wrap. The raw grid path is then shortened by line-of-sight
smoothing that never trades away clearance (:mod:`bomc_bt.path_smoothing`); the
clearance itself comes from :mod:`bomc_bt.costmap`.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable

import cv2
import numpy as np

from bomc_bt.algorithm_params import PlannerParams
from bomc_bt.costmap import clearance_fields, grid_clearance
from bomc_bt.grid import UNKNOWN, OccupancyGrid
from bomc_bt.path_smoothing import smooth_cells
from bomc_bt.polyline import dedupe_waypoints, path_clear_of, path_length

# path_clear_of and path_length live in bomc_bt.polyline; the simulator imports them from here.
__all__ = ["DrivenLengths", "GridPlanner", "PlannerParams", "path_clear_of", "path_length"]

_SQRT2 = math.sqrt(2.0)


class GridPlanner:
    """Plans on one snapshot of a grid; build a new planner when the map changes."""

    def __init__(self, grid: OccupancyGrid, params: PlannerParams | None = None,
                 extra_obstacles: np.ndarray | None = None):
        self.params = params or PlannerParams()
        self.grid = grid
        factor = max(1, int(round(self.params.resolution / grid.resolution)))
        self.factor = factor
        self.resolution = grid.resolution * factor
        if extra_obstacles is not None:
            if extra_obstacles.shape != grid.data.shape:
                raise ValueError("extra_obstacles must have the grid's shape")
            clearance, unknown = clearance_fields(grid.occupied_mask() | extra_obstacles, grid.unknown_mask(),
                                                  grid.resolution, factor)
        else:
            clearance, unknown = grid_clearance(grid, factor)
        p = self.params
        lethal = clearance < p.robot_radius
        if not p.allow_unknown:
            lethal |= unknown
        span = max(p.inflation_radius - p.robot_radius, 1e-9)
        penalty = p.cost_weight * np.clip((p.inflation_radius - clearance) / span, 0.0, 1.0) ** 2
        # Interior of the padded planning grid; row 0 / col 0 of the arrays are the border.
        self.shape = lethal.shape  # unpadded (rows, cols)
        self.lethal = lethal
        self.clearance = clearance
        self._cost_array = np.where(lethal, np.inf, 1.0 + penalty)
        padded = np.pad(self._cost_array, 1, constant_values=np.inf)
        self._w = padded.shape[1]
        self._cost = padded.ravel().tolist()
        w = self._w
        self._moves = ((1, 1.0), (-1, 1.0), (w, 1.0), (-w, 1.0),
                       (w + 1, _SQRT2), (w - 1, _SQRT2), (-w + 1, _SQRT2), (-w - 1, _SQRT2))
        data = np.where(lethal, 100, 0).astype(np.int8)
        data[unknown & ~lethal] = -1
        self.planning_grid = OccupancyGrid(data, self.resolution, tuple(grid.origin))
        self._labels: np.ndarray | None = None
        self._fine: np.ndarray | None = None
        self._unreached: list[float] | None = None  # distances_from's start: -1 lethal, inf the rest

    # -- coordinates ---------------------------------------------------------------------
    def cell(self, xy) -> tuple[int, int]:
        """Planning-grid (row, col) of a map-frame point (may be out of bounds)."""
        r, c = self.planning_grid.world_to_cell(xy[0], xy[1])
        return int(r), int(c)

    def _centre(self, r: int, c: int) -> np.ndarray:
        x, y = self.planning_grid.cell_to_world(r, c)
        return np.array([float(x), float(y)])

    def _inside(self, r: int, c: int) -> bool:
        return 0 <= r < self.shape[0] and 0 <= c < self.shape[1]

    def traversable(self, xy) -> bool:
        """True when the robot's centre may be at ``xy``."""
        r, c = self.cell(xy)
        return self._inside(r, c) and not bool(self.lethal[r, c])

    def _nearest_traversable(self, xy, radius: float, visible: bool = False) -> tuple[int, int] | None:
        """The traversable planning cell nearest to ``xy`` within ``radius`` metres."""
        r0, c0 = self.cell(xy)
        k = int(math.ceil(radius / self.resolution)) + 1
        rlo, rhi = max(r0 - k, 0), min(r0 + k + 1, self.shape[0])
        clo, chi = max(c0 - k, 0), min(c0 + k + 1, self.shape[1])
        if rlo >= rhi or clo >= chi:
            return None
        rows, cols = np.nonzero(~self.lethal[rlo:rhi, clo:chi])
        if rows.size == 0:
            return None
        x, y = self.planning_grid.cell_to_world(rows + rlo, cols + clo)
        d = np.hypot(x - xy[0], y - xy[1])
        for i in np.argsort(d, kind="stable"):
            if d[i] > radius + 1e-9:
                return None
            if not visible or self._in_sight(xy, (float(x[i]), float(y[i]))):
                return int(rows[i] + rlo), int(cols[i] + clo)
        return None

    def _in_sight(self, a, b) -> bool:
        """Whether the robot can drive the straight line from ``a`` to ``b``: it crosses
        only known free map cells (the cell ``a`` lies in aside, and where ``a`` lies on unknown
        map the unknown cells the line starts with, within ``robot_radius``), and nowhere comes nearer
        a wall than the robot at ``a`` is (or :attr:`PlannerParams.squeeze_radius`, if
        less), less one map cell.

        A start inside the inflated zone (a strip 0.7 m wide along a one-cell wall) is
        planned from the nearest traversable cell: without this test that cell could lie
        behind the wall, and the robot drove into the wall for good (hospital, issue 16).
        A wall seen at grazing angles is mapped with one-cell holes, unknown or free (the
        hospital's bottom wall also has one-cell gaps in the map image itself): a line
        through such a hole put the start behind the wall again (hospital, 20-start draw,
        gain start 16: 150 s pushing into the wall, then `stuck`).

        A robot can stand on cells the saved map holds unknown: the lidar shadow a table
        cast while the map was built, which the pass's obstacle layer saw free and planned
        through. The cells under it are free whatever the map says, so a line may start
        through them; without that, every later goal failed at once (generated 36 x 28 m
        office, seed 7911, pass 8: a viewpoint reached at the tip of a table's shadow, and
        the pass ended there, "boxed in", with 47 % of the floor seen).
        """
        length = math.hypot(b[0] - a[0], b[1] - a[1])
        n = max(2, int(math.ceil(length / (0.5 * self.grid.resolution))) + 1)
        rows, cols = self.grid.world_to_cell(np.linspace(a[0], b[0], n), np.linspace(a[1], b[1], n))
        inside = self.grid.in_bounds(rows, cols)
        rows, cols = rows[inside], cols[inside]
        if len(rows) == 0:
            return True
        away = (rows != rows[0]) | (cols != cols[0])
        cells = self.grid.data[rows, cols]
        passable = cells == 0
        if cells[0] == UNKNOWN:  # standing where the saved map is unknown: what is under the robot is free
            under = np.linspace(0.0, length, n)[inside] <= self.params.robot_radius
            passable |= np.cumprod(under & (cells == UNKNOWN)).astype(bool)
        if not (passable | ~away).all():
            return False
        room = self._fine_clearance()[rows, cols]
        return bool(room.min() >= min(room[0], self.params.squeeze_radius) - self.grid.resolution)

    def _fine_clearance(self) -> np.ndarray:
        """Metres from each map cell to the nearest occupied one (computed once, on demand)."""
        if self._fine is None:
            free = (~self.grid.occupied_mask()).astype(np.uint8)
            self._fine = cv2.distanceTransform(free, cv2.DIST_L2, 5) * self.grid.resolution
        return self._fine

    def nearest_traversable(self, xy, radius: float, visible: bool = False) -> np.ndarray | None:
        """``xy`` itself when traversable, else the nearest traversable cell centre within
        ``radius`` metres (``visible``: in a straight line that crosses no occupied cell),
        else None (how a lethal goal is judged)."""
        cell = self._endpoint(np.asarray(xy, dtype=float)[:2], radius, visible)
        if cell is None:
            return None
        return np.asarray(xy, dtype=float)[:2] if self.traversable(xy) else self._centre(*cell)

    def path_is_clear(self, path: np.ndarray, skip: float = 0.0) -> bool:
        """Whether every point of a polyline (sampled at half the planning resolution) is
        traversable, ignoring the first ``skip`` metres (the robot may be hugging a wall)."""
        path = np.asarray(path, dtype=float)
        if len(path) == 0:
            return True
        seg = np.diff(path, axis=0)
        lengths = np.hypot(seg[:, 0], seg[:, 1])
        total = float(lengths.sum())
        s = np.arange(skip, total, 0.5 * self.resolution)
        if len(s) == 0:
            return True
        cum = np.concatenate([[0.0], np.cumsum(lengths)])
        x = np.interp(s, cum, path[:, 0])
        y = np.interp(s, cum, path[:, 1])
        r, c = self.planning_grid.world_to_cell(x, y)
        inside = (r >= 0) & (r < self.shape[0]) & (c >= 0) & (c < self.shape[1])
        if not inside.all():
            return False
        return not bool(self.lethal[r, c].any())

    def _endpoint(self, xy, radius: float, visible: bool = False) -> tuple[int, int] | None:
        r, c = self.cell(xy)
        if self._inside(r, c) and not self.lethal[r, c]:
            return r, c
        return self._nearest_traversable(xy, radius, visible)

    # -- search --------------------------------------------------------------------------
    def plan(self, start_xy, goal_xy) -> np.ndarray | None:
        """Waypoints (N, 2) from start to goal, or None when the goal is unreachable.

        A lethal start (robot hugging a wall) escapes to the nearest traversable cell
        within ``escape_radius``; a lethal goal moves to the nearest traversable cell
        within ``goal_tolerance`` (the last waypoint is then that cell's centre).
        """
        start_xy = np.asarray(start_xy, dtype=float)[:2]
        goal_xy = np.asarray(goal_xy, dtype=float)[:2]
        s = self._endpoint(start_xy, self.params.escape_radius, visible=True)
        g = self._endpoint(goal_xy, self.params.goal_tolerance)
        if s is None or g is None:
            return None
        if not self.connected(s, g):
            return None
        cells = self._astar(s, g)
        if cells is None:
            return None
        cells = smooth_cells(cells, self._last_costs, self._cost_array)
        middle = [self._centre(r, c) for r, c in cells[1:-1]]
        head = [start_xy] if self.traversable(start_xy) else [start_xy, self._centre(*cells[0])]
        tail = [goal_xy] if self.traversable(goal_xy) else [self._centre(*cells[-1])]
        pts = head + middle + tail
        return dedupe_waypoints(np.array(pts, dtype=float))

    def connected(self, a: tuple[int, int], b: tuple[int, int]) -> bool:
        """Whether two traversable planning cells are in the same 8-connected component.

        One OpenCV labelling per planner answers unreachable goals at once, instead of an
        A* search that exhausts the whole component first.
        """
        labels = self._components()
        return bool(labels[a] == labels[b] and labels[a] != 0)

    def _components(self) -> np.ndarray:
        """8-connected labels of the traversable planning cells (0: lethal), computed once."""
        if self._labels is None:
            _, self._labels = cv2.connectedComponents((~self.lethal).astype(np.uint8), connectivity=8)
        return self._labels

    def shut_in(self, xy) -> bool:
        """Whether ``xy`` (or the traversable cell a start there escapes to) lies outside this
        planner's largest traversable component, or nowhere traversable: in a pocket its
        clearance cannot leave, such as a room the navigator squeezed into through a doorway
        narrower than ``robot_radius`` allows."""
        s = self._endpoint(np.asarray(xy, dtype=float)[:2], self.params.escape_radius)
        if s is None:
            return True
        labels = self._components()
        sizes = np.bincount(labels.ravel())
        sizes[0] = 0  # the lethal cells
        return int(labels[s]) != int(np.argmax(sizes))

    def distance(self, start_xy, goal_xy) -> float:
        """Length (m) of the planned path, inf when unreachable."""
        path = self.plan(start_xy, goal_xy)
        return math.inf if path is None else path_length(path)

    def _flat(self, r: int, c: int) -> int:
        return (r + 1) * self._w + (c + 1)

    def _unflat(self, i: int) -> tuple[int, int]:
        return i // self._w - 1, i % self._w - 1

    def _astar(self, s: tuple[int, int], g: tuple[int, int]) -> list[tuple[int, int]] | None:
        """Weighted A* with the octile heuristic (every step costs at least its length).

        The heuristic is evaluated for a cell when the search first reaches it (the same
        expression, in the same order, as a numpy pass over the grid would evaluate), so a
        short plan on a building-sized map does not pay for a heuristic of every cell.
        """
        w, cost, moves = self._w, self._cost, self._moves
        start, goal = self._flat(*s), self._flat(*g)
        goal_row, goal_col = divmod(goal, w)
        row_gap = [abs(r - goal_row) for r in range(len(cost) // w)]  # |dr| per padded row
        col_gap = [abs(c - goal_col) for c in range(w)]
        # A hair above the weight breaks ties towards the goal (fewer expansions in the open).
        scale = self.params.heuristic_weight * (1.0 + 1e-3)
        diagonal = _SQRT2 - 2.0
        inf = math.inf
        best = [inf] * len(cost)
        closed = [False] * len(cost)
        best[start] = 0.0
        self._last_costs: list[float] = []  # cost-to-come along the returned path
        parent: dict[int, int] = {start: -1}
        heap = [(0.0, 0.0, start)]
        push, pop = heapq.heappush, heapq.heappop
        while heap:
            _, gs, i = pop(heap)
            if i == goal:
                out = []
                while i != -1:
                    out.append(self._unflat(i))
                    self._last_costs.append(best[i])
                    i = parent[i]
                self._last_costs.reverse()
                return out[::-1]
            if closed[i]:
                continue
            closed[i] = True  # no re-expansion: weighted A* stays fast (bounded suboptimality)
            for step, length in moves:
                j = i + step
                ng = gs + length * cost[j]
                if ng < best[j] and not closed[j]:
                    best[j] = ng
                    parent[j] = i
                    row, col = divmod(j, w)
                    dr, dc = row_gap[row], col_gap[col]
                    push(heap, (ng + (dr + dc + diagonal * (dr if dr < dc else dc)) * scale, ng, j))
        return None

    def distances_from(self, start_xy) -> np.ndarray:
        """Path length (m) from ``start_xy`` to every planning cell; inf where unreachable.

        Geometric length along 8-connected traversable cells (no clearance cost), so it
        answers "how far would I drive" for reachability and traversal ordering. Index it
        with :meth:`cell` or :meth:`lookup`.
        """
        out = np.full(self.shape, np.inf)
        s = self._endpoint(np.asarray(start_xy, dtype=float)[:2], self.params.escape_radius)
        if s is None:
            return out
        w, moves = self._w, self._moves
        if self._unreached is None:  # lethal cells at -1: no path improves them, no test per step
            self._unreached = [-1.0 if c == math.inf else math.inf for c in self._cost]
        start = self._flat(*s)
        best = list(self._unreached)
        best[start] = 0.0
        heap = [(0.0, start)]
        push, pop = heapq.heappush, heapq.heappop
        while heap:
            d, i = pop(heap)
            if d > best[i]:
                continue
            for step, length in moves:
                j = i + step
                nd = d + length
                if nd < best[j]:
                    best[j] = nd
                    push(heap, (nd, j))
        field = np.asarray(best).reshape(-1, w)[1:-1, 1:-1]
        field[field < 0.0] = np.inf
        return field * self.resolution

    def path_lengths_from(self, start_xy) -> Callable[[np.ndarray], np.ndarray]:
        """A function giving the path lengths (m) from ``start_xy`` to points (K, 2).

        One :meth:`distances_from` field, looked up per point: what the refresh tour
        (:mod:`bomc_bt.refresh`) prices its stops with.
        """
        field = self.distances_from(start_xy)
        return lambda points: np.array([self.lookup(field, p) for p in np.asarray(points).reshape(-1, 2)])

    def lookup(self, field: np.ndarray, xy) -> float:
        """Value of a planning-grid field (e.g. from :meth:`distances_from`) at ``xy``."""
        r, c = self.cell(xy)
        return float(field[r, c]) if self._inside(r, c) else math.inf


class DrivenLengths:
    """Path lengths from a start as the robot drives them (a :data:`bomc_bt.refresh.DistanceField`).

    On the planner's clearance, as every plan is made; but from a start the planner sees
    shut in a pocket (:meth:`GridPlanner.shut_in`), on ``squeeze_radius``, the clearance the
    navigator falls back on to leave it (``bomc_bt.sim.planning.SimPlanners.squeeze``).
    Without this, a robot that ended a pass's gap viewpoints in a room it had squeezed into
    (willow at 0.1 m: a pocket of 4.3 m² at 0.3 m of clearance, joined to the floor at 0.25 m)
    found 2 of the 253 places it had reached reachable, and the refresh tour planned no stop.
    """

    def __init__(self, grid: OccupancyGrid, params: PlannerParams):
        self.planner = GridPlanner(grid, params)
        self._grid = grid
        self._squeeze: GridPlanner | None = None

    def __call__(self, start_xy) -> Callable[[np.ndarray], np.ndarray]:
        planner, squeezed = self.planner, self.planner.params.squeezed()
        if squeezed is not None and planner.shut_in(start_xy):
            if self._squeeze is None:
                self._squeeze = GridPlanner(self._grid, squeezed)
            planner = self._squeeze
        return planner.path_lengths_from(start_xy)
