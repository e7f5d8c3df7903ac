"""The colour of a detected object's own surface, from the pixels its depth points came from.

Why chromaticity (r and g over r + g + b) and not RGB: the same chair is darker across the
room than beside the robot, and in shade than under a lamp; dividing by the sum takes most
of that out (the simulator darkens with distance by one factor per pixel, which it takes
out entirely). Why the median over the points the centroid keeps and not the whole mask: a
mask bleeds onto the wall and the floor around an object, and the points that lie on the
object's own surface, above the floor, are the ones projection already picked
(:func:`bomc_bt.perception.projection.detections_to_observations`). What it is used for:
:mod:`bomc_bt.graph.looks`.
"""

from __future__ import annotations

import numpy as np

MIN_SUM = 30  # r + g + b below this is too dark for its chromaticity to mean anything
MIN_PIXELS = 5  # fewer usable pixels than this: no colour


def surface_colour(rgb: np.ndarray | None, points_cam: np.ndarray, K: np.ndarray) -> np.ndarray | None:
    """Median (r, g) chromaticity of the pixels of ``points_cam`` (optical frame, as
    back-projected from this image), or None without an image or enough lit pixels."""
    if rgb is None or len(points_cam) < MIN_PIXELS or rgb.ndim != 3 or rgb.shape[2] < 3:
        return None
    z = points_cam[:, 2]
    u = np.rint(points_cam[:, 0] / z * K[0, 0] + K[0, 2]).astype(np.intp)
    v = np.rint(points_cam[:, 1] / z * K[1, 1] + K[1, 2]).astype(np.intp)
    inside = (u >= 0) & (u < rgb.shape[1]) & (v >= 0) & (v < rgb.shape[0])
    px = rgb[v[inside], u[inside], :3].astype(np.float32)
    total = px.sum(axis=1)
    lit = total >= MIN_SUM
    if int(np.count_nonzero(lit)) < MIN_PIXELS:
        return None
    return np.median(px[lit, :2] / total[lit, None], axis=0).astype(float)
