"""Shortening a grid path by line of sight without pulling it towards walls.

A* on an 8-connected grid returns staircase paths; a robot should drive the straight
lines between them. Each shortcut is priced on the same clearance-weighted cost array
the search used, so straightening never trades away clearance.
"""

from __future__ import annotations

import math

import numpy as np


def smooth_cells(cells: list[tuple[int, int]], costs_to_come: list[float],
                 cost_array: np.ndarray) -> list[tuple[int, int]]:
    """Greedy line-of-sight shortcutting that never makes the path more expensive.

    A shortcut from cell i to cell k is taken when every cell on the segment is
    traversable and the segment's clearance-weighted cost is no higher than the cost
    A* paid between the two cells, so smoothing straightens paths without pulling
    them back towards walls.
    """
    if len(cells) <= 2:
        return cells
    arr = np.array(cells)
    g = np.asarray(costs_to_come) if len(costs_to_come) == len(cells) else None
    out = [cells[0]]
    i, n = 0, len(cells)
    while i < n - 1:
        j = i + 1
        step = 1
        # Exponential then linear search for the farthest acceptable cell.
        while j + step < n:
            k = j + step
            budget = (g[k] - g[i]) * (1.0 + 1e-6) + 1e-9 if g is not None else math.inf
            if segment_cost(cost_array, arr[i], arr[k]) <= budget:
                j = k
                step *= 2
            else:
                if step == 1:
                    break
                step = 1
        out.append(cells[j])
        i = j
    return out

def segment_cost(cost_array: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Cost of driving straight from cell a to cell b (inf through lethal cells)."""
    n = int(max(abs(b[0] - a[0]), abs(b[1] - a[1]))) * 2 + 1
    t = np.linspace(0.0, 1.0, n)
    r = np.rint(a[0] + (b[0] - a[0]) * t).astype(np.int64)
    c = np.rint(a[1] + (b[1] - a[1]) * t).astype(np.int64)
    costs = cost_array[r, c]
    if not np.isfinite(costs).all():
        return math.inf
    length = math.hypot(float(b[0] - a[0]), float(b[1] - a[1]))
    # Trapezoid over the samples, excluding the start cell (A* charges arrival cells).
    mean = float((costs[1:].sum() + 0.0) / max(n - 1, 1)) if n > 1 else float(costs[0])
    return length * mean
