"""A pass with a budget of robot time: which viewpoints to visit, and when to head home.

The full pass (:mod:`bomc_bt.coverage_plan`) visits every stop; with a budget the robot
can afford only some, so the question is an orienteering problem: a tour from the dock
and back to it, no longer than the budget in robot time, that collects the most value.
A stop's value is what it is expected to find (:mod:`bomc_bt.change_model`) that the
stops already in the tour do not see (:mod:`bomc_bt.budget_stops`): for each region, the
changes waiting there times the share of the region's floor it adds; with
``budget.strategy: uniform`` it is the floor it adds (every region alike).

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
from collections.abc import Callable
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
    planned_m: float = 0.0  # [m] the tour's planned driving (grid path lengths, back to the dock included)
    headings: int = 0  # the tour's headings (waypoints but the dock)
    elapsed: float = 0.0  # [s] robot time gone when the tour was planned (relocalization)
    expected_changes: float = 0.0  # the changes the tour is expected to find (the model's)
    stops: int = 0  # stops in the tour, of ``stops_total``
    stops_total: int = 0
    full_pass: bool = False  # the budget covers a full pass: run one, unchanged
    driven_m: float = 0.0  # [m] driven on the legs reached so far (NavigateTo's odometer)
    odometer: float | None = None  # [m] the robot's odometer when the pass left the dock
    homeward: bool = False  # a detour used up the budget: no more tour waypoints, only the dock
    mapped_m: float = 0.0  # [m] the saved map's path lengths of those legs

    @property
    def detour(self) -> float:
        """How much longer the pass's legs were than the saved map says (>= 1): a corridor
        closed since the map was made lengthens the way home too, so the way home is
        reckoned that much longer."""
        return max(1.0, self.driven_m / self.mapped_m) if self.mapped_m > 0 else 1.0

    def note_leg(self, mapped_m: float, driven_m: float) -> None:
        """A leg reached: ``mapped_m`` on the saved map, ``driven_m`` driven."""
        if math.isfinite(mapped_m) and mapped_m > 0:
            self.mapped_m += mapped_m
            self.driven_m += driven_m

    def way_back_too_long(self, elapsed: float, odometer: float, leg_back_m: float = math.inf) -> bool:
        """On a leg the saved map proved wrong (a detour), the way home known to be open is
        the way the robot came: back along this leg to where it started, then home from there
        as the pass reckons its way home (``leg_back_m``), and never more than all it drove
        since the dock. Is that now too long to arrive within the budget?

        All it drove alone is far too much late in a long pass: on a 93 x 90 m floor one
        detour sent the robot home with 227 of 829 waypoints and 2,160 of its 5,946 s left."""
        if self.full_pass or self.odometer is None:
            return False
        back_m = min(odometer - self.odometer, leg_back_m)
        return elapsed + back_m / self.speed + self.heading_time > self.seconds

    def home_seconds(self, index: int) -> float:
        """Planned seconds from waypoint ``index`` home to the dock, detours reckoned in."""
        return self.home_m[index] * self.detour / self.speed

    def allows(self, elapsed: float, leg_m: float, index: int) -> bool:
        """Can the robot, ``elapsed`` seconds into the pass and ``leg_m`` from waypoint
        ``index``, still go there, look, and get back to the dock within the budget? The
        dock is a waypoint too: arriving there (turning to its heading) takes a heading's time."""
        if self.full_pass or index >= len(self.home_m) - 1:  # the last waypoint is the dock itself
            return True
        if self.homeward:
            return False
        need = leg_m * self.detour / self.speed + self.home_seconds(index) + 2 * self.heading_time
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
              max_two_opt_passes: int = 20, marginal: Callable[[list[int]], np.ndarray] | None = None) -> Tour:
    """The tour over stops 1..n of ``dist`` (metres, place 0 the dock) worth most within ``budget`` s.

    ``values`` and ``service`` (seconds at each stop) are per stop (length n). With
    ``marginal``, a stop's value depends on the tour: ``marginal(stops in the tour)`` gives
    every stop's value added to it (what it sees that the tour does not yet), and the
    tour's value is the sum of what each stop added when it was inserted. A budget that
    does not reach any stop and back gives the empty tour: the robot stays home.
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
    total = 0.0
    while True:
        if marginal is not None:
            value = np.concatenate([[0.0], np.asarray(marginal([i - 1 for i in route[1:-1]]), float)])
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
        total += float(value[cand[k]])
        used[cand[k]] = True
        if len(route) > 3:
            route = two_opt_route(np.where(np.isfinite(closed), closed, 1e9), route, max_two_opt_passes,
                                  fixed_first=True, fixed_last=True)
        cost = _route_seconds(closed, route, stay)
    order = [i - 1 for i in route[1:-1]]
    return Tour(order, cost, total)


def _route_seconds(closed: np.ndarray, route: list[int], stay: np.ndarray) -> float:
    drive = sum(closed[a, b] for a, b in zip(route[:-1], route[1:], strict=True))
    return float(drive + sum(stay[i] for i in route[1:-1]))


def leg_length(a, b) -> float:
    """Straight-line metres: the guard's cheap, optimistic leg when no planner is at hand."""
    return math.hypot(b[0] - a[0], b[1] - a[1])
