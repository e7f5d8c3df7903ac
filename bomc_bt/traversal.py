"""The monitor mission's traversal plan: where to revisit, and in which order.

Following the paper (Environment Traversing): waypoints are sampled along the recorded
exploration trajectory so that every two are at least ``spacing`` (2 m) apart, and ordered
by the greedy nearest-neighbour TSP heuristic. The trajectory is where the robot has
already driven, so its points are reachable and saw everything the map holds; keeping a
waypoint whenever the path has moved ``spacing`` away from *all* kept ones also means
every trajectory point ends up within ``spacing`` of a waypoint (coverage).

Two choices differ from the paper, both for an operator's sake: the tour starts from the
waypoint nearest the robot (its dock), not from p1, and is an open path improved by 2-opt
(which only ever shortens it; the greedy tour's long jump back across the map is what
2-opt removes best).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from bomc_bt.algorithm_params import TraversalParams
from bomc_bt.errors import BomcError, read_input_text
from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.grid import OccupancyGrid

GridDistance = Callable[[tuple, tuple], float]


@dataclass
class TraversalPlan:
    """Waypoints in visiting order and the tour's length."""

    waypoints: list[Pose2D]
    euclidean_length: float  # m, straight lines between consecutive waypoints (from the start)
    grid_length: float | None = None  # m, along planned paths; None when not computed

    def to_json(self) -> dict:
        return {
            "waypoints": [[w.x, w.y, w.yaw] for w in self.waypoints],
            "euclidean_length": self.euclidean_length,
            "grid_length": None if self.grid_length is None or not math.isfinite(self.grid_length)
            else self.grid_length,
        }

    @classmethod
    def from_json(cls, data: dict, file: str | Path | None = None) -> TraversalPlan:
        """Read a plan written by :meth:`to_json` (errors name ``file`` and the field)."""
        if not isinstance(data, dict):
            raise BomcError("expected a mapping", file)
        raw = data.get("waypoints")
        if not isinstance(raw, list):
            raise BomcError("missing or not a list", file, "waypoints")
        waypoints = []
        for i, w in enumerate(raw):
            if not (isinstance(w, (list, tuple)) and len(w) == 3 and all(_is_number(v) for v in w)):
                raise BomcError("expected [x, y, yaw] numbers", file, f"waypoints[{i}]")
            waypoints.append(Pose2D(float(w[0]), float(w[1]), float(w[2])))
        length = data.get("euclidean_length")
        if not _is_number(length):
            raise BomcError("missing or not a number", file, "euclidean_length")
        grid = data.get("grid_length")
        if grid is not None and not _is_number(grid):
            raise BomcError("must be a number or null", file, "grid_length")
        return cls(waypoints, float(length), None if grid is None else float(grid))


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


# -- trajectory ---------------------------------------------------------------------------
def load_trajectory(csv_path: str | Path) -> np.ndarray:
    """Read ``trajectory.csv`` (header ``t,x,y,yaw``) as an (N, 4) float array."""
    path = Path(csv_path)
    text = read_input_text(path, "trajectory")
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise BomcError("empty trajectory file (expected a header t,x,y,yaw and poses)", path)
    header = [h.strip() for h in rows[0]]
    if header != ["t", "x", "y", "yaw"]:
        raise BomcError(f"line 1: expected the header t,x,y,yaw, got {','.join(header)!r}", path)
    out = []
    for lineno, row in enumerate(rows[1:], start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != 4:
            raise BomcError(f"line {lineno}: expected 4 values (t,x,y,yaw), got {len(row)}", path)
        try:
            values = [float(c) for c in row]
        except ValueError:
            raise BomcError(f"line {lineno}: not a number in {','.join(row)!r}", path) from None
        if not all(math.isfinite(v) for v in values):
            raise BomcError(f"line {lineno}: values must be finite", path)
        out.append(values)
    if not out:
        raise BomcError("no poses in the trajectory (only a header)", path)
    return np.asarray(out, dtype=float)


# -- sampling -----------------------------------------------------------------------------
def sample_waypoints(trajectory_xy: np.ndarray, spacing: float) -> np.ndarray:
    """Waypoints (M, 2) at least ``spacing`` apart along the path (see :func:`sample_indices`)."""
    xy = np.asarray(trajectory_xy, dtype=float).reshape(-1, 2)
    return xy[sample_indices(xy, spacing)]


def sample_indices(trajectory_xy: np.ndarray, spacing: float) -> np.ndarray:
    """Indices (into ``trajectory_xy``) of points kept as waypoints, in path order.

    Walks the path and keeps a point when it is at least ``spacing`` from every waypoint
    kept so far. Only kept waypoints within ``spacing`` can veto a point, so a spatial
    hash with ``spacing``-sized buckets makes each check look at 9 buckets: 10k-point
    trajectories take milliseconds. Every trajectory point ends within ``spacing`` of a
    waypoint (it was either kept or vetoed by one that close).
    """
    xy = np.asarray(trajectory_xy, dtype=float).reshape(-1, 2)
    if spacing <= 0:
        raise ValueError("spacing must be positive")
    keys = np.floor(xy / spacing).astype(np.int64)
    buckets: dict[tuple[int, int], list[int]] = {}
    kept: list[int] = []
    s2 = spacing * spacing
    for i in range(len(xy)):
        kx, ky = int(keys[i, 0]), int(keys[i, 1])
        x, y = xy[i]
        near = False
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for j in buckets.get((kx + dx, ky + dy), ()):
                    if (xy[j, 0] - x) ** 2 + (xy[j, 1] - y) ** 2 < s2:
                        near = True
                        break
                if near:
                    break
            if near:
                break
        if not near:
            kept.append(i)
            buckets.setdefault((kx, ky), []).append(i)
    return np.asarray(kept, dtype=np.int64)


# -- ordering -----------------------------------------------------------------------------
def greedy_tsp(points: np.ndarray, start_xy) -> list[int]:
    """Nearest-neighbour order, beginning at the point nearest ``start_xy``.

    The paper starts at p1, the first sampled pose; an operator expects the robot to
    begin where it stands, so the first waypoint is the one nearest the start. O(n^2)
    with one vectorised distance row per step.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(pts)
    if n == 0:
        return []
    start = np.asarray(start_xy, dtype=float)[:2]
    current = int(np.argmin(np.hypot(*(pts - start).T)))
    visited = np.zeros(n, dtype=bool)
    order = [current]
    visited[current] = True
    for _ in range(n - 1):
        d = np.hypot(*(pts - pts[current]).T)
        d[visited] = np.inf
        current = int(np.argmin(d))  # ties -> lowest index: deterministic
        visited[current] = True
        order.append(current)
    return order


def two_opt(points: np.ndarray, order: Sequence[int], distance: np.ndarray | None = None,
            max_passes: int = 20, start_xy=None) -> list[int]:
    """Improve an open path by reversing segments while that shortens it.

    ``distance`` is an optional (n, n) matrix (Euclidean by default). With ``start_xy``
    the path is anchored at the start (the leg from it to the first waypoint counts),
    otherwise both ends are free. Each pass checks all moves from one position at once
    (vectorised) and applies the best improving one; no move lengthens the path.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    route = list(order)
    anchored = start_xy is not None
    if anchored:
        pts = np.vstack([np.asarray(start_xy, dtype=float)[:2], pts])
        route = [0] + [i + 1 for i in route]
    if distance is None:
        dmat = np.hypot(pts[:, None, 0] - pts[None, :, 0], pts[:, None, 1] - pts[None, :, 1])
    else:
        dmat = np.asarray(distance, dtype=float)
        if anchored:
            d0 = np.hypot(*(pts[1:] - pts[0]).T)
            dmat = np.block([[np.zeros((1, 1)), d0[None, :]], [d0[:, None], dmat]])
    route = _two_opt_open(dmat, np.asarray(route, dtype=np.int64), max_passes, fixed_first=anchored)
    if anchored:
        return [int(i) - 1 for i in route[1:]]
    return [int(i) for i in route]


def _two_opt_open(d: np.ndarray, route: np.ndarray, max_passes: int, fixed_first: bool,
                  fixed_last: bool = False) -> np.ndarray:
    """First-improvement 2-opt on an open path; each position's moves are one vector op.

    Reversing route[i..j] replaces edges (i-1, i) and (j, j+1) by (i-1, j) and (i, j+1);
    at the path's ends the missing edge costs nothing, which is what makes it open. With
    ``fixed_last`` the last place stays last (a tour back to where it started).
    """
    n = len(route)
    if n < 3:
        return route
    eps = 1e-9
    first = 1 if fixed_first else 0
    end = n - 1 if fixed_last else n  # j < end: the places a reversal may move
    for _ in range(max_passes):
        improved = False
        for i in range(first, end - 1):
            a = route[i - 1] if i > 0 else -1
            b = route[i]
            js = np.arange(i + 1, end)
            c = route[js]
            nxt = np.where(js + 1 < n, route[np.minimum(js + 1, n - 1)], -1)
            has_next = js + 1 < n
            old = (d[a, b] if a >= 0 else 0.0) + np.where(has_next, d[c, nxt], 0.0)
            new = (d[a, c] if a >= 0 else np.zeros(len(js))) + np.where(has_next, d[b, nxt], 0.0)
            gain = old - new
            k = int(np.argmax(gain))
            if gain[k] > eps:
                j = int(js[k])
                route[i:j + 1] = route[i:j + 1][::-1].copy()
                improved = True
        if not improved:
            break
    return route


def two_opt_route(d: np.ndarray, route: Sequence[int], max_passes: int = 20, fixed_first: bool = True,
                  fixed_last: bool = False) -> list[int]:
    """2-opt on a route over a distance matrix ``d`` (what a path-length tour is improved by)."""
    out = _two_opt_open(np.asarray(d, dtype=float), np.asarray(route, dtype=np.int64), max_passes,
                        fixed_first, fixed_last)
    return [int(i) for i in out]


def or_opt_route(d: np.ndarray, route: Sequence[int], max_segment: int = 3, max_passes: int = 20,
                 fixed_first: bool = True, fixed_last: bool = False) -> list[int]:
    """Or-opt: move runs of 1..``max_segment`` places, either way round, to where they
    shorten the route most; what 2-opt misses when a detour is better taken elsewhere."""
    d = np.asarray(d, dtype=float)
    route = [int(i) for i in route]
    first, stop = (1 if fixed_first else 0), len(route) - (1 if fixed_last else 0)
    for _ in range(max_passes):
        improved = False
        for size in range(1, max_segment + 1):
            i = first
            while i + size <= stop:
                moved = _best_move(d, route, i, size, first, stop)
                if moved is None:
                    i += 1
                else:
                    route, improved = moved, True
        if not improved:
            break
    return route


def _best_move(d: np.ndarray, route: list[int], i: int, size: int, first: int, stop: int) -> list[int] | None:
    """route with route[i:i + size] moved to its best place, or None when no move shortens it."""
    seg = route[i:i + size]
    s0, s1 = seg[0], seg[-1]
    p = route[i - 1] if i > 0 else -1
    q = route[i + size] if i + size < len(route) else -1
    saved = (d[p, s0] if p >= 0 else 0.0) + (d[s1, q] if q >= 0 else 0.0) - (d[p, q] if p >= 0 and q >= 0 else 0.0)
    rest = np.asarray(route[:i] + route[i + size:], dtype=np.int64)
    lo, hi = max(first - 1, 0), min(stop - size, len(rest) - 1)  # between rest[k] and rest[k + 1], lo <= k < hi
    a, b = rest[lo:hi], rest[lo + 1:hi + 1]
    forward = d[a, s0] + d[s1, b] - d[a, b]
    backward = d[a, s1] + d[s0, b] - d[a, b]
    if stop == len(route):  # an open end: the run may also go last
        forward, backward = np.append(forward, d[rest[-1], s0]), np.append(backward, d[rest[-1], s1])
    if len(forward) == 0:
        return None
    cost = np.minimum(forward, backward)
    k = int(np.argmin(cost))
    if saved - cost[k] <= 1e-9:
        return None
    run = seg if forward[k] <= backward[k] else seg[::-1]
    at = lo + k + 1
    return [int(x) for x in rest[:at]] + run + [int(x) for x in rest[at:]]


def path_length(start_xy, points: np.ndarray) -> float:
    """Length of the polyline start -> points[0] -> ... (Euclidean)."""
    pts = np.vstack([np.asarray(start_xy, dtype=float)[:2], np.asarray(points, dtype=float).reshape(-1, 2)])
    return float(np.hypot(*np.diff(pts, axis=0).T).sum())


# -- the plan ------------------------------------------------------------------------------
def plan_traversal(trajectory: np.ndarray, start: Pose2D, params: TraversalParams | None = None,
                   grid_distance: GridDistance | None = None) -> TraversalPlan:
    """Sample, order and orient the monitor mission's waypoints.

    ``trajectory`` is (N, 4) t, x, y, yaw (as :func:`load_trajectory` returns) or (N, 2/3)
    x, y[, yaw]. ``grid_distance(a_xy, b_xy)`` (e.g. ``GridPlanner.distance``), when given,
    measures the tour along the grid (``grid_length``); it is not used for ordering, which
    would cost n^2 planner calls.
    """
    params = params or TraversalParams()
    traj = np.asarray(trajectory, dtype=float)
    if traj.ndim != 2 or traj.shape[1] not in (2, 3, 4) or len(traj) == 0:
        raise ValueError("trajectory must be a non-empty (N, 2|3|4) array")
    xy = traj[:, 1:3] if traj.shape[1] == 4 else traj[:, 0:2]
    yaw = traj[:, 3] if traj.shape[1] == 4 else (traj[:, 2] if traj.shape[1] == 3 else np.zeros(len(traj)))
    idx = sample_indices(xy, params.spacing)
    pts = xy[idx]
    order = greedy_tsp(pts, start.xy)
    if params.two_opt and len(order) > 2:
        order = two_opt(pts, order, max_passes=params.max_two_opt_passes, start_xy=start.xy)
    pts, yaws = pts[order], yaw[idx][order]
    waypoints = _orient(start, pts, yaws, params.face_travel_direction)
    length = path_length(start.xy, pts)
    grid_len = None
    if grid_distance is not None:
        legs = [(float(start.x), float(start.y))] + [(float(x), float(y)) for x, y in pts]
        grid_len = float(sum(grid_distance(a, b) for a, b in zip(legs[:-1], legs[1:], strict=True)))
    return TraversalPlan(waypoints, length, grid_len)


def _orient(start: Pose2D, pts: np.ndarray, yaws: np.ndarray, face_travel: bool) -> list[Pose2D]:
    """Waypoint yaws: along the leg to the next waypoint (the last keeps its arrival heading)."""
    if not face_travel:
        return [Pose2D(float(x), float(y), wrap_angle(float(t))) for (x, y), t in zip(pts, yaws, strict=True)]
    out = []
    prev = start.xy
    for i, p in enumerate(pts):
        nxt = pts[i + 1] if i + 1 < len(pts) else None
        v = (nxt - p) if nxt is not None else (p - prev)
        heading = math.atan2(v[1], v[0]) if np.hypot(*v) > 1e-9 else float(yaws[i])
        out.append(Pose2D(float(p[0]), float(p[1]), wrap_angle(heading)))
        prev = p
    return out


# -- keeping waypoints reachable -------------------------------------------------------------
def snap_to_free(grid: OccupancyGrid, waypoints: Sequence[Pose2D], clearance: float,
                 max_shift: float | None = None) -> list[Pose2D]:
    """Move each waypoint to the nearest known-free cell ``clearance`` from obstacles.

    A map saved after exploration can put an obstacle (a chair, a closed door) on a pose
    the robot once drove through; navigating there would fail. Waypoints already clear
    stay put; others move to the nearest clear cell (one distance transform for all of
    them), and are dropped when none lies within ``max_shift`` (default: 2 * clearance +
    one metre) or when they fall outside the map. Order and yaw are kept.
    """
    if not waypoints:
        return []
    res = grid.resolution
    obstacles = grid.occupied_mask() | grid.unknown_mask()
    clear_dist = cv2.distanceTransform((~obstacles).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    clear_dist = clear_dist * res
    ok = grid.free_mask() & (clear_dist >= clearance)
    if not ok.any():
        return []
    # Distance from every cell to the nearest clear cell, with the index of that cell.
    dist, labels = cv2.distanceTransformWithLabels((~ok).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5,
                                                   labelType=cv2.DIST_LABEL_PIXEL)
    ok_rows, ok_cols = np.nonzero(ok)
    # Labels number the zero pixels in raster order, which is np.nonzero's order.
    limit = (2.0 * clearance + 1.0) if max_shift is None else max_shift
    xs = np.array([w.x for w in waypoints])
    ys = np.array([w.y for w in waypoints])
    rows, cols = grid.world_to_cell(xs, ys)
    inside = grid.in_bounds(rows, cols)
    out = []
    for k, w in enumerate(waypoints):
        if not inside[k]:
            continue
        r, c = int(rows[k]), int(cols[k])
        if ok[r, c]:
            out.append(w)
            continue
        if dist[r, c] * res > limit:
            continue
        lab = int(labels[r, c]) - 1
        x, y = grid.cell_to_world(ok_rows[lab], ok_cols[lab])
        out.append(Pose2D(float(x), float(y), w.yaw))
    return out
