"""Relocalize: find the robot in the saved map before a monitor pass starts.

The tree retries a local search around the dock pose, then falls back to a global
search, then aborts: a monitor pass never runs unlocalized. The leaf writes how the
robot was localized (``local`` or ``global``) to the ``localized`` key; the session
report shows it. A resumed pass whose robot state was restored (``resumed``) is already
localized where the killed run left it and asks nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

from py_trees.common import Status

from bomc_bt.robot import Handle
from bomc_bt.tree.action import ActionLeaf
from bomc_bt.tree.registry import register


@dataclass
class RelocalizeParams:
    global_search: bool = False  # [bool] search the whole map instead of around the dock pose
    timeout: float = 60.0  # [s] robot time for an answer
    hint: str = "dock"  # [choice] dock: search around the dock pose; pose: around the current estimate

    def __post_init__(self) -> None:
        if self.hint not in ("dock", "pose"):
            raise ValueError(f"hint must be dock or pose, not {self.hint!r}")


@register("Relocalize")
class Relocalize(ActionLeaf):
    """Asks the robot to localize from the dock pose (or globally) and waits for it."""

    Params = RelocalizeParams
    writes = ("localized",)

    def label(self) -> str:
        return "global" if self.params.global_search else "local"

    def send(self) -> Handle | None:
        if self.context.restored and self.context.robot.pose() is not None:
            return None  # a resumed pass: the robot is where the killed run left it, localized
        hint = None if self.params.global_search else self.context.dock
        if hint is not None and self.params.hint == "pose":  # a pass that lost its way relocalizes where it is
            hint = self.context.robot.pose() or self.context.dock
        return self.context.robot.relocalize(hint, global_search=self.params.global_search)

    def timeout(self) -> float:
        return self.params.timeout

    def idle(self) -> Status:
        self.say("already localized (resumed pass)")
        self.set("localized", "resumed")
        return Status.SUCCESS

    def on_success(self) -> Status:
        pose = self.context.robot.pose()
        self.say(f"localized at ({pose.x:.2f}, {pose.y:.2f}, {pose.yaw:.2f})")
        self.set("localized", self.label())
        return Status.SUCCESS

    def on_running(self) -> Status:
        self.say("matching scans")
        return Status.RUNNING
