"""Session, map, perception and the small common leaves, tick by tick on a scripted robot."""

from __future__ import annotations

import json

import numpy as np
import py_trees
from fake_robot import tick
from py_trees.common import Status

from behaviours.common import Fail, FailParams, Wait, WaitParams
from behaviours.perceive import PerceiveAssociate
from behaviours.save_map import SaveMap
from behaviours.session import EndSession, EndSessionParams, StartSession
from bomc_bt.monitoring import FrameResult
from bomc_bt.robot import RGBDFrame


def test_start_session_opens_the_session_in_the_store(ctx):
    leaf = StartSession("Start", None, ctx)
    assert tick(leaf) == Status.SUCCESS and leaf.feedback_message.startswith("session 1 started")
    assert [r.number for r in ctx.store.sessions()] == [1]


def test_end_session_closes_it_and_the_report_says_how_the_robot_localized(ctx):
    tick(StartSession("Start", None, ctx))
    py_trees.blackboard.Blackboard.set("/localized", "global")  # what Relocalize wrote
    assert tick(EndSession("End", EndSessionParams(outcome="completed"), ctx)) == Status.SUCCESS
    report = json.loads((ctx.site.session_dir(1) / "report.json").read_text())
    assert report["outcome"] == "completed" and report["localized"] == "global"
    assert ctx.store.sessions()[0].outcome == "completed"


def test_an_unlocalized_pass_reports_so(ctx):
    tick(StartSession("Start", None, ctx))
    tick(EndSession("Close", EndSessionParams(outcome="aborted"), ctx))
    assert json.loads((ctx.site.session_dir(1) / "report.json").read_text())["localized"] == "no"


def test_save_map_writes_the_map_and_the_build_record(ctx):
    leaf = SaveMap("Save", None, ctx)
    assert tick(leaf) == Status.SUCCESS
    assert ctx.site.map_yaml.exists() and ctx.site.build_json.exists()
    assert json.loads(ctx.site.build_json.read_text())["termination"] == "not started"


class CountingPerception:
    """Stands in for :class:`bomc_bt.monitoring.Perception`: counts the frames it is given."""

    def __init__(self):
        self.frames = 0
        self.events: list = []

    def process(self, frame):
        self.frames += 1
        return FrameResult(detections=2, observations=2, expected=1, events=[])


def frame() -> RGBDFrame:
    return RGBDFrame(0.0, None, np.zeros((4, 4), np.float32), np.eye(3), np.eye(4), np.eye(4))


def test_perceive_associate_runs_forever_and_processes_each_localized_frame(ctx, robot):
    ctx.perception = CountingPerception()
    leaf = PerceiveAssociate("Perceive", None, ctx)
    robot.distance_travelled = 2.5
    assert tick(leaf) == Status.RUNNING and ctx.perception.frames == 0  # no frame yet
    assert ctx.progress.path_length == 2.5  # the progress line and the viewer's header say how far (issue 19)
    robot.frames.append(frame())
    assert tick(leaf) == Status.RUNNING and ctx.perception.frames == 1 == ctx.progress.frames
    assert "2 detections, 1 expected" in leaf.feedback_message
    robot.place(None)
    robot.frames.append(frame())
    assert tick(leaf) == Status.RUNNING and ctx.perception.frames == 1
    assert leaf.feedback_message == "not localized: frame skipped"


def test_fail_gives_its_reason_to_the_mission_unless_it_has_one(ctx):
    assert tick(Fail("Fail", FailParams("exploration failed"), ctx)) == Status.FAILURE
    assert ctx.reason == "exploration failed"
    tick(Fail("Fail Again", FailParams("something else"), ctx))
    assert ctx.reason == "exploration failed"


def test_wait_waits_on_the_robot_clock(ctx, robot):
    leaf = Wait("Wait", WaitParams(duration=2.0), ctx)
    assert tick(leaf) == Status.RUNNING
    robot.advance(1.9)
    assert tick(leaf) == Status.RUNNING
    robot.advance(0.1)
    assert tick(leaf) == Status.SUCCESS
