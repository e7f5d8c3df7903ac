"""Relocalize: find the robot in the saved map before a monitor pass starts.

The tree retries a local search around the dock pose, then falls back to a global
search, then aborts: a monitor pass never runs unlocalized.
"""

from __future__ import annotations

from dataclasses import dataclass

from py_trees.common import Status

from bomc_bt.robot import Status as Nav
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register


@dataclass
class RelocalizeParams:
    global_search: bool = False
    timeout: float = 60.0  # s of robot time


@register("Relocalize")
class Relocalize(Leaf):
    """Asks the robot to localize from the dock pose (or globally) and waits for it."""

    Params = RelocalizeParams

    def initialise(self) -> None:
        hint = None if self.params.global_search else self.context.dock
        self.handle = self.context.robot.relocalize(hint, global_search=self.params.global_search)
        self.deadline = self.context.now() + self.params.timeout

    def update(self) -> Status:
        status = self.handle.status()
        kind = "global" if self.params.global_search else "local"
        if status is Nav.SUCCEEDED:
            pose = self.context.robot.pose()
            self.feedback_message = f"{kind}: localized at ({pose.x:.2f}, {pose.y:.2f}, {pose.yaw:.2f})"
            self.context.extras["localized"] = kind
            return Status.SUCCESS
        if status.done:
            self.feedback_message = f"{kind}: {status.value}: {self.handle.message}"
            return Status.FAILURE
        if self.context.now() >= self.deadline:
            self.handle.cancel()
            self.feedback_message = f"{kind}: no answer within {self.params.timeout:.0f} s"
            return Status.FAILURE
        self.feedback_message = f"{kind}: matching scans"
        return Status.RUNNING

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID and getattr(self, "handle", None) is not None:
            self.handle.cancel()
