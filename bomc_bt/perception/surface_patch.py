"""A view that is a patch of a bigger surface: a false box on a wall is no object.

A detector's false box on plain background (a wall) gets a mask, and the mask's depth
points stand above the floor, so the floor test of :mod:`bomc_bt.perception.projection`
keeps it. Traced on an unseen 93 x 90 m office (seed 9611, pass 2): the robot stood turning
in front of a corridor wall, and two "cabinet" boxes 6.5 s apart fell on one patch of it,
0.9 m up; the two views confirmed each other, and the pass reported a cabinet added inside
the wall (a phantom, until pass 3 took it off on 17 misses). A wall patch named "sofa" once
stretched a real sofa's footprint along the wall for twelve passes
(:mod:`bomc_bt.graph.walls`).

An object standing on the floor stands out from what is around it: around its box the
camera sees the wall behind it, the floor in front, or something nearer. A patch of a wall
is flat, and the wall goes on around it at the same depth. So a view is a patch when its
own surface (the points the projection kept) is flat, and nearly all of the depth pixels
in a ring round its mask's box lie on that surface's plane. A door in its wall is flush
with it and a flat screen hangs a few centimetres off one, so such categories are exempt
(``projection.flush_categories``).

Only geometry of the one frame: no map, so a wall built after the build map is judged the
same, and so is a cabinet that stood in the build.
"""

from __future__ import annotations

import math

import numpy as np

_MAX_POINTS = 400  # surface points the plane is fitted to (an even subsample of more)
_MAX_RING = 1000  # ring pixels sampled at most (about)
RING_WIDTH = 0.25  # [-] the ring round a box, as a share of the box's width (height) on each side


def plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(centre, unit normal, RMS distance of ``points`` from the plane) of the least-squares
    plane through (N, 3) points, N >= 3."""
    if len(points) > _MAX_POINTS:
        points = points[np.linspace(0, len(points) - 1, _MAX_POINTS).astype(np.intp)]
    centre = points.mean(axis=0)
    _, s, vt = np.linalg.svd(points - centre, full_matrices=False)
    return centre, vt[-1], float(s[-1] / np.sqrt(len(points)))


def ring_points(depth: np.ndarray, bounds: tuple[int, int, int, int], K: np.ndarray, depth_range: tuple[float, float],
                width: float, stride: int) -> np.ndarray:
    """(M, 3) camera-frame points of the valid depth pixels in a band round the box ``bounds``
    (x, y, w, h), ``width`` of the box's size wide on each side (at least 2 pixels), inside
    the image, sampled every ``stride`` pixels or sparser: about ``_MAX_RING`` pixels at most
    (a share needs no more, and a near object's ring has tens of thousands)."""
    x, y, w, h = bounds
    rows, cols = depth.shape
    dx, dy = max(2, round(width * w)), max(2, round(width * h))
    r0, r1, c0, c1 = max(0, y - dy), min(rows, y + h + dy), max(0, x - dx), min(cols, x + w + dx)
    step = max(stride, math.ceil(math.sqrt(max((r1 - r0) * (c1 - c0) - w * h, 1) / _MAX_RING)))
    v, u = np.mgrid[r0:r1:step, c0:c1:step]
    outside = (u < x) | (u >= x + w) | (v < y) | (v >= y + h)
    v, u = v[outside], u[outside]
    z = depth[v, u].astype(float)
    with np.errstate(invalid="ignore"):
        ok = (z > max(depth_range[0], 0.0)) & (z <= depth_range[1])  # NaN compares False
    v, u, z = v[ok], u[ok], z[ok]
    return np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], axis=1)


def on_plane_share(surface: np.ndarray, ring: np.ndarray, rotation: np.ndarray, tolerance: float = 0.05,
                   flatness: float = 0.03, upright: float = 0.3) -> float | None:
    """Share of the ``ring`` points within ``tolerance`` (m) of the plane of ``surface`` (both
    (N, 3), camera frame); None where that is no wall-like plane: fewer than 3 surface points
    or 20 ring points, the surface not flat (RMS distance from its plane above ``flatness``,
    m), or the plane not upright (its normal, turned to the map by ``rotation``, rising more
    than ``upright`` out of the floor plane: a floor-level sliver is the floor tests' to judge)."""
    if len(surface) < 3 or len(ring) < 20:
        return None
    centre, normal, rms = plane(surface)
    if rms > flatness or abs(float((rotation @ normal)[2])) > upright:
        return None
    return float(np.mean(np.abs((ring - centre) @ normal) <= tolerance))


def is_surface_patch(depth: np.ndarray, bounds: tuple[int, int, int, int], K: np.ndarray, T: np.ndarray,
                     depth_range: tuple[float, float], surface: np.ndarray, share: float, stride: int = 1) -> bool:
    """Whether a view whose mask spans ``bounds`` (x, y, w, h) and whose own surface is
    ``surface`` ((N, 3), camera frame; ``T`` the camera's map pose) is a patch of a bigger
    upright flat surface: at least ``share`` of the ring round its box lies on its plane.

    A box touching the image border is not judged: the ring is then on one side only, and
    the views of true objects that came nearest the rule were all such slivers (a cabinet's
    edge 5 pixels wide at the border). ``share`` above 1 turns the test off.
    """
    x, y, w, h = bounds
    rows, cols = depth.shape
    if share > 1.0 or x == 0 or y == 0 or x + w >= cols or y + h >= rows:
        return False
    ring = ring_points(depth, bounds, K, depth_range, RING_WIDTH, stride)
    found = on_plane_share(surface, ring, T[:3, :3])
    return found is not None and found >= share
