"""The waypoint loop of a monitor pass: next waypoint, detour, and how each one ended.

The loop is ``visit_waypoints`` in ``trees/traverse.yaml``: ``WaypointsDone`` is its exit
condition, ``NextWaypoint`` writes the ``goal``, and ``MarkWaypoint`` records the outcome
and saves the pass so a killed run resumes at the next waypoint. The bookkeeping is
:class:`bomc_bt.monitoring.TraversalState`; resume, the look-ahead and the detour
candidates are :mod:`bomc_bt.monitor_pass`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from py_trees.common import Status

from bomc_bt.budget_pass import budget_spent, next_within_budget
from bomc_bt.budget_plan import leg_length
from bomc_bt.monitor_pass import DetourFinder, DetourParams, miss_stop, pass_exhausted, save_pass
from bomc_bt.monitoring import DETOURED, MISSED, VISITED
from bomc_bt.planner import GridPlanner
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register


@register("WaypointsDone")
class WaypointsDone(Leaf):
    """The visit loop's exit condition: succeeds once no waypoint is left to hand out
    (missed ones included, which come back once); fails (the loop goes on) otherwise."""

    def update(self) -> Status:
        state = self.context.traverse
        if budget_spent(state, self.context.budget):
            state.current = None
            self.feedback_message = "budget spent: back at the dock"
            return Status.SUCCESS
        if not pass_exhausted(state):
            self.feedback_message = f"{len(state.states) - state.done_count} waypoints left"
            return Status.FAILURE
        state.current = None
        self.feedback_message = "all waypoints done"
        return Status.SUCCESS


@register("NextWaypoint")
class NextWaypoint(Leaf):
    """Writes the next waypoint as the ``goal`` (``WaypointsDone`` said there is one).

    In a pass with a budget, a waypoint the robot could no longer visit and still be back
    at the dock in time is skipped with the rest of the tour (:mod:`bomc_bt.budget_pass`).
    """

    writes = ("goal",)

    def update(self) -> Status:
        ctx = self.context
        state = ctx.traverse
        i = state.next() if ctx.budget is None else next_within_budget(
            state, ctx.budget, ctx.now() - ctx.budget.started, self.leg)
        if i is None:
            self.feedback_message = "all waypoints done"
            return Status.FAILURE
        self.set("goal", state.waypoint(i))
        retry = " (retry)" if i in state.retried else ""
        self.feedback_message = f"waypoint {i + 1}/{len(state.states)}{retry}"
        return Status.SUCCESS


    def leg(self, i: int) -> float:
        """Metres the robot drives to waypoint ``i`` on the saved map (the budget check's leg);
        the straight line when the map has no way."""
        ctx = self.context
        pose, goal = ctx.robot.pose(), ctx.traverse.waypoint(i)
        if pose is None:
            return 0.0
        if ctx.map_planner is None:
            ctx.map_planner = GridPlanner(ctx.robot.live_map(), ctx.config.sim.planner)
        d = ctx.map_planner.distance(pose.xy, goal.xy)
        return d if math.isfinite(d) else leg_length(pose.xy, goal.xy)


@register("FindDetour")
class FindDetour(Leaf):
    """Proposes the next untried viewpoint near the current waypoint that still sees it.

    The places tried so far (``detours_tried``: waypoint index -> places) are on the
    blackboard, so a waypoint retried at the end of the pass does not try them again.
    """

    Params = DetourParams
    reads = ("detours_tried",)
    writes = ("goal", "detours_tried")

    def update(self) -> Status:
        ctx = self.context
        i = ctx.traverse.current
        finder = DetourFinder(self.params, self.get("detours_tried") or {})
        goal = finder.next(ctx.robot.live_map(), i, ctx.traverse.waypoint(i))
        self.set("detours_tried", finder.tried)
        if goal is None:
            self.feedback_message = f"no detour left for waypoint {i + 1}"
            return Status.FAILURE
        self.set("goal", goal)
        self.feedback_message = f"detour for waypoint {i + 1} via ({goal.x:.1f}, {goal.y:.1f})"
        return Status.SUCCESS


@dataclass
class MarkWaypointParams:
    state: str = VISITED  # [choice] visited | detoured | missed

    def __post_init__(self) -> None:
        if self.state not in (VISITED, DETOURED, MISSED):
            raise ValueError(f"state must be visited, detoured or missed, not {self.state!r}")


@register("MarkWaypoint")
class MarkWaypoint(Leaf):
    """Records how the current waypoint ended and saves the pass's progress.

    A waypoint marked visited that ``NavigateTo`` reached by a detour (``nav_detour``:
    around something the map does not have) is recorded as detoured. A waypoint marked
    missed takes the rest of its stop (its other headings, at the same place) with it
    (:func:`~bomc_bt.monitor_pass.miss_stop`).
    """

    Params = MarkWaypointParams
    reads = ("nav_detour",)

    def update(self) -> Status:
        ctx = self.context
        i = ctx.traverse.current
        state = self.params.state
        if state == VISITED and self.get("nav_detour", False):
            state = DETOURED
        others: list[int] = []
        if state == MISSED:
            others = miss_stop(ctx.traverse, i)
        else:
            ctx.traverse.mark(i, state)
        save_pass(ctx.store, ctx.session, ctx.traverse, ctx.perception)
        ctx.progress.waypoint = ctx.traverse.done_count
        self.feedback_message = f"waypoint {i + 1} {state}" + (
            f", and its stop's {len(others)} other heading(s) with it" if others else "")
        return Status.SUCCESS
