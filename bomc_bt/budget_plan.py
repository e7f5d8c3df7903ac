"""A pass with a budget of robot time: which viewpoints to visit, and when to head home.

The full pass (:mod:`bomc_bt.coverage_plan`) visits every stop; with a budget the robot
can afford only some, so the question is an orienteering problem: a tour from the dock
and back to it, no longer than the budget in robot time, that collects the most value.
A stop's value is what it is expected to find (:mod:`bomc_bt.change_model`): for each
region, the changes waiting there times the share of the region's floor this stop sees
first; with ``budget.strategy: uniform`` it is the floor it sees (every region alike).

:func:`orienteer` is a greedy insertion heuristic (as for the prize-collecting TSP): it
starts with the empty tour dock -> dock and repeatedly inserts the stop, at its cheapest
place in the tour, with the most value per second added (driving ``d / speed`` plus
``heading_time`` per heading), as long as the tour still fits the budget; after each
insertion 2-opt shortens the tour, which makes room for more. Times are planned on grid
path lengths (:mod:`bomc_bt.path_matrix`).

What the plan cannot foresee (a detour, a slow turn) is caught while driving by
:meth:`PassBudget.allows`: before each waypoint the robot checks that it can still get
there, look, and drive home within the budget; when it cannot, the rest of the tour is
skipped and the next waypoint is the dock. The same check cuts the ``cut`` strategy's
tour (the configured full plan in order).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from bomc_bt.traversal import two_opt_route


@dataclass
class PassBudget:
    """What a budgeted pass committed to: JSON-able, saved with the pass for ``--resume``."""

    seconds: float  # [s] the budget, from the session's start
    strategy: str
    speed: float  # [m/s] planned driving speed
    heading_time: float  # [s] planned per waypoint (one heading)
    started: float = 0.0  # [s] robot time the session started (the budget counts from there)
    home_m: list[float] = field(default_factory=list)  # per waypoint: path length back to the dock
    planned_s: float = 0.0  # the tour's planned time
    expected_changes: float = 0.0  # the changes the tour is expected to find (the model's)
    stops: int = 0  # stops in the tour, of ``stops_total``
    stops_total: int = 0
    full_pass: bool = False  # the budget covers a full pass: run one, unchanged

    def allows(self, elapsed: float, leg_m: float, index: int) -> bool:
        """Can the robot, ``elapsed`` seconds into the pass and ``leg_m`` from waypoint
        ``index``, still go there, look, and get back to the dock within the budget?"""
        if self.full_pass or index >= len(self.home_m) - 1:  # the last waypoint is the dock itself
            return True
        need = (leg_m + self.home_m[index]) / self.speed + self.heading_time
        return elapsed + need <= self.seconds

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict) -> PassBudget:
        return cls(**{k: data[k] for k in cls.__dataclass_fields__ if k in data})


@dataclass
class Tour:
    """The chosen stops in visiting order (indices into the candidate stops) and its cost."""

    order: list[int]
    seconds: float  # planned: driving from and back to the dock plus the stops' time
    value: float


def orienteer(dist: np.ndarray, values: np.ndarray, service: np.ndarray, speed: float, budget: float,
              max_two_opt_passes: int = 20) -> Tour:
    """The tour over stops 1..n of ``dist`` (metres, place 0 the dock) worth most within ``budget`` s.

    ``values`` and ``service`` (seconds at each stop) are per stop (length n). A budget
    that does not reach any stop and back gives the empty tour: the robot stays home.
    """
    n = len(values)
    travel = np.where(np.isfinite(dist), dist, np.inf) / speed
    closed = np.vstack([np.hstack([travel, travel[:, :1]]), np.hstack([travel[:1], [[0.0]]])])
    route = [0, n + 1]  # dock ... dock (the copy at n + 1 keeps the way back in 2-opt)
    used = np.zeros(n + 1, dtype=bool)
    used[0] = True
    value = np.concatenate([[0.0], np.asarray(values, float)])
    stay = np.concatenate([[0.0], np.asarray(service, float)])
    cost = _route_seconds(closed, route, stay)
    while True:
        a, b = np.array(route[:-1]), np.array(route[1:])
        cand = np.nonzero(~used)[0]
        if not len(cand):
            break
        bi = np.where(b == n + 1, 0, b)
        added = travel[a][:, cand] + travel[cand][:, bi].T - travel[a, bi][:, None] + stay[cand][None, :]
        added = np.where(np.isfinite(added), added, np.inf)
        best_edge = np.argmin(added, axis=0)
        extra = added[best_edge, np.arange(len(cand))]
        fits = (cost + extra <= budget) & (value[cand] > 0)
        if not fits.any():
            break
        ratio = np.where(fits, value[cand] / np.maximum(extra, 1e-6), -1.0)
        k = int(np.argmax(ratio))  # ties: the lowest index, so the tour is deterministic
        route.insert(int(best_edge[k]) + 1, int(cand[k]))
        used[cand[k]] = True
        if len(route) > 3:
            route = two_opt_route(np.where(np.isfinite(closed), closed, 1e9), route, max_two_opt_passes,
                                  fixed_first=True, fixed_last=True)
        cost = _route_seconds(closed, route, stay)
    order = [i - 1 for i in route[1:-1]]
    return Tour(order, cost, float(sum(values[i] for i in order)))


def _route_seconds(closed: np.ndarray, route: list[int], stay: np.ndarray) -> float:
    drive = sum(closed[a, b] for a, b in zip(route[:-1], route[1:], strict=True))
    return float(drive + sum(stay[i] for i in route[1:-1]))


def stop_values(stop_targets: list[np.ndarray], target_shape: tuple[int, int], target_step: float,
                region_of_target, waiting: np.ndarray | None) -> np.ndarray:
    """Each stop's value: the floor it sees first (``waiting`` None: uniform), or the changes
    expected there: per region, waiting changes times the share of its floor targets seen.

    ``region_of_target(rows, cols)`` gives the region (i, j) of target raster cells.
    """
    if waiting is None:
        return np.array([float(len(t)) for t in stop_targets]) * target_step**2
    rows, cols = np.divmod(np.arange(target_shape[0] * target_shape[1]), target_shape[1])
    ti, tj = region_of_target(rows, cols)
    ti, tj = np.clip(ti, 0, waiting.shape[0] - 1), np.clip(tj, 0, waiting.shape[1] - 1)
    per_region = np.zeros(waiting.shape, dtype=float)
    seen_any = np.zeros(rows.size, dtype=bool)
    for t in stop_targets:
        seen_any[t] = True
    np.add.at(per_region, (ti[seen_any], tj[seen_any]), 1.0)
    weight = np.where(per_region > 0, waiting / np.maximum(per_region, 1.0), 0.0)[ti, tj]
    return np.array([float(weight[t].sum()) for t in stop_targets])


def leg_length(a, b) -> float:
    """Straight-line metres: the guard's cheap, optimistic leg when no planner is at hand."""
    return math.hypot(b[0] - a[0], b[1] - a[1])
