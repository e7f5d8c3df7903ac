"""Traverse Waypoints: plan the pass, visit each waypoint, detour or skip when blocked.

The control flow (retries, detours, skipping) is in ``trees/traverse.yaml``; the
waypoint bookkeeping is :class:`bomc_bt.monitoring.TraversalState`, persisted in the site
store after every waypoint so a killed pass resumes at the next one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from py_trees.common import Status

from behaviours.common import cancel_if_interrupted
from bomc_bt.geometry import Pose2D
from bomc_bt.monitoring import (
    DETOURED,
    GAPS,
    MISSED,
    REFRESH,
    VISITED,
    TraversalState,
    detour_viewpoints,
    unverified_headings,
)
from bomc_bt.planner import GridPlanner
from bomc_bt.refresh import RefreshParams, refresh_viewpoints, stale_nodes
from bomc_bt.robot import Status as Nav
from bomc_bt.site import write_json
from bomc_bt.traversal import TraversalPlan, load_trajectory, plan_traversal, snap_to_free
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register
from bomc_bt.viewpoints import GapParams, gap_viewpoints


def progress_key(ctx) -> str:
    """Where the pass's waypoint bookkeeping is saved in the store (one key per session)."""
    return f"traverse/{ctx.session}"


@dataclass
class PlanTraversalParams:
    clearance: float = 0.45  # m: waypoints closer to a wall are moved into the open


@register("PlanTraversal")
class PlanTraversal(Leaf):
    """Samples waypoints along the build trajectory and orders them (greedy TSP + 2-opt)."""

    Params = PlanTraversalParams

    def update(self) -> Status:
        ctx = self.context
        if ctx.traverse is None:
            saved = ctx.store.get_progress(progress_key(ctx)) if ctx.resume else None
            if saved and "plan" in saved:  # resuming: the same plan, at the next waypoint
                ctx.plan = TraversalPlan.from_json(saved["plan"], ctx.store.path)
                ctx.traverse = TraversalState(ctx.plan)
                ctx.traverse.restore(saved)
            else:
                ctx.plan = self.plan(ctx)
                ctx.traverse = TraversalState(ctx.plan)
                ctx.store.set_progress(progress_key(ctx), {**ctx.traverse.to_json(), "plan": ctx.plan.to_json()})
        ctx.progress.waypoints = len(ctx.traverse.states)
        ctx.progress.waypoint = ctx.traverse.done_count
        length = ctx.plan.grid_length or ctx.plan.euclidean_length
        self.feedback_message = f"{len(ctx.plan.waypoints)} waypoints, {length:.0f} m"
        return Status.SUCCESS

    def plan(self, ctx) -> TraversalPlan:
        grid = ctx.robot.live_map()
        trajectory = load_trajectory(ctx.site.trajectory_csv)
        planner = GridPlanner(grid, ctx.config.sim.planner)
        plan = plan_traversal(trajectory, ctx.robot.pose(), ctx.config.traversal, grid_distance=planner.distance)
        plan.waypoints = snap_to_free(grid, plan.waypoints, self.params.clearance)
        write_json(ctx.site.plan_json, plan.to_json())
        return plan


@register("NextWaypoint")
class NextWaypoint(Leaf):
    """Writes the next waypoint as the goal; fails when the pass has visited them all."""

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


@register("PlanGapViewpoints")
class PlanGapViewpoints(Leaf):
    """After the last waypoint: adds viewpoints that see the floor the camera has not seen.

    Fails when they were planned already this pass or nothing is worth a look, which ends
    the traversal (see :mod:`bomc_bt.viewpoints`).
    """

    Params = GapParams

    def update(self) -> Status:
        ctx = self.context
        state = ctx.traverse
        if state.planned(GAPS) or ctx.perception is None:
            self.feedback_message = "gaps already covered" if state.planned(GAPS) else "no perception"
            return Status.FAILURE
        views = gap_viewpoints(ctx.robot.live_map(), ctx.perception.coverage.seen, ctx.robot.pose(), self.params)
        _extend(ctx, GAPS, views)
        self.feedback_message = f"{len(views)} gap viewpoints"
        return Status.SUCCESS if views else Status.FAILURE


@register("PlanRefreshStops")
class PlanRefreshStops(Leaf):
    """Before the pass ends: adds stops that look again at the nodes confirmed longest ago.

    An object taken away after the camera passed it is only noticed if the camera looks
    again (see :mod:`bomc_bt.refresh`). Fails when the stops were planned already this
    pass or nothing is stale, which ends the traversal.
    """

    Params = RefreshParams

    def update(self) -> Status:
        ctx = self.context
        state = ctx.traverse
        pose = ctx.robot.pose()
        if state.planned(REFRESH) or ctx.graph is None or pose is None:
            self.feedback_message = "refresh already planned" if state.planned(REFRESH) else "nothing to refresh"
            return Status.FAILURE
        now = ctx.now()
        stale = stale_nodes(ctx.graph.nodes.values(), now, self.params.stale_after)
        grid = ctx.robot.live_map()
        distances = GridPlanner(grid, ctx.config.sim.planner).path_lengths_from
        budget = self.params.budget * (ctx.plan.grid_length or ctx.plan.euclidean_length)
        stops = refresh_viewpoints(grid, stale, now, state.reached(), pose, budget, distances, self.params)
        _extend(ctx, REFRESH, stops)
        self.feedback_message = f"{len(stops)} refresh stops for {len(stale)} stale nodes"
        return Status.SUCCESS if stops else Status.FAILURE


def _extend(ctx, phase: str, views: list[Pose2D]) -> None:
    """Appends a phase's viewpoints to the pass and saves the bookkeeping (resume)."""
    ctx.traverse.add_viewpoints(phase, views)
    ctx.store.set_progress(progress_key(ctx), {**ctx.traverse.to_json(), "plan": ctx.plan.to_json()})
    ctx.progress.waypoints = len(ctx.traverse.states)


@dataclass
class NavigateToParams:
    timeout: float = 240.0  # s of robot time for one goal
    # A goal reached after driving more than detour_ratio times the map's shortest path
    # plus detour_margin metres went around something the map does not have: a detour.
    detour_ratio: float = 1.3
    detour_margin: float = 2.0


@register("NavigateTo")
class NavigateTo(Leaf):
    """Drives to the blackboard goal; fails on abort, blockage or timeout (robot clock)."""

    Params = NavigateToParams
    reads = ("goal",)
    writes = ("nav_failure",)

    def initialise(self) -> None:
        ctx = self.context
        self.goal: Pose2D = self.get("goal")
        self.handle = ctx.robot.navigate(self.goal)
        self.deadline = ctx.now() + self.params.timeout
        self.start_odometer = getattr(ctx.robot, "distance_travelled", None)
        pose = ctx.robot.pose()
        self.expected = math.inf
        if pose is not None and self.start_odometer is not None:
            planner = ctx.extras.get("map_planner")
            if planner is None:
                planner = ctx.extras["map_planner"] = GridPlanner(ctx.robot.live_map(), ctx.config.sim.planner)
            self.expected = planner.distance((pose.x, pose.y), (self.goal.x, self.goal.y))
        ctx.extras["last_nav_detour"] = False

    def update(self) -> Status:
        status = self.handle.status()
        if status is Nav.SUCCEEDED:
            driven = getattr(self.context.robot, "distance_travelled", 0.0) - (self.start_odometer or 0.0)
            detour = driven > self.params.detour_ratio * self.expected + self.params.detour_margin
            self.context.extras["last_nav_detour"] = detour
            way = f" by a detour ({driven:.0f} m for {self.expected:.0f} m)" if detour else ""
            self.feedback_message = f"reached ({self.goal.x:.1f}, {self.goal.y:.1f}){way}"
            return Status.SUCCESS
        if status.done:
            self.set("nav_failure", f"{status.value}: {self.handle.message}")
            self.feedback_message = f"{status.value}: {self.handle.message}"
            return Status.FAILURE
        if self.context.now() >= self.deadline:
            self.handle.cancel()
            self.set("nav_failure", "timeout")
            self.feedback_message = f"no arrival within {self.params.timeout:.0f} s"
            return Status.FAILURE
        pose = self.context.robot.pose()
        if pose is not None:
            self.feedback_message = f"to ({self.goal.x:.1f}, {self.goal.y:.1f}), {pose.distance_to(self.goal):.1f} m"
        return Status.RUNNING

    def terminate(self, new_status: Status) -> None:
        cancel_if_interrupted(self, new_status)


@dataclass
class FindDetourParams:
    radius: float = 2.0  # m around the blocked waypoint
    count: int = 6  # candidates considered per waypoint
    clearance: float = 0.45  # m from obstacles


@register("FindDetour")
class FindDetour(Leaf):
    """Proposes the next untried viewpoint near the current waypoint that still sees it."""

    Params = FindDetourParams
    writes = ("goal",)

    def update(self) -> Status:
        ctx = self.context
        i = ctx.traverse.current
        tried = ctx.extras.setdefault("detours_tried", {}).setdefault(i, [])
        target = ctx.traverse.waypoint(i)
        grid = ctx.robot.live_map()
        options = detour_viewpoints(grid, (target.x, target.y), self.params.radius, self.params.count,
                                    self.params.clearance, avoid=[(target.x, target.y), *tried])
        if not options:
            self.feedback_message = f"no detour left for waypoint {i + 1}"
            return Status.FAILURE
        x, y = options[0]
        tried.append((x, y))
        self.set("goal", Pose2D(x, y, math.atan2(target.y - y, target.x - x)))  # look at the waypoint
        self.feedback_message = f"detour for waypoint {i + 1} via ({x:.1f}, {y:.1f})"
        return Status.SUCCESS


@dataclass
class MarkWaypointParams:
    state: str = VISITED  # visited | detoured | missed

    def __post_init__(self) -> None:
        if self.state not in (VISITED, DETOURED, MISSED):
            raise ValueError(f"state must be visited, detoured or missed, not {self.state!r}")


@register("MarkWaypoint")
class MarkWaypoint(Leaf):
    """Records how the current waypoint ended and saves the pass's progress."""

    Params = MarkWaypointParams

    def update(self) -> Status:
        ctx = self.context
        i = ctx.traverse.current
        state = self.params.state
        if state == VISITED and ctx.extras.get("last_nav_detour"):
            state = DETOURED  # reached, but around something the map does not have
        ctx.traverse.mark(i, state)
        ctx.store.set_progress(progress_key(ctx), {**ctx.traverse.to_json(), "plan": ctx.plan.to_json()})
        ctx.progress.waypoint = ctx.traverse.done_count
        self.feedback_message = f"waypoint {i + 1} {state}"
        return Status.SUCCESS


@dataclass
class LookAroundParams:
    radius: float = 5.0  # m: nodes this close are worth a look (projection.expect_range)
    max_turns: int = 2  # headings per waypoint at most
    dwell: float = 1.5  # s of robot time facing each heading (frames to confirm or miss)
    timeout: float = 30.0  # s for the whole look-around
    # s of robot time: a node this pass confirmed longer ago gets a look again, in case it
    # was taken away after the camera passed (0: only nodes not confirmed yet)
    refresh_after: float = 600.0

    def __post_init__(self) -> None:
        if self.radius <= 0 or self.max_turns < 0 or self.dwell < 0 or self.timeout <= 0:
            raise ValueError("need radius > 0, max_turns >= 0, dwell >= 0 and timeout > 0")
        if self.refresh_after < 0:
            raise ValueError("refresh_after must be >= 0 (0: no refresh)")


@register("LookAround")
class LookAround(Leaf):
    """At a waypoint, turns the camera towards nodes this pass has not yet confirmed, or
    confirmed so long ago (``refresh_after``) that they may have gone since."""

    Params = LookAroundParams

    def initialise(self) -> None:
        ctx = self.context
        pose = ctx.robot.pose()
        hfov = math.radians(ctx.config.camera.hfov_deg)
        self.headings = [] if pose is None else unverified_headings(
            ctx.graph, pose, ctx.session, ctx.robot.live_map(), self.params.radius, hfov, self.params.max_turns,
            now=ctx.now(), stale_after=self.params.refresh_after)
        self.pose = pose
        self.handle = None
        self.dwell_until: float | None = None
        self.deadline = ctx.now() + self.params.timeout

    def update(self) -> Status:
        ctx = self.context
        if self.dwell_until is not None and ctx.now() < self.dwell_until:
            return Status.RUNNING
        if self.handle is not None and not self.handle.status().done:
            if ctx.now() >= self.deadline:
                self.handle.cancel()
                return Status.SUCCESS
            return Status.RUNNING
        if self.handle is not None and self.dwell_until is None and self.handle.status() is Nav.SUCCEEDED:
            self.dwell_until = ctx.now() + self.params.dwell
            return Status.RUNNING
        if not self.headings or ctx.now() >= self.deadline:
            self.feedback_message = "nothing left to check here"
            return Status.SUCCESS
        heading = self.headings.pop(0)
        self.handle = ctx.robot.navigate(Pose2D(self.pose.x, self.pose.y, heading))
        self.dwell_until = None
        self.feedback_message = f"looking towards {math.degrees(heading):.0f}°, {len(self.headings)} more"
        return Status.RUNNING

    def terminate(self, new_status: Status) -> None:
        cancel_if_interrupted(self, new_status)
