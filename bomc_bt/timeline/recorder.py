"""Records a monitor pass's timeline while it runs, for replay in ``bomc view`` (issue 19).

:class:`TimelineRecorder` is an ``on_tick`` hook of the pass. Ticks are the pass's hot
loop, so a tick costs a status comparison per tree node (statuses change rarely: only the
changes are written), a look at the perception's frame and event counters, and the pose
and the nodes' feedback messages only every ``mission.timeline_pose_period`` seconds of
robot time. ``benchmarks/bench_timeline.py`` measures what it costs a pass (under 5 %).

The tree's nodes are listed once, depth first, when the first tick comes; their index in
that list is how later records name them.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from bomc_bt.timeline.format import VERSION, TimelineWriter, timeline_path
from bomc_bt.tree.view import kind_of

STATUS_LETTER = {"SUCCESS": "s", "FAILURE": "f", "RUNNING": "r", "INVALID": "i"}


def _round(value: float, digits: int = 3) -> float | None:
    value = float(value)
    return round(value, digits) if math.isfinite(value) else None


def _pose(pose: Any) -> list[float | None] | None:
    return None if pose is None else [_round(pose.x), _round(pose.y), _round(pose.yaw)]


class TimelineRecorder:
    """``on_tick`` hook writing the pass's timeline (see :mod:`bomc_bt.timeline.format`)."""

    def __init__(self, ctx: Any, writer: TimelineWriter, pose_period: float):
        self.ctx = ctx
        self.writer = writer
        self.pose_period = pose_period
        self._nodes: list[Any] = []
        self._status: list[Any] = []
        self._feedback: list[str] = []
        self._next_pose = -math.inf
        self._frames = 0
        self._events = 0
        now = ctx.now()
        writer.write({"k": "head", "v": VERSION, "session": ctx.session, "t": _round(now),
                      "resume": bool(ctx.resume)})
        perception = ctx.perception
        if perception is not None:  # a resumed pass: only what comes after its restored state
            self._frames, self._events = perception.frames, len(perception.events)

    @classmethod
    def open(cls, ctx: Any) -> TimelineRecorder | None:
        """The recorder of ``ctx``'s pass, appending to its session's file; None when
        ``mission.timeline`` is off."""
        mission = ctx.config.mission
        if not mission.timeline:
            return None
        path: Path = timeline_path(ctx.site.session_dir(ctx.session))
        return cls(ctx, TimelineWriter(path, mission.timeline_flush_period), mission.timeline_pose_period)

    def __call__(self, runner: Any) -> None:
        t = self.ctx.now()
        if not self._nodes:
            self._write_tree(runner.root, t)
        sampling = t >= self._next_pose
        changes = self._changes(sampling)
        if changes:
            self.writer.write({"k": "st", "t": _round(t), "c": changes})
        if sampling:
            self._next_pose = t + self.pose_period
            self._write_pose(t)
        perception = self.ctx.perception
        if perception is not None:
            if perception.frames != self._frames:
                self._frames = perception.frames
                self._write_frame(perception)
            if len(perception.events) != self._events:
                self._write_events(perception.events[self._events:], t)
                self._events = len(perception.events)

    def close(self) -> None:
        self.writer.close()

    # ------------------------------------------------------------------ records
    def _write_tree(self, root: Any, t: float) -> None:
        rows: list[list[Any]] = []

        def visit(node: Any, parent: int) -> None:
            index = len(rows)
            rows.append([node.name, kind_of(node), type(node).__name__, parent])
            self._nodes.append(node)
            for child in node.children:
                visit(child, index)

        visit(root, -1)
        self._status = [None] * len(self._nodes)
        self._feedback = [""] * len(self._nodes)
        self.writer.write({"k": "tree", "t": _round(t), "n": rows})

    def _changes(self, with_feedback: bool) -> list[list[Any]]:
        """``[index, status letter, feedback]`` of nodes whose status changed (or, when
        ``with_feedback``, whose feedback message changed)."""
        out = []
        status, feedback = self._status, self._feedback
        for i, node in enumerate(self._nodes):
            now = node.status
            if now is not status[i] or (with_feedback and node.feedback_message != feedback[i]):
                status[i] = now
                feedback[i] = message = node.feedback_message or ""
                out.append([i, STATUS_LETTER.get(now.name, "i"), message])
        return out

    def _write_pose(self, t: float) -> None:
        robot = self.ctx.robot
        record: dict[str, Any] = {"k": "pose", "t": _round(t), "p": _pose(robot.pose())}
        truth = getattr(robot, "true_pose", None)  # the simulator's ground truth, when there is one
        if truth is not None and hasattr(truth, "yaw"):
            record["g"] = _pose(truth)
        self.writer.write(record)

    def _write_frame(self, perception: Any) -> None:
        frame = perception.last_frame
        if frame is None:
            return
        detections = [[d.category, *(_round(v, 1) for v in d.box), _round(d.score)] for d in frame.detections]
        points = [[o.category, _round(o.position[0]), _round(o.position[1])] for o in frame.observations]
        self.writer.write({"k": "frame", "t": _round(frame.stamp), "n": perception.frames,
                           "wh": list(frame.size), "d": detections, "o": points})

    def _write_events(self, events: list[Any], t: float) -> None:
        rows = []
        for e in events:
            prev = e.previous
            rows.append([e.kind, int(e.node_id), e.category, _round(e.position[0]), _round(e.position[1]),
                         None if prev is None else _round(prev[0]), None if prev is None else _round(prev[1])])
        self.writer.write({"k": "ev", "t": _round(t), "e": rows})
