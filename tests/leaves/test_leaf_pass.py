"""The monitor pass's leaves, tick by tick on a scripted robot: plan (and resume), the
waypoint loop's exit condition, next waypoint, detours, marks, gaps, refresh, Look Around."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import py_trees
from fake_robot import key, open_room, tick
from py_trees.common import Status

from behaviours.look_around import LookAround
from behaviours.plan_pass import PlanGapViewpoints, PlanLastLooks, PlanRefreshStops, PlanTraversal
from behaviours.waypoints import FindDetour, MarkWaypoint, MarkWaypointParams, NextWaypoint, WaypointsDone
from bomc_bt.geometry import Pose2D
from bomc_bt.graph import AssociationParams, Node, ObjectGraph, Observation
from bomc_bt.look_around import LookAroundParams
from bomc_bt.monitor_pass import DetourParams, progress_key, save_pass
from bomc_bt.monitoring import DETOURED, GAPS, LAST_LOOKS, MISSED, REFRESH, VISITED, Coverage, TraversalState
from bomc_bt.refresh import RefreshParams
from bomc_bt.robot import Status as Nav
from bomc_bt.site import TrajectoryRecorder
from bomc_bt.traversal import TraversalPlan
from bomc_bt.viewpoints import GapParams


def start_pass(ctx, *points: tuple[float, float]) -> TraversalState:
    ctx.plan = TraversalPlan([Pose2D(x, y, 0.0) for x, y in points], euclidean_length=100.0)
    ctx.traverse = TraversalState(ctx.plan)
    return ctx.traverse


def test_plan_traversal_plans_along_the_build_trajectory_and_saves_the_pass(ctx):
    recorder = TrajectoryRecorder(ctx.site.trajectory_csv, period=0.0)
    for i in range(40):
        recorder.record(float(i), 1.0 + i * 0.2, 5.0, 0.0, force=True)
    recorder.close()
    leaf = PlanTraversal("Plan", None, ctx)
    assert tick(leaf) == Status.SUCCESS
    assert ctx.plan is ctx.traverse.plan and len(ctx.plan.waypoints) >= 2
    assert ctx.site.plan_json.exists()
    saved = ctx.store.get_progress(progress_key(ctx.session))
    assert len(saved["plan"]["waypoints"]) == len(ctx.plan.waypoints) and saved["index"] == 0


def test_plan_traversal_on_resume_picks_up_the_saved_pass_at_its_next_waypoint(ctx):
    state = start_pass(ctx, (2, 2), (4, 4), (6, 6))
    state.next()
    state.mark(0, VISITED)
    save_pass(ctx.store, ctx.session, state)
    ctx.plan = ctx.traverse = None
    ctx.resume = True
    assert tick(PlanTraversal("Plan", None, ctx)) == Status.SUCCESS
    assert ctx.traverse.index == 1 and ctx.traverse.states[0] == VISITED and ctx.progress.waypoint == 1
    assert [w.x for w in ctx.plan.waypoints] == [2, 4, 6]


def test_next_waypoint_writes_the_goal_and_the_loop_ends_after_one_retry_of_each_missed(ctx):
    state = start_pass(ctx, (2, 2), (4, 4))
    done, next_ = WaypointsDone("Done", None, ctx), NextWaypoint("Next", None, ctx)
    assert tick(done) == Status.FAILURE and tick(next_) == Status.SUCCESS and key("goal") == Pose2D(2, 2, 0)
    state.mark(0, MISSED)
    assert tick(done) == Status.FAILURE and tick(next_) == Status.SUCCESS and key("goal") == Pose2D(4, 4, 0)
    state.mark(1, VISITED)
    assert tick(done) == Status.FAILURE  # waypoint 1 comes back once
    assert tick(next_) == Status.SUCCESS and key("goal") == Pose2D(2, 2, 0) and "retry" in next_.feedback_message
    assert tick(done) == Status.SUCCESS and state.current is None
    assert tick(next_) == Status.FAILURE


def test_mark_waypoint_records_the_state_saves_the_pass_and_tells_a_detour(ctx):

    state = start_pass(ctx, (2, 2), (4, 4))
    state.next()
    py_trees.blackboard.Blackboard.set("/nav_detour", True)
    assert tick(MarkWaypoint("Mark Visited", MarkWaypointParams(VISITED), ctx)) == Status.SUCCESS
    assert state.states[0] == DETOURED  # reached, but round something the map does not have
    state.next()
    py_trees.blackboard.Blackboard.set("/nav_detour", False)
    tick(MarkWaypoint("Mark Visited", MarkWaypointParams(VISITED), ctx))
    assert state.states[1] == VISITED
    assert ctx.store.get_progress(progress_key(ctx.session))["states"] == [DETOURED, VISITED]


def test_find_detour_proposes_untried_places_facing_the_waypoint(ctx):
    state = start_pass(ctx, (5, 5))
    state.next()
    leaf = FindDetour("Find", DetourParams(radius=2.0, count=6, clearance=0.45), ctx)
    assert tick(leaf) == Status.SUCCESS
    first = key("goal")
    assert tick(leaf) == Status.SUCCESS
    second = key("goal")
    assert first != second and key("detours_tried")[0] == [(first.x, first.y), (second.x, second.y)]
    for goal in (first, second):
        assert 0.7 <= math.hypot(goal.x - 5, goal.y - 5) <= 2.0
        assert abs(math.atan2(5 - goal.y, 5 - goal.x) - goal.yaw) < 1e-9  # faces the waypoint


def test_find_detour_fails_when_no_place_sees_the_waypoint(ctx, robot):
    walls = robot.grid.data
    walls[88:113, 88:113] = 100
    walls[92:109, 92:109] = 0  # the waypoint at (5, 5) sits in a closed box
    state = start_pass(ctx, (5, 5))
    state.next()
    assert tick(FindDetour("Find", DetourParams(), ctx)) == Status.FAILURE


def test_plan_gap_viewpoints_adds_the_phase_once_and_reads_the_range_from_the_config(ctx, robot):
    state = start_pass(ctx, (2, 2))
    ctx.perception = SimpleNamespace(coverage=Coverage(robot.grid))
    leaf = PlanGapViewpoints("Gaps", GapParams(max_viewpoints=3), ctx)
    assert leaf.params.view_range == ctx.config.projection.expect_range
    assert tick(leaf) == Status.SUCCESS and state.planned(GAPS)
    added = state.phase_count(GAPS)
    assert 1 <= added <= 3 and len(ctx.store.get_progress(progress_key(1))["states"]) == 1 + added
    assert tick(leaf) == Status.SUCCESS and state.phase_count(GAPS) == added  # planned once per pass


def stale_graph(at: tuple[float, float], seen: float) -> ObjectGraph:
    """A chair the pass mapped at ``seen`` and matched once more (a node matched in no frame
    after the one that added it is left unresolved, a look of its own)."""
    graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=1))
    for t in (seen - 1.0, seen):
        graph.associate([Observation("chair", np.array([*at, 0.5]), 0.9)], [], 1, t)
    return graph


def test_plan_refresh_stops_go_back_to_nodes_seen_long_ago(ctx, robot):
    state = start_pass(ctx, (2, 5), (8, 5))
    for _ in range(2):
        state.mark(state.next(), VISITED)
    ctx.graph = stale_graph((8.5, 6.0), seen=0.0)
    robot.advance(700.0)
    leaf = PlanRefreshStops("Refresh", RefreshParams(stale_after=600.0, budget=0.3), ctx)
    assert tick(leaf) == Status.SUCCESS and state.phase_count(REFRESH) == 1
    assert leaf.feedback_message == "1 refresh stops for 1 stale nodes"


def test_plan_refresh_stops_from_a_room_the_robot_squeezed_into(ctx, robot):
    """The last gap viewpoint lay in a room the navigator reaches only on squeeze_radius, here
    behind a doorway 0.55 m wide (willow at 0.1 m, a world `bomc world map` made with seed 6975). From there
    the refresh tour found every place the pass had reached unreachable and planned no stop
    ("0 refresh stops for 27 stale nodes ..."): the objects seen once were never looked at again."""
    robot.grid.data[:, 140:142] = 100  # a wall at x = 7 m ...
    robot.grid.data[95:106, 140:142] = 0  # ... with a doorway 0.55 m wide at y = 5 m
    state = start_pass(ctx, (2, 5), (5, 8), (8.5, 5))
    for _ in range(3):
        state.mark(state.next(), VISITED)
    robot.place(Pose2D(8.5, 5.0, 0.0))
    ctx.graph = stale_graph((3.0, 8.5), seen=0.0)
    robot.advance(700.0)
    leaf = PlanRefreshStops("Refresh", RefreshParams(stale_after=600.0, budget=0.3), ctx)
    assert tick(leaf) == Status.SUCCESS and state.phase_count(REFRESH) == 1
    assert leaf.feedback_message == "1 refresh stops for 1 stale nodes"
    stop = state.waypoint(len(state.states) - 1)
    assert (stop.x, stop.y) in ((2, 5), (5, 8))


def test_plan_refresh_stops_look_again_from_another_place_at_a_node_missed_from_one_spot(ctx, robot):
    """association.miss_spacing: the run of misses from (8, 5) would remove the chair but was one
    look; the refresh tour looks from elsewhere, within projection.miss_full_range (2.5 m) of
    the chair, where a miss weighs in full, not back from (8, 5)."""
    state = start_pass(ctx, (2, 5), (6.5, 5), (8, 5))
    for _ in range(3):
        state.mark(state.next(), VISITED)
    graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=1, miss_spacing=0.2))
    graph.associate([Observation("chair", np.array([8.5, 6.0, 0.5]), 0.9)], [], 1, 0.0)
    for t in (0.5, 1.0, 1.5, 2.0):
        assert graph.associate([], [0], 1, t, place=np.array([8.0, 5.0])) == []
    ctx.graph = graph
    robot.advance(10.0)  # nothing is stale yet
    leaf = PlanRefreshStops("Refresh", RefreshParams(stale_after=600.0, budget=0.3), ctx)
    assert tick(leaf) == Status.SUCCESS and state.phase_count(REFRESH) == 1
    assert leaf.feedback_message == "1 refresh stops for 0 stale nodes and 1 awaiting a second look"
    stop = state.waypoint(len(state.states) - 1)
    assert math.dist((stop.x, stop.y), (8.0, 5.0)) >= 0.2 + 0.3 and math.dist((stop.x, stop.y), (8.5, 6.0)) <= 2.5


def test_plan_refresh_stops_look_at_a_node_the_pass_left_unresolved_past_no_other_object(ctx, robot):
    """Session 2 never matched the table session 1 mapped by the west wall: every frame saw it
    past the chair pushed in at it, in the lidar's shadow (unknown on the map). The leaf plans a
    stop where the robot has been that sees the table clear of the chair, not the one behind it."""
    robot.grid.data[88:112, 4:40] = -1  # the table's and chair's shadow on the saved map
    state = start_pass(ctx, (2.5, 7.0), (3.5, 5.0), (6.0, 5.0))
    for _ in range(3):
        state.mark(state.next(), VISITED)
    table = Node(0, "table", np.array([1.0, 5.0, 0.4]), 0.9, 1, 1, footprint=np.array([0.6, 4.4, 1.3, 5.6]))
    chair = Node(1, "chair", np.array([1.7, 5.0, 0.45]), 0.9, 1, 2, footprint=np.array([1.45, 4.7, 1.95, 5.3]))
    ctx.session, ctx.graph = 2, ObjectGraph(AssociationParams(mode="robust", confirm_detections=1), [table, chair])
    robot.advance(10.0)  # nothing is stale
    leaf = PlanRefreshStops("Refresh", RefreshParams(stale_after=600.0, budget=0.3, second_look_radii=()), ctx)
    assert tick(leaf) == Status.SUCCESS and state.phase_count(REFRESH) == 1
    assert leaf.feedback_message == "1 refresh stops for 0 stale nodes and 1 left unresolved"
    stop = state.waypoint(len(state.states) - 1)
    assert (stop.x, stop.y) == (2.5, 7.0)
    assert abs(math.atan2(5.0 - 7.0, 1.0 - 2.5) - stop.yaw) < math.radians(25.0)


def _refresh_faces_the_bin(ctx, state: TraversalState, params: RefreshParams, stops: int, message: str) -> None:
    """Plan Refresh Stops plans ``stops`` (0 or 1) stops; one faces the bin at (1, 5) and says ``message``."""
    leaf = PlanRefreshStops("Refresh", params, ctx)
    assert tick(leaf) == Status.SUCCESS and state.phase_count(REFRESH) == stops
    if stops:
        assert leaf.feedback_message == message
        stop = state.waypoint(len(state.states) - 1)
        assert abs(math.atan2(5.0 - stop.y, 1.0 - stop.x) - stop.yaw) < math.radians(25.0)


def test_plan_refresh_stops_look_at_a_node_that_may_have_moved_to_one_the_pass_added(ctx, robot):
    """36 x 28 m office, seed 7421, pass 10: a bin moved 1.1 m during the pass after the robot
    had seen it; seen at its new place later on, it was added, and nothing looked at its old
    node again (an addition reported, the removal a pass late). The leaf plans a stop facing
    the old node; with ``unresolved: false`` it plans none."""
    for unresolved, stops in ((True, 1), (False, 0)):
        state = start_pass(ctx, (2.5, 7.0), (6.0, 5.0))
        for _ in range(2):
            state.mark(state.next(), VISITED)
        old = Node(0, "trash bin", np.array([1.0, 5.0, 0.3]), 0.9, 1, 2)
        ctx.session, ctx.graph = 2, ObjectGraph(AssociationParams(mode="robust", confirm_detections=1), [old])
        old.last_seen = ctx.now()  # matched in this pass, then the bin was carried off
        robot.advance(30.0)
        added = ctx.graph.add(Observation("trash bin", np.array([2.06, 5.0, 0.3]), 0.9), 2, ctx.now())
        ctx.graph.add_observations(ctx.graph.nodes[added.node_id], 5)  # confirmed: no doubt of its own
        ctx.perception = SimpleNamespace(events=[added])
        robot.advance(10.0)
        params = RefreshParams(stale_after=600.0, budget=0.3, second_look_radii=(), unresolved=unresolved)
        _refresh_faces_the_bin(ctx, state, params, stops, "1 refresh stops for 0 stale nodes and 1 left unresolved")


def test_plan_refresh_stops_look_again_where_the_pass_caught_an_object_in_one_frame_only(ctx, robot):
    """A trash bin the camera caught in one frame while the robot turned was never confirmed
    (a new object needs two frames) and no node stands there. The leaf plans a stop where the
    robot has been, facing the bin; with ``unconfirmed: false`` it plans none."""
    for unconfirmed, stops in ((True, 1), (False, 0)):
        state = start_pass(ctx, (2.5, 7.0), (6.0, 5.0))
        for _ in range(2):
            state.mark(state.next(), VISITED)
        ctx.session = 2
        ctx.graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2, tentative_ttl=10.0))
        ctx.graph.associate([Observation("trash bin", np.array([1.0, 5.0, 0.3]), 0.9)], [], 2, ctx.now())
        robot.advance(30.0)
        ctx.graph.associate([], [], 2, ctx.now())  # its ttl ran out unconfirmed
        params = RefreshParams(stale_after=600.0, budget=0.3, second_look_radii=(), unconfirmed=unconfirmed)
        message = "1 refresh stops for 0 stale nodes and 1 unconfirmed sightings"
        _refresh_faces_the_bin(ctx, state, params, stops, message)


def test_plan_refresh_stops_look_again_at_an_object_the_pass_added_on_its_two_confirming_frames_only(ctx, robot):
    """Two frames 4.5 s apart confirmed a trash bin (two false detections at one place on a
    wall, in the run this was traced on) and no frame matched it after: the leaf plans a stop
    where the robot has been, facing it, so the pass itself confirms or retracts it."""
    state = start_pass(ctx, (2.5, 7.0), (6.0, 5.0))
    for _ in range(2):
        state.mark(state.next(), VISITED)
    ctx.session = 2
    ctx.graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2, tentative_ttl=10.0))
    for dt in (0.0, 4.5):
        robot.advance(dt)
        ctx.graph.associate([Observation("trash bin", np.array([1.0, 5.0, 0.3]), 0.9)], [], 2, ctx.now())
    assert [n.category for n in ctx.graph.nodes.values()] == ["trash bin"]
    robot.advance(30.0)
    leaf = PlanRefreshStops("Refresh", RefreshParams(stale_after=600.0, budget=0.3, second_look_radii=()), ctx)
    assert tick(leaf) == Status.SUCCESS and state.phase_count(REFRESH) == 1
    assert leaf.feedback_message == "1 refresh stops for 0 stale nodes and 1 left unresolved"
    stop = state.waypoint(len(state.states) - 1)
    assert abs(math.atan2(5.0 - stop.y, 1.0 - stop.x) - stop.yaw) < math.radians(25.0)


def test_last_looks_decide_a_node_added_while_the_refresh_stops_were_driven_once(ctx, robot):
    """93 x 90 m office, seed 7921, pass 3: two false detections of a potted plant at one
    place, 8.5 s apart, added a node at a refresh stop; the robot turned away and drove on,
    no frame matched it again, and the map kept it (a phantom addition). The refresh tour,
    planned before, could not look at it. Plan Last Looks plans a stop facing it, and none
    for the bin the refresh tour was already planned to decide nor for a chair caught once on
    the way (Look Around's); planned once, saved with the pass, and an empty phase when
    nothing came up."""
    state = start_pass(ctx, (2.5, 7.0), (6.0, 5.0))
    for _ in range(2):
        state.mark(state.next(), VISITED)
    ctx.session = 2
    ctx.graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2, tentative_ttl=10.0))
    for dt in (0.0, 4.5):  # a bin added on its two confirming frames: the refresh tour's to decide
        robot.advance(dt)
        ctx.graph.associate([Observation("trash bin", np.array([6.0, 7.0, 0.3]), 0.9)], [], 2, ctx.now())
    robot.advance(30.0)
    params = RefreshParams(stale_after=600.0, budget=0.3, second_look_radii=())
    assert tick(PlanRefreshStops("Refresh", params, ctx)) == Status.SUCCESS and state.phase_count(REFRESH) == 1
    assert state.looked_for == {"nodes": [0]}
    assert tick(PlanLastLooks("Last", params, ctx)) == Status.SUCCESS
    assert state.planned(LAST_LOOKS) and state.phase_count(LAST_LOOKS) == 0  # nothing came up

    state = start_pass(ctx, (2.5, 7.0), (6.0, 5.0))
    for _ in range(2):
        state.mark(state.next(), VISITED)
    assert tick(PlanRefreshStops("Refresh", params, ctx)) == Status.SUCCESS
    for dt in (0.0, 8.5):  # during the refresh stops: the plant, at the west wall
        robot.advance(dt)
        ctx.graph.associate([Observation("potted plant", np.array([1.0, 5.0, 0.4]), 0.9)], [], 2, ctx.now())
    ctx.graph.associate([Observation("chair", np.array([3.0, 8.0, 0.45]), 0.9)], [], 2, ctx.now())  # seen once
    assert sorted(n.category for n in ctx.graph.unresolved(2)) == ["potted plant", "trash bin"]
    save_pass(ctx.store, ctx.session, state)  # a kill here: the resumed pass knows what the tour was for
    saved = ctx.store.get_progress(progress_key(ctx.session))
    resumed = TraversalState(TraversalPlan(list(state.plan.waypoints), euclidean_length=100.0))
    resumed.restore(saved)
    assert resumed.planned(REFRESH) and resumed.looked_for == {"nodes": [0]}
    ctx.traverse = resumed
    leaf = PlanLastLooks("Last", params, ctx)
    assert tick(leaf) == Status.SUCCESS and resumed.phase_count(LAST_LOOKS) == 1
    assert leaf.feedback_message == "1 last looks for 1 nodes new since the refresh plan"
    stop = resumed.waypoint(len(resumed.states) - 1)
    assert abs(math.atan2(5.0 - stop.y, 1.0 - stop.x) - stop.yaw) < math.radians(25.0)
    assert tick(leaf) == Status.SUCCESS and resumed.phase_count(LAST_LOOKS) == 1  # once per pass
    off = RefreshParams(stale_after=600.0, budget=0.3, second_look_radii=(), unresolved=False)
    ctx.traverse = TraversalState(TraversalPlan(list(state.plan.waypoints), euclidean_length=100.0))
    ctx.traverse.restore(saved)  # the pass as it was before Plan Last Looks, with it turned off
    assert ctx.traverse.planned(REFRESH) and not ctx.traverse.planned(LAST_LOOKS)
    assert tick(PlanLastLooks("Last", off, ctx)) == Status.SUCCESS and ctx.traverse.planned(LAST_LOOKS)
    assert ctx.traverse.phase_count(LAST_LOOKS) == 0


def test_plan_refresh_stops_with_nothing_stale_adds_an_empty_phase(ctx, robot):
    state = start_pass(ctx, (2, 5))
    state.mark(state.next(), VISITED)
    ctx.graph = stale_graph((3.0, 6.0), seen=0.0)
    robot.advance(100.0)
    assert tick(PlanRefreshStops("Refresh", RefreshParams(stale_after=600.0), ctx)) == Status.SUCCESS
    assert state.planned(REFRESH) and state.phase_count(REFRESH) == 0


def look_around(ctx, **params) -> LookAround:
    ctx.session = 2  # the node below was confirmed in session 1 only
    ctx.graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=1),
                            [Node(0, "chair", np.array([5.0, 8.0, 0.5]), 0.9, 1, 1)])
    return LookAround("Look", LookAroundParams(**params), ctx)


def test_look_around_turns_to_an_unconfirmed_node_dwells_then_succeeds(ctx, robot):
    leaf = look_around(ctx, dwell=1.5)
    assert leaf.params.radius == ctx.config.projection.expect_range
    assert tick(leaf) == Status.RUNNING
    assert robot.goals == [Pose2D(5.0, 5.0, math.pi / 2)]  # on the spot, towards (5, 8)
    robot.last.finish(Nav.SUCCEEDED, "turned")
    assert tick(leaf) == Status.RUNNING  # the dwell starts
    robot.advance(1.4)
    assert tick(leaf) == Status.RUNNING
    robot.advance(0.1)
    assert tick(leaf) == Status.SUCCESS and len(robot.goals) == 1


def test_look_around_turns_to_an_object_seen_once_on_the_way_and_marks_the_place_looked_at(ctx, robot):
    ctx.session = 2
    ctx.graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2))
    ctx.graph.associate([Observation("trash bin", np.array([5.0, 8.0, 0.3]), 0.9)], [], 2, ctx.now())
    leaf = LookAround("Look", LookAroundParams(dwell=1.5), ctx)
    assert tick(leaf) == Status.RUNNING
    assert robot.goals == [Pose2D(5.0, 5.0, math.pi / 2)]  # on the spot, towards the bin at (5, 8)
    assert ctx.graph.unconfirmed_sightings() == []  # one look: no other waypoint turns to it


def test_a_turn_from_afar_leaves_an_object_caught_at_both_ends_to_the_refresh_tour(ctx, robot):
    """36 x 28 m office, seed 7913, pass 1: a cabinet caught through a doorway at its two
    ends, 0.76 m apart, once each, was never confirmed; Look Around turned to it from 4.6 m
    outside, where its frames missed it, that turn counted as the place's one look, the
    refresh tour planned none and the cabinet was never mapped. Here a turn from 3 m (beyond
    projection.miss_full_range, 2.5 m) still stops other waypoints turning to the two
    sightings, but the refresh tour plans a stop facing them; after a turn from 1.5 m it
    plans none, nor for a lone sighting (most often a false positive) turned to from 3 m."""
    ends = [np.array([4.6, 8.0, 0.6]), np.array([5.4, 8.0, 0.6])]
    for start, seen, stops in (((5.0, 5.0), ends, 1), ((5.0, 6.5), ends, 0), ((5.0, 5.0), ends[:1], 0)):
        state = start_pass(ctx, (5.0, 6.5), (5.0, 5.0))
        for _ in range(2):
            state.mark(state.next(), VISITED)
        robot.place(Pose2D(*start, 0.0))
        ctx.session = 2
        ctx.graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2, tentative_ttl=10.0))
        ctx.graph.associate([Observation("cabinet", at, 0.9) for at in seen], [], 2, ctx.now())
        assert tick(LookAround("Look", LookAroundParams(dwell=1.5), ctx)) == Status.RUNNING
        assert ctx.graph.unconfirmed_sightings() == []  # no other waypoint turns to them
        robot.advance(30.0)
        ctx.graph.associate([], [], 2, ctx.now())  # their ttl ran out unconfirmed
        leaf = PlanRefreshStops("Refresh", RefreshParams(stale_after=600.0, budget=0.3, second_look_radii=()), ctx)
        assert tick(leaf) == Status.SUCCESS and state.phase_count(REFRESH) == stops
        if stops:
            assert leaf.feedback_message == "1 refresh stops for 0 stale nodes and 2 unconfirmed sightings"
            stop = state.waypoint(len(state.states) - 1)
            assert (stop.x, stop.y) == (5.0, 6.5) and abs(stop.yaw - math.pi / 2) < math.radians(25.0)


def test_look_around_skips_a_turn_that_failed(ctx, robot):
    leaf = look_around(ctx)
    tick(leaf)
    robot.last.finish(Nav.FAILED, "cannot turn")
    assert tick(leaf) == Status.SUCCESS and leaf.feedback_message == "nothing left to check here"


def test_look_around_drops_a_turn_still_in_flight_at_its_timeout(ctx, robot):
    leaf = look_around(ctx, timeout=30.0)
    tick(leaf)
    robot.advance(30.0)
    assert tick(leaf) == Status.SUCCESS and robot.last.status() is Nav.CANCELLED


def test_look_around_halted_cancels_its_turn(ctx, robot):
    leaf = look_around(ctx)
    tick(leaf)
    leaf.stop(Status.INVALID)
    assert robot.last.status() is Nav.CANCELLED


def test_look_around_without_a_pose_has_nothing_to_do(ctx, robot):
    robot.place(None)
    assert tick(look_around(ctx)) == Status.SUCCESS and robot.goals == []


def test_a_stop_the_robot_cannot_get_to_is_missed_with_all_its_headings(ctx):
    # one stop facing three ways (three waypoints at one place), then the next stop
    state = start_pass(ctx, (6, 6), (6, 6), (6, 6), (9, 6))
    done, next_ = WaypointsDone("Done", None, ctx), NextWaypoint("Next", None, ctx)
    mark_missed = MarkWaypoint("Mark Missed", MarkWaypointParams(MISSED), ctx)
    assert tick(next_) == Status.SUCCESS and (key("goal").x, key("goal").y) == (6, 6)
    assert tick(mark_missed) == Status.SUCCESS
    assert "2 other heading" in mark_missed.feedback_message
    assert state.states[:3] == [MISSED, MISSED, MISSED]
    assert tick(next_) == Status.SUCCESS and (key("goal").x, key("goal").y) == (9, 6)  # no drive to (6, 6) twice more
    tick(MarkWaypoint("Mark Visited", MarkWaypointParams(VISITED), ctx))
    # the stop comes back once at the end; its first heading missed again ends it for good
    assert tick(done) == Status.FAILURE and tick(next_) == Status.SUCCESS and state.current == 0
    tick(mark_missed)
    assert tick(done) == Status.SUCCESS
    assert ctx.store.get_progress(progress_key(ctx.session))["states"] == [MISSED, MISSED, MISSED, VISITED]


def test_a_stop_reached_on_its_second_chance_faces_its_other_headings_too(ctx):
    state = start_pass(ctx, (6, 6), (6, 6), (9, 6))
    next_ = NextWaypoint("Next", None, ctx)
    tick(next_)
    tick(MarkWaypoint("Mark Missed", MarkWaypointParams(MISSED), ctx))
    tick(next_)
    tick(MarkWaypoint("Mark Visited", MarkWaypointParams(VISITED), ctx))
    tick(next_)  # the end of the loop: the stop's first heading again
    assert state.current == 0
    tick(MarkWaypoint("Mark Visited", MarkWaypointParams(VISITED), ctx))
    assert tick(next_) == Status.SUCCESS and state.current == 1  # then its other heading


def shipped_leaf(ctx, tmp_path, kind: type):
    """The one ``kind`` leaf of the shipped Refresh Stale subtree (trees/traverse.yaml), built
    by the tree loader as a mission builds it: its params are the shipped ones."""
    from bomc_bt.config import resource_dir
    from bomc_bt.tree.loader import load_tree
    from bomc_bt.tree.registry import load_registry

    path = tmp_path / "refresh_stale.yaml"
    path.write_text("version: 1\ninclude: [traverse.yaml]\nroot: {subtree: refresh_stale}\n")
    root = load_tree(path, load_registry(), ctx, clock=ctx.now, extra_search_paths=[resource_dir("trees")])
    [leaf] = [b for b in root.iterate() if type(b) is kind]
    return leaf


def test_the_shipped_last_looks_reach_a_bin_that_moved_while_the_refresh_tour_drove_across_the_floor(ctx, robot,
                                                                                                    tmp_path):
    """36 x 28 m office, seed 9721, pass 8: a bin the pass had seen was moved 2.9 m during it;
    the refresh tour, planned before, saw it at its new place (an addition) and ended 22 m
    away. Its old node may have moved there, and only a look at its old place tells a move
    from a second bin. With the last looks' budget at 0.05 of the plan's length (about 20 m
    on that floor) the look was not planned: the pass reported an addition, left the old
    node on the map and removed it a pass late (change F1 0.750 and 0.889, object F1 0.991).
    The shipped budget plans it on a floor where it lies a tenth of the plan's length away."""
    robot.grid = open_room(30.0)
    robot.place(Pose2D(2.0, 2.0, 0.0))
    ctx.plan = TraversalPlan([Pose2D(2.0, 2.0, 0.0), Pose2D(20.0, 16.0, 0.0)], euclidean_length=300.0)
    ctx.traverse = state = TraversalState(ctx.plan)
    for _ in range(2):
        state.mark(state.next(), VISITED)
    ctx.session = 2
    ctx.graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2),
                            [Node(0, "trash bin", np.array([20.0, 20.0, 0.3]), 0.9, 1, 1)])
    ctx.graph.associate([Observation("trash bin", np.array([20.0, 20.0, 0.3]), 0.9)], [0], 2, ctx.now())
    robot.advance(100.0)
    leaf = shipped_leaf(ctx, tmp_path, PlanLastLooks)
    params = leaf.params
    assert tick(PlanRefreshStops("Refresh", params, ctx)) == Status.SUCCESS and state.phase_count(REFRESH) == 0
    events = []
    for dt in (10.0, 4.5, 1.0, 1.0):  # on the way: a bin 2.9 m from the old one, added and seen again
        robot.advance(dt)
        events += ctx.graph.associate([Observation("trash bin", np.array([20.5, 22.9, 0.3]), 0.9)], [], 2, ctx.now())
    ctx.perception = SimpleNamespace(events=events)
    assert [e.kind for e in events if e.kind != "updated"] == ["added"] and ctx.graph.nodes[1].observations > 1
    assert tick(leaf) == Status.SUCCESS and state.phase_count(LAST_LOOKS) >= 1, leaf.feedback_message
    assert leaf.feedback_message.endswith("for 1 nodes new since the refresh plan")  # the old bin's node
    looks = [state.waypoint(i) for i in range(state.phases[LAST_LOOKS], len(state.states))]
    # a look at the old place from where a miss weighs in full, facing it
    assert any(math.hypot(p.x - 20.0, p.y - 20.0) <= params.look_range + 1e-6
               and abs(math.atan2(20.0 - p.y, 20.0 - p.x) - p.yaw) < math.radians(25.0) for p in looks)
