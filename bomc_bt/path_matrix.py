"""Driving distances between many places at once: the coverage tour's path-length matrix.

A tour of n viewpoints needs n x n path lengths on the grid. One Dijkstra per viewpoint
(:meth:`GridPlanner.distances_from`) costs n searches over the whole floor, too slow in
Python at building scale. Instead one multi-source Dijkstra grows all the places at once
over the planner's traversable cells; every cell learns its nearest place and the path
length to it (a geodesic Voronoi partition). Where two regions touch, the shortest path
joining their places through that seam is ``d(u) + step + d(v)``: an edge of a small graph
whose all-pairs shortest paths (Floyd-Warshall, vectorised) give the matrix. A path
between far places is measured through the places it passes, which is exact along a
corridor and at most slightly long elsewhere; a tour visits those places anyway.

The search runs on the planning grid pooled by an integer factor (a pooled cell is
traversable when any of its cells is): the pooled cells touching across a wall or
between two obstacles are never nearer than the robot's diameter in traversable space,
so pooling joins nothing the robot cannot drive through, and it never closes a door.
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from bomc_bt.grid import any_per_block
from bomc_bt.planner import GridPlanner

_SQRT2 = math.sqrt(2.0)


def pooling_factor(planner: GridPlanner, resolution: float) -> int:
    """The coarsest factor up to ``resolution`` that cannot join cells across an obstacle:
    cells of neighbouring pooled cells are at most sqrt(2) (2f - 1) cells apart, and
    traversable cells on two sides of an obstacle at least twice the robot radius."""
    f = max(1, int(round(resolution / planner.resolution)))
    gap = 2.0 * planner.params.robot_radius
    while f > 1 and _SQRT2 * (2 * f - 1) * planner.resolution >= gap:
        f -= 1
    return f


def _pooled_traversable(planner: GridPlanner, f: int) -> np.ndarray:
    free = ~planner.lethal
    return free if f == 1 else any_per_block(free, f)


def nearest_sources(traversable: np.ndarray, sources: list[tuple[int, int]], cell: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(distance in m, index of the nearest source; -1 where none) for every cell.

    Multi-source Dijkstra over 8-connected traversable cells with geometric step lengths,
    on flat Python lists with a blocked one-cell border (as the planner's search).
    """
    h, w = traversable.shape
    wp = w + 2
    ok = np.pad(traversable, 1, constant_values=False).ravel().tolist()
    best = [math.inf] * len(ok)
    owner = [-1] * len(ok)
    heap = []
    for k, (r, c) in enumerate(sources):
        i = (r + 1) * wp + c + 1
        if ok[i] and best[i] > 0.0:
            best[i], owner[i] = 0.0, k
            heap.append((0.0, i))
    heapq.heapify(heap)
    moves = ((1, 1.0), (-1, 1.0), (wp, 1.0), (-wp, 1.0),
             (wp + 1, _SQRT2), (wp - 1, _SQRT2), (-wp + 1, _SQRT2), (-wp - 1, _SQRT2))
    push, pop = heapq.heappush, heapq.heappop
    while heap:
        d, i = pop(heap)
        if d > best[i]:
            continue
        o = owner[i]
        for step, length in moves:
            j = i + step
            if not ok[j]:
                continue
            nd = d + length
            if nd < best[j]:
                best[j] = nd
                owner[j] = o
                push(heap, (nd, j))
    dist = np.asarray(best).reshape(h + 2, wp)[1:-1, 1:-1] * cell
    return dist, np.asarray(owner, dtype=np.int64).reshape(h + 2, wp)[1:-1, 1:-1]


def _seam_graph(dist: np.ndarray, owner: np.ndarray, n: int, cell: float) -> np.ndarray:
    """(n, n) lengths of the shortest paths joining two sources through their regions' seam."""
    out = np.full((n, n), np.inf)
    h, w = owner.shape
    for dr, dc, step in ((0, 1, 1.0), (1, 0, 1.0), (1, 1, _SQRT2), (1, -1, _SQRT2)):
        a = (slice(0, h - dr), slice(max(0, -dc), w - max(0, dc)))
        b = (slice(dr, h), slice(max(0, dc), w + min(0, dc)))
        oa, ob = owner[a], owner[b]
        seam = (oa >= 0) & (ob >= 0) & (oa != ob)
        length = dist[a][seam] + dist[b][seam] + step * cell
        np.minimum.at(out, (oa[seam], ob[seam]), length)
    out = np.minimum(out, out.T)
    np.fill_diagonal(out, 0.0)
    return out


def _all_pairs(d: np.ndarray) -> np.ndarray:
    """Floyd-Warshall, one vectorised relaxation per intermediate place."""
    d = d.copy()
    for k in range(len(d)):
        np.minimum(d, d[:, k:k + 1] + d[k:k + 1, :], out=d)
    return d


def path_length_matrix(planner: GridPlanner, points: np.ndarray, resolution: float = 0.2) -> np.ndarray:
    """(n, n) driving distances (m) between map points; inf between unconnected ones.

    A point on a lethal cell starts from the nearest traversable one within the planner's
    escape radius (as a plan from there would); a point with none has inf to all others.
    Points in one pooled cell share its region and are 0 apart.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(pts)
    if n == 0:
        return np.zeros((0, 0))
    f = pooling_factor(planner, resolution)
    traversable = _pooled_traversable(planner, f)
    cells: dict[tuple[int, int], int] = {}
    site_of = np.full(n, -1, dtype=np.int64)
    for k, p in enumerate(pts):
        snapped = planner.nearest_traversable(p, planner.params.escape_radius)
        if snapped is None:
            continue
        r, c = planner.cell(snapped)
        site_of[k] = cells.setdefault((r // f, c // f), len(cells))
    if not cells:
        return np.where(np.eye(n, dtype=bool), 0.0, np.inf)
    dist, owner = nearest_sources(traversable, list(cells), planner.resolution * f)
    sites = _all_pairs(_seam_graph(dist, owner, len(cells), planner.resolution * f))
    out = np.full((n, n), np.inf)
    known = site_of >= 0
    out[np.ix_(known, known)] = sites[np.ix_(site_of[known], site_of[known])]
    np.fill_diagonal(out, 0.0)
    return out
