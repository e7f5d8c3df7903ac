"""Getting unstuck: the leaves of ``trees/recover.yaml`` (``keep_going``).

After each waypoint of the visit loop, ``CheckProgress`` asks :class:`bomc_bt.stuck.StuckWatch`
whether the pass is still getting somewhere; when waypoint after waypoint failed it writes
the trigger (``stuck``) and fails, and the tree runs the recovery: ``DiagnoseStuck`` finds
out why (:func:`bomc_bt.stuck.diagnose`, written to ``stuck_cause``), ``StuckCauseIs``
picks the branch that acts on it (``BackOutGoal`` + ``NavigateTo``, ``ClearObstacles``,
``RefreshMap``, ``Relocalize``), and ``EndPassEarly`` ends the pass with the diagnosis when rounds with
no waypoint reached in between are used up. Thresholds are the configuration's
``recovery`` section. ``WatchFloor`` runs beside the traversal the whole pass, keeping the
floor the lidar sees where the saved map holds furniture, for the ``stale_map`` diagnosis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from py_trees.common import Status

from bomc_bt.geometry import Pose2D
from bomc_bt.monitor_pass import give_up, save_pass
from bomc_bt.monitoring import MISSED, PENDING
from bomc_bt.stale_map import FloorSeen, with_floor
from bomc_bt.stuck import CAUSES, CUT_OFF, LOST, StuckWatch, diagnose, diagnosis_line
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register

ENDED_EARLY = "ended_early"
"""The session outcome of a pass that gave up on being stuck (the report's ``reason`` says why)."""


def watch_of(ctx) -> StuckWatch:
    """The mission's watch, made on first use (its no-progress clock starts then)."""
    if ctx.watch is None:
        ctx.watch = StuckWatch(ctx.now())
    return ctx.watch


@dataclass
class CheckProgressParams:
    max_missed: int = 3  # [count] waypoints missed in a row that start a recovery
    no_progress_time: float = 600.0  # [s] robot time without a waypoint reached that starts one


@register("CheckProgress")
class CheckProgress(Leaf):
    """Records how the waypoint just finished ended; fails (writing ``stuck``) when the
    pass stopped getting anywhere, so the recovery runs. A missed waypoint tried again at
    the end of the loop and missed again does not count (it was blocked before)."""

    Params = CheckProgressParams
    config_params = {"max_missed": "recovery.max_missed", "no_progress_time": "recovery.no_progress_time"}
    writes = ("stuck",)

    def update(self) -> Status:
        ctx = self.context
        watch = watch_of(ctx)
        state = ctx.traverse
        i = state.current if state is not None else None
        # A missed waypoint's second chance at the end of the loop failing again is expected
        # (it was blocked the first time): only first attempts count towards being stuck.
        if i is not None and not (i in state.retried and state.states[i] == MISSED):
            watch.record(i, state.states[i], ctx.now(), ctx.robot.distance_travelled)
        why = watch.trigger(ctx.now(), self.params.max_missed, self.params.no_progress_time)
        if why is None:
            self.feedback_message = f"getting somewhere ({watch.missed_in_row} missed in a row)"
            return Status.SUCCESS
        self.set("stuck", why)
        self.feedback_message = why
        return Status.FAILURE


@dataclass
class DiagnoseStuckParams:
    max_rounds: int = 2  # [count] recovery rounds with no waypoint reached in between


@register("DiagnoseStuck")
class DiagnoseStuck(Leaf):
    """Finds out why waypoints keep failing (``stuck_cause``); fails when the rounds are used up."""

    Params = DiagnoseStuckParams
    config_params = {"max_rounds": "recovery.max_rounds"}
    reads = ("stuck",)
    writes = ("stuck_cause",)

    def update(self) -> Status:
        ctx = self.context
        watch = watch_of(ctx)
        state = ctx.traverse
        failed = [_xy(state.waypoint(i)) for i in watch.missed]
        left = [i for i, s in enumerate(state.states) if s in (PENDING, MISSED)]
        # After a clear in this spell, what the layer marks the lidar saw again: real obstacles.
        layer = ctx.robot.obstacle_layer() if watch.cleared_in_spell() else None
        watch.start_round(ctx.now(), self.get("stuck") or "stuck")
        moved = watch.moved_since_first_miss(ctx.robot.distance_travelled)
        grid = ctx.robot.live_map()
        same_map = ctx.floor is not None and ctx.floor.grid.data.shape == grid.data.shape  # ROS: /map may change
        floor = ctx.floor.cells() if same_map else None
        found = diagnose(grid, ctx.robot.pose(), ctx.robot.scan(), failed,
                         [_xy(state.waypoint(i)) for i in left], ctx.config.recovery,
                         ctx.config.sim.planner.robot_radius, moved, layer, floor)
        found = replace(found, cut_off=[left[k] for k in found.cut_off])  # waypoint indices from here on
        watch.log[-1].cause, watch.log[-1].detail = found.cause, found.detail
        self.set("stuck_cause", found)
        self.feedback_message = str(found)
        if found.cause == LOST:
            watch.act("relocalize")
        if found.cause == CUT_OFF:
            watch.carry_on()
        elif watch.rounds > self.params.max_rounds:
            self.feedback_message = f"{watch.rounds - 1} recovery round(s) did not help: {found}"
            return Status.FAILURE
        return Status.SUCCESS


def _xy(p: Pose2D) -> tuple[float, float]:
    return (p.x, p.y)


@dataclass
class StuckCauseIsParams:
    cause: str = CUT_OFF  # [choice] lost | stale_obstacles | stale_map | boxed_in | cut_off

    def __post_init__(self) -> None:
        if self.cause not in CAUSES:
            raise ValueError(f"cause must be one of {', '.join(CAUSES)}, not {self.cause!r}")


@register("StuckCauseIs")
class StuckCauseIs(Leaf):
    """Condition: succeeds when the diagnosis (``stuck_cause``) is ``cause``."""

    Params = StuckCauseIsParams
    reads = ("stuck_cause",)

    def update(self) -> Status:
        found = self.get("stuck_cause")
        ok = found is not None and found.cause == self.params.cause
        self.feedback_message = f"{'yes' if ok else 'no'}: {found.cause if found else 'no diagnosis'}"
        return Status.SUCCESS if ok else Status.FAILURE


@register("SkipCutOff")
class SkipCutOff(Leaf):
    """Gives up on the waypoints the diagnosis (``stuck_cause``) found behind obstacles the
    lidar saw again after a clear (:func:`bomc_bt.monitor_pass.give_up`: missed, no second
    chance at the end of the loop), but a budgeted pass's dock, its last waypoint. Saves the
    pass's progress; always succeeds (the pass carries on)."""

    reads = ("stuck_cause",)

    def update(self) -> Status:
        ctx = self.context
        found = self.get("stuck_cause")
        state = ctx.traverse
        dock = len(state.states) - 1 if ctx.budget is not None else None
        behind, untried = give_up(state, found.cut_off if found else [], keep=dock)
        result = (f"carried on without {len(behind)} waypoint(s) behind the same obstacles ({len(untried)} not tried)"
                  if behind else "carried on: the robot can reach other waypoints")
        watch_of(ctx).act("none", result)
        if behind:
            save_pass(ctx.store, ctx.session, state, ctx.perception)
            ctx.progress.waypoint = state.done_count
        self.feedback_message = f"gave up on {len(behind)} waypoint(s) behind the obstacles"
        return Status.SUCCESS


@dataclass
class ClearObstaclesParams:
    rebuild_time: float = 2.0  # [s] robot time the lidar gets to refill the layer


@register("ClearObstacles")
class ClearObstacles(Leaf):
    """Clears the navigation's obstacle layer, then waits while the lidar rebuilds it."""

    Params = ClearObstaclesParams
    config_params = {"rebuild_time": "recovery.rebuild_time"}

    def initialise(self) -> None:
        self.context.robot.clear_costmaps()
        self.until = self.context.now() + self.params.rebuild_time
        watch_of(self.context).act("clear_obstacles")

    def update(self) -> Status:
        if self.context.now() < self.until:
            self.feedback_message = "obstacle layer cleared; rebuilding from the lidar"
            return Status.RUNNING
        self.feedback_message = "obstacle layer rebuilt"
        return Status.SUCCESS


@register("RefreshMap")
class RefreshMap(Leaf):
    """Hands the robot the map in use with the floor the diagnosis (``stuck_cause``) found
    where the map holds furniture cleared (``RobotPort.refresh_map``): the waypoints from
    here on plan on it. The saved map does not change. Always succeeds."""

    reads = ("stuck_cause",)

    def update(self) -> Status:
        ctx = self.context
        found = self.get("stuck_cause")
        grid = ctx.robot.live_map()
        ctx.robot.refresh_map(with_floor(grid, found.floor))
        area = len(found.floor) * grid.resolution ** 2
        watch_of(ctx).act("refresh_map", f"navigating on the map with {area:.1f} m² of floor cleared")
        self.feedback_message = f"map refreshed: {area:.1f} m² of floor where furniture stood at the build"
        return Status.SUCCESS


@dataclass
class WatchFloorParams:
    period: float = 1.0  # [s] robot time between scans folded in
    furniture_area: float = 2.0  # [m2] occupied blobs of the map this small are furniture; 0: off
    max_range: float = 6.0  # [m] scans count as seeing floor this far
    min_seen: int = 2  # [count] scans that must see a cell as floor


@register("WatchFloor")
class WatchFloor(Leaf):
    """Every ``period`` s of robot time, folds the latest scan into the floor seen this pass
    (``ctx.floor``, :class:`bomc_bt.stale_map.FloorSeen`, made on the map in use at the first
    localized tick). Runs beside the traversal; never finishes."""

    Params = WatchFloorParams
    config_params = {"period": "recovery.floor_period", "furniture_area": "recovery.stale_furniture_area",
                     "max_range": "recovery.floor_range", "min_seen": "recovery.floor_min_seen"}

    def initialise(self) -> None:
        self.next_at = -math.inf

    def update(self) -> Status:
        ctx = self.context
        pose = ctx.robot.pose()
        p = self.params
        if pose is None or p.furniture_area <= 0 or ctx.now() < self.next_at:
            return Status.RUNNING
        if ctx.floor is None:
            ctx.floor = FloorSeen(ctx.robot.live_map(), p.furniture_area, p.max_range, p.min_seen)
        self.next_at = ctx.now() + p.period
        ctx.floor.add(pose, ctx.robot.scan())
        self.feedback_message = f"{ctx.floor.scans} scan(s) folded in"
        return Status.RUNNING


@dataclass
class BackOutGoalParams:
    distance: float = 1.5  # [m] back along the path driven


@register("BackOutGoal")
class BackOutGoal(Leaf):
    """Writes as the ``goal`` a place ``distance`` back along the way the robot drove in
    (``ctx.trail``); fails when the robot has not driven that far yet."""

    Params = BackOutGoalParams
    config_params = {"distance": "recovery.backout_distance"}
    writes = ("goal",)

    def update(self) -> Status:
        ctx = self.context
        pose = ctx.robot.pose()
        back = None if pose is None else ctx.trail.back((pose.x, pose.y), self.params.distance)
        if back is None:
            watch_of(ctx).act("back_out", "nowhere to back out to")
            self.feedback_message = "no way back recorded"
            return Status.FAILURE
        yaw = math.atan2(back[1] - pose.y, back[0] - pose.x)
        self.set("goal", Pose2D(back[0], back[1], yaw))
        watch_of(ctx).act("back_out")
        self.feedback_message = f"back out to ({back[0]:.1f}, {back[1]:.1f})"
        return Status.SUCCESS


@register("EndPassEarly")
class EndPassEarly(Leaf):
    """Ends the pass: stops the robot, records the diagnosis as the session's reason, fails."""

    reads = ("stuck_cause", "stuck")

    def update(self) -> Status:
        ctx = self.context
        watch = watch_of(ctx)
        found = self.get("stuck_cause")
        state = ctx.traverse
        where = f"waypoint {state.current + 1}/{len(state.states)}" if state and state.current is not None else "start"
        watch.act("end_pass")
        ctx.robot.cancel_all()
        ctx.outcome = ENDED_EARLY
        ctx.reason = diagnosis_line(found, watch, where) if found else f"pass ended early: {self.get('stuck')}"
        self.feedback_message = ctx.reason
        return Status.FAILURE
