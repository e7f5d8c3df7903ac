"""Frontier search on an occupancy grid: where known free space meets the unknown.

Definitions (applied identically by :func:`find_frontiers` and the breadth-first
:func:`find_frontiers_reference`, so the two agree cell for cell):

* **free** cell: value ``0`` (``OccupancyGrid.free_mask``); **unknown**: value ``< 0``.
  Occupied or "probably occupied" values (``1..100``) are neither.
* **frontier cell**: a free cell with at least one unknown 4-neighbour. This is the
  classic definition of Yamauchi (1997). (explore_lite marks the *unknown* cell next to
  free space instead; marking the free side keeps every frontier cell a place the robot
  can actually stand on, and the goal point is then on known ground.) Neighbours outside
  the grid do not count: the map edge is not a frontier.
* **reachable**: free cells 4-connected through free cells to the start cell, the
  robot's own cell, or if that is not free (the robot starts in unknown or occupied
  space, e.g. before the first scan is integrated or after SLAM drift), the free cell
  nearest the robot within ``start_radius`` metres (ties: lowest row, then column).
  4-connectivity is what a breadth-first search over a costmap uses (explore_lite's
  ``nhood4``) and it does not squeeze diagonally between two wall cells.
* **frontier**: an 8-connected cluster of (reachable) frontier cells, so a diagonal
  boundary stays one frontier.

Each frontier reports its size, its centroid (mean of its cell centres), its cell nearest
the robot and the Euclidean distance to it. Centroids are computed from exact integer
sums of row/column indices so both implementations produce bit-identical numbers, and
frontiers are sorted by ``(distance, centroid x, centroid y, first cell)``, which is a
total order because clusters are disjoint.

The fast version is vectorised (numpy shifts for the frontier mask, OpenCV flood fill
for the reachable region and connected components for the clusters, ``np.bincount`` /
``np.lexsort`` for per-cluster statistics) and only touches the bounding box of the
reachable region, so it stays cheap on building-sized maps at 5 cm.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.grid import OccupancyGrid

# How far (m) to look for a free start cell when the robot's own cell is not free: about
# one robot diameter of a Fetch-class base plus SLAM jitter, so a robot standing in a
# not-yet-cleared cell still finds the free space around it without jumping across a wall.
DEFAULT_START_RADIUS = 1.0


@dataclass
class Frontier:
    """One connected stretch of boundary between known free space and the unknown."""

    cells: np.ndarray  # (N, 2) int64 (row, col), sorted row-major
    size: int  # number of cells
    centroid: tuple[float, float]  # map-frame metres (mean of the cell centres)
    nearest: tuple[float, float]  # map-frame centre of the cell nearest the robot
    distance: float  # Euclidean metres from the robot to ``nearest``
    resolution: float  # metres per cell of the grid it was found on

    @property
    def length(self) -> float:
        """Frontier length in metres (cell count times resolution), as explore_lite measures it."""
        return self.size * self.resolution


# -- shared helpers (used by both implementations so only the search itself differs) -----
def start_cell(grid: OccupancyGrid, robot_xy: tuple[float, float],
               start_radius: float = DEFAULT_START_RADIUS) -> tuple[int, int] | None:
    """The free cell the search starts from, or None when no free cell is near the robot."""
    rx, ry = float(robot_xy[0]), float(robot_xy[1])
    row, col = grid.world_to_cell(rx, ry)
    row, col = int(row), int(col)
    if grid.in_bounds(row, col) and grid.data[row, col] == 0:
        return row, col
    reach = int(math.ceil(max(start_radius, 0.0) / grid.resolution)) + 1
    r0, r1 = max(row - reach, 0), min(row + reach + 1, grid.height)
    c0, c1 = max(col - reach, 0), min(col + reach + 1, grid.width)
    if r0 >= r1 or c0 >= c1:
        return None
    rows, cols = np.nonzero(grid.data[r0:r1, c0:c1] == 0)
    if rows.size == 0:
        return None
    rows, cols = rows + r0, cols + c0
    x, y = grid.cell_to_world(rows, cols)
    dist = np.sqrt((x - rx) ** 2 + (y - ry) ** 2)
    ok = dist <= start_radius
    if not ok.any():
        return None
    rows, cols, dist = rows[ok], cols[ok], dist[ok]
    best = np.lexsort((cols, rows, dist))[0]
    return int(rows[best]), int(cols[best])


def _sort_key(f: Frontier, width: int) -> tuple[float, float, float, int]:
    first = int(f.cells[0, 0]) * width + int(f.cells[0, 1])
    return (f.distance, f.centroid[0], f.centroid[1], first)


def _check_min_size(min_size: int) -> int:
    if int(min_size) != min_size or min_size < 1:
        raise ValueError(f"min_size must be a positive whole number of cells, got {min_size!r}")
    return int(min_size)


# -- fast, vectorised --------------------------------------------------------------------
def find_frontiers(grid: OccupancyGrid, robot_xy: tuple[float, float], min_size: int = 1,
                   reachable_only: bool = True,
                   start_radius: float = DEFAULT_START_RADIUS) -> list[Frontier]:
    """All frontiers of at least ``min_size`` cells, nearest first (see module docstring).

    With ``reachable_only`` only frontiers in the free region connected to the robot are
    returned (frontiers behind walls or in disconnected SLAM artefacts are useless goals);
    if no free cell is within ``start_radius`` of the robot the result is empty.
    """
    min_size = _check_min_size(min_size)
    free = grid.data == 0
    if reachable_only:
        start = start_cell(grid, robot_xy, start_radius)
        if start is None:
            return []
        region, (r0, c0) = _reachable_region(free, start)
    else:
        region, (r0, c0) = free, (0, 0)
    r1, c1 = r0 + region.shape[0], c0 + region.shape[1]
    # One cell of margin so the unknown neighbours of the region's border are seen.
    m0, m1 = max(r0 - 1, 0), min(r1 + 1, grid.height)
    n0, n1 = max(c0 - 1, 0), min(c1 + 1, grid.width)
    touches = touches_unknown(grid.data[m0:m1, n0:n1] < 0)[r0 - m0:r1 - m0, c0 - n0:c1 - n0]
    mask = region & touches
    return _clusters(grid, mask, (r0, c0), robot_xy, min_size)


def _reachable_region(free: np.ndarray, start: tuple[int, int]) -> tuple[np.ndarray, tuple[int, int]]:
    """Free cells 4-connected to ``start``, cropped to their bounding box (mask, offset)."""
    h, w = free.shape
    image = free.view(np.uint8)
    fill = np.zeros((h + 2, w + 2), np.uint8)
    flags = 4 | cv2.FLOODFILL_MASK_ONLY | (1 << 8)
    _, _, _, (x, y, bw, bh) = cv2.floodFill(image, fill, (start[1], start[0]), 1, 0, 0, flags)
    region = fill[1 + y:1 + y + bh, 1 + x:1 + x + bw].astype(bool)
    return region, (y, x)


def touches_unknown(unknown: np.ndarray) -> np.ndarray:
    """Cells with an unknown 4-neighbour (cells beyond the array edge are not unknown)."""
    out = np.zeros_like(unknown)
    out[1:, :] |= unknown[:-1, :]
    out[:-1, :] |= unknown[1:, :]
    out[:, 1:] |= unknown[:, :-1]
    out[:, :-1] |= unknown[:, 1:]
    return out


def _clusters(grid: OccupancyGrid, mask: np.ndarray, offset: tuple[int, int],
              robot_xy: tuple[float, float], min_size: int) -> list[Frontier]:
    """8-connected clusters of ``mask`` as Frontier records (per-cell work vectorised)."""
    image = mask.view(np.uint8)
    points = cv2.findNonZero(image)  # (col, row) pairs in row-major order, or None
    if points is None:
        return []
    points = points.reshape(-1, 2)
    # Plain labelling (no per-pixel stats pass): sizes come from the frontier cells alone.
    n, labels = cv2.connectedComponents(image, connectivity=8, ltype=cv2.CV_32S)
    cols, rows = points[:, 0], points[:, 1]
    lab = labels[rows, cols]
    keep = np.bincount(lab, minlength=n) >= min_size
    keep[0] = False
    chosen = keep[lab]
    if not chosen.any():
        return []
    rows = rows[chosen].astype(np.int64) + offset[0]
    cols = cols[chosen].astype(np.int64) + offset[1]
    lab = lab[chosen]
    rx, ry = float(robot_xy[0]), float(robot_xy[1])
    x, y = grid.cell_to_world(rows, cols)
    dx, dy = x - rx, y - ry
    dist = np.sqrt(dx * dx + dy * dy)

    by_label = np.argsort(lab, kind="stable")  # cells grouped by label, row-major inside
    labels_kept = np.flatnonzero(keep)
    counts = np.bincount(lab, minlength=n)[labels_kept]
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    row_sum = np.bincount(lab, weights=rows, minlength=n)[labels_kept]
    col_sum = np.bincount(lab, weights=cols, minlength=n)[labels_kept]
    cx, cy = grid.cell_to_world(row_sum / counts, col_sum / counts)
    nearest = np.lexsort((dist, lab))[starts]  # stable: ties keep the lowest flat index
    cells = np.stack((rows[by_label], cols[by_label]), axis=1)

    frontiers = [
        Frontier(cells=cells[s:s + k], size=int(k), centroid=(float(ax), float(ay)),
                 nearest=(float(x[i]), float(y[i])), distance=float(dist[i]),
                 resolution=float(grid.resolution))
        for s, k, ax, ay, i in zip(starts, counts, cx, cy, nearest, strict=True)
    ]
    frontiers.sort(key=lambda f: _sort_key(f, grid.width))
    return frontiers


# -- plain breadth-first reference -------------------------------------------------------
def find_frontiers_reference(grid: OccupancyGrid, robot_xy: tuple[float, float], min_size: int = 1,
                             reachable_only: bool = True,
                             start_radius: float = DEFAULT_START_RADIUS) -> list[Frontier]:
    """The same result as :func:`find_frontiers`, by explicit breadth-first searches.

    explore_lite style: a BFS over free space from the start cell, then each frontier
    cell not yet assigned seeds a BFS over its 8-connected frontier neighbours. Slow
    (pure Python per cell); it exists to check the fast version and as a benchmark baseline.
    """
    min_size = _check_min_size(min_size)
    data = grid.data.tolist()
    h, w = grid.height, grid.width
    if reachable_only:
        start = start_cell(grid, robot_xy, start_radius)
        if start is None:
            return []
        region = _bfs_free(data, h, w, start)
    else:
        region = {(r, c) for r in range(h) for c in range(w) if data[r][c] == 0}
    frontier_cells = {cell for cell in region if _has_unknown_neighbour(data, h, w, *cell)}
    seen: set[tuple[int, int]] = set()
    out = []
    for seed in sorted(frontier_cells):
        if seed in seen:
            continue
        cluster = _bfs_cluster(frontier_cells, seen, seed)
        if len(cluster) >= min_size:
            out.append(_make_frontier(grid, sorted(cluster), robot_xy))
    out.sort(key=lambda f: _sort_key(f, w))
    return out


def _bfs_free(data: list, h: int, w: int, start: tuple[int, int]) -> set[tuple[int, int]]:
    visited = {start}
    queue = deque([start])
    while queue:
        r, c = queue.popleft()
        for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
            if 0 <= nr < h and 0 <= nc < w and (nr, nc) not in visited and data[nr][nc] == 0:
                visited.add((nr, nc))
                queue.append((nr, nc))
    return visited


def _has_unknown_neighbour(data: list, h: int, w: int, r: int, c: int) -> bool:
    for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
        if 0 <= nr < h and 0 <= nc < w and data[nr][nc] < 0:
            return True
    return False


def _bfs_cluster(frontier_cells: set, seen: set, seed: tuple[int, int]) -> list[tuple[int, int]]:
    seen.add(seed)
    cluster = [seed]
    queue = deque([seed])
    while queue:
        r, c = queue.popleft()
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                nbr = (r + dr, c + dc)
                if nbr in frontier_cells and nbr not in seen:
                    seen.add(nbr)
                    cluster.append(nbr)
                    queue.append(nbr)
    return cluster


def _make_frontier(grid: OccupancyGrid, cells: list[tuple[int, int]], robot_xy) -> Frontier:
    ox, oy = float(grid.origin[0]), float(grid.origin[1])
    res = float(grid.resolution)
    rx, ry = float(robot_xy[0]), float(robot_xy[1])
    best = None
    row_sum = col_sum = 0
    for r, c in cells:  # row-major, so the first minimum is the lowest flat index
        row_sum += r
        col_sum += c
        x, y = ox + (c + 0.5) * res, oy + (r + 0.5) * res
        dx, dy = x - rx, y - ry
        d = math.sqrt(dx * dx + dy * dy)
        if best is None or d < best[0]:
            best = (d, x, y)
    n = len(cells)
    centroid = (ox + (float(col_sum) / n + 0.5) * res, oy + (float(row_sum) / n + 0.5) * res)
    return Frontier(cells=np.array(cells, dtype=np.int64).reshape(-1, 2), size=n, centroid=centroid,
                    nearest=(best[1], best[2]), distance=best[0], resolution=res)
