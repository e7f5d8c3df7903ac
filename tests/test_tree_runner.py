"""The tick loop on the robot clock, stopping, and the views of a running tree."""

from __future__ import annotations

import io
import json

import py_trees
import pytest
from py_trees.common import Status
from test_tree_loader import FakeRobot, make_registry, write

from bomc_bt.tree import TerminalView, TreeRunner, load_tree, snapshot


@pytest.fixture(autouse=True)
def clean_blackboard():
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()


TREE = """
    root:
      sequence: Mission
      memory: true
      children:
        - {behaviour: Counter}
        - {behaviour: WaitUntil, name: Drive, params: {until: 3.0}}
"""


def build(tmp_path, robot, text=TREE):
    return load_tree(write(tmp_path, "t.yaml", text), make_registry(), robot, robot.now)


def test_runs_until_success_stepping_the_robot_between_ticks(tmp_path):
    robot = FakeRobot(dt=1.0)
    seen = []
    runner = TreeRunner(build(tmp_path, robot), robot, on_tick=lambda r: seen.append((r.ticks, robot.now())))
    result = runner.run()
    assert (result.status, result.reason) == (Status.SUCCESS, "succeeded")
    assert (result.ticks, result.sim_time) == (4, 3.0)
    assert result.succeeded
    assert seen == [(1, 0.0), (2, 1.0), (3, 2.0), (4, 3.0)]  # tick, hook, step: alternating
    assert robot.terminated == [("Drive", Status.SUCCESS)]


def test_failure_ends_the_run(tmp_path):
    robot = FakeRobot()
    text = "root: {behaviour: FailTimes, params: {failures: 1}}\n"
    result = TreeRunner(build(tmp_path, robot, text), robot).run()
    assert (result.status, result.reason, result.ticks) == (Status.FAILURE, "failed", 1)


def test_max_time_stops_with_reason_and_cancels_leaves(tmp_path):
    robot = FakeRobot(dt=0.5)
    robot.t = 100.0  # max_time counts from the start of the run, not from zero
    text = "root: {behaviour: WaitUntil, name: Forever, params: {until: 1000000.0}}\n"
    root = build(tmp_path, robot, text)
    result = TreeRunner(root, robot, max_time=10.0).run()
    assert (result.status, result.reason) == (Status.RUNNING, "time limit")
    assert (result.sim_time, result.ticks) == (10.0, 21)
    assert robot.terminated == [("Forever", Status.INVALID)]
    assert root.status == Status.INVALID


def test_request_stop_exits_after_the_tick_and_terminates_running_leaves(tmp_path):
    robot = FakeRobot()
    root = build(tmp_path, robot)

    def stop_on_third(runner):
        if runner.ticks == 3:
            runner.request_stop("interrupted")

    result = TreeRunner(root, robot, on_tick=stop_on_third).run()
    assert (result.reason, result.ticks, result.status) == ("interrupted", 3, Status.RUNNING)
    assert robot.terminated == [("Drive", Status.INVALID)]  # the leaf could cancel and save
    assert all(node.status == Status.INVALID for node in root.iterate() if node.name != "Counter")


def test_terminal_view_redraws_in_place_on_a_tty(tmp_path):
    robot = FakeRobot(dt=1.0)
    stream = io.StringIO()
    wall = iter(range(100))
    view = TerminalView(stream, interval_wall_s=2.0, progress=lambda: f"t={robot.now():.0f}",
                        tty=True, wall_clock=lambda: float(next(wall)))
    TreeRunner(build(tmp_path, robot), robot, on_tick=view).run()
    view.close()
    frames = stream.getvalue().split("\x1b[4F\x1b[J")  # cursor up over 4 lines, clear below
    assert len(frames) == 3  # drawn at wall 0 and 2 (1 and 3 rate-limited), then the final frame
    assert frames[0].splitlines() == [
        "● Mission [sequence]",
        "  ✔ Counter [Counter]",
        "  ● Drive [WaitUntil]",
        "t=0",
    ]
    assert frames[1].splitlines()[-1] == "t=2"
    assert frames[2].splitlines() == [
        "✔ Mission [sequence]",
        "  ✔ Counter [Counter]",
        "  ✔ Drive [WaitUntil]",
        "t=3",
    ]


def test_terminal_view_logs_progress_on_sim_time_when_not_a_tty(tmp_path):
    robot = FakeRobot(dt=1.0)
    text = "root: {behaviour: WaitUntil, params: {until: 25.0}}\n"
    stream = io.StringIO()
    view = TerminalView(stream, progress=lambda: "exploring", interval_sim_s=10.0, tty=False)
    TreeRunner(build(tmp_path, robot, text), robot, on_tick=view).run()
    lines = stream.getvalue().splitlines()
    assert lines == ["[      0.0 s] exploring", "[     10.0 s] exploring", "[     20.0 s] exploring"]
    view.close()
    assert stream.getvalue().splitlines()[3:] == ["✔ WaitUntil [WaitUntil]", "exploring"]
    assert "\x1b" not in stream.getvalue()


def test_snapshot_is_json_with_statuses_and_feedback(tmp_path):
    robot = FakeRobot(dt=1.0)
    text = """
        root:
          timeout: {duration: 10}
          child: {behaviour: WaitUntil, name: Drive, params: {until: 5.0}}
    """
    root = build(tmp_path, robot, text)
    root.tick_once()
    snap = json.loads(json.dumps(snapshot(root)))
    assert snap["name"] == "Timeout" and snap["kind"] == "decorator" and snap["status"] == "running"
    assert snap["feedback"] == "10.0 s left"
    assert snap["children"] == [
        {"name": "Drive", "kind": "behaviour", "type": "WaitUntil", "status": "running", "feedback": "",
         "children": []}
    ]


def test_a_run_starts_with_the_leaves_keys_unset_whatever_an_earlier_run_left(tmp_path):
    py_trees.blackboard.Blackboard.set("/count", 41)  # left by an earlier mission in this process
    py_trees.blackboard.Blackboard.set("/unrelated", "kept")
    robot = FakeRobot(dt=1.0)
    TreeRunner(build(tmp_path, robot), robot).run()
    assert py_trees.blackboard.Blackboard.get("/count") == 1  # counted from scratch
    assert py_trees.blackboard.Blackboard.get("/unrelated") == "kept"



class CountingVisitor(py_trees.visitors.VisitorBase):
    """Counts the nodes the tree hands it (all of them each tick: a full visitor)."""

    def __init__(self):
        super().__init__(full=True)
        self.visits = 0

    def run(self, behaviour):
        self.visits += 1


def test_a_visitor_or_tick_handler_on_the_tree_still_sees_every_tick(tmp_path):
    """The runner ticks the root directly only when nothing is attached to the tree."""
    robot = FakeRobot(dt=1.0)
    runner = TreeRunner(build(tmp_path, robot), robot)
    visitor = CountingVisitor()
    runner.tree.add_visitor(visitor)
    handled = []
    runner.tree.add_post_tick_handler(lambda tree: handled.append(tree.count))
    result = runner.run()
    assert result.ticks == 4 and handled == [0, 1, 2, 3] and runner.tree.count == 4
    assert visitor.visits == 4 * len(list(runner.root.iterate()))  # 3 nodes, every tick
