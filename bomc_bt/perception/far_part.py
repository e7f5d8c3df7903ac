"""The far part of an object seen end-on: what the range cut drops that is still the object.

Why: the robust centroid (:func:`bomc_bt.perception.projection.robust_centroid`) keeps the
points whose range from the camera lies near the range most of the mask shares, to drop the
background a mask bled onto. Seen end-on, a table's near end is that range and its top
stretches 1.6 m farther in a tenth of its pixels: the cut kept 0.34 m of the table, and the
observation stood at its near end, 0.7 m from its centre. On a generated floor, views of
tables end-on put the observation 0.63 m from the table's centre at the median and 18 % of
them past the scoring distance (0.7 m); a table's node was 0.6-1.1 m off in every
Environment-A-size pass measured.

What the cut dropped beyond the kept range is the object where it goes on from the kept
part without a jump in range: a table's top recedes row by row, while what a mask spills
onto past its outline (the floor, a wall metres behind) lies across a jump or at floor
height. So the far part is the mask's pixels above the floor, joined to the kept ones by a
path of neighbouring pixels whose ranges step by less than ``JUMP_ABS + JUMP_REL * range``
(a surface seen at a grazing angle steps by about range^2 x pixel angle / height above it:
0.15 m at 4 m on a 320-pixel-wide image, under the 0.45 m allowed there).

The far part moves the view's centre, not its floor box (see the projection): one chair view
in many grown over the table it touches is enough to lengthen a category's longest view.
"""

from __future__ import annotations

import cv2
import numpy as np

JUMP_ABS = 0.05  # m, range step between neighbouring pixels that always parts two surfaces ...
JUMP_REL = 0.1  # [-] ... plus this share of the range (depth noise and grazing steps grow with range)
INNER_PX = 6  # px at 640 wide: a mask eroded by this holds the object itself, not what it spilled onto
TOP_MARGIN = 0.05  # m, a far part lies no higher than the kept part's top by more than this
ABOVE_FLOOR = 0.15  # m, a far part lies at least this high: below, noisy floor pixels chain an object to a wall


def far_part(depth: np.ndarray, mask: np.ndarray, origin: tuple[int, int], stride: int, K: np.ndarray,
             T_map_camera: np.ndarray, kept: np.ndarray, depth_range: tuple[float, float],
             floor_height: float, image_width: int) -> np.ndarray:
    """(N, 3) optical-frame points of the object beyond the ``kept`` ones (optical frame, what
    the range cut kept): farther than all of them, no higher than their top.

    ``depth`` and ``mask`` are the mask's window on the ``stride`` lattice, whose first pixel
    is ``origin`` (row, column) of the image, ``image_width`` pixels wide."""
    ranges = np.sqrt(np.einsum("ij,ij->i", kept, kept))
    near, far = float(ranges.min()), float(ranges.max())
    top = float((kept @ T_map_camera[2, :3]).max() + T_map_camera[2, 3])
    k = max(1, round(INNER_PX * image_width / 640 / stride))
    mask = cv2.erode(mask.astype(np.uint8), np.ones((2 * k + 1, 2 * k + 1), np.uint8)).astype(bool)
    h, w = depth.shape
    v, u = np.mgrid[0:h, 0:w]
    x = ((u * stride + origin[1]) - K[0, 2]) / K[0, 0] * depth
    y = ((v * stride + origin[0]) - K[1, 2]) / K[1, 1] * depth
    with np.errstate(invalid="ignore"):
        valid = mask & (depth > max(depth_range[0], 0.0)) & (depth <= depth_range[1])  # NaN compares False
    r = np.sqrt(x * x + y * y + depth * depth)
    height = T_map_camera[2, 0] * x + T_map_camera[2, 1] * y + T_map_camera[2, 2] * depth + T_map_camera[2, 3]
    solid = valid & (height >= max(floor_height, ABOVE_FLOOR)) & (height <= top + TOP_MARGIN)
    if not (solid & (r > far)).any():
        return np.empty((0, 3))
    joined = solid & ~_jumps(np.where(solid, r, np.nan))
    _, labels = cv2.connectedComponents(joined.astype(np.uint8), connectivity=4)
    core = np.unique(labels[joined & (r >= near) & (r <= far)])
    part = np.isin(labels, core[core > 0]) & (r > far)
    return np.stack([x[part], y[part], depth[part]], axis=1)


def _jumps(r: np.ndarray) -> np.ndarray:
    """Pixels whose range differs from a 4-neighbour's by more than the allowed step (both
    pixels of such a pair are marked; NaN, no solid point, marks nothing)."""
    out = np.zeros(r.shape, dtype=bool)
    for a, b in (((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                 ((slice(1, None), slice(None)), (slice(None, -1), slice(None)))):
        with np.errstate(invalid="ignore"):
            step = np.abs(r[a] - r[b]) > JUMP_ABS + JUMP_REL * np.fmin(r[a], r[b])
        out[a] |= step
        out[b] |= step
    return out
