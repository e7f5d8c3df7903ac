"""Perception geometry shared by every backend: masks to map-frame objects, and the view.

The paper back-projects each segment's depth pixels with the camera intrinsics, moves the
points to the map with full SE(3) transforms (``P_map = T_map_base @ T_base_camera @
P_camera``), and takes their mean as the object's position. It also forms an approximate
field-of-view polygon "from the limits of the depth point cloud" to decide which nodes
should be visible. This module does exactly that, vectorised, plus two safeguards a real
segmenter needs: a robust centroid (masks bleed onto the background behind an object) and
an occlusion test (a node inside the FoV polygon may still be hidden behind something).

Numpy (and OpenCV for a mask's bounding box); nothing here knows which detector produced the masks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import cv2
import numpy as np

from bomc_bt.algorithm_params import ProjectionParams
from bomc_bt.errors import BomcError
from bomc_bt.graph import Observation
from bomc_bt.perception.colour import surface_colour
from bomc_bt.perception.far_part import far_part
from bomc_bt.perception.frames import Detection
from bomc_bt.perception.surface_patch import is_surface_patch
from bomc_bt.robot import RGBDFrame

_BIN = 0.05  # m, range histogram bin of the robust centroid
_MIN_HALF_WIDTH = 0.1  # m, the robust centroid never cuts closer than this to the mode
_MAD_K = 3.0 * 1.4826  # three standard deviations, from the median absolute deviation
_DETACHED_GAP = 1.0  # m, an empty stretch of range this long parts the object from what its mask bled onto
_DETACHED_SHARE = 0.15  # [-] a group beyond such a stretch with less than this share of the points is not the object
_STANDING_SHARE = 0.5  # [-] a view whose own surface has less than this share above the floor is of the floor


@dataclass
class ProjectionStats:
    """What happened to a batch of detections (skips are counted, never raised)."""

    detections: int = 0
    observations: int = 0
    no_mask: int = 0  # no mask or an empty one
    no_depth: int = 0  # no valid depth under the mask
    few_points: int = 0  # fewer than min_points valid points
    on_floor: int = 0  # enough valid points, but fewer than min_points above the floor
    too_far: int = 0  # most of the mask's depth lies beyond the range used: a far object's
    on_wall: int = 0  # a patch of a wall, flush with what is round it (surface_patch.py)

    def add(self, other: ProjectionStats) -> None:
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))


# -- back-projection -----------------------------------------------------------------------
def backproject(depth: np.ndarray, mask: np.ndarray, K: np.ndarray, stride: int = 1,
                depth_range: tuple[float, float] | None = None) -> np.ndarray:
    """(N, 3) optical-frame points of the masked pixels with finite, in-range depth.

    Only the mask's bounding box is visited, on the global ``stride`` lattice (so a
    point's pixel does not depend on where the mask starts).
    """
    if mask.shape != depth.shape:
        raise BomcError(f"mask shape {mask.shape} differs from the depth image {depth.shape}",
                        field="mask")
    window = _on_lattice(depth, mask, stride)
    if window is None:
        return np.empty((0, 3))
    d, m, r0, c0 = window
    lo, hi = depth_range if depth_range is not None else (0.0, np.inf)
    with np.errstate(invalid="ignore"):
        valid = m & (d > max(lo, 0.0)) & (d <= hi)  # NaN compares False
    v, u = np.nonzero(valid)
    z = d[v, u].astype(float)
    u = u * stride + c0
    v = v * stride + r0
    x = (u - K[0, 2]) / K[0, 0] * z
    y = (v - K[1, 2]) / K[1, 1] * z
    return np.stack([x, y, z], axis=1)


def mostly_beyond(depth: np.ndarray, mask: np.ndarray, stride: int, far: float) -> bool:
    """Whether more of the mask's pixels (on the ``stride`` lattice, finite depth) lie farther
    than ``far`` than nearer: the detection is of an object beyond the range used.

    Why: cutting such a mask at ``far`` keeps only what it bled onto in front of the object
    (a door frame, a table's edge) and makes that the object. A cabinet 7.9 m away, seen
    past a doorway, became a "cabinet" 2 m nearer, made of its mask's rim on the frame
    (PAL's Willow Garage map: two phantom additions in one pass).
    """
    window = _on_lattice(depth, mask, stride)
    if window is None:
        return False
    d = window[0][window[1]]
    with np.errstate(invalid="ignore"):
        beyond = int(np.count_nonzero(d > far))  # NaN compares False
        within = int(np.count_nonzero((d > 0.0) & (d <= far)))
    return beyond > within


def _on_lattice(depth: np.ndarray, mask: np.ndarray, stride: int
                ) -> tuple[np.ndarray, np.ndarray, int, int] | None:
    """Depth and mask over the mask's bounding box on the global ``stride`` lattice, with the
    window's first row and column; None for an empty mask."""
    bounds = _mask_bounds(mask)
    if bounds is None:
        return None
    x, y, w, h = bounds
    r0, c0 = -(-y // stride) * stride, -(-x // stride) * stride
    return depth[r0:y + h:stride, c0:x + w:stride], mask[r0:y + h:stride, c0:x + w:stride], r0, c0


def truncated(depth: np.ndarray, mask: np.ndarray, object_depth: float, margin: float = 0.2,
              ring: int = 2) -> bool:
    """Whether only part of the object can be in the mask: it touches the image border, or
    something nearer than the object (by ``margin`` m) borders it.

    Such a view's centroid is biased towards the visible part, by up to half the object's
    length; association must not take it for a second object next to the first.
    """
    bounds = _mask_bounds(mask)
    if bounds is None:
        return False
    x, y, w, h = bounds
    rows, cols = mask.shape
    if x == 0 or y == 0 or x + w >= cols or y + h >= rows:
        return True
    r0, r1, c0, c1 = max(0, y - ring), min(rows, y + h + ring), max(0, x - ring), min(cols, x + w + ring)
    m = np.ascontiguousarray(mask[r0:r1, c0:c1], dtype=np.uint8)
    around = cv2.dilate(m, np.ones((2 * ring + 1, 2 * ring + 1), np.uint8)).astype(bool) & ~m.astype(bool)
    with np.errstate(invalid="ignore"):
        nearer = depth[r0:r1, c0:c1] < object_depth - margin  # NaN compares False
    return bool((around & nearer).any())


def _mask_bounds(mask: np.ndarray) -> tuple[int, int, int, int] | None:
    """(x, y, w, h) of the mask's set pixels, None when there are none (OpenCV: fast)."""
    m = np.ascontiguousarray(mask, dtype=bool).view(np.uint8)
    x, y, w, h = cv2.boundingRect(m)
    return (int(x), int(y), int(w), int(h)) if w > 0 and h > 0 else None


def robust_centroid(points_map: np.ndarray, origin: np.ndarray | None = None) -> np.ndarray | None:
    """Mean of the object's points, ignoring what the mask bled onto; None if empty.

    Why: a segment's mask usually spills a few pixels past the object's outline, and those
    pixels see the background -- a wall or the floor metres *behind* the object. A plain
    mean is dragged far along the viewing ray by them. The object itself is the densest,
    nearest cluster in range from the camera, so: histogram the points' range (distance
    from ``origin``, the camera; without it, distance from the median point), take the
    nearest histogram peak holding at least half the highest peak's mass (prefers the
    foreground object over an equally strong background), keep the points within three
    robust standard deviations (from the median absolute deviation about that peak, never
    less than 10 cm) and return their mean -- the paper's mean of the point cloud.
    """
    points = np.asarray(points_map, dtype=float).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    if len(points) == 0:
        return None
    centre = np.asarray(origin, dtype=float) if origin is not None else np.median(points, axis=0)
    return points[_dominant_cluster(np.linalg.norm(points - centre, axis=1))].mean(axis=0)


def _dominant_cluster(r: np.ndarray) -> np.ndarray | slice:
    """Which ranges ``r`` belong to the nearest dominant cluster (see robust_centroid)."""
    r_min = float(r.min())
    span = float(r.max()) - r_min
    if span <= 2.0 * _MIN_HALF_WIDTH:
        return slice(None)
    n_bins = int(math.ceil(span / _BIN)) + 1
    hist = np.bincount(((r - r_min) * (1.0 / _BIN)).astype(np.intp), minlength=n_bins).astype(float)
    smooth = np.convolve(hist, np.ones(3), mode="same")
    peak = int(np.flatnonzero(smooth >= 0.5 * smooth.max())[0])
    while peak + 1 < n_bins and smooth[peak + 1] > smooth[peak]:  # climb to that peak's top
        peak += 1
    dev = np.abs(r - (r_min + (peak + 0.5) * _BIN))
    keep = dev <= max(_MIN_HALF_WIDTH, _MAD_K * float(np.median(dev)))
    return keep & _attached(r, keep, r_min, peak)


def _attached(r: np.ndarray, keep: np.ndarray, r_min: float, peak: int) -> np.ndarray:
    """Which of the ranges ``r`` do not lie in a small group cut off from the peak's by an
    empty stretch of at least ``_DETACHED_GAP``: what the mask bled onto metres behind (or in
    front of) the object. The three-deviation cut cannot tell: an object seen in two parts
    around an occluder spreads its own ranges widely. A table seen end-on past the chair in
    front of it (two range groups, 1.5-2.0 m and 2.5-3.3 m) kept the 5 % of its mask on the
    wall 6 m off; its floor box reached 2.7 m past the table, the node went to the table's
    far end and stayed there, pass after pass (Environment-A-size floor, seed 9922, table-71)."""
    bins = ((r - r_min) * (1.0 / _BIN)).astype(np.intp)
    occupied = np.flatnonzero(np.bincount(bins[keep], minlength=peak + 1))
    ends = occupied[np.flatnonzero(np.diff(occupied) > _DETACHED_GAP / _BIN)]  # last bin of each group but one
    if ends.size == 0:
        return np.ones(len(r), dtype=bool)
    group = np.searchsorted(ends, bins, side="left")
    small = np.bincount(group[keep], minlength=ends.size + 1) < _DETACHED_SHARE * int(np.count_nonzero(keep))
    small[np.searchsorted(ends, peak, side="left")] = False  # never the peak's own group
    return ~small[group]


def horizontal_extent(points_map: np.ndarray, centre: np.ndarray, quantile: float = 0.95) -> float:
    """How far (m, in the floor plane) the object's visible points spread from its centroid.

    The centroid of a table seen from its end and from its side differs by up to half its
    length; association uses this spread to tell "the same big object from another side"
    from "a second object" (see AssociationParams.extent_gate).
    """
    if len(points_map) == 0:
        return 0.0
    d = np.hypot(points_map[:, 0] - centre[0], points_map[:, 1] - centre[1])
    return float(np.quantile(d, quantile))


def detections_to_observations(frame: RGBDFrame, detections: list[Detection],
                               params: ProjectionParams | None = None,
                               stats: ProjectionStats | None = None) -> list[Observation]:
    """Map-frame observations of the detections' masks (unusable ones are counted in ``stats``)."""
    params = params or ProjectionParams()
    stats = stats if stats is not None else ProjectionStats()
    stride, min_points = params.scaled(frame.shape)
    depth_range = (frame.depth_range[0], min(frame.depth_range[1], params.max_depth))
    T = frame.T_map_camera
    out = []
    for det in detections:
        stats.detections += 1
        if det.mask is None or _mask_bounds(det.mask) is None:
            stats.no_mask += 1
            continue
        cam = backproject(frame.depth, det.mask, frame.K, stride, depth_range)
        if len(cam) == 0:
            stats.no_depth += 1
            continue
        if mostly_beyond(frame.depth, det.mask, stride, depth_range[1]):
            stats.too_far += 1
            continue
        if len(cam) < min_points:
            stats.few_points += 1
            continue
        # A detection whose mask is all floor is no object: a false detection on bare floor
        # (a "sofa" at floor height once stretched a real sofa's footprint over 3 m of the
        # floor beside it, and the node stayed 0.96 m off for the rest of a 12-pass run).
        # An object's own view keeps the floor its mask spilled onto: dropping that too moved
        # every chair's box and merged more chairs (Environment A pass 1, F1 -0.01 on 3 seeds).
        if int(np.count_nonzero(cam @ T[2, :3] + T[2, 3] >= params.floor_height)) < min_points:
            stats.on_floor += 1
            continue
        # The points robust_centroid(points_map, camera position) keeps, cheaper (ranges are
        # norms in the camera frame, and the transform is affine, so only the mean is
        # transformed), and the far part of a deep object that cut dropped (far_part.py).
        ranges = np.sqrt(np.einsum("ij,ij->i", cam, cam))
        keep = _dominant_cluster(ranges)
        kept = cam[keep]
        # The same for the surface the view is of (the nearest dominant range cluster): a
        # shadow taken for a chair, its mask reaching up the wall behind, has enough points
        # above the floor, all of them on the wall. Kept, it was a chair at floor height,
        # seen again from where the robot passed and never denied (hard preset, 36 x 28 m,
        # seed 7752: a chair and a sofa, kept over three passes). Of 7,300 views of true
        # objects measured, two had less than half of it above the floor, the rest 0.56 or more.
        # floor_height 0 turns it off: the floor's own points scatter about 0 with depth noise.
        above = kept @ T[2, :3] + T[2, 3] >= params.floor_height
        if params.floor_height > 0.0 and np.count_nonzero(above) < _STANDING_SHARE * len(kept):
            stats.on_floor += 1
            continue
        surface = kept[above]  # its own surface, not the floor it stands on
        if det.category not in params.flush_categories and is_surface_patch(
                frame.depth, _mask_bounds(det.mask), frame.K, T, depth_range, surface, params.patch_share, stride):
            stats.on_wall += 1  # a false box on a wall (surface_patch.py)
            continue
        whole = kept
        if params.far_part and not isinstance(keep, slice):  # the cut dropped points: some may be its far part
            d, m, r0, c0 = _on_lattice(frame.depth, det.mask, stride)
            whole = np.concatenate([kept, far_part(d, m, (r0, c0), stride, frame.K, T, kept, depth_range,
                                                   params.floor_height, det.mask.shape[1])])
        # The far part moves the centre only; the floor box and the spread stay those of what
        # the cut kept. A box is a view's length, and the longest whole view of a category
        # tells a part of an object from a whole one (bomc_bt.graph.parts): with far parts in
        # the boxes, a chair view grown over the table it touches lengthens every chair's, and
        # at the end of pass 2 of an Environment-A-size floor 23 chairs were joined to their
        # neighbours (seed 9955, object F1 0.990 -> 0.921).
        centre = T[:3, :3] @ whole.mean(axis=0) + T[:3, 3]
        points = kept @ T[:3, :3].T + T[:3, 3]
        lo, hi = np.percentile(points[:, :2], [1.0, 99.0], axis=0)  # the floor area it covers
        if params.centre == "footprint":  # the middle of all its points' floor spread, far part included
            spread = (lo, hi) if whole is kept else np.percentile(whole @ T[:2, :3].T + T[:2, 3], [1.0, 99.0], axis=0)
            centre = np.array([*((spread[0] + spread[1]) / 2.0), centre[2]])
        distance = float(np.median(kept[:, 2]))
        box = np.concatenate([lo, hi]) if distance <= params.box_range else None
        _, top, _, _ = _mask_bounds(det.mask)
        out.append(Observation(det.category, centre, float(det.score), len(cam), horizontal_extent(points, centre),
                               box=box, truncated=truncated(frame.depth, det.mask, distance),
                               above_image=top == 0, colour=surface_colour(frame.rgb, surface, frame.K)))
        stats.observations += 1
    return out


# -- what the frame observes ---------------------------------------------------------------
def fov_polygon(frame: RGBDFrame, params: ProjectionParams | None = None) -> np.ndarray:
    """(K, 2) counter-clockwise map-frame polygon of the floor area the frame observes,
    vertex 0 the camera (:class:`bomc_bt.monitoring.Coverage` cuts its rays from there).

    The paper's "approximate FoV polygon from the limits of the depth point cloud": for
    ``fov_columns`` image columns, the farthest valid depth pixel (capped at ``max_depth``
    along its ray, since farther points are not used for observations either) gives one
    vertex; the polygon is the fan from the camera position through those vertices. Where
    a wall is near, the fan stops at the wall, so nodes behind it are not expected. It
    over-approximates behind objects in the column (use :func:`visible` for occlusion).
    Columns without any valid depth are left out; fewer than two usable columns give an
    empty (0, 2) array.
    """
    params = params or ProjectionParams()
    h, w = frame.shape
    cols = np.unique(np.linspace(0, w - 1, params.fov_columns).round().astype(np.intp))
    lo = frame.depth_range[0]
    with np.errstate(invalid="ignore"):
        d = frame.depth[:, cols]
        d = np.where(d >= lo, np.minimum(d, params.max_depth), -1.0)  # NaN -> -1
    rows = d.argmax(axis=0)
    far = d[rows, np.arange(len(cols))]
    ok = far > 0.0
    if np.count_nonzero(ok) < 2:
        return np.empty((0, 2))
    K = frame.K
    u, v, z = cols[ok].astype(float), rows[ok].astype(float), far[ok].astype(float)
    cam = np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], axis=1)
    T = frame.T_map_camera
    xy = (cam @ T[:3, :3].T + T[:3, 3])[:, :2]
    polygon = np.vstack([T[:2, 3], xy])
    if _signed_area(polygon) < 0.0:  # counter-clockwise, the camera staying vertex 0
        polygon = np.vstack([T[:2, 3], xy[::-1]])
    return polygon


def in_polygon(polygon: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Bool per (x, y) point: inside ``polygon`` (even-odd rule, vectorised)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    poly = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(poly) < 3:
        return np.zeros(len(pts), dtype=bool)
    x, y = pts[:, 0:1], pts[:, 1:2]
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (np.count_nonzero(crosses & (x < x_at), axis=1) % 2) == 1


def visible(frame: RGBDFrame, positions: np.ndarray, margin: float = 0.3,
            max_depth: float | None = None) -> np.ndarray:
    """Bool per map-frame 3D point: expected to be seen in this frame.

    A point is visible when it projects into the image, its depth is within the frame's
    depth range (and ``max_depth``), and the measured depth at its pixel is not more than
    ``margin`` closer than the point -- otherwise something stands in front of it. A pixel
    without valid depth counts as *not* visible: absence of evidence must not remove a node.
    """
    pts = np.asarray(positions, dtype=float).reshape(-1, 3)
    if len(pts) == 0:
        return np.zeros(0, dtype=bool)
    u, v, z, inside = pixels(frame, pts)
    lo, hi = frame.depth_range
    if max_depth is not None:
        hi = min(hi, max_depth)
    inside &= (z >= lo) & (z <= hi)
    out = np.zeros(len(pts), dtype=bool)
    idx = np.flatnonzero(inside)
    measured = frame.depth[v[idx], u[idx]]
    with np.errstate(invalid="ignore"):
        out[idx] = measured >= z[idx] - margin  # NaN compares False
    return out


def pixels(frame: RGBDFrame, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where map-frame ``points`` (n, 3) fall in the frame: pixel columns and rows (0 where
    outside), depths along the optical axis, and whether each is in front and inside the image."""
    T = frame.T_map_camera
    cam = (points - T[:3, 3]) @ T[:3, :3]
    z = cam[:, 2]
    h, w = frame.shape
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.rint(frame.K[0, 0] * cam[:, 0] / z + frame.K[0, 2])
        v = np.rint(frame.K[1, 1] * cam[:, 1] / z + frame.K[1, 2])
    inside = (z > 0.0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    u = np.where(inside, u, 0).astype(np.intp)
    v = np.where(inside, v, 0).astype(np.intp)
    return u, v, z, inside


def _signed_area(polygon: np.ndarray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
