"""A pass with a budget, tick by tick on the scripted robot: the plan ends at the dock within
the budget, a waypoint the robot can no longer afford is skipped with the rest of the tour,
the later phases stay empty, and a budget too small to leave the dock plans nothing else."""

from __future__ import annotations

import numpy as np
from fake_robot import key, tick, write_goal
from py_trees.common import Status

from behaviours.look_around import LookAround
from behaviours.navigate import NavigateTo
from behaviours.plan_pass import PlanGapViewpoints, PlanRefreshStops, PlanTraversal
from behaviours.waypoints import NextWaypoint, WaypointsDone
from bomc_bt.budget_pass import CLOSING_S, budget_key, look_time_left
from bomc_bt.budget_plan import PassBudget
from bomc_bt.geometry import Pose2D
from bomc_bt.graph import AssociationParams, Node, ObjectGraph
from bomc_bt.look_around import LookAroundParams
from bomc_bt.monitoring import TraversalState
from bomc_bt.robot import Status as Nav
from bomc_bt.traversal import TraversalPlan


def begin(ctx, seconds: float) -> None:
    ctx.store.begin_session(ctx.session, {"stamp": ctx.now()})
    ctx.config.budget.seconds = seconds


def test_a_budgeted_plan_ends_at_the_dock_and_is_planned_within_the_budget(ctx):
    begin(ctx, 40.0)
    assert tick(PlanTraversal("Plan", None, ctx)) == Status.SUCCESS
    budget = ctx.budget
    assert budget is not None and not budget.full_pass
    assert 0 < budget.stops < budget.stops_total  # 40 s cannot see all of a 10 x 10 m room's stops
    assert budget.planned_s <= 40.0
    last = ctx.plan.waypoints[-1]
    assert (last.x, last.y) == (ctx.dock.x, ctx.dock.y)
    assert ctx.store.get_progress(budget_key(ctx.session))["seconds"] == 40.0


def test_a_budget_too_small_to_leave_the_dock_plans_only_the_way_home(ctx):
    begin(ctx, 1.0)
    assert tick(PlanTraversal("Plan", None, ctx)) == Status.SUCCESS
    assert len(ctx.plan.waypoints) == 1 and ctx.budget.stops == 0
    assert tick(WaypointsDone("Done", None, ctx)) == Status.FAILURE
    assert tick(NextWaypoint("Next", None, ctx)) == Status.SUCCESS
    assert key("goal").x == ctx.dock.x
    assert tick(WaypointsDone("Done", None, ctx)) == Status.SUCCESS


def test_the_tree_parameter_overrides_the_configuration(ctx):
    begin(ctx, 0.0)
    leaf = PlanTraversal("Plan", None, ctx)
    leaf.params.budget = 60.0
    assert tick(leaf) == Status.SUCCESS
    assert ctx.budget is not None and ctx.budget.seconds == 60.0


def test_a_waypoint_that_would_overrun_the_budget_is_skipped_with_the_rest_and_the_dock_comes_next(ctx, robot):
    waypoints = [Pose2D(3.0, 1.0, 0.0), Pose2D(8.0, 8.0, 0.0), Pose2D(3.0, 2.0, 0.0), Pose2D(1.0, 1.0, 0.0)]
    ctx.plan = TraversalPlan(waypoints, 20.0)
    ctx.traverse = TraversalState(ctx.plan)
    ctx.budget = PassBudget(60.0, "expected_changes", speed=0.5, heading_time=4.0, started=robot.now(),
                            home_m=[2.0, 10.0, 2.2, 0.0])
    robot.place(Pose2D(1.0, 1.0, 0.0))
    assert tick(NextWaypoint("Next", None, ctx)) == Status.SUCCESS  # 2 + 2 m at 0.5 m/s + 4 s: fits
    assert key("goal").x == 3.0
    robot.advance(30.0)
    robot.place(Pose2D(3.0, 1.0, 0.0))
    assert tick(NextWaypoint("Next", None, ctx)) == Status.SUCCESS  # (8.6 + 10) / 0.5 + 4 > 30 s left
    assert (key("goal").x, key("goal").y) == (1.0, 1.0)
    assert ctx.traverse.states[1:3] == ["pending", "pending"]  # skipped: reported as not reached
    assert tick(WaypointsDone("Done", None, ctx)) == Status.SUCCESS


def test_gap_and_refresh_phases_stay_empty_in_a_budgeted_pass(ctx):
    begin(ctx, 120.0)
    tick(PlanTraversal("Plan", None, ctx))
    before = len(ctx.traverse.states)
    assert tick(PlanGapViewpoints("Gaps", None, ctx)) == Status.SUCCESS
    assert tick(PlanRefreshStops("Refresh", None, ctx)) == Status.SUCCESS
    assert len(ctx.traverse.states) == before


def test_a_budget_that_covers_the_last_full_pass_runs_the_full_pass(ctx, robot):
    ctx.store.begin_session(1, {"stamp": 0.0})
    ctx.store.end_session(1, "completed", {"stamp": 100.0})
    ctx.session = 2
    begin(ctx, 150.0)
    assert tick(PlanTraversal("Plan", None, ctx)) == Status.SUCCESS
    assert ctx.budget.full_pass
    last = ctx.plan.waypoints[-1]
    assert (last.x, last.y) != (ctx.dock.x, ctx.dock.y)  # the full plan, no way home appended
    gaps = PlanGapViewpoints("Gaps", None, ctx)
    tick(gaps)
    assert "budget" not in gaps.feedback_message  # the full pass's phases run as always


def budgeted_look_around(ctx, robot, seconds: float) -> LookAround:
    """A look-around at waypoint 0 of a budgeted pass, 4 m from home, an unconfirmed node in view."""
    ctx.session = 2
    ctx.graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=1),
                            [Node(0, "chair", np.array([5.0, 8.0, 0.5]), 0.9, 1, 1)])
    ctx.plan = TraversalPlan([Pose2D(5.0, 5.0, 0.0), Pose2D(1.0, 1.0, 0.0)], 10.0)
    ctx.traverse = TraversalState(ctx.plan)
    ctx.traverse.current = 0
    ctx.budget = PassBudget(seconds, "expected_changes", speed=0.5, heading_time=4.0, started=robot.now(),
                            home_m=[4.0, 0.0])
    return LookAround("Look", LookAroundParams(dwell=20.0, timeout=30.0), ctx)


def test_a_look_around_ends_when_the_budget_must_head_home(ctx, robot):
    leaf = budgeted_look_around(ctx, robot, 24.0)  # 24 s - 4 m / 0.5 m/s - 2 x 4 s to turn: 8 s to look
    assert tick(leaf) == Status.RUNNING and len(robot.goals) == 1
    robot.last.finish(Nav.SUCCEEDED, "turned")
    assert tick(leaf) == Status.RUNNING  # a dwell of 20 s starts
    robot.advance(7.9)
    assert tick(leaf) == Status.RUNNING
    robot.advance(0.2)
    assert tick(leaf) == Status.SUCCESS and "budget" in leaf.feedback_message


def test_a_budget_with_no_time_left_looks_at_nothing_and_a_full_pass_looks_as_always(ctx, robot):
    leaf = budgeted_look_around(ctx, robot, 16.0)  # exactly the way home: nothing to spare
    assert tick(leaf) == Status.SUCCESS and robot.goals == []  # not even one turn
    # at the dock: the rest of the budget but the ticks that close the pass (it ended 0.1 s late)
    assert look_time_left(ctx.budget, 0.0, 1) == 16.0 - CLOSING_S
    ctx.budget.full_pass = True
    assert look_time_left(ctx.budget, 0.0, 0) is None


def test_the_drive_to_a_tour_waypoint_gives_up_when_the_robot_must_head_home_but_not_the_drive_home(ctx, robot):
    ctx.plan = TraversalPlan([Pose2D(9.0, 9.0, 0.0), Pose2D(1.0, 1.0, 0.0)], 20.0)
    ctx.traverse = TraversalState(ctx.plan)
    ctx.traverse.current = 0
    ctx.budget = PassBudget(30.0, "expected_changes", speed=0.5, heading_time=4.0, started=robot.now(),
                            home_m=[5.0, 0.0])
    write_goal(Pose2D(9.0, 9.0, 0.0))
    leaf = NavigateTo("Go", None, ctx)
    assert tick(leaf) == Status.RUNNING and leaf.timeout() == 12.0  # 30 s - 5 m / 0.5 m/s - 2 x 4 s to turn
    robot.advance(12.0)
    assert tick(leaf) == Status.FAILURE and "budget" in leaf.feedback_message
    ctx.traverse.current = 1  # the dock
    write_goal(Pose2D(1.0, 1.0, 0.0))
    home = NavigateTo("Home", None, ctx)
    assert tick(home) == Status.RUNNING and home.timeout() == home.params.timeout


def test_a_detour_on_the_way_out_makes_the_way_home_reckoned_longer():
    budget = PassBudget(60.0, "expected_changes", speed=0.5, heading_time=4.0, home_m=[10.0, 0.0])
    assert budget.allows(10.0, 2.0, 0)  # 10 + (2 + 10) / 0.5 + 8 = 42 s
    budget.note_leg(10.0, 20.0)  # a closed corridor: twice the map's way
    assert budget.detour == 2.0 and budget.home_seconds(0) == 40.0
    assert not budget.allows(10.0, 2.0, 0)  # 10 + 8 + 40 + 8 = 66 s
    assert look_time_left(budget, 10.0, 0) == 2.0
    budget.note_leg(float("inf"), 5.0)  # a leg the map has no way for says nothing
    assert budget.detour == 2.0


def test_a_detour_the_budget_cannot_afford_is_given_up_while_the_way_back_still_fits(ctx, robot):
    ctx.plan = TraversalPlan([Pose2D(9.0, 1.0, 0.0), Pose2D(1.0, 1.0, 0.0)], 20.0)
    ctx.traverse = TraversalState(ctx.plan)
    ctx.traverse.current = 0
    ctx.budget = PassBudget(60.0, "expected_changes", speed=0.5, heading_time=4.0, started=robot.now(),
                            home_m=[8.0, 0.0], odometer=robot.distance_travelled)
    write_goal(Pose2D(9.0, 1.0, 0.0))
    leaf = NavigateTo("Go", None, ctx)
    assert tick(leaf) == Status.RUNNING  # the map's way: 8 m
    robot.distance_travelled += 12.0  # 12 m driven and not there: a detour
    robot.advance(20.0)
    assert tick(leaf) == Status.RUNNING  # 20 s + 5 s ahead + 12 m back / 0.5 m/s + 4 s = 53 s: fits
    robot.distance_travelled += 4.0
    robot.advance(8.0)
    assert tick(leaf) == Status.FAILURE and key("nav_failure") == "budget"  # 28 + 5 + 32 + 4 > 60 s
    assert robot.last.status() is Nav.CANCELLED
    retry = NavigateTo("Retry", None, ctx)
    assert tick(retry) == Status.FAILURE  # no second try: the budget has turned home
    assert not ctx.budget.allows(28.0, 0.0, 0) and ctx.budget.allows(28.0, 0.0, 1)  # only the dock is left


def test_a_detour_late_in_a_long_pass_is_driven_when_its_own_way_back_fits(ctx, robot):
    """The way home known to be open is this leg's way back, then the map's way home from its
    start: not everything driven since the dock, which late in a long pass never fits."""
    robot.place(Pose2D(2.0, 1.0, 0.0))  # one metre from the dock
    ctx.plan = TraversalPlan([Pose2D(9.0, 1.0, 0.0), Pose2D(1.0, 1.0, 0.0)], 20.0)
    ctx.traverse = TraversalState(ctx.plan)
    ctx.traverse.current = 0
    ctx.budget = PassBudget(600.0, "expected_changes", speed=0.5, heading_time=4.0, started=robot.now() - 300.0,
                            home_m=[8.0, 0.0], odometer=robot.distance_travelled - 200.0)  # 200 m since the dock
    write_goal(Pose2D(9.0, 1.0, 0.0))
    leaf = NavigateTo("Go", None, ctx)
    assert tick(leaf) == Status.RUNNING
    robot.distance_travelled += 20.0  # 20 m for the map's 7 m: a detour
    robot.advance(20.0)
    # 320 s + 5 s ahead + (20 m back + 1 m home) / 0.5 m/s + 4 s = 371 s of 600: drive on (all 220 m since
    # the dock would be 769 s: home)
    assert tick(leaf) == Status.RUNNING and not ctx.budget.homeward
    robot.distance_travelled += 100.0
    robot.advance(80.0)
    assert tick(leaf) == Status.FAILURE and ctx.budget.homeward  # 400 + 5 + 242 + 4 s > 600 s
