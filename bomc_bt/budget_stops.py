"""Where a pass with a budget stops, and which way it looks there.

The full pass's coverage plan (:mod:`bomc_bt.coverage_plan`) is no good source of stops
for a budgeted tour: each of its stops is credited only with the floor no earlier stop,
and no drive along the full tour, sees first. A room the full tour glimpses on the way
gets no stop of its own, and a stop's worth depends on stops the budget will not visit.
A budgeted tour of a few stops must instead stand where each stop itself sees what is
worth seeing, and the worth of a stop is what it adds to the stops already in the tour.

So this module builds the budget's own candidates from the same pieces as the coverage
plan (the floor targets, the reachable lattice places, :class:`~bomc_bt.sight.Sight`):

1. every target gets a weight: the changes waiting in its region (the change model's
   ``waiting``) shared over the region's targets, or, for ``uniform``, its floor area;
2. :func:`shortlist` keeps the places that together see most weight (weighted greedy
   max coverage), so the path-length matrix stays small on a large floor;
3. :class:`MarginalValue` gives the orienteering (:func:`~bomc_bt.budget_plan.orienteer`)
   each place's value given the tour so far: the weight of the targets it sees that no
   stop of the tour sees yet (submodular: two stops looking at one room are not worth two
   rooms);
4. :func:`stop_headings` turns each chosen place into headings facing what it was chosen
   for, as the coverage plan does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bomc_bt.algorithm_params import TraversalParams
from bomc_bt.coverage_plan import _world, candidate_places, turned_stops
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.planner import GridPlanner
from bomc_bt.sight import Sight, headings_for
from bomc_bt.viewpoints import floor_mask


@dataclass
class StopCandidates:
    """Places the robot can stop at and the floor targets each sees all around."""

    xy: np.ndarray  # (K, 2) map-frame positions
    views: list[np.ndarray]  # per place: flat indices into the target raster it sees
    shape: tuple[int, int]  # the target raster (every k-th map cell)
    k: int  # map cells per target step
    target_step: float  # [m] between targets

    def target_xy(self, grid: OccupancyGrid, flat: np.ndarray) -> np.ndarray:
        rows, cols = np.divmod(np.asarray(flat, dtype=np.int64), self.shape[1])
        return _world(grid, rows * self.k, cols * self.k)

    def subset(self, keep: list[int]) -> StopCandidates:
        return StopCandidates(self.xy[keep], [self.views[i] for i in keep], self.shape, self.k, self.target_step)


def stop_candidates(grid: OccupancyGrid, planner: GridPlanner, start: Pose2D, view_range: float,
                    params: TraversalParams) -> StopCandidates:
    """The coverage plan's candidate places (reachable, with clearance) and their views."""
    k = max(1, int(round(params.target_step / grid.resolution)))
    m = max(1, int(round(params.candidate_step / (k * grid.resolution))))
    floor = floor_mask(grid, params.shadow)[::k, ::k]
    places = candidate_places(grid, planner, start, floor.shape, k, m, params.clearance)
    views = Sight(grid, floor, k, view_range, params.min_range, params.shadow).visible(places)
    return StopCandidates(_world(grid, places[:, 0] * k, places[:, 1] * k).reshape(-1, 2), views, floor.shape, k,
                          k * grid.resolution)


def target_weights(cands: StopCandidates, region_n: int, waiting: np.ndarray | None) -> np.ndarray:
    """Per target of the raster: the changes expected waiting there (its region's ``waiting``
    shared over the region's targets some place sees); ``waiting`` None: its floor area."""
    n = cands.shape[0] * cands.shape[1]
    seeable = np.zeros(n, dtype=bool)
    for v in cands.views:
        seeable[v] = True
    if waiting is None:
        return np.where(seeable, cands.target_step**2, 0.0)
    rows, cols = np.divmod(np.arange(n), cands.shape[1])
    ri = np.clip((rows * cands.k) // region_n, 0, waiting.shape[0] - 1)
    rj = np.clip((cols * cands.k) // region_n, 0, waiting.shape[1] - 1)
    per_region = np.zeros(waiting.shape, dtype=float)
    np.add.at(per_region, (ri[seeable], rj[seeable]), 1.0)
    share = np.where(per_region > 0, waiting / np.maximum(per_region, 1.0), 0.0)
    return np.where(seeable, share[ri, rj], 0.0)


class MarginalValue:
    """Each place's value given the targets already seen: the weight of the rest it sees.

    The views are kept as one flat index array with offsets, so the values of all places
    are one ``np.add.reduceat`` per call."""

    def __init__(self, views: list[np.ndarray], weights: np.ndarray):
        self.lens = np.array([len(v) for v in views], dtype=np.int64)
        self.indices = np.concatenate(views).astype(np.int64) if self.lens.sum() else np.zeros(0, np.int64)
        self.starts = np.concatenate([[0], np.cumsum(self.lens)[:-1]]).astype(np.int64)
        self.views, self.weights = views, np.asarray(weights, dtype=float)

    def values(self, taken: list[int]) -> np.ndarray:
        """(K,) value of each place after the places ``taken`` have looked."""
        left = self.weights.copy()
        for i in taken:
            left[self.views[i]] = 0.0
        return self._sums(left)

    def _sums(self, left: np.ndarray) -> np.ndarray:
        if not len(self.indices):
            return np.zeros(len(self.lens))
        sums = np.add.reduceat(np.append(left[self.indices], 0.0), np.minimum(self.starts, len(self.indices)))
        return np.where(self.lens > 0, sums[:len(self.lens)], 0.0)


def shortlist(cands: StopCandidates, weights: np.ndarray, count: int, start_xy, max_range: float) -> list[int]:
    """Up to ``count`` places that together see most weight (weighted greedy max coverage),
    each adding some; the places within ``max_range`` (m, straight line) of the start only."""
    value = MarginalValue(cands.views, weights)
    near = np.hypot(cands.xy[:, 0] - start_xy[0], cands.xy[:, 1] - start_xy[1]) <= max_range
    left = value.weights.copy()
    chosen: list[int] = []
    while len(chosen) < count:
        gains = np.where(near, value._sums(left), 0.0)
        i = int(np.argmax(gains))  # ties: the lowest index (raster order), deterministic
        if gains[i] <= 1e-12:
            break
        chosen.append(i)
        left[cands.views[i]] = 0.0
    return chosen


def stop_headings(grid: OccupancyGrid, planner: GridPlanner, cands: StopCandidates, weights: np.ndarray,
                  order: list[int], start: Pose2D, params: TraversalParams, end_xy=None) -> list[list[Pose2D]]:
    """Per stop of the tour (``order``, indices into ``cands``): the poses it turns through,
    facing the valued targets it is the first of the tour to see, in the order that turns
    least between the legs in and out (the last leg goes to ``end_xy``, the dock)."""
    hfov = math.radians(params.hfov_deg)
    min_count = max(1, int(math.ceil((params.min_gain / cands.target_step) ** 2 - 1e-9)))
    left = np.asarray(weights, dtype=float) > 0
    headings: list[list[float]] = []
    for s in order:
        p = cands.xy[s]
        mine = cands.views[s][left[cands.views[s]]]
        left[cands.views[s]] = False
        targets = cands.target_xy(grid, mine)
        bearings = np.arctan2(targets[:, 1] - p[1], targets[:, 0] - p[0])
        headings.append(headings_for(bearings, hfov, min_count, params.max_headings))
    return turned_stops(planner, start, cands.xy[list(order)].reshape(-1, 2), headings, end_xy)


def heading_counts(grid: OccupancyGrid, cands: StopCandidates, weights: np.ndarray,
                   params: TraversalParams) -> np.ndarray:
    """Per place: how many headings it turns through to face all the valued targets it sees
    (the orienteering's time at a stop; in the tour a stop may need fewer)."""
    hfov = math.radians(params.hfov_deg)
    min_count = max(1, int(math.ceil((params.min_gain / cands.target_step) ** 2 - 1e-9)))
    out = np.ones(len(cands.views), dtype=float)
    for i, v in enumerate(cands.views):
        mine = v[np.asarray(weights)[v] > 0]
        if len(mine):
            t = cands.target_xy(grid, mine)
            bearings = np.arctan2(t[:, 1] - cands.xy[i, 1], t[:, 0] - cands.xy[i, 0])
            out[i] = max(1, len(headings_for(bearings, hfov, min_count, params.max_headings)))
    return out
