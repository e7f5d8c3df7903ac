"""Explore: Dynamic Window Frontier Exploration as tree leaves.

The loop itself is in ``trees/explore.yaml``: choose a frontier, drive to it, blacklist
it when it cannot be reached, until the explorer says done, time limit or stuck
(``ExplorationOver``, the loop's exit condition). The decisions are
:class:`bomc_bt.exploration.explorer.Explorer`'s; these leaves only ask it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from py_trees.common import Status

from bomc_bt.exploration.explorer import DONE, EXPLORING, Explorer, still_open
from bomc_bt.geometry import Pose2D
from bomc_bt.robot import Handle
from bomc_bt.robot import Status as Nav
from bomc_bt.site import TrajectoryRecorder
from bomc_bt.tree.action import ActionLeaf
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register


@dataclass
class StartExplorationParams:
    max_consecutive_failures: int = 5  # [count] failed goals in a row that make the explorer stuck


@register("StartExploration")
class StartExploration(Leaf):
    """Creates the explorer and opens the trajectory file."""

    Params = StartExplorationParams

    def update(self) -> Status:
        ctx = self.context
        if ctx.explorer is None:
            clearance = ctx.config.sim.planner.robot_radius + 0.05
            ctx.explorer = Explorer(ctx.config.exploration, ctx.now(), ctx.max_time,
                                    self.params.max_consecutive_failures, clearance,
                                    planner=ctx.config.sim.planner)
        if ctx.trajectory is None:
            ctx.trajectory = TrajectoryRecorder(ctx.site.trajectory_csv, ctx.config.mission.trajectory_period)
        self.feedback_message = f"explorer: {ctx.config.exploration.explorer}"
        return Status.SUCCESS


@register("RecordTrajectory")
class RecordTrajectory(Leaf):
    """Records the robot's pose at the configured rate while its siblings explore."""

    def update(self) -> Status:
        ctx = self.context
        pose = ctx.robot.pose()
        if pose is not None and ctx.trajectory is not None:
            ctx.trajectory.record(ctx.now(), pose.x, pose.y, pose.yaw)
            ctx.progress.path_length = ctx.trajectory.length
        self.feedback_message = f"{ctx.trajectory.rows if ctx.trajectory else 0} poses"
        return Status.RUNNING


@register("ChooseFrontier")
class ChooseFrontier(Leaf):
    """Asks the explorer for the next frontier (the ``goal``); without one, exploration is over.

    Succeeds either way: ``ExplorationOver`` right after it tells the loop whether to stop.
    """

    writes = ("goal",)

    def update(self) -> Status:
        ctx = self.context
        pose = ctx.robot.pose()
        if pose is None:
            self.feedback_message = "waiting for a pose"
            return Status.RUNNING
        grid = ctx.robot.live_map()
        ctx.progress.explored_area = grid.free_area()
        goal = ctx.explorer.next_goal(grid, (pose.x, pose.y), ctx.now(), pose.yaw)
        if goal is None:
            self.feedback_message = f"{ctx.explorer.status}: {ctx.explorer.reason}"
            return Status.SUCCESS
        self.set("goal", goal)
        n = len(ctx.explorer.frontiers)
        if goal.backout:
            self.feedback_message = f"backing out to ({goal.xy[0]:.1f}, {goal.xy[1]:.1f}), {n} frontiers"
            return Status.SUCCESS
        self.feedback_message = (
            f"{goal.window} window: frontier of {goal.frontier.length:.1f} m at "
            f"({goal.xy[0]:.1f}, {goal.xy[1]:.1f}), {n} frontiers")
        return Status.SUCCESS


@register("ExplorationOver")
class ExplorationOver(Leaf):
    """The exploration loop's exit condition: succeeds once the explorer says done, a limit
    ended it or it is stuck; fails (the loop goes on) while it is still exploring."""

    def update(self) -> Status:
        explorer = self.context.explorer
        self.feedback_message = explorer.status
        return Status.FAILURE if explorer.status == EXPLORING else Status.SUCCESS


@dataclass
class DriveToFrontierParams:
    recheck_period: float = 2.0  # [s] robot time between checks that the frontier is still open
    open_radius: float = 0.6  # [m] around the goal searched for unknown cells
    min_unknown: int = 3  # [count] fewer frontier cells (free next to unknown) near it: mapped, move on
    arrive_radius: float = 0.3  # [m] this near the goal the robot has arrived (sim.planner.goal_tolerance)
    in_view_deg: float = 90.0  # [deg] a frontier this near the heading on arrival is in the lidar's view: no turn

    def __post_init__(self) -> None:
        if not (self.open_radius > 0 and self.arrive_radius >= 0 and 0 <= self.in_view_deg <= 180):
            raise ValueError("need open_radius > 0, arrive_radius >= 0 and 0 <= in_view_deg <= 180")


@register("DriveToFrontier")
class DriveToFrontier(ActionLeaf):
    """Drives to the chosen frontier; succeeds early once it has been mapped (checked every
    ``recheck_period`` on the way), on arrival with it mapped or in the lidar's view, or when
    time is up.

    The goal's heading faces the frontier, for a robot that arrives with it in the blind
    sector behind. Arriving with it in view, the turn to that heading shows nothing new: on 8
    starts of a small real map (small_house), the gain explorer turned on the spot for 8.5 s
    of the 50 s it took to map 95 %, the baseline for 4.2 s (docs/exploration.md 7.14).
    A frontier in view but still open is not blacklisted then: the lidar's map is updated
    every quarter metre or 14 degrees, so the robot may not have mapped what it sees from
    there yet, and the next goal's first metre does. Which arrivals are spared the turn is
    the explorer's to remember (:mod:`bomc_bt.exploration.turn_look`).
    """

    Params = DriveToFrontierParams
    config_params = {"arrive_radius": "sim.planner.goal_tolerance"}
    reads = ("goal",)
    writes = ("nav_failure",)

    def send(self) -> Handle:
        self.goal = self.get("goal")
        pose = self.context.robot.pose()
        # Arrive facing the frontier: the lidar's blind sector is behind the robot. A standoff
        # goal faces the frontier cell it looks at; a goal on the frontier, the way there.
        (ax, ay), (gx, gy) = self.goal.looks_at, self.goal.xy
        if math.hypot(ax - gx, ay - gy) > 0.1:
            yaw = math.atan2(ay - gy, ax - gx)
        else:
            yaw = math.atan2(gy - pose.y, gx - pose.x) if pose is not None else 0.0
        handle = self.context.robot.navigate(Pose2D(*self.goal.xy, yaw))
        self.next_check = self.context.now() + self.params.recheck_period
        return handle

    def still_open(self, grid) -> bool:
        p = self.params
        return still_open(grid, self.goal.looks_at, p.open_radius, p.min_unknown)

    def arrived(self, pose: Pose2D) -> str | None:
        """Why the drive may end here without the turn to the goal's heading, or None. Not for
        a back-out or a turn on the spot, whose heading is the point."""
        if self.goal.backout or self.goal.window == "turn":
            return None
        if pose.distance_to(Pose2D(*self.goal.xy)) > self.params.arrive_radius:
            return None
        if not self.still_open(self.context.robot.live_map()):
            return "arrived, the frontier mapped"
        turns = self.context.explorer.turns
        if turns.skip_arrival_turn(self.goal.looks_at, (pose.x, pose.y, pose.yaw), self.params.in_view_deg,
                                   self.params.open_radius):
            return "arrived with the frontier in view"
        return None  # out of view, or the second arrival: turn, and blacklist it if still open

    def before_poll(self) -> Status | None:
        ctx, explorer = self.context, self.context.explorer
        now = ctx.now()
        pose = ctx.robot.pose()
        explorer.observe((pose.x, pose.y) if pose is not None else None, now, ctx.progress.explored_area)
        if explorer.limit_reached(now):  # a time limit or the progress guard: exploration is over,
            self.feedback_message = explorer.reason  # not this drive a failure
            return Status.SUCCESS
        return None

    def on_success(self) -> Status:
        self.context.explorer.goal_reached(self.goal, self.still_open(self.context.robot.live_map()))
        return Status.SUCCESS

    def on_failure(self, status: Nav) -> Status:
        grid = self.context.robot.live_map()
        if status is Nav.BLOCKED and not self.still_open(grid):
            # The frontier turned out to be a wall once seen: explored, not a failure.
            self.context.explorer.goal_reached(self.goal, still_open=True)
            self.feedback_message = "frontier closed by a wall"
            return Status.SUCCESS
        self.set("nav_failure", f"{status.value}: {self.handle.message}")
        self.feedback_message = f"goal {status.value}: {self.handle.message}"
        return Status.FAILURE

    def on_running(self) -> Status:
        ctx = self.context
        now = ctx.now()
        if now >= self.next_check and not self.goal.backout:
            self.next_check = now + self.params.recheck_period
            grid = ctx.robot.live_map()
            ctx.progress.explored_area = grid.free_area()
            if not self.still_open(grid):
                ctx.explorer.goal_reached()
                self.feedback_message = "frontier mapped on the way"
                return Status.SUCCESS
        pose = ctx.robot.pose()
        why = self.arrived(pose) if pose is not None else None
        if why is not None:
            self.handle.cancel()
            ctx.explorer.goal_reached()
            self.feedback_message = why
            return Status.SUCCESS
        if pose is not None:
            d = pose.distance_to(Pose2D(*self.goal.xy))
            self.feedback_message = f"driving to ({self.goal.xy[0]:.1f}, {self.goal.xy[1]:.1f}), {d:.1f} m"
        return Status.RUNNING


@register("BlacklistGoal")
class BlacklistGoal(Leaf):
    """Marks the failed goal unreachable (which may leave the explorer stuck: the loop's
    ``ExplorationOver`` then ends it, and ``ExplorationOutcome`` fails the build)."""

    reads = ("goal", "nav_failure")

    def update(self) -> Status:
        explorer = self.context.explorer
        if explorer.status != EXPLORING:
            self.feedback_message = f"exploration {explorer.status}: nothing to blacklist"
            return Status.SUCCESS
        goal = self.get("goal")
        why = self.get("nav_failure") or "unreachable"
        pose = self.context.robot.pose()
        explorer.goal_failed(goal, why, (pose.x, pose.y) if pose is not None else None, self.context.now(),
                             self.context.robot.live_map())
        self.feedback_message = f"blacklisted ({goal.xy[0]:.1f}, {goal.xy[1]:.1f}): {why}"
        return Status.SUCCESS


@register("ExplorationOutcome")
class ExplorationOutcome(Leaf):
    """Succeeds when exploration is done; fails when a limit cut it short or it is stuck."""

    def update(self) -> Status:
        ctx = self.context
        explorer = ctx.explorer
        if explorer.status == EXPLORING:  # the loop ended without a verdict: out of frontiers
            explorer.status, explorer.reason = DONE, "no frontiers left"
        ctx.reason = f"{explorer.status}: {explorer.reason}"
        self.feedback_message = ctx.reason
        return Status.SUCCESS if explorer.status == DONE else Status.FAILURE

