"""Small leaves every tree can use."""

from __future__ import annotations

from dataclasses import dataclass

from py_trees.common import Status

from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register


@dataclass
class FailParams:
    message: str = "failed"  # [text] the reason given (and the mission's reason, if it has none yet)


@register("Fail")
class Fail(Leaf):
    """Fails with a message (ends a fallback branch with a clear reason)."""

    Params = FailParams

    def update(self) -> Status:
        self.feedback_message = self.params.message
        if not self.context.reason:
            self.context.reason = self.params.message
        return Status.FAILURE


@dataclass
class WaitParams:
    duration: float = 1.0  # [s] robot time to wait


@register("Wait")
class Wait(Leaf):
    """Waits on the robot clock (never wall time)."""

    Params = WaitParams

    def initialise(self) -> None:
        self.until = self.context.now() + self.params.duration

    def update(self) -> Status:
        left = self.until - self.context.now()
        self.feedback_message = f"{max(left, 0.0):.1f} s left"
        return Status.SUCCESS if left <= 0 else Status.RUNNING
