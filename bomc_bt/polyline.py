"""Polylines (N, 2) of map-frame waypoints: their length and whether obstacles touch them.

Plans, trajectories and traversal routes are all polylines; these helpers need no
costmap, so a robot can ask "is my plan still good?" every tick cheaply.
"""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.grid import OccupancyGrid


def path_clear_of(obstacles: np.ndarray, grid: OccupancyGrid, path: np.ndarray, radius: float,
                  skip: float = 0.0) -> bool:
    """Whether no ``obstacles`` cell (bool mask on ``grid``) lies within ``radius`` of a polyline.

    A cheap test for "is my plan still good?" that needs no costmap rebuild: the path is
    sampled every cell and a disc of cell offsets is looked up around each sample. The
    first ``skip`` metres are ignored (the robot itself may be close to a wall).
    """
    path = np.asarray(path, dtype=float)
    if len(path) < 2:
        return True
    lengths = np.hypot(*np.diff(path, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    s = np.arange(skip, cum[-1] + 1e-9, grid.resolution)
    if len(s) == 0:
        return True
    r, c = grid.world_to_cell(np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1]))
    k = int(math.ceil(radius / grid.resolution))
    dr, dc = np.mgrid[-k:k + 1, -k:k + 1]
    disc = (dr**2 + dc**2) * grid.resolution**2 <= radius**2
    rr = r[:, None] + dr[disc][None, :]
    cc = c[:, None] + dc[disc][None, :]
    inside = (rr >= 0) & (rr < grid.height) & (cc >= 0) & (cc < grid.width)
    hits = obstacles[np.clip(rr, 0, grid.height - 1), np.clip(cc, 0, grid.width - 1)] & inside
    return not bool(hits.any())


def path_length(path: np.ndarray) -> float:
    """Sum of segment lengths of an (N, 2) polyline."""
    path = np.asarray(path, dtype=float)
    if len(path) < 2:
        return 0.0
    return float(np.hypot(*np.diff(path[:, :2], axis=0).T).sum())


def dedupe_waypoints(path: np.ndarray) -> np.ndarray:
    """Drop consecutive duplicate waypoints (keeps at least one)."""
    if len(path) < 2:
        return path
    keep = np.ones(len(path), dtype=bool)
    keep[1:] = np.hypot(*np.diff(path, axis=0).T) > 1e-9
    return path[keep]
