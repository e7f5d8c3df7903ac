"""LookAround: at a waypoint, turn the camera towards nodes worth another look.

The head turns are :class:`bomc_bt.look_around.HeadTurns` (which headings, the dwell
after each turn, the deadline); this leaf sends each turn as a navigation goal on the
spot and says what its outcomes mean: a turn done starts the dwell, a turn that failed
moves on to the next heading, and running out of time ends the look-around successfully
(it is a best effort, never a reason to fail the waypoint).
"""

from __future__ import annotations

import math

from py_trees.common import Status

from bomc_bt.budget_pass import look_time_left
from bomc_bt.geometry import Pose2D
from bomc_bt.look_around import LookAroundParams, plan_head_turns
from bomc_bt.tree.action import ActionLeaf
from bomc_bt.tree.registry import register


@register("LookAround")
class LookAround(ActionLeaf):
    """Turns the camera towards nodes this pass has not yet confirmed, or confirmed so long
    ago (``refresh_after``) that they may have gone since. In a pass with a budget it takes
    no longer than the budget leaves after the way home (:func:`~bomc_bt.budget_pass.look_time_left`)."""

    Params = LookAroundParams
    config_params = {"radius": "projection.expect_range", "refresh_after": "mission.stale_after"}

    def send(self) -> None:
        ctx = self.context
        self.pose = ctx.robot.pose()
        self.turns = plan_head_turns(ctx.graph, self.pose, ctx.session, ctx.robot.live_map(), self.params,
                                     ctx.config.camera.hfov_deg, ctx.now())
        place = None if self.pose is None else (self.pose.x, self.pose.y)
        ctx.graph.mark_sightings_looked(self.turns.faced, place)  # one look a place (a false positive's too)
        self.time_left = None if ctx.budget is None or ctx.traverse is None else look_time_left(
            ctx.budget, ctx.now() - ctx.budget.started, ctx.traverse.current)
        return None  # the first turn starts on the first tick, like every later one

    def timeout(self) -> float:
        left = getattr(self, "time_left", None)
        return self.params.timeout if left is None else min(self.params.timeout, left)

    def before_poll(self) -> Status | None:
        if self.time_left is not None and self.handle is None and self.context.now() >= self.deadline:
            self.feedback_message = "the budget leaves no more time to look"
            return Status.SUCCESS  # a budgeted pass: not even the rest of a dwell
        return Status.RUNNING if self.turns.dwelling(self.context.now()) else None

    def idle(self) -> Status:
        heading = self.turns.next_heading(self.context.now())
        if heading is None:
            self.feedback_message = "nothing left to check here"
            return Status.SUCCESS
        self.handle = self.context.robot.navigate(Pose2D(self.pose.x, self.pose.y, heading))
        self.feedback_message = f"looking towards {math.degrees(heading):.0f}°, {len(self.turns.headings)} more"
        return Status.RUNNING

    def on_success(self) -> Status:
        self.turns.turned(self.context.now())
        self.handle = None
        return Status.RUNNING

    def on_failure(self, status) -> Status:
        self.handle = None
        return self.idle()

    def on_timeout(self) -> Status:
        return Status.SUCCESS
