"""The recovery leaves (behaviours/recover.py), tick by tick on the scripted robot."""

from __future__ import annotations

import numpy as np
import py_trees
import pytest
from fake_robot import key, open_room, tick
from py_trees.common import Status

from behaviours.recover import (
    ENDED_EARLY,
    BackOutGoal,
    CheckProgress,
    CheckProgressParams,
    ClearObstacles,
    ClearObstaclesParams,
    DiagnoseStuck,
    DiagnoseStuckParams,
    EndPassEarly,
    RefreshMap,
    SkipCutOff,
    StuckCauseIs,
    StuckCauseIsParams,
    WatchFloor,
    WatchFloorParams,
)
from bomc_bt.algorithm_params import RecoveryParams
from bomc_bt.budget_plan import PassBudget
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitor_pass import progress_key
from bomc_bt.monitoring import MISSED, PENDING, VISITED, TraversalState
from bomc_bt.stale_map import FloorSeen
from bomc_bt.stuck import CUT_OFF, STALE_MAP, STALE_OBSTACLES, Diagnosis
from bomc_bt.traversal import TraversalPlan
from tests.test_stuck import cast, with_box


@pytest.fixture(autouse=True)
def recovery_on(ctx):
    """The defaults, with the opt-in wedged check on (README: When a monitor pass gets stuck)."""
    ctx.config.recovery = RecoveryParams(max_missed=3, no_progress_time=600.0, min_agreement=0.4,
                                         wedged_distance=0.5)


def start_pass(ctx, n: int = 6) -> TraversalState:
    ctx.plan = TraversalPlan([Pose2D(1.0 + i, 2.0, 0.0) for i in range(n)], euclidean_length=10.0)
    ctx.traverse = TraversalState(ctx.plan)
    return ctx.traverse


def finish(state: TraversalState, outcome: str, robot=None) -> None:
    state.mark(state.next(), outcome)
    if robot is not None:
        robot.distance_travelled += 3.0  # it drove about, round the detours


def test_check_progress_fails_and_says_why_after_three_missed_in_a_row(ctx):
    state = start_pass(ctx)
    check = CheckProgress("Making Progress", CheckProgressParams(max_missed=3, no_progress_time=600.0), ctx)
    finish(state, VISITED)
    assert tick(check) == Status.SUCCESS
    for _ in range(2):
        finish(state, MISSED)
        assert tick(check) == Status.SUCCESS
    finish(state, MISSED)
    assert tick(check) == Status.FAILURE and key("stuck") == "3 waypoints missed in a row"


def test_a_missed_waypoint_missed_again_on_its_retry_does_not_count(ctx):
    state = start_pass(ctx, 3)
    check = CheckProgress("Making Progress", CheckProgressParams(max_missed=3, no_progress_time=600.0), ctx)
    for _ in range(3):
        finish(state, MISSED if state.index < 2 else VISITED)
        assert tick(check) == Status.SUCCESS
    for _ in range(2):  # the two missed ones come back once, and fail again
        finish(state, MISSED)
        assert tick(check) == Status.SUCCESS
    assert ctx.watch.missed_in_row == 0


def test_check_progress_reads_its_thresholds_from_the_configuration(ctx):
    ctx.config.recovery.max_missed = 1
    start_pass(ctx)
    check = CheckProgress("Making Progress", None, ctx)
    finish(ctx.traverse, MISSED)
    assert check.params.max_missed == 1 and tick(check) == Status.FAILURE


def test_diagnose_writes_the_cause_and_fails_once_the_rounds_are_used_up(ctx, robot):
    ctx.config.recovery.max_rounds = 1  # the leaf reads it from the configuration
    state = start_pass(ctx)
    for _ in range(3):
        finish(state, MISSED, robot)
        CheckProgress("Check", CheckProgressParams(), ctx).tick_once()
    leaf = DiagnoseStuck("Find Out Why", None, ctx)
    # an open room, no scan: the map shows a way to the failed waypoints -> the layer is stale
    assert tick(leaf) == Status.SUCCESS
    assert key("stuck_cause").cause == STALE_OBSTACLES and ctx.watch.rounds == 1
    assert ctx.watch.log[0].cause == STALE_OBSTACLES
    leaf = DiagnoseStuck("Find Out Why", None, ctx)
    assert tick(leaf) == Status.FAILURE and "1 recovery round(s) did not help" in leaf.feedback_message


def test_stuck_cause_is_picks_the_branch_of_the_diagnosis(ctx, robot):
    finish(start_pass(ctx), MISSED)
    CheckProgress("Check", CheckProgressParams(), ctx).tick_once()
    robot.distance_travelled += 3.0
    DiagnoseStuck("Why", DiagnoseStuckParams(), ctx).tick_once()
    assert tick(StuckCauseIs("Stale", StuckCauseIsParams(STALE_OBSTACLES), ctx)) == Status.SUCCESS
    assert tick(StuckCauseIs("Boxed", StuckCauseIsParams("boxed_in"), ctx)) == Status.FAILURE


def test_clear_obstacles_clears_once_then_waits_for_the_lidar_to_rebuild(ctx, robot):
    start_pass(ctx)
    leaf = ClearObstacles("Clear", ClearObstaclesParams(rebuild_time=2.0), ctx)
    assert tick(leaf) == Status.RUNNING and robot.costmap_clears == 1
    robot.advance(1.0)
    assert tick(leaf) == Status.RUNNING and robot.costmap_clears == 1
    robot.advance(1.5)
    assert tick(leaf) == Status.SUCCESS and ctx.watch.log == []  # no round open: nothing to log into


def test_back_out_goal_is_back_along_the_way_the_robot_came(ctx, robot):
    start_pass(ctx)
    assert tick(BackOutGoal("Way Back", None, ctx)) == Status.FAILURE  # it has not driven anywhere yet
    for i in range(12):
        ctx.trail.add((2.0 + 0.25 * i, 5.0))  # drove east along y = 5 to (4.75, 5)
    robot.place(Pose2D(4.75, 5.0, 0.0))
    assert tick(BackOutGoal("Way Back", None, ctx)) == Status.SUCCESS
    goal = key("goal")
    assert abs(goal.y - 5.0) < 1e-9 and 3.0 <= goal.x <= 3.3  # 1.5 m back, facing where it goes


def test_end_pass_early_stops_the_robot_and_records_the_diagnosis(ctx, robot):
    state = start_pass(ctx)
    finish(state, MISSED)
    CheckProgress("Check", CheckProgressParams(), ctx).tick_once()
    DiagnoseStuck("Why", DiagnoseStuckParams(), ctx).tick_once()  # it never moved: wedged
    leaf = EndPassEarly("End", None, ctx)
    assert tick(leaf) == Status.FAILURE and robot.cancelled_all
    assert ctx.outcome == ENDED_EARLY
    assert ctx.reason.startswith("pass ended early at waypoint 1/6") and "boxed_in: wedged" in ctx.reason


def keep_going_tree(ctx, tmp_path):
    """The shipped ``keep_going`` subtree (trees/recover.yaml) as a tree of its own."""
    from bomc_bt.config import resource_dir
    from bomc_bt.tree.loader import load_tree
    from bomc_bt.tree.registry import load_registry

    path = tmp_path / "keep_going.yaml"
    path.write_text("version: 1\ninclude: [recover.yaml]\nroot: {subtree: keep_going}\n")
    return load_tree(path, load_registry(), ctx, clock=ctx.now, extra_search_paths=[resource_dir("trees")])


def run_once(root, robot, limit: int = 200):
    """Tick ``root`` until it is no longer RUNNING (the scripted robot's clock advancing)."""
    for _ in range(limit):
        root.tick_once()
        if root.status != Status.RUNNING:
            return root.status
        robot.step()
    raise AssertionError("the subtree kept running")


def test_the_shipped_recovery_clears_a_stale_layer_then_ends_the_pass_when_nothing_helps(ctx, robot, tmp_path):
    """Tick-simulation of Keep Going on the scripted robot: three missed waypoints start a
    round (stale layer: cleared, the pass goes on); a waypoint reached resets it; rounds
    with nothing reached in between end the pass with the diagnosis."""
    root = keep_going_tree(ctx, tmp_path)
    state = start_pass(ctx, 14)
    outcomes = []
    for _ in range(3):
        finish(state, MISSED, robot)
        outcomes.append(run_once(root, robot))
    assert outcomes == [Status.SUCCESS] * 3 and robot.costmap_clears == 1  # round 1: clear, go on
    assert ctx.watch.log[0].action == "clear_obstacles" and ctx.outcome == ""
    finish(state, VISITED, robot)  # it helped: a waypoint reached
    assert run_once(root, robot) == Status.SUCCESS and ctx.watch.log[0].result.startswith("waypoint 4 reached")
    for _ in range(6):  # two more rounds (max_rounds: 2), nothing reached in between: both act
        finish(state, MISSED, robot)
        assert run_once(root, robot) == Status.SUCCESS
    assert robot.costmap_clears == 3 and ctx.outcome == ""
    for _ in range(3):  # a third round is one too many
        finish(state, MISSED, robot)
        last = run_once(root, robot)
    assert last == Status.FAILURE and robot.costmap_clears == 3
    assert ctx.outcome == ENDED_EARLY and robot.cancelled_all
    assert ctx.reason.startswith("pass ended early at waypoint 13/14 after 2 recovery round(s) (clear_obstacles): "
                                 "stale_obstacles")


def two_rooms() -> OccupancyGrid:
    """The 10 m open room with a wall across at x = 5 m and a 1.2 m doorway (y 4.4 to 5.6)."""
    grid = open_room()
    data = grid.data.copy()
    data[:, 99:101] = 100
    data[88:112, 99:101] = 0
    return OccupancyGrid(data, grid.resolution, grid.origin)


DOORWAY_CABINET = np.stack(np.meshgrid(np.arange(4.85, 5.3, 0.05), np.arange(4.3, 5.75, 0.05)), -1).reshape(-1, 2)


def test_skip_cut_off_marks_missed_the_waypoints_still_to_visit_behind_the_obstacles(ctx):
    state = start_pass(ctx, 6)
    finish(state, VISITED)
    finish(state, MISSED)
    behind = Diagnosis(CUT_OFF, "behind a cabinet", 1.0, 10.0, cut_off=[0, 1, 3, 5])
    py_trees.blackboard.Blackboard.set("/stuck_cause", behind)
    assert tick(SkipCutOff("Skip", None, ctx)) == Status.SUCCESS
    assert state.states == [VISITED, MISSED, PENDING, MISSED, PENDING, MISSED]  # a visited one stays visited
    assert [state.next() for _ in range(3)] == [2, 4, None]  # passed over, and not back at the end either
    saved = ctx.store.get_progress(progress_key(ctx.session))  # a kill from here on resumes with them skipped
    assert saved["states"] == state.states and sorted(saved["retried"]) == [1, 3, 5]


def test_skip_cut_off_never_gives_up_a_budgeted_pass_s_dock(ctx):
    state = start_pass(ctx, 4)
    ctx.budget = PassBudget(seconds=600.0, strategy="changes", speed=0.5, heading_time=5.0)
    py_trees.blackboard.Blackboard.set("/stuck_cause", Diagnosis(CUT_OFF, "behind", 1.0, 1.0, cut_off=[1, 2, 3]))
    assert tick(SkipCutOff("Skip", None, ctx)) == Status.SUCCESS
    assert state.states == [PENDING, MISSED, MISSED, PENDING]  # the last waypoint is the way home


def test_waypoints_behind_an_obstacle_seen_again_after_a_clear_are_skipped_and_the_pass_goes_on(ctx, robot, tmp_path):
    """The shipped Keep Going on the scripted robot: waypoints in the far room fail, the
    layer is cleared (it could be stale); the lidar marks the cabinet in the doorway again
    as the robot drives up, and the next failures are a cut-off far room, not a stale
    layer: its waypoints are skipped and the pass goes on in the robot's room, where it
    used to clear the layer once more and end the pass."""
    robot.grid = two_rooms()
    robot.place(Pose2D(2.5, 5.0, 0.0))
    root = keep_going_tree(ctx, tmp_path)
    far = [(7.0, y) for y in (2.0, 4.0, 6.0, 8.0)] + [(8.5, y) for y in (2.0, 5.0, 8.0)]
    near = [(2.0, 2.0), (2.0, 8.0), (3.5, 5.0)]
    ctx.plan = TraversalPlan([Pose2D(x, y, 0.0) for x, y in far + near], euclidean_length=30.0)
    state = ctx.traverse = TraversalState(ctx.plan)
    for _ in range(3):
        finish(state, MISSED, robot)
        run_once(root, robot)
    assert robot.costmap_clears == 1 and ctx.watch.log[0].cause == STALE_OBSTACLES
    robot.layer = DOORWAY_CABINET  # driving up to the doorway again, the lidar marks the cabinet
    for _ in range(3):
        finish(state, MISSED, robot)
        assert run_once(root, robot) == Status.SUCCESS
    assert ctx.outcome == "" and robot.costmap_clears == 1
    assert ctx.watch.log[1].cause == CUT_OFF and "marked again" in ctx.watch.log[1].detail
    assert ctx.watch.log[1].result == "carried on without 7 waypoint(s) behind the same obstacles (1 not tried)"
    assert state.states == [MISSED] * 7 + [PENDING] * 3
    assert [state.next() for _ in range(4)] == [7, 8, 9, None]  # on with the robot's own room, and done


def doorway_with_a_table_gone():
    """The saved map: a table stood in the doorway's lower part at the build (clear of the
    jambs). Now it has gone and a cabinet stands in the upper part: 0.75 m of the doorway
    are open, enough for the robot, but the map's table and the cabinet leave 0.3 m."""
    saved = with_box(two_rooms(), 4.85, 4.5, 5.3, 4.85)
    now = with_box(two_rooms(), 4.85, 5.15, 5.3, 5.5)
    return saved, now


def test_watch_floor_folds_a_scan_in_every_period_once_localized(ctx, robot):
    saved, now = doorway_with_a_table_gone()
    robot.grid, robot.latest_scan = saved, cast(now, Pose2D(3.5, 5.0, 0.0))
    robot.place(None)
    leaf = WatchFloor("Watch Floor", WatchFloorParams(period=1.0, min_seen=2), ctx)
    assert tick(leaf) == Status.RUNNING and ctx.floor is None  # no pose: nothing folded in
    robot.place(Pose2D(3.5, 5.0, 0.0))
    assert tick(leaf, 3) == Status.RUNNING and ctx.floor.scans == 1  # once per period of robot time
    assert len(ctx.floor.cells()) == 0
    robot.advance(1.0)
    assert tick(leaf) == Status.RUNNING and ctx.floor.scans == 2
    x, y = saved.cell_to_world(ctx.floor.cells()[:, 0], ctx.floor.cells()[:, 1])
    assert len(x) > 10 and np.all((x > 4.75) & (x < 5.35) & (y > 4.45) & (y < 4.9))  # the table's cells only


def test_refresh_map_hands_the_robot_the_map_with_the_floor_cleared(ctx, robot):
    saved, _ = doorway_with_a_table_gone()
    robot.grid = saved
    floor = np.argwhere(saved.occupied_mask() & ~two_rooms().occupied_mask())
    py_trees.blackboard.Blackboard.set("/stuck_cause", Diagnosis(STALE_MAP, "a table gone", 0.9, 20.0, floor=floor))
    assert tick(RefreshMap("Refresh", None, ctx)) == Status.SUCCESS and robot.refreshed_maps == 1
    assert np.array_equal(robot.grid.data, two_rooms().data)  # navigating on the map without the table
    assert saved.occupied_mask()[floor[:, 0], floor[:, 1]].all()  # the saved map itself is unchanged


def test_the_shipped_recovery_navigates_on_the_floor_seen_when_a_table_gone_hems_the_robot_in(ctx, robot, tmp_path):
    """Tick-simulation of Keep Going: waypoints beyond the doorway fail three in a row; the
    floor seen this pass where the map's table stood opens the way, so the round hands the
    robot the map without it instead of backing out, and the pass goes on."""
    saved, now = doorway_with_a_table_gone()
    here = Pose2D(3.5, 5.0, 0.0)
    robot.grid, robot.latest_scan = saved, cast(now, here)
    robot.place(here)
    ctx.floor = FloorSeen(saved, 2.0, 6.0, 2)
    for _ in range(2):
        ctx.floor.add(here, robot.latest_scan)
    ctx.plan = TraversalPlan([Pose2D(8.0, y, 0.0) for y in (5.0, 3.0, 7.0, 2.0, 8.0)], euclidean_length=10.0)
    state = ctx.traverse = TraversalState(ctx.plan)
    root = keep_going_tree(ctx, tmp_path)
    for _ in range(3):
        finish(state, MISSED, robot)
        assert run_once(root, robot) == Status.SUCCESS
    assert ctx.watch.log[0].cause == STALE_MAP and ctx.watch.log[0].action == "refresh_map"
    assert robot.refreshed_maps == 1 and robot.costmap_clears == 0 and ctx.outcome == ""
    table = saved.occupied_mask() & ~two_rooms().occupied_mask()
    assert not robot.grid.occupied_mask()[table].all()  # the robot plans through where the table stood
