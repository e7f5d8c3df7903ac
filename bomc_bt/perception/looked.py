"""The floor a frame looked at: where an object standing on it would have been in view.

Why: a later pass tells an object *new to the map* from one *added* by whether an earlier
pass looked at its place (:mod:`bomc_bt.first_seen`). The field-of-view fan
(:func:`bomc_bt.perception.projection.fov_polygon`) takes each image column's farthest
depth pixel, so it reaches the wall behind a table or a cabinet and counts the floor
hidden behind that furniture as looked at. An object brought there later was then
reported as added, a change at a place no pass had actually seen.

Here each sampled column stops at the nearest thing standing on the floor (a pixel whose
map-frame height is between ``STANDING_MIN`` and ``STANDING_MAX``): furniture, a wall, a
person. Beyond it the floor is hidden at the height objects have, so it was not looked
at. Pixels at floor height (within depth noise of the floor) do not cut the column, and
neither does anything above ``STANDING_MAX`` (a lamp, a door frame): an object's body
below it would still be in view. A column with nothing standing
in it ends at its farthest valid pixel, as the fan does; every vertex is then pulled in to
``reach`` (``projection.expect_range``). Each column ends no farther than the fan's own
(which takes the pixel of greatest optical depth, this one of greatest floor distance,
nearly always the same pixel): conservative, more first sightings, fewer claimed additions.
"""

from __future__ import annotations

import numpy as np

from bomc_bt.algorithm_params import ProjectionParams
from bomc_bt.robot import RGBDFrame

STANDING_MIN = 0.15  # m above the floor: lower is floor (depth noise at 6 m is a few cm in height)
STANDING_MAX = 1.0  # m above the floor: higher does not hide an object's body behind it


def looked_polygon(frame: RGBDFrame, params: ProjectionParams, reach: float) -> np.ndarray:
    """(K, 2) counter-clockwise map-frame fan, vertex 0 the camera: the floor this frame looked
    at within ``reach``.

    An empty (0, 2) array when fewer than two sampled columns have valid depth.
    """
    h, w = frame.shape
    cols = np.unique(np.linspace(0, w - 1, params.fov_columns).round().astype(np.intp))
    lo = frame.depth_range[0]
    d = frame.depth[:, cols].astype(float)
    with np.errstate(invalid="ignore"):
        valid = (d >= lo) & (d <= params.max_depth)  # NaN compares False
    if np.count_nonzero(valid.any(axis=0)) < 2:
        return np.empty((0, 2))
    K, T = frame.K, frame.T_map_camera
    z = np.where(valid, d, 0.0)
    u = cols[None, :].astype(float)
    v = np.arange(h, dtype=float)[:, None]
    cam = np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], axis=-1)
    pts = cam @ T[:3, :3].T + T[:3, 3]  # (H, C, 3) map frame
    offset = pts[..., :2] - T[:2, 3]
    ranges = np.where(valid, np.hypot(offset[..., 0], offset[..., 1]), np.nan)
    standing = valid & (pts[..., 2] > STANDING_MIN) & (pts[..., 2] <= STANDING_MAX)
    far_row = np.nanargmax(np.where(valid, ranges, -1.0), axis=0)
    near_row = np.argmin(np.where(standing, ranges, np.inf), axis=0)
    row = np.where(standing.any(axis=0), near_row, far_row)
    ok = valid.any(axis=0)
    index = np.arange(len(cols))
    xy = pts[row[ok], index[ok], :2]
    out = xy - T[:2, 3]
    dist = np.hypot(out[:, 0], out[:, 1])
    scale = np.minimum(1.0, reach / np.maximum(dist, 1e-9))
    fan = T[:2, 3] + out * scale[:, None]
    polygon = np.vstack([T[:2, 3], fan])
    return polygon if _signed_area(polygon) >= 0.0 else np.vstack([T[:2, 3], fan[::-1]])


def _signed_area(polygon: np.ndarray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
