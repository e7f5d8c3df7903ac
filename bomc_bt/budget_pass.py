"""Planning a monitor pass with a budget, and keeping it within the budget while it runs.

The pieces: the site's change model (:mod:`bomc_bt.change_model`), the stops that see
what is worth seeing (:mod:`bomc_bt.budget_stops`) and the orienteering tour over them
(:mod:`bomc_bt.budget_plan`). :func:`plan_budget_pass` turns them into an ordinary
:class:`~bomc_bt.traversal.TraversalPlan` ending at the dock, plus the
:class:`~bomc_bt.budget_plan.PassBudget` the waypoint loop checks before each waypoint
(:func:`next_within_budget`, :func:`budget_spent`).

A budget at least as long as the site's full passes take (:func:`last_full_pass_seconds`:
the median of the last three; ``budget.full_tolerance`` short of it is as good) runs a
full pass, unchanged: with that much time nothing is gained by leaving anything out.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bomc_bt.budget_plan import PassBudget, orienteer
from bomc_bt.budget_stops import (
    MarginalValue,
    heading_counts,
    shortlist,
    stop_candidates,
    stop_headings,
    target_weights,
)
from bomc_bt.change_model import ChangeModel, RegionGrid, region_rows, skipped_regions
from bomc_bt.config import Config
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.path_matrix import path_length_matrix
from bomc_bt.planner import GridPlanner
from bomc_bt.traversal import TraversalPlan, path_length


def budget_key(session: int) -> str:
    """Where a pass's budget is saved in the store's progress table (read back on --resume)."""
    return f"budget/{session}"


def last_full_pass_seconds(sessions, count: int = 3) -> float | None:
    """Robot time a full pass of the site takes: the median of its last ``count`` completed
    full passes (one slow pass, a detour around a closed corridor, does not move it much);
    None when it had none."""
    times = []
    for s in sorted(sessions, key=lambda r: -r.number):
        budget = s.report.get("budget") if isinstance(s.report, dict) else None
        full = not budget or not budget.get("seconds") or budget.get("full_pass")
        if s.outcome == "completed" and full and s.started_stamp is not None and s.ended_stamp is not None:
            times.append(s.ended_stamp - s.started_stamp)
        if len(times) == count:
            break
    return float(np.median(times)) if times else None


def load_model(store, grid: OccupancyGrid, config: Config, before: int | None = None) -> ChangeModel:
    """The change model of the site in ``store`` on ``grid`` (the uniform prior without
    history), from the passes before session ``before`` (all when None)."""
    rows = [r for r in store.region_rows() if before is None or r[0] < before]
    return ChangeModel(RegionGrid(grid, config.budget.region_size), config.budget, rows)


def pass_regions(store, grid: OccupancyGrid, config: Config, seen: np.ndarray | None, changes, session: int,
                 stamp: float | None, budget: PassBudget | None) -> tuple[list[tuple], dict]:
    """What a pass adds to the change model (the store's rows) and what its report says of
    it: the budget it ran with and the regions it skipped, with how stale each now is.
    ``seen``: the floor the pass looked at; ``changes``: its net changes."""
    model = load_model(store, grid, config, before=session)
    seen = np.zeros(grid.data.shape, dtype=bool) if seen is None else seen
    objects = np.array([n.position[:2] for n in store.graph_after(session - 1)], dtype=float).reshape(-1, 2)
    rows = region_rows(model.regions, seen, changes, session, stamp, model, objects, config.budget.object_reach)
    info = {k: v for k, v in (budget.to_json() if budget else {}).items() if k != "home_m"}
    skipped = skipped_regions(model, rows, session)
    return rows, {**info, "regions": len(rows), "skipped_regions": skipped}


def plan_budget_pass(grid: OccupancyGrid, dock: Pose2D, pose: Pose2D, config: Config, model: ChangeModel,
                     session: int, seconds: float, elapsed: float, started: float, view_range: float,
                     full_plan: Callable[[], TraversalPlan]) -> tuple[TraversalPlan, PassBudget]:
    """The pass's plan and budget: ``seconds`` of robot time from the session's start, of
    which ``elapsed`` are gone (relocalization). ``full_plan`` makes the configured plan
    (for the ``cut`` strategy)."""
    p = config.budget
    budget = PassBudget(seconds, p.strategy, p.speed, p.heading_time, started=started, elapsed=round(elapsed, 2))
    planner = GridPlanner(grid, config.sim.planner)
    if p.strategy == "cut":
        plan = full_plan()
        waypoints = [*plan.waypoints, dock]
        home = planner.path_lengths_from(dock.xy)(np.array([[w.x, w.y] for w in waypoints]))
        budget.home_m = [float(h) if np.isfinite(h) else 1e6 for h in home]
        budget.stops = budget.stops_total = len(plan.waypoints)
        return TraversalPlan(waypoints, plan.euclidean_length, plan.grid_length), budget
    places = stop_candidates(grid, planner, pose, p.view_range or view_range, config.traversal)
    waiting = None if p.strategy == "uniform" else model.waiting(session)
    weights = target_weights(places, model.regions.n, waiting)
    available = seconds * (1.0 - p.margin) - elapsed - p.heading_time  # the dock's arrival: one heading
    count = p.max_stops
    while True:
        keep = shortlist(places, weights, count, pose.xy, available * p.speed / 2)
        cands = places.subset(keep)
        dist = path_length_matrix(planner, np.vstack([np.asarray(pose.xy, float), cands.xy]),
                                  config.traversal.path_resolution)
        value = MarginalValue(cands.views, weights)
        service = heading_counts(grid, cands, weights, config.traversal) * p.heading_time
        tour = orienteer(dist, value.values([]), service, p.speed, available, config.traversal.max_two_opt_passes,
                         marginal=value.values)
        if not budget_outgrows_shortlist(len(tour.order), len(keep), count, tour.seconds, available):
            break
        count = min(2 * count, MAX_SHORTLIST)
    waypoints: list[Pose2D] = []
    home: list[float] = []
    turned = stop_headings(grid, planner, cands, weights, tour.order, pose, config.traversal, dock.xy)
    for s, views in zip(tour.order, turned, strict=True):
        waypoints += views
        home += [float(dist[s + 1, 0]) if np.isfinite(dist[s + 1, 0]) else 1e6] * len(views)
    waypoints.append(dock)
    budget.home_m = [*home, 0.0]
    budget.planned_s, budget.stops, budget.stops_total = round(tour.seconds, 1), len(tour.order), len(keep)
    legs = [0, *(s + 1 for s in tour.order), 0]
    budget.planned_m = round(float(sum(dist[a, b] for a, b in zip(legs[:-1], legs[1:], strict=True))), 2)
    budget.headings = len(waypoints) - 1
    budget.expected_changes = round(float(tour.value), 3) if waiting is not None else 0.0
    pts = np.array([[w.x, w.y] for w in waypoints], dtype=float)
    return TraversalPlan(waypoints, path_length(pose.xy, pts), round(tour.seconds * p.speed, 1)), budget


MAX_SHORTLIST = 1000  # stops a budgeted tour is ever planned over (budget.max_stops' upper bound)


def budget_outgrows_shortlist(visited: int, listed: int, count: int, planned_s: float, available_s: float) -> bool:
    """Plan again over twice the places: the tour visits every one of a full shortlist of
    ``count`` and still leaves a tenth of the ``available_s`` seconds unplanned.

    ``budget.max_stops`` places are enough for an office; a budget on a building-size floor
    affords more, and a tour cut off at the shortlist's end leaves the rest of the budget
    unused (93 x 90 m office, a budget the length of its build: 60 stops, 2,255 of 5,946 s).
    A shortlist the tour does not exhaust, or one that ran out of places worth a look, stays.
    """
    return visited == listed == count < MAX_SHORTLIST and planned_s < 0.9 * available_s


def next_within_budget(state, budget: PassBudget, elapsed: float, leg: Callable[[int], float]) -> int | None:
    """The next waypoint of ``state`` (a :class:`~bomc_bt.monitoring.TraversalState`) the budget
    still allows, ``leg(i)`` being the metres from the robot to waypoint i. When one is no
    longer affordable, the rest of the tour is skipped (left pending) and the dock, the plan's
    last waypoint, comes next. Missed waypoints get no second try: that time is not there."""
    last = len(state.states) - 1
    while True:
        i = state.next()
        if i is None or budget.full_pass:
            return i
        if state.index > last + 1 or i in state.retried:  # a retry after the dock
            continue
        if i == last or budget.allows(elapsed, leg(i), i):
            return i
        state.index = last  # skip to the dock
        state.current = None


def look_time_left(budget: PassBudget | None, elapsed: float, index: int | None) -> float | None:
    """Seconds a look-around at waypoint ``index`` may take and still leave the robot time to
    drive home and arrive (one heading) within the budget; None without a budget."""
    if budget is None or budget.full_pass or index is None or not budget.home_m:
        return None
    index = min(index, len(budget.home_m) - 1)
    # two headings' time: turning to set off for home, and to the dock's heading on arrival (a short
    # way home is mostly turning); at the dock itself only the ticks that close the pass
    turns = 2 * budget.heading_time if index < len(budget.home_m) - 1 else CLOSING_S
    return max(0.0, budget.seconds - elapsed - budget.home_seconds(index) - turns)


CLOSING_S = 0.5  # [s] kept back from a look at the dock: the ticks after it that close the pass


def drive_time_left(budget: PassBudget | None, elapsed: float, index: int | None) -> float | None:
    """Seconds the drive to tour waypoint ``index`` may take before the robot must turn for
    home instead (a detour around a closed door would overrun the budget); None without a
    budget, and for the dock itself, which the robot drives to whatever it takes."""
    if budget is None or index is None or index >= len(budget.home_m) - 1:
        return None
    return 0.0 if budget.homeward else look_time_left(budget, elapsed, index)


def budget_spent(state, budget: PassBudget | None) -> bool:
    """A budgeted pass is over once the dock, its last waypoint, was handed out."""
    if budget is None or budget.full_pass:
        return False
    if state.index >= len(state.states):
        state.retried = sorted(set(state.retried) | set(range(len(state.states))))
        return True
    return False
