"""Refresh tour: going back, before the pass ends, to nodes confirmed longest ago."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.graph import Event, Node
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitoring import GAPS, PENDING, REFRESH, VISITED, TraversalState
from bomc_bt.planner import GridPlanner, PlannerParams
from bomc_bt.refresh import (
    RefreshParams,
    added_times,
    displaced_nodes,
    object_boxes,
    refresh_viewpoints,
    second_look_places,
    stale_nodes,
)
from bomc_bt.traversal import TraversalPlan

NOW = 1000.0


def corridor(wall: bool = False) -> OccupancyGrid:
    """30 x 4 m of free floor; with ``wall``, a wall at x = 15 m from y = 2 m up (y 0-2 open)."""
    data = np.zeros((80, 600), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    if wall:
        data[40:, 300] = 100
    return OccupancyGrid(data, 0.05, (0.0, 0.0))


def node(i: int, x: float, y: float, last_seen: float | None) -> Node:
    n = Node(i, "chair", np.array([x, y, 0.45]), 0.9, 1, 2)
    n.last_seen = last_seen
    return n


def euclidean(at):
    return lambda points: np.hypot(points[:, 0] - at[0], points[:, 1] - at[1])


def grid_paths(grid: OccupancyGrid):
    return GridPlanner(grid, PlannerParams()).path_lengths_from


def tour_length(start: Pose2D, stops: list[Pose2D]) -> float:
    xy = [(start.x, start.y)] + [(s.x, s.y) for s in stops]
    return float(sum(math.dist(a, b) for a, b in zip(xy, xy[1:], strict=False)))


def faces(stop: Pose2D, n: Node, hfov_deg: float = 50.0) -> bool:
    bearing = math.atan2(n.position[1] - stop.y, n.position[0] - stop.x)
    return abs(wrap_angle(bearing - stop.yaw)) <= math.radians(hfov_deg) / 2 + 1e-6


CANDIDATES = np.array([[x, 1.0] for x in np.arange(1.0, 30.0, 2.0)])


def test_only_nodes_confirmed_longer_ago_than_stale_after_are_stale():
    nodes = [node(0, 5, 3, 100.0), node(1, 9, 3, 500.0), node(2, 12, 3, None)]
    assert [n.id for n in stale_nodes(nodes, NOW, 600.0)] == [0]
    assert [n.id for n in stale_nodes(nodes, NOW, 0.0)] == [0, 1]  # never seen this pass: not a refresh


def test_a_stop_brings_the_stale_node_into_the_camera_view():
    target = node(0, 20.0, 3.0, 100.0)
    stops = refresh_viewpoints(corridor(), [target], NOW, CANDIDATES, Pose2D(1, 1, 0), 100.0, euclidean)
    assert len(stops) == 1
    (stop,) = stops
    assert 0.5 <= math.dist((stop.x, stop.y), target.position[:2]) <= 5.0
    assert faces(stop, target)


def test_the_oldest_node_wins_when_the_budget_allows_one_stop():
    old, recent = node(0, 25.0, 3.0, 50.0), node(1, 5.0, 3.0, 350.0)  # ages 950 and 650 s
    start = Pose2D(15.0, 1.0, 0.0)  # 10 m from either
    stops = refresh_viewpoints(corridor(), [old, recent], NOW, CANDIDATES, start, 10.0, euclidean)
    assert len(stops) == 1 and faces(stops[0], old) and math.dist((stops[0].x, stops[0].y), (25, 3)) <= 5.0


def test_the_tour_stays_within_its_budget():
    nodes = [node(i, x, 3.0, 0.0) for i, x in enumerate((5.0, 15.0, 25.0))]
    start = Pose2D(1.0, 1.0, 0.0)
    for budget in (3.0, 12.0, 22.0, 100.0):
        stops = refresh_viewpoints(corridor(), nodes, NOW, CANDIDATES, start, budget, euclidean)
        assert tour_length(start, stops) <= budget + 1e-9
    assert refresh_viewpoints(corridor(), nodes, NOW, CANDIDATES, start, 0.0, euclidean) == []
    everything = refresh_viewpoints(corridor(), nodes, NOW, CANDIDATES, start, 100.0, euclidean)
    assert all(any(math.dist((s.x, s.y), n.position[:2]) <= 5.0 for s in everything) for n in nodes)


def test_stops_come_in_driving_order_whatever_order_they_were_chosen_in():
    """The far node is oldest and chosen first; the near one is inserted before it."""
    far, near = node(0, 27.0, 3.0, 0.0), node(1, 9.0, 3.0, 390.0)
    start = Pose2D(1.0, 1.0, 0.0)
    stops = refresh_viewpoints(corridor(), [far, near], NOW, CANDIDATES, start, 100.0, euclidean)
    assert len(stops) == 2
    assert stops[0].x < stops[1].x  # near first, then far: no doubling back
    assert tour_length(start, stops) <= tour_length(start, stops[::-1])


def test_no_stop_looks_through_a_wall_and_paths_go_round_it():
    """The node is just behind a wall; the candidate across it is nearer but sees nothing."""
    grid = corridor(wall=True)
    target = node(0, 16.0, 3.0, 0.0)
    candidates = np.array([[14.0, 3.0], [18.0, 3.0]])
    start = Pose2D(14.0, 3.5, 0.0)
    stops = refresh_viewpoints(grid, [target], NOW, candidates, start, 100.0, grid_paths(grid))
    assert [(round(s.x), round(s.y)) for s in stops] == [(18, 3)]
    # 4 m as the crow flies, but the way round the wall is longer than 5 m
    assert [(round(s.x), round(s.y)) for s in
            refresh_viewpoints(grid, [target], NOW, candidates, start, 5.0, euclidean)] == [(18, 3)]
    assert refresh_viewpoints(grid, [target], NOW, candidates, start, 5.0, grid_paths(grid)) == []


def test_a_node_awaiting_a_second_look_comes_first_and_is_seen_from_another_place():
    """Its misses were all seen from (17, 1) (association.miss_spacing): a stop there decides
    nothing, so the tour looks from at least ``spacing`` away, before an older stale node."""
    waiting, stale = node(0, 20.0, 3.0, 990.0), node(1, 9.0, 3.0, 50.0)  # only the second is stale
    start = Pose2D(15.0, 1.0, 0.0)  # 2 m from places that see either: one stop in the budget
    reached_only = RefreshParams(second_look_radii=())  # no places round the node: reached ones only
    plan = dict(now=NOW, start=start, budget=4.5, distances=euclidean, params=reached_only)
    alone = refresh_viewpoints(corridor(), [stale], candidates=CANDIDATES, **plan)
    assert len(alone) == 1 and faces(alone[0], stale)
    stops = refresh_viewpoints(corridor(), [stale], candidates=CANDIDATES, **plan,
                               second_looks=[(waiting, (17.0, 1.0))], spacing=1.5)
    assert len(stops) == 1 and faces(stops[0], waiting)
    assert math.dist((stops[0].x, stops[0].y), (17.0, 1.0)) >= 1.5
    assert math.dist((stops[0].x, stops[0].y), (20.0, 3.0)) <= 5.0
    # a spacing of 0.2 m plans the look from at least 0.2 m plus arrival_tolerance (0.3 m) away
    near = refresh_viewpoints(corridor(), [stale], candidates=np.array([[13.0, 1.0], [17.3, 1.0], [19.0, 1.0]]),
                              **plan, second_looks=[(waiting, (17.0, 1.0))], spacing=0.2)
    assert [(s.x, s.y) for s in near] == [(19.0, 1.0)] and faces(near[0], waiting)
    # no other place in reach of it: no stop for it, and the stale node gets the budget
    only_there = np.array([[17.0, 1.0], [13.0, 1.0]])
    stops = refresh_viewpoints(corridor(), [stale], candidates=only_there, **plan,
                               second_looks=[(waiting, (17.0, 1.0))], spacing=1.5)
    assert [(s.x, s.y) for s in stops] == [(13.0, 1.0)] and faces(stops[0], stale)
    # an object standing between the one place in the budget and the node: no miss would count there
    box = np.array([[19.3, 1.8, 19.8, 2.4]])
    stops = refresh_viewpoints(corridor(), [stale], candidates=CANDIDATES, **plan,
                               second_looks=[(waiting, (17.0, 1.0))], spacing=1.5, occluders=box)
    assert [(s.x, s.y) for s in stops] == [(13.0, 1.0)]
    stops = refresh_viewpoints(corridor(), [stale], candidates=CANDIDATES, **plan,
                               second_looks=[(waiting, (17.0, 1.0))], spacing=1.5, occluders=box + [0, 2, 0, 2])
    assert [(s.x, s.y) for s in stops] == [(19.0, 1.0)]  # the box moved out of the line of sight


def test_a_node_the_pass_left_unresolved_is_looked_at_first_from_where_no_object_stands_in_the_way():
    """A table (its footprint 1.2 m long) by the wall, a chair pushed in at it in front: from
    the reached places straight in front, the chair hides the table's middle and no miss
    counts. The look comes first (before an older stale node), from a place with a clear
    line past the chair's box; the table's own box is in nobody's way."""
    table, stale = node(0, 20.0, 3.5, None), node(1, 9.0, 3.0, 50.0)
    table.category = "table"
    boxes = np.array([[19.7, 2.9, 20.3, 3.9], [19.75, 2.3, 20.25, 2.8]])  # the table's, the chair's
    ids = np.array([0, 7])
    start = Pose2D(15.0, 1.0, 0.0)
    ahead = np.array([[20.0, 1.0], [13.0, 1.0], [24.0, 1.0]])  # only (20, 1) stands behind the chair
    # look_range 0: the view range (5 m), as far as these places stand
    plan = dict(now=NOW, start=start, distances=euclidean, params=RefreshParams(second_look_radii=(), look_range=0.0))
    stops = refresh_viewpoints(corridor(), [stale], candidates=ahead, budget=12.0, **plan,
                               second_looks=[(table, None)], occluders=boxes, occluder_ids=ids)
    assert [(s.x, s.y) for s in stops][:1] == [(24.0, 1.0)] and faces(stops[0], table)
    # the table's own box counted as in its way: no place would see it
    blind = refresh_viewpoints(corridor(), [], candidates=ahead, budget=12.0, **plan,
                               second_looks=[(table, None)], occluders=boxes)
    assert blind == []
    # no place given: no spacing rule, so the place in front is fine once the chair is gone
    clear = refresh_viewpoints(corridor(), [], candidates=ahead[:1], budget=12.0, **plan,
                               second_looks=[(table, None)], spacing=5.0, occluders=boxes[:1], occluder_ids=ids[:1])
    assert [(s.x, s.y) for s in clear] == [(20.0, 1.0)]


def test_a_look_that_must_decide_stands_where_a_miss_weighs_in_full():
    """A trash bin the pass added on its two confirming frames (two false detections) is looked
    at from 4.5 m, the reached place on the robot's way: frames there count a fifth of a miss
    each and the bin stayed on the map (issue 17, s7717 pass 3). With ``look_range`` 2.5 m the
    look stands at the reached place 2 m from it, though it is farther to drive; with 0 (the
    view range) the near-the-way place does, as before, and with a range below ``min_range``
    (no place could be that near and show it) too, rather than no look at all."""
    bin_ = node(0, 20.0, 3.5, None)
    bin_.category = "trash bin"
    reached = np.array([[16.0, 1.5], [20.0, 1.5]])  # 4.5 m and 2.0 m from the bin
    start = Pose2D(14.0, 1.5, 0.0)
    for look_range, place in ((2.5, (20.0, 1.5)), (0.0, (16.0, 1.5))):
        stops = refresh_viewpoints(corridor(), [], NOW, reached, start, 12.0, euclidean,
                                   RefreshParams(second_look_radii=(), look_range=look_range),
                                   second_looks=[(bin_, None)])
        assert [(s.x, s.y) for s in stops] == [place] and faces(stops[0], bin_)
    # a miss_full_range the camera cannot stand within (below min_range) falls back to the view range
    stops = refresh_viewpoints(corridor(), [], NOW, reached, start, 12.0, euclidean,
                               RefreshParams(second_look_radii=(), look_range=0.4), second_looks=[(bin_, None)])
    assert [(s.x, s.y) for s in stops] == [(16.0, 1.5)]
    with pytest.raises(ValueError):
        RefreshParams(look_range=-1.0)


def test_a_second_look_may_stand_on_free_floor_round_the_node_where_the_robot_never_stopped():
    """Reached places are sparse: the one in the budget is where the misses were seen. A
    free place round the node (2.5 m from it, with room for the robot) is used instead;
    none is put in a wall or outside the map."""
    waiting = node(0, 20.0, 3.0, 990.0)
    stops = refresh_viewpoints(corridor(), [], NOW, np.array([[19.0, 1.0]]), Pose2D(19.0, 1.0, 0.0), 10.0,
                               euclidean, second_looks=[(waiting, (19.0, 1.0))], spacing=0.2)
    assert len(stops) == 1 and faces(stops[0], waiting)
    assert math.dist((stops[0].x, stops[0].y), (19.0, 1.0)) >= 0.5
    assert min(abs(math.dist((stops[0].x, stops[0].y), (20.0, 3.0)) - r) for r in (1.5, 2.5)) < 1e-6
    places = second_look_places(corridor(), [waiting], RefreshParams())
    assert len(places) > 0 and (places[:, 1] >= 0.45).all() and (places[:, 1] <= 4.0 - 0.45).all()


def test_object_boxes_are_the_present_nodes_footprints_or_a_square_round_each():
    from bomc_bt.graph import AssociationParams, ObjectGraph
    graph = ObjectGraph(AssociationParams(), nodes=[node(0, 5.0, 3.0, None), node(1, 9.0, 3.0, None)])
    graph.nodes[1].footprint = np.array([8.5, 2.6, 9.6, 3.3])
    assert np.allclose(object_boxes(graph), [[4.75, 2.75, 5.25, 3.25], [8.5, 2.6, 9.6, 3.3]])
    assert np.allclose(object_boxes(graph, skip={0}), [[8.5, 2.6, 9.6, 3.3]])


def test_nothing_stale_means_no_tour():
    fresh = [node(0, 10.0, 3.0, 900.0)]
    assert refresh_viewpoints(corridor(), stale_nodes(fresh, NOW, 600.0), NOW, CANDIDATES,
                              Pose2D(1, 1, 0), 100.0, euclidean) == []


@pytest.mark.parametrize("field,value", [("stale_after", -1.0), ("budget", -0.1), ("max_viewpoints", -1),
                                          ("view_range", 0.2), ("hfov_deg", 0.0), ("stop_cost", -1.0),
                                          ("arrival_tolerance", -0.5), ("second_look_radii", (0.2,)),
                                          ("second_look_clearance", -0.1)])
def test_bad_params_are_refused(field, value):
    with pytest.raises(ValueError):
        RefreshParams(**{field: value})


def test_refresh_stops_extend_the_pass_after_the_gaps_and_survive_a_resume():
    plan = TraversalPlan([Pose2D(0, 0, 0), Pose2D(3, 0, 0)], 3.0)
    state = TraversalState(plan)
    for _ in range(2):
        state.mark(state.next(), VISITED)
    state.add_viewpoints(GAPS, [Pose2D(5, 5, 1.0)])
    state.mark(state.next(), VISITED)
    state.add_viewpoints(REFRESH, [Pose2D(0, 1, 0.0), Pose2D(3, 1, 0.0)])
    assert state.next() == 3 and state.states[3:] == [PENDING, PENDING]
    assert state.reached().tolist() == [[0, 0], [3, 0], [5, 5]]
    saved = {**state.to_json(), "plan": plan.to_json()}
    resumed = TraversalState(TraversalPlan.from_json(saved["plan"]))
    resumed.restore(saved)
    assert resumed.gaps_from == 2 and resumed.waypoint(2) == Pose2D(5, 5, 1.0) and resumed.planned(REFRESH)
    assert resumed.summary()["gap_viewpoints"] == 1 and resumed.summary()["refresh_stops"] == 2


def test_a_pass_saved_before_refresh_stops_existed_resumes():
    plan = TraversalPlan([Pose2D(0, 0, 0), Pose2D(3, 0, 0), Pose2D(5, 5, 1.0)], 3.0)
    state = TraversalState(plan)
    state.restore({"states": [VISITED, VISITED, PENDING], "index": 2, "retried": [], "gaps_from": 2})
    assert state.gaps_from == 2 and not state.planned(REFRESH) and state.next() == 2


def test_an_empty_gap_phase_does_not_count_the_refresh_stops_after_it():
    """A pass that found no gap to cover but went back to two stale nodes reports 0 gap
    viewpoints and 2 refresh stops (it reported 2 and 2), also after a resume."""
    plan = TraversalPlan([Pose2D(0, 0, 0), Pose2D(3, 0, 0)], 3.0)
    state = TraversalState(plan)
    state.add_viewpoints(GAPS, [])
    state.add_viewpoints(REFRESH, [Pose2D(0, 1, 0.0), Pose2D(3, 1, 0.0)])
    resumed = TraversalState(TraversalPlan.from_json(plan.to_json()))
    resumed.restore(state.to_json())
    shuffled = TraversalState(TraversalPlan.from_json(plan.to_json()))  # a saved pass read back in any key order
    shuffled.restore({**state.to_json(), "phases": {REFRESH: 2, GAPS: 2}})
    for s in (state, resumed, shuffled):
        assert (s.summary()["gap_viewpoints"], s.summary()["refresh_stops"]) == (0, 2)


def _bin(i: int, x: float, first_session: int, last_seen: float | None, category: str = "trash bin") -> Node:
    n = Node(i, category, np.array([x, 0.0, 0.3]), 0.9, first_session, 2)
    n.last_seen = last_seen
    return n


def test_a_node_last_seen_before_one_of_its_kind_was_added_near_it_may_have_moved_there():
    """36 x 28 m office, seed 7421, pass 10: a bin moved 1.1 m during the pass after the robot
    had seen it (node 54, last seen at 198 s); the robot came by its new place at 983 s and
    added it (node 81). Nothing looked at the old place again: the pass reported an addition,
    and the removal a pass late, where the bin had moved."""
    old, new = _bin(54, 0.0, 1, 198.0), _bin(81, 1.06, 2, 1150.0)
    assert [n.id for n in displaced_nodes([old, new], {81: 983.0}, 2, 5.0)] == [54]


def test_a_node_the_pass_never_saw_may_have_moved_to_one_of_its_kind_it_added():
    """36 x 28 m office, seed 9105, pass 3: table-6 moved 2 m during the pass before the robot
    came by (its node last seen at 1,180 s of pass 2, on pass 2's clock); the pass added it at
    its new place at 497 s. Robot times of two passes do not compare: the node is a doubt."""
    old, new = _bin(26, 0.0, 1, 1180.0, "table"), _bin(63, 2.0, 3, 1328.0, "table")
    old.last_session, new.last_session = 2, 3
    assert [n.id for n in displaced_nodes([old, new], {63: 497.5}, 3, 5.0)] == [26]
    old.last_session = 3  # seen in this pass at 1,180 s, after the addition: two tables
    assert displaced_nodes([old, new], {63: 497.5}, 3, 5.0) == []


def test_no_look_for_a_node_seen_after_the_addition_or_of_another_kind_or_far_or_new():
    seen_since = [_bin(1, 0.0, 1, 990.0), _bin(2, 1.0, 2, 995.0)]  # both seen at once since: two bins
    chair = [_bin(1, 0.0, 1, 198.0, "chair"), _bin(2, 1.0, 2, 995.0)]
    far = [_bin(1, 0.0, 1, 198.0), _bin(2, 5.5, 2, 995.0)]
    both_new = [_bin(1, 0.0, 2, 198.0), _bin(2, 1.0, 2, 995.0)]  # pass 1 of its place: nothing to move
    for nodes in (seen_since, chair, far, both_new):
        assert displaced_nodes(nodes, {2: 983.0}, 2, 5.0) == []
    gone = [_bin(1, 0.0, 1, 198.0), _bin(2, 1.0, 2, 995.0)]
    gone[0].state = "removed"
    assert displaced_nodes(gone, {2: 983.0}, 2, 5.0) == []


def test_added_times_are_each_node_s_first_addition_in_the_pass():
    def ev(kind: str, node: int, stamp: float) -> Event:
        return Event(kind, node, "chair", np.zeros(3), 2, stamp)

    events = [ev("added", 4, 10.0), ev("updated", 4, 11.0), ev("removed", 4, 20.0), ev("added", 4, 30.0),
              ev("added", 7, 15.0), ev("moved", 8, 16.0)]
    assert added_times(events) == {4: 10.0, 7: 15.0}
