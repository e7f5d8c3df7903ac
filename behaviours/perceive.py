"""Perceive-Associate: every new RGB-D frame updates the object graph while the robot moves.

Runs beside Traverse Waypoints in a parallel, at the camera's rate. It never works on a
frame without a localized pose: an unlocalized frame cannot be put in the map.
"""

from __future__ import annotations

from py_trees.common import Status

from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register


@register("PerceiveAssociate")
class PerceiveAssociate(Leaf):
    """Detect, segment, back-project and associate each frame (Algorithm 2 per frame)."""

    def update(self) -> Status:
        ctx = self.context
        ctx.progress.path_length = ctx.robot.distance_travelled  # the pass's driving, for the progress line
        frame = ctx.robot.frame()
        if frame is None:
            return Status.RUNNING
        if ctx.robot.pose() is None:
            self.feedback_message = "not localized: frame skipped"
            return Status.RUNNING
        result = ctx.perception.process(frame)
        ctx.progress.frames = ctx.perception.frames
        ctx.progress.nodes = len(ctx.graph.nodes)
        changes = ", ".join(f"{e.kind} {e.category} #{e.node_id}" for e in result.events[:3])
        self.feedback_message = (f"frame {ctx.perception.frames}: {result.detections} detections, "
                                 f"{result.expected} expected" + (f"; {changes}" if changes else ""))
        return Status.RUNNING
