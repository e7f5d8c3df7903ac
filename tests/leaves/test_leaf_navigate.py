"""NavigateTo and Relocalize, tick by tick: the action-leaf contract (send, poll, robot-clock
timeout, cancel on halt) and what each writes on the blackboard."""

from __future__ import annotations

from fake_robot import key, tick, write_goal
from py_trees.common import Status

from behaviours.navigate import NavigateTo, NavigateToParams
from behaviours.relocalize import Relocalize, RelocalizeParams
from bomc_bt.geometry import Pose2D
from bomc_bt.robot import Status as Nav


def navigate(ctx, **params) -> NavigateTo:
    write_goal(Pose2D(8.0, 5.0, 0.0))
    return NavigateTo("Navigate", NavigateToParams(**params), ctx)


def test_navigate_sends_the_goal_runs_and_succeeds_when_the_robot_arrives(ctx, robot):
    leaf = navigate(ctx)
    assert tick(leaf) == Status.RUNNING
    assert robot.goals == [Pose2D(8.0, 5.0, 0.0)] and key("nav_detour") is False
    robot.distance_travelled = 3.0  # the map's shortest path
    robot.last.finish(Nav.SUCCEEDED, "arrived")
    assert tick(leaf) == Status.SUCCESS
    assert key("nav_detour") is False and len(robot.goals) == 1


def test_navigate_reached_by_a_long_way_round_is_a_detour(ctx, robot):
    leaf = navigate(ctx, detour_ratio=1.3, detour_margin=2.0)
    tick(leaf)
    robot.distance_travelled = 3.0 * 1.3 + 2.0 + 0.5
    robot.last.finish(Nav.SUCCEEDED, "arrived")
    assert tick(leaf) == Status.SUCCESS and key("nav_detour") is True
    assert "by a detour" in leaf.feedback_message


def test_navigate_fails_with_the_reason_when_the_robot_gives_up(ctx, robot):
    leaf = navigate(ctx)
    tick(leaf)
    robot.last.finish(Nav.BLOCKED, "no progress")
    assert tick(leaf) == Status.FAILURE
    assert key("nav_failure") == "blocked: no progress"


def test_navigate_times_out_on_the_robot_clock_and_cancels_the_goal(ctx, robot):
    leaf = navigate(ctx, timeout=10.0)
    tick(leaf)
    robot.advance(9.9)
    assert tick(leaf) == Status.RUNNING
    robot.advance(0.1)
    assert tick(leaf) == Status.FAILURE
    assert robot.last.status() is Nav.CANCELLED and key("nav_failure") == "timeout"


def test_navigate_halted_by_the_tree_cancels_its_goal(ctx, robot):
    leaf = navigate(ctx)
    tick(leaf)
    leaf.stop(Status.INVALID)
    assert robot.last.status() is Nav.CANCELLED


def test_navigate_that_ended_is_not_cancelled_again(ctx, robot):
    leaf = navigate(ctx)
    tick(leaf)
    robot.last.finish(Nav.SUCCEEDED, "arrived")
    tick(leaf)
    leaf.stop(Status.INVALID)
    assert robot.last.status() is Nav.SUCCEEDED


def test_relocalize_locally_from_the_dock_writes_how_it_localized(ctx, robot):
    leaf = Relocalize("Local", RelocalizeParams(global_search=False, timeout=60.0), ctx)
    assert tick(leaf) == Status.RUNNING and robot.relocalizations == [(ctx.dock, False)]
    robot.last.finish(Nav.SUCCEEDED, "localized")
    assert tick(leaf) == Status.SUCCESS and key("localized") == "local"


def test_relocalize_globally_without_a_hint(ctx, robot):
    leaf = Relocalize("Global", RelocalizeParams(global_search=True), ctx)
    tick(leaf)
    robot.last.finish(Nav.SUCCEEDED, "localized")
    assert tick(leaf) == Status.SUCCESS
    assert robot.relocalizations == [(None, True)] and key("localized") == "global"


def test_relocalize_fails_when_not_confident_and_writes_nothing(ctx, robot):
    leaf = Relocalize("Local", RelocalizeParams(), ctx)
    tick(leaf)
    robot.last.finish(Nav.FAILED, "not confident")
    assert tick(leaf) == Status.FAILURE and key("localized") is None
    assert "not confident" in leaf.feedback_message


def test_relocalize_times_out_on_the_robot_clock_and_cancels(ctx, robot):
    leaf = Relocalize("Local", RelocalizeParams(timeout=5.0), ctx)
    tick(leaf)
    robot.advance(5.0)
    assert tick(leaf) == Status.FAILURE
    assert robot.last.status() is Nav.CANCELLED and "no answer within 5 s" in leaf.feedback_message


def test_relocalize_halted_cancels(ctx, robot):
    leaf = Relocalize("Local", RelocalizeParams(), ctx)
    tick(leaf)
    leaf.stop(Status.INVALID)
    assert robot.last.status() is Nav.CANCELLED
