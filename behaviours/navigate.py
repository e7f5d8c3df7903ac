"""NavigateTo: drive to the blackboard ``goal`` (a waypoint or a detour).

Besides success, it tells whether the goal was reached by a detour: when the robot drove
much farther than the map's shortest path, something the map does not have was in the way
(``nav_detour``, which ``MarkWaypoint`` records). The shortest paths come from one
:class:`~bomc_bt.planner.GridPlanner` on the saved map per mission (``ctx.map_planner``).
In a pass with a budget, the drive to a tour waypoint gives up once the robot must head
home to keep the budget (:func:`~bomc_bt.budget_pass.drive_time_left`); the dock it
drives to whatever it takes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from py_trees.common import Status

from bomc_bt.budget_pass import drive_time_left
from bomc_bt.geometry import Pose2D
from bomc_bt.monitor_pass import reached_by_detour
from bomc_bt.planner import GridPlanner
from bomc_bt.robot import Handle
from bomc_bt.tree.action import ActionLeaf
from bomc_bt.tree.registry import register


@dataclass
class NavigateToParams:
    timeout: float = 240.0  # [s] robot time for one goal
    # [-] a goal reached after driving more than detour_ratio times the map's shortest path
    # plus detour_margin metres went around something the map does not have: a detour
    detour_ratio: float = 1.3
    detour_margin: float = 2.0  # [m] see detour_ratio
    # [s] a budgeted pass gives up a waypoint on a detour this long before the way it came
    # would no longer get it home in time (time to stop and turn round)
    detour_check_ahead: float = 5.0


@register("NavigateTo")
class NavigateTo(ActionLeaf):
    """Drives to the blackboard goal; fails on abort, blockage or timeout (robot clock)."""

    Params = NavigateToParams
    reads = ("goal",)
    writes = ("nav_failure", "nav_detour")

    def send(self) -> Handle:
        ctx = self.context
        self.goal: Pose2D = self.get("goal")
        handle = ctx.robot.navigate(self.goal)
        self.start_odometer = ctx.robot.distance_travelled
        pose = ctx.robot.pose()
        self.expected = math.inf
        if pose is not None:
            if ctx.map_planner is None:
                ctx.map_planner = GridPlanner(ctx.robot.live_map(), ctx.config.sim.planner)
            self.expected = ctx.map_planner.distance((pose.x, pose.y), (self.goal.x, self.goal.y))
        self.set("nav_detour", False)
        self.time_left = None if ctx.budget is None or ctx.traverse is None else drive_time_left(
            ctx.budget, ctx.now() - ctx.budget.started, ctx.traverse.current)
        self.start_home_m = self._home_m(pose) if self.time_left is not None else math.inf
        return handle

    def _home_m(self, pose: Pose2D | None) -> float:
        """The saved map's way from ``pose`` to the dock, reckoned longer by the pass's
        detours so far (:attr:`PassBudget.detour`); inf where unknown."""
        ctx = self.context
        if pose is None or ctx.dock is None or ctx.map_planner is None:
            return math.inf
        if ctx.dock_field is None:
            ctx.dock_field = ctx.map_planner.distances_from(ctx.dock.xy)
        return ctx.map_planner.lookup(ctx.dock_field, pose.xy) * ctx.budget.detour

    def timeout(self) -> float:
        left = getattr(self, "time_left", None)
        return self.params.timeout if left is None else min(self.params.timeout, left)

    def on_success(self) -> Status:
        driven = self.context.robot.distance_travelled - self.start_odometer
        p = self.params
        detour = reached_by_detour(driven, self.expected, p.detour_ratio, p.detour_margin)
        if self.context.budget is not None:
            self.context.budget.note_leg(self.expected, driven)
        self.set("nav_detour", detour)
        way = f" by a detour ({driven:.0f} m for {self.expected:.0f} m)" if detour else ""
        self.feedback_message = f"reached ({self.goal.x:.1f}, {self.goal.y:.1f}){way}"
        return Status.SUCCESS

    def on_failure(self, status) -> Status:
        self.set("nav_failure", f"{status.value}: {self.handle.message}")
        return super().on_failure(status)

    def on_timeout(self) -> Status:
        self.set("nav_failure", "timeout")
        self.feedback_message = f"no arrival within {self.timeout():.0f} s" + (
            " (the budget's time to head home)" if getattr(self, "time_left", None) is not None else "")
        return Status.FAILURE

    def on_running(self) -> Status:
        pose = self.context.robot.pose()
        if pose is not None:
            self.context.trail.add(pose.xy)
            self.feedback_message = f"to ({self.goal.x:.1f}, {self.goal.y:.1f}), {pose.distance_to(self.goal):.1f} m"
        if getattr(self, "time_left", None) is not None and self._detour_overruns_budget():
            self.handle.cancel()
            self.context.budget.homeward = True  # no retry, no detour viewpoint: home
            self.set("nav_failure", "budget")
            self.feedback_message = "a detour the budget cannot afford: heading home the way it came"
            return Status.FAILURE
        return Status.RUNNING

    def _detour_overruns_budget(self) -> bool:
        """A budgeted pass on a detour (the map's way is closed) gives up the waypoint while
        the way it came still gets it home in time (:meth:`PassBudget.way_back_too_long`)."""
        ctx, p = self.context, self.params
        driven = ctx.robot.distance_travelled - self.start_odometer
        if not reached_by_detour(driven, self.expected, p.detour_ratio, p.detour_margin):
            return False
        budget = ctx.budget
        return budget.way_back_too_long(ctx.now() - budget.started + p.detour_check_ahead, ctx.robot.distance_travelled,
                                        driven + self.start_home_m)
