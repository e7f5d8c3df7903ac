"""Footprints: the floor-plane boxes (xmin, ymin, xmax, ymax) that objects' points cover.

Robust association compares an observation's box with the footprint a node's object has
shown so far (see :mod:`bomc_bt.graph.extents`); these are the box operations it needs,
plain functions of numpy arrays. A box is None when unknown; NaN rows in an array of
boxes never overlap anything.
"""

from __future__ import annotations

import math

import numpy as np

# m: how far a view's box may stick out of a footprint and still be the same floor (depth
# noise at box_range, and the points being samples of a surface rather than its outline)
NOISE_PAD = 0.1


def box_or_none(box) -> np.ndarray | None:
    """``box`` as a float (4,) array, or None when it is missing, not finite or inverted."""
    if box is None:
        return None
    b = np.asarray(box, dtype=float).reshape(4)
    return b if np.isfinite(b).all() and b[2] >= b[0] and b[3] >= b[1] else None


def union(a: np.ndarray | None, b: np.ndarray | None) -> np.ndarray | None:
    """The smallest box holding both (the other one when one is unknown)."""
    if a is None or b is None:
        return b if a is None else a
    return np.array([min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])])


def sides(box: np.ndarray) -> np.ndarray:
    """The floor box's x and y extents."""
    return np.array([box[2] - box[0], box[3] - box[1]], dtype=float)


def inside(box: np.ndarray, outer: np.ndarray, pad: float) -> bool:
    """Whether ``box`` lies within ``outer`` grown by ``pad`` on every side."""
    return bool(box[0] >= outer[0] - pad and box[1] >= outer[1] - pad
                and box[2] <= outer[2] + pad and box[3] <= outer[3] + pad)


def box_gap(a: np.ndarray, b: np.ndarray) -> float:
    """Distance between two boxes (0 when they overlap)."""
    dx = max(0.0, a[0] - b[2], b[0] - a[2])
    dy = max(0.0, a[1] - b[3], b[1] - a[3])
    return math.hypot(dx, dy)


def longest_side(box: np.ndarray) -> float:
    """The longer side of a floor box."""
    return float(max(box[2] - box[0], box[3] - box[1]))


def shortest_side(box: np.ndarray) -> float:
    """The shorter side of a floor box."""
    return float(min(box[2] - box[0], box[3] - box[1]))


def half_diagonal(box: np.ndarray) -> float:
    """Half the box's diagonal: how far its corners reach from its middle."""
    return 0.5 * math.hypot(box[2] - box[0], box[3] - box[1])


def overlapping(boxes: np.ndarray, box: np.ndarray, fraction: float) -> np.ndarray:
    """Which of ``boxes`` (K, 4) share at least ``fraction`` of the smaller box's area with
    ``box`` ((4,) or (K, 4)); NaN boxes never do. Degenerate (zero-area) boxes count by
    their larger side, so a thin sliver still overlaps what it lies on."""
    b = np.broadcast_to(box, boxes.shape)
    w = np.minimum(boxes[:, 2], b[:, 2]) - np.maximum(boxes[:, 0], b[:, 0])
    h = np.minimum(boxes[:, 3], b[:, 3]) - np.maximum(boxes[:, 1], b[:, 1])
    pad = 0.05  # m: points are samples of a surface, not its outline
    with np.errstate(invalid="ignore"):
        inter = np.clip(w + pad, 0.0, None) * np.clip(h + pad, 0.0, None)
        area_a = (boxes[:, 2] - boxes[:, 0] + pad) * (boxes[:, 3] - boxes[:, 1] + pad)
        area_b = (b[:, 2] - b[:, 0] + pad) * (b[:, 3] - b[:, 1] + pad)
        return (w > -pad) & (h > -pad) & (inter >= fraction * np.minimum(area_a, area_b))
