"""The build's leaves, tick by tick on a scripted robot: start, record, choose, drive,
blacklist, the loop's exit condition and the outcome."""

from __future__ import annotations

import numpy as np
import py_trees
import pytest
from fake_robot import FakeRobot, key, open_room, tick
from py_trees.common import Status

from behaviours.explore import (
    BlacklistGoal,
    ChooseFrontier,
    DriveToFrontier,
    DriveToFrontierParams,
    ExplorationOutcome,
    ExplorationOver,
    RecordTrajectory,
    StartExploration,
    StartExplorationParams,
)
from bomc_bt.exploration.explorer import DONE, EXPLORING, NO_PROGRESS, STUCK, TIME_LIMIT
from bomc_bt.geometry import Pose2D
from bomc_bt.robot import Status as Nav


@pytest.fixture
def robot() -> FakeRobot:
    """A room whose east half is still unknown: one frontier along x = 7 m."""
    grid = open_room()
    grid.data[:, 140:] = -1
    return FakeRobot(grid, Pose2D(3.0, 5.0, 0.0))


@pytest.fixture
def build(ctx):
    ctx.mission = "build"
    tick(StartExploration("Start", StartExplorationParams(max_consecutive_failures=2), ctx))
    return ctx


def test_start_exploration_makes_the_explorer_and_the_trajectory_file(build):
    assert build.explorer.status == EXPLORING and build.explorer.max_consecutive_failures == 2
    assert build.trajectory is not None and build.site.trajectory_csv.exists()


def test_record_trajectory_keeps_running_and_records_the_path(build, robot):
    leaf = RecordTrajectory("Record", None, build)
    assert tick(leaf) == Status.RUNNING
    robot.advance(10.0)
    robot.place(Pose2D(4.0, 5.0, 0.0))
    assert tick(leaf) == Status.RUNNING
    assert build.progress.path_length == pytest.approx(1.0) and build.trajectory.rows == 2


def test_choose_frontier_writes_the_goal_and_the_loop_goes_on(build):
    assert tick(ChooseFrontier("Choose", None, build)) == Status.SUCCESS
    assert key("goal").xy[0] > 5.0 and build.explorer.goals == 1
    assert tick(ExplorationOver("Over", None, build)) == Status.FAILURE


def test_choose_frontier_with_nothing_left_ends_the_loop_successfully(build, robot):
    robot.grid.data[:, 140:] = 0  # all mapped
    robot.grid.data[:, -1] = 100
    assert tick(ChooseFrontier("Choose", None, build)) == Status.SUCCESS and key("goal") is None
    assert build.explorer.status == DONE
    assert tick(ExplorationOver("Over", None, build)) == Status.SUCCESS
    assert tick(ExplorationOutcome("Outcome", None, build)) == Status.SUCCESS


def test_choose_frontier_waits_for_a_pose(build, robot):
    robot.place(None)
    assert tick(ChooseFrontier("Choose", None, build)) == Status.RUNNING


def drive(build) -> DriveToFrontier:
    tick(ChooseFrontier("Choose", None, build))
    return DriveToFrontier("Drive", DriveToFrontierParams(recheck_period=2.0), build)


def test_drive_to_frontier_faces_the_frontier_and_succeeds_on_arrival(build, robot):
    leaf = drive(build)
    assert tick(leaf) == Status.RUNNING
    goal = key("goal")
    assert robot.goals[0].x == goal.xy[0] and abs(robot.goals[0].yaw) < 0.5  # facing east
    robot.last.finish(Nav.SUCCEEDED, "arrived")
    assert tick(leaf) == Status.SUCCESS


def test_drive_to_frontier_ends_on_arrival_at_a_mapped_frontier_without_turning_to_face_it(build, robot):
    leaf = drive(build)
    assert tick(leaf) == Status.RUNNING
    goal = key("goal")
    robot.grid.data[:, 140:] = 0  # mapped on the last metre, before the 2 s recheck
    robot.place(Pose2D(goal.xy[0] - 0.2, goal.xy[1], 1.2))  # arrived, not facing the goal's heading
    assert tick(leaf) == Status.SUCCESS and leaf.feedback_message == "arrived, the frontier mapped"
    assert robot.last.status() is Nav.CANCELLED  # no turn on the spot


def test_drive_to_frontier_ends_on_arrival_with_an_open_frontier_in_view_only_the_first_time(build, robot):
    leaf = drive(build)
    tick(leaf)
    goal = key("goal")
    robot.place(Pose2D(goal.xy[0] - 0.2, goal.xy[1], 1.2))  # arrived, the frontier 1.2 rad off its heading:
    assert tick(leaf) == Status.SUCCESS  # in the lidar's 220 degrees, though still unknown (not yet mapped)
    assert leaf.feedback_message == "arrived with the frontier in view" and not build.explorer.blacklist.points
    leaf.stop(Status.SUCCESS)
    assert tick(leaf) == Status.RUNNING  # the same frontier again: turn to face it
    robot.last.finish(Nav.SUCCEEDED, "arrived")
    assert tick(leaf) == Status.SUCCESS and build.explorer.blacklist.points  # still open: not chosen again


def test_drive_to_frontier_turns_to_face_a_frontier_that_arrival_leaves_behind(build, robot):
    leaf = drive(build)
    tick(leaf)
    goal = key("goal")
    robot.place(Pose2D(goal.xy[0] - 0.2, goal.xy[1], 2.5))  # arrived facing away: the blind sector
    assert tick(leaf) == Status.RUNNING and robot.last.status() is Nav.RUNNING  # navigation turns it


def test_drive_to_frontier_succeeds_early_once_the_frontier_is_mapped(build, robot):
    leaf = drive(build)
    tick(leaf)
    robot.grid.data[:, 140:] = 0
    robot.advance(2.0)
    assert tick(leaf) == Status.SUCCESS and leaf.feedback_message == "frontier mapped on the way"


def test_drive_to_frontier_failure_is_written_for_blacklist_goal(build, robot):
    leaf = drive(build)
    tick(leaf)
    robot.last.finish(Nav.FAILED, "no path")
    assert tick(leaf) == Status.FAILURE and key("nav_failure") == "failed: no path"
    blacklist = BlacklistGoal("Blacklist", None, build)
    assert tick(blacklist) == Status.SUCCESS and "no path" in blacklist.feedback_message
    assert build.explorer.blacklist.points  # the frontier is skipped from now on


def test_drive_to_frontier_ends_the_loop_when_the_users_time_limit_is_up(ctx, robot):
    ctx.mission, ctx.max_time = "build", 60.0  # bomc build --max-time 60
    tick(StartExploration("Start", StartExplorationParams(), ctx))
    leaf = drive(ctx)
    tick(leaf)
    robot.advance(61.0)
    assert tick(leaf) == Status.SUCCESS and ctx.explorer.status == TIME_LIMIT
    assert robot.last.status() is Nav.RUNNING  # the next goal pre-empts it; nothing was cancelled
    assert tick(ExplorationOver("Over", None, ctx)) == Status.SUCCESS
    assert tick(ExplorationOutcome("Outcome", None, ctx)) == Status.FAILURE  # cut short: not "done"


def test_without_a_time_limit_only_the_progress_guard_ends_a_drive(build, robot):
    assert build.explorer.max_time is None
    leaf = drive(build)
    tick(leaf)
    robot.advance(500.0)  # nothing newly mapped, but not for no_progress_time (600 s) yet
    assert tick(leaf) == Status.RUNNING and build.explorer.status == EXPLORING
    robot.advance(200.0)
    assert tick(leaf) == Status.SUCCESS and build.explorer.status == NO_PROGRESS
    assert tick(ExplorationOutcome("Outcome", None, build)) == Status.FAILURE


def test_drive_to_frontier_halted_cancels_its_goal(build, robot):
    leaf = drive(build)
    tick(leaf)
    leaf.stop(Status.INVALID)
    assert robot.last.status() is Nav.CANCELLED


def test_a_stuck_explorer_ends_the_loop_and_fails_the_build(ctx, robot):
    ctx.mission = "build"
    ctx.config.exploration.max_backouts = 0  # no back-out allowed: stuck once goals keep failing in place
    tick(StartExploration("Start", StartExplorationParams(max_consecutive_failures=2), ctx))
    build = ctx
    tick(ChooseFrontier("Choose", None, build))
    for _ in range(2):  # the same goal fails twice without the robot moving
        leaf = DriveToFrontier("Drive", DriveToFrontierParams(), build)
        tick(leaf)
        robot.advance(5.0)  # not refused at once: the robot tried
        robot.last.finish(Nav.BLOCKED, "no progress")
        tick(leaf)
        assert tick(BlacklistGoal("Blacklist", None, build)) == Status.SUCCESS
    assert build.explorer.status == STUCK
    assert tick(ExplorationOver("Over", None, build)) == Status.SUCCESS
    assert tick(ExplorationOutcome("Outcome", None, build)) == Status.FAILURE and "stuck" in build.reason


def test_blacklist_goal_has_nothing_to_do_once_exploration_is_over(build):
    build.explorer.status = DONE
    py_trees.blackboard.Blackboard.set("/goal", None)
    assert tick(BlacklistGoal("Blacklist", None, build)) == Status.SUCCESS
    assert np.size(build.explorer.blacklist.points) == 0


@pytest.mark.parametrize("bad", [{"in_view_deg": -5.0}, {"in_view_deg": 200.0}, {"open_radius": 0.0},
                                 {"arrive_radius": -0.1}])
def test_drive_to_frontier_refuses_parameters_out_of_range(bad):
    with pytest.raises(ValueError):
        DriveToFrontierParams(**bad)
