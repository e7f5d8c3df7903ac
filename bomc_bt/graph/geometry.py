"""Plane and point geometry shared by the spatial index and the linear-scan reference.

The distances are written out component by component so that the index and the
reference compute bit-identical values (a benchmark and the tests compare them).
"""

from __future__ import annotations

import numpy as np


def points_in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule, vectorised over points: bool mask of ``points`` (M, 2) inside ``polygon`` (K, 2)."""
    x, y = points[:, 0], points[:, 1]
    inside = np.zeros(len(points), dtype=bool)
    xj, yj = polygon[-1]
    for xi, yi in polygon:
        if yi != yj:
            crosses = (yi > y) != (yj > y)
            with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # near-horizontal edges
                x_at = (xj - xi) * (y - yi) / (yj - yi) + xi
            inside ^= crosses & (x < x_at)
        xj, yj = xi, yi
    return inside


def check_polygon(polygon: np.ndarray) -> np.ndarray:
    """``polygon`` as a float (K >= 3, 2) array; ValueError for anything else."""
    poly = np.asarray(polygon, dtype=float)
    if poly.ndim != 2 or poly.shape[1] != 2 or len(poly) < 3:
        raise ValueError(f"polygon must be (K >= 3, 2), got shape {poly.shape}")
    return poly


def dist2(points: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Squared distances of ``points`` (N, 3) to ``p`` (3,)."""
    d = points - p
    return d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]


def dist2_scalar(a: np.ndarray, b: np.ndarray) -> float:
    """Squared distance of two (3,) points, as Python floats."""
    dx, dy, dz = float(a[0] - b[0]), float(a[1] - b[1]), float(a[2] - b[2])
    return dx * dx + dy * dy + dz * dz
