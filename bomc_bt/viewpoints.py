"""Gap viewpoints: where to stand, and which way to look, to see what a pass has not seen.

The paper's monitor samples waypoints along the build trajectory. The build drove where
frontiers led, which is not everywhere the camera needs to look: a room mapped by the lidar
through its door, or the far side of a table, may never come into the camera's view, and
objects there are never detected (nor their removal noticed). After the planned waypoints,
the pass knows which free floor its camera actually saw (:class:`~bomc_bt.monitoring.Coverage`);
this module turns the rest into a few extra viewpoints.

Greedy set cover on a coarse lattice: unseen floor in regions of at least ``min_area``
is the target -- free cells, and unknown cells within ``shadow`` of free ones, because
furniture is exactly what casts lidar shadows (the lidar sees a table's legs, the camera
the chair behind it); candidates are places the robot can reach (through gaps of twice
``pass_clearance``) with ``clearance``; a candidate sees a target within ``view_range``
(and beyond ``min_range``, where the tilted camera's image starts) along a line that
crosses no occupied cell and unknown ones only in the target's own shadow; the best
heading of a candidate is the ``hfov``-wide window holding most targets not yet covered.
Viewpoints are taken while one still adds ``min_gain`` square metres, at most
``max_viewpoints``, and ordered by nearest neighbour from the robot.

After a resumed pass only the frames since the resume count as seen, so the gap phase
may then add viewpoints an uninterrupted pass would not need: extra driving, never a
missed look.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid


@dataclass
class GapParams:
    """Settings of the gap-viewpoint search (a leaf's ``params`` in ``trees/traverse.yaml``)."""

    min_area: float = 1.0  # m²: unseen regions smaller than this are left alone
    # extra viewpoints per pass at most: a bound on the extra driving; min_gain is what
    # normally ends the list (on office-s the 20th viewpoint, 1.5 m², was the only one
    # that sees into a room whose door a chair half blocks)
    max_viewpoints: int = 40
    min_gain: float = 1.0  # m² of newly seen floor that makes a viewpoint worth driving to
    # m: planned reach of the camera; projection.expect_range, so a viewpoint is planned as
    # far as the graph would expect (and confirm) objects in a frame
    view_range: float = 5.0
    min_range: float = 1.0  # m: nearer floor is below the tilted camera's image
    hfov_deg: float = 50.0  # planned field of view: the camera's, less a margin
    clearance: float = 0.45  # m from obstacles for a viewpoint
    pass_clearance: float = 0.3  # m: the robot's radius, for what it can reach (a narrow door)
    # m of unknown map beyond free floor that count as floor to see: the lidar's shadows,
    # which is where furniture stands (the lidar sees legs, the camera the whole chair)
    shadow: float = 0.75
    target_step: float = 0.25  # m between target samples
    candidate_step: float = 0.5  # m between candidate viewpoints

    def __post_init__(self) -> None:
        if self.min_area < 0 or self.min_gain < 0:
            raise ValueError("min_area and min_gain must be >= 0")
        if self.max_viewpoints < 0:
            raise ValueError("max_viewpoints must be >= 0")
        if not 0 <= self.min_range < self.view_range:
            raise ValueError("need 0 <= min_range < view_range")
        if not 0 < self.hfov_deg <= 360:
            raise ValueError("hfov_deg must be in (0, 360]")
        if self.clearance < 0 or self.target_step <= 0 or self.candidate_step <= 0:
            raise ValueError("clearance must be >= 0 and the steps > 0")
        if not 0 <= self.pass_clearance <= self.clearance:
            raise ValueError("need 0 <= pass_clearance <= clearance")
        if self.shadow < 0:
            raise ValueError("shadow must be >= 0")


def floor_mask(grid: OccupancyGrid, shadow: float) -> np.ndarray:
    """Where objects can stand: free cells, and unknown ones within ``shadow`` metres of them."""
    free = grid.free_mask()
    if shadow <= 0:
        return free
    near = cv2.distanceTransform((~free).astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    return free | (grid.unknown_mask() & (near <= shadow))


def gap_targets(grid: OccupancyGrid, seen: np.ndarray, params: GapParams) -> np.ndarray:
    """(M, 2) map points sampling the floor not seen, in regions of at least min_area.

    Floor is the free cells and the unknown cells within ``shadow`` of them: behind a
    table or a chair the lidar saw only legs, and the camera, higher up, sees what stands
    there.
    """
    missing = (floor_mask(grid, params.shadow) & ~seen.astype(bool)).astype(np.uint8)
    missing = cv2.morphologyEx(missing, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))  # no slivers
    n, labels, stats, _ = cv2.connectedComponentsWithStats(missing, connectivity=8)
    big = np.zeros(n, dtype=bool)
    big[1:] = stats[1:, cv2.CC_STAT_AREA] * grid.resolution**2 >= params.min_area
    step = max(1, round(params.target_step / grid.resolution))
    lattice = np.zeros_like(missing, dtype=bool)
    lattice[::step, ::step] = True
    rows, cols = np.nonzero(big[labels] & lattice)
    x, y = grid.cell_to_world(rows, cols)
    return np.stack([np.asarray(x, float), np.asarray(y, float)], axis=1).reshape(-1, 2)


def _candidates(grid: OccupancyGrid, targets: np.ndarray, start: tuple[float, float] | None,
                params: GapParams) -> np.ndarray:
    """(K, 2) reachable free places with clearance, within view range of some target."""
    free = grid.free_mask().astype(np.uint8)
    room = cv2.distanceTransform(free, cv2.DIST_L2, 5) * grid.resolution
    clear = room >= params.clearance
    if start is not None:  # the free space the robot can drive in, through doors narrower than 2 * clearance
        _, labels = cv2.connectedComponents((room >= params.pass_clearance).astype(np.uint8), connectivity=8)
        r, c = grid.world_to_cell(np.array([start[0]]), np.array([start[1]]))
        if grid.in_bounds(r, c)[0] and labels[r[0], c[0]] > 0:
            clear &= labels == labels[r[0], c[0]]
    near = np.zeros(free.shape, np.uint8)
    tr, tc = grid.world_to_cell(targets[:, 0], targets[:, 1])
    near[tr, tc] = 1
    reach = cv2.distanceTransform(1 - near, cv2.DIST_L2, 5) * grid.resolution <= params.view_range
    step = max(1, round(params.candidate_step / grid.resolution))
    lattice = np.zeros(free.shape, dtype=bool)
    lattice[::step, ::step] = True
    rows, cols = np.nonzero(clear & reach & lattice)
    x, y = grid.cell_to_world(rows, cols)
    return np.stack([np.asarray(x, float), np.asarray(y, float)], axis=1).reshape(-1, 2)


class _Blocked:
    """What stops the camera's view, pooled to ``cell`` metres so a ray sampled every
    ``cell`` cannot step over a one-cell wall: occupied cells, and unknown ones."""

    def __init__(self, grid: OccupancyGrid, cell: float):
        self.k = max(1, round(cell / grid.resolution))
        self.occupied = self._pool(grid.occupied_mask())
        self.unknown = self._pool(~grid.free_mask())
        self.origin, self.cell = grid.origin, grid.resolution * self.k

    def _pool(self, mask: np.ndarray) -> np.ndarray:
        k = self.k
        h, w = -(-mask.shape[0] // k) * k, -(-mask.shape[1] // k) * k
        padded = np.ones((h, w), dtype=bool)
        padded[: mask.shape[0], : mask.shape[1]] = mask
        return padded.reshape(h // k, k, w // k, k).any(axis=(1, 3))

    def hits(self, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(occupied, occupied or unknown) at each point; outside the map is both."""
        cols = np.floor((xs - self.origin[0]) / self.cell).astype(np.int64)
        rows = np.floor((ys - self.origin[1]) / self.cell).astype(np.int64)
        inside = (rows >= 0) & (rows < self.occupied.shape[0]) & (cols >= 0) & (cols < self.occupied.shape[1])
        occ, unk = np.ones(xs.shape, dtype=bool), np.ones(xs.shape, dtype=bool)
        occ[inside] = self.occupied[rows[inside], cols[inside]]
        unk[inside] = self.unknown[rows[inside], cols[inside]]
        return occ, unk


def _visible(blocked: _Blocked, at: np.ndarray, targets: np.ndarray, params: GapParams) -> np.ndarray:
    """Indices of ``targets`` in range of ``at`` with a clear line of sight to them: no
    occupied cell on the way, and unknown ones only in the last ``shadow`` metres."""
    d = np.hypot(targets[:, 0] - at[0], targets[:, 1] - at[1])
    idx = np.nonzero((d >= params.min_range) & (d <= params.view_range))[0]
    if len(idx) == 0:
        return idx
    samples = max(2, int(math.ceil(params.view_range / blocked.cell)) + 1)
    # stop a cell short of the target: its own (pooled) cell may hold the wall it stands by
    t = np.linspace(0.0, 1.0, samples)[None, :] * np.maximum(0.0, 1.0 - 1.5 * blocked.cell / d[idx])[:, None]
    xs = at[0] + t * (targets[idx, 0] - at[0])[:, None]
    ys = at[1] + t * (targets[idx, 1] - at[1])[:, None]
    occ, unk = blocked.hits(xs, ys)
    before_shadow = t * d[idx][:, None] < d[idx][:, None] - params.shadow - blocked.cell
    return idx[~(occ | (unk & before_shadow)).any(axis=1)]


def best_heading(bearings: np.ndarray, weight: np.ndarray, hfov: float) -> tuple[float, float]:
    """(heading, weight inside) of the hfov-wide window holding the most weight."""
    if len(bearings) == 0 or not weight.any():
        return 0.0, 0.0
    order = np.argsort(bearings)
    b, w = bearings[order], weight[order].astype(float)
    b2 = np.concatenate([b, b + 2 * math.pi])
    cum = np.concatenate([[0.0], np.cumsum(np.concatenate([w, w]))])
    end = np.searchsorted(b2, b + hfov, side="right")
    inside = cum[end] - cum[np.arange(len(b))]
    k = int(np.argmax(inside))
    ends = b2[min(end[k], len(b2)) - 1]
    heading = math.atan2(math.sin((b[k] + ends) / 2), math.cos((b[k] + ends) / 2))
    return heading, float(inside[k])


def gap_viewpoints(grid: OccupancyGrid, seen: np.ndarray, start: Pose2D | None,
                   params: GapParams | None = None) -> list[Pose2D]:
    """Viewpoints (with the heading to face) that see most of what ``seen`` lacks."""
    params = params or GapParams()
    if params.max_viewpoints == 0:
        return []
    targets = gap_targets(grid, seen, params)
    if len(targets) == 0:
        return []
    xy = None if start is None else (start.x, start.y)
    candidates = _candidates(grid, targets, xy, params)
    blocked = _Blocked(grid, 0.1)
    views = [_visible(blocked, c, targets, params) for c in candidates]
    bearings = [np.arctan2(targets[v, 1] - c[1], targets[v, 0] - c[0]) for c, v in zip(candidates, views, strict=True)]
    covered = np.zeros(len(targets), dtype=bool)
    cell = params.target_step**2
    hfov = math.radians(params.hfov_deg)
    chosen: list[Pose2D] = []
    while len(chosen) < params.max_viewpoints:
        best = (0.0, -1, 0.0)
        for k, (v, b) in enumerate(zip(views, bearings, strict=True)):
            if len(v) * cell < max(params.min_gain, best[0] * cell):
                continue  # cannot beat the best even if all of it were new
            heading, gain = best_heading(b, ~covered[v], hfov)
            if gain > best[0]:
                best = (gain, k, heading)
        gain, k, heading = best
        if k < 0 or gain * cell < params.min_gain:
            break
        v, b = views[k], bearings[k]
        covered[v[np.abs(np.angle(np.exp(1j * (b - heading)))) <= hfov / 2 + 1e-9]] = True
        chosen.append(Pose2D(float(candidates[k, 0]), float(candidates[k, 1]), heading))
    return _nearest_neighbour_order(chosen, start)


def _nearest_neighbour_order(views: list[Pose2D], start: Pose2D | None) -> list[Pose2D]:
    if not views or start is None:
        return views
    left, out, at = list(views), [], (start.x, start.y)
    while left:
        nxt = min(left, key=lambda p: (math.hypot(p.x - at[0], p.y - at[1]), p.x, p.y))
        left.remove(nxt)
        out.append(nxt)
        at = (nxt.x, nxt.y)
    return out
