"""The waypoint loop of a monitor pass: next waypoint, detour, and how each one ended.

The loop is ``visit_waypoints`` in ``trees/traverse.yaml``: ``WaypointsDone`` is its exit
condition, ``NextWaypoint`` writes the ``goal``, and ``MarkWaypoint`` records the outcome
and saves the pass so a killed run resumes at the next waypoint. The bookkeeping is
:class:`bomc_bt.monitoring.TraversalState`; resume, the look-ahead and the detour
candidates are :mod:`bomc_bt.monitor_pass`.
"""

from __future__ import annotations

from dataclasses import dataclass

from py_trees.common import Status

from bomc_bt.monitor_pass import DetourFinder, DetourParams, pass_exhausted, save_pass
from bomc_bt.monitoring import DETOURED, MISSED, VISITED
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register


@register("WaypointsDone")
class WaypointsDone(Leaf):
    """The visit loop's exit condition: succeeds once no waypoint is left to hand out
    (missed ones included, which come back once); fails (the loop goes on) otherwise."""

    def update(self) -> Status:
        state = self.context.traverse
        if not pass_exhausted(state):
            self.feedback_message = f"{len(state.states) - state.done_count} waypoints left"
            return Status.FAILURE
        state.current = None
        self.feedback_message = "all waypoints done"
        return Status.SUCCESS


@register("NextWaypoint")
class NextWaypoint(Leaf):
    """Writes the next waypoint as the ``goal`` (``WaypointsDone`` said there is one)."""

    writes = ("goal",)

    def update(self) -> Status:
        state = self.context.traverse
        i = state.next()
        if i is None:
            self.feedback_message = "all waypoints done"
            return Status.FAILURE
        self.set("goal", state.waypoint(i))
        retry = " (retry)" if i in state.retried else ""
        self.feedback_message = f"waypoint {i + 1}/{len(state.states)}{retry}"
        return Status.SUCCESS


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
    around something the map does not have) is recorded as detoured.
    """

    Params = MarkWaypointParams
    reads = ("nav_detour",)

    def update(self) -> Status:
        ctx = self.context
        i = ctx.traverse.current
        state = self.params.state
        if state == VISITED and self.get("nav_detour", False):
            state = DETOURED
        ctx.traverse.mark(i, state)
        save_pass(ctx.store, ctx.session, ctx.traverse, ctx.perception)
        ctx.progress.waypoint = ctx.traverse.done_count
        self.feedback_message = f"waypoint {i + 1} {state}"
        return Status.SUCCESS
