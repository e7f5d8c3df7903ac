"""Look Around: which way a waypoint turns the camera to confirm nodes, or see they are gone."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bomc_bt.geometry import Pose2D
from bomc_bt.graph import AssociationParams, Node, ObjectGraph, Observation
from bomc_bt.grid import OccupancyGrid
from bomc_bt.look_around import HeadTurns, LookAroundParams, plan_head_turns
from bomc_bt.monitoring import unverified_headings

ROBUST = AssociationParams(mode="robust", confirm_detections=1)
FOV = math.radians(60.0)


def open_room() -> OccupancyGrid:
    """10 x 10 m of free floor inside walls, with a wall at x = 7 m (closed, no door)."""
    data = np.zeros((200, 200), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[:, 140] = 100
    return OccupancyGrid(data, 0.05, (0.0, 0.0))


def graph_seen_at(stamp: float, session: int = 2) -> ObjectGraph:
    """Chairs east (behind the wall), north and south of (5, 5), all matched at ``stamp``."""
    nodes = [Node(0, "chair", np.array([8.0, 5.0, 0.5]), 0.9, 1, 1),
             Node(1, "chair", np.array([5.0, 8.0, 0.5]), 0.9, 1, 1),
             Node(2, "chair", np.array([5.0, 2.0, 0.5]), 0.9, 1, 1)]
    g = ObjectGraph(ROBUST, nodes)
    g.associate([Observation("chair", n.position.copy(), 0.9) for n in nodes], [0, 1, 2], session, stamp)
    return g


def test_matching_a_node_records_when_it_was_seen():
    g = graph_seen_at(42.0)
    assert all(n.last_seen == 42.0 for n in g.nodes.values())
    g.associate([Observation("chair", np.array([5.0, 8.1, 0.5]), 0.9)], [1], 2, 50.0)
    assert g.nodes[1].last_seen == 50.0 and g.nodes[0].last_seen == 42.0
    events = g.associate([Observation("table", np.array([3.0, 3.0, 0.4]), 0.9)], [], 2, 51.0)
    added = g.nodes[events[0].node_id]
    assert added.last_seen == 51.0


def test_nodes_not_confirmed_this_pass_get_a_look_but_not_through_a_wall():
    g = graph_seen_at(10.0, session=1)  # matched in session 1: session 2 has confirmed none
    headings = unverified_headings(g, Pose2D(5.0, 5.0, 0.0), 2, open_room(), 5.0, FOV, 4)
    assert sorted(round(math.degrees(h)) for h in headings) == [-90, 90]  # not east: the wall


def test_recently_confirmed_nodes_need_no_look():
    g = graph_seen_at(100.0)
    pose = Pose2D(5.0, 5.0, 0.0)
    assert unverified_headings(g, pose, 2, open_room(), 5.0, FOV, 4, now=200.0, stale_after=600.0) == []


def test_nodes_confirmed_long_ago_get_a_look_again():
    """An object can be taken away after the camera passed it: a node this pass confirmed
    more than ``stale_after`` seconds ago is looked at again from where the robot stands."""
    g = graph_seen_at(100.0)
    pose = Pose2D(5.0, 5.0, 0.0)
    headings = unverified_headings(g, pose, 2, open_room(), 5.0, FOV, 4, now=800.0, stale_after=600.0)
    assert sorted(round(math.degrees(h)) for h in headings) == [-90, 90]
    # refresh off (0), or no clock: only what this pass has not confirmed
    assert unverified_headings(g, pose, 2, open_room(), 5.0, FOV, 4, now=800.0, stale_after=0.0) == []
    assert unverified_headings(g, pose, 2, open_room(), 5.0, FOV, 4, stale_after=600.0) == []
    # max_turns bounds the turning, nearest turn first
    assert len(unverified_headings(g, Pose2D(5.0, 5.0, 1.5), 2, open_room(), 5.0, FOV, 1,
                                   now=800.0, stale_after=600.0)) == 1


def test_a_node_loaded_from_the_store_is_not_stale_until_seen():
    """``last_seen`` is robot time of this process; a node read from the store has none."""
    g = ObjectGraph(ROBUST, [Node(0, "chair", np.array([5.0, 8.0, 0.5]), 0.9, 2, 2)])
    assert g.nodes[0].last_seen is None
    assert unverified_headings(g, Pose2D(5.0, 5.0, 0.0), 2, open_room(), 5.0, FOV, 4,
                               now=5000.0, stale_after=600.0) == []


@pytest.mark.parametrize("field,value", [("refresh_after", -1.0), ("radius", 0.0), ("max_turns", -1)])
def test_bad_look_around_params_are_refused(field, value):
    with pytest.raises(ValueError, match=field):
        LookAroundParams(**{field: value})


def test_head_turns_hand_out_headings_dwell_after_each_and_stop_at_the_deadline():
    turns = HeadTurns([0.5, 1.5, 2.5], dwell=2.0, deadline=10.0)
    assert turns.next_heading(0.0) == 0.5 and not turns.dwelling(0.0)
    turns.turned(1.0)
    assert turns.dwelling(2.9) and not turns.dwelling(3.0)
    assert turns.next_heading(3.0) == 1.5 and not turns.dwelling(3.0)
    assert turns.next_heading(10.0) is None and turns.headings == [2.5]  # time is up


def test_planned_head_turns_need_a_pose():
    g = graph_seen_at(10.0, session=1)
    params = LookAroundParams(radius=5.0, max_turns=4, timeout=30.0)
    assert plan_head_turns(g, None, 2, open_room(), params, 60.0, now=5.0).headings == []
    turns = plan_head_turns(g, Pose2D(5.0, 5.0, 0.0), 2, open_room(), params, 60.0, now=5.0)
    assert sorted(round(math.degrees(h)) for h in turns.headings) == [-90, 90] and turns.deadline == 35.0


def test_the_robot_holds_its_heading_while_a_node_in_front_is_being_missed():
    """A table by a wall, missed once by the frame the robot arrived with: the robot faces it
    for a dwell before any turn, so the next frames remove it (or see it). A node being
    missed behind the robot, or behind a wall, or a node with no misses, is no reason to wait;
    one in the lidar shadow (unknown cells in front of it) is: the camera looks over it."""
    grid = open_room()
    grid.data[90:110, 100:120] = -1  # the shadow of the table and its chair: unknown on the map
    table = Node(0, "table", np.array([6.5, 5.0, 0.4]), 0.9, 1, 1)
    behind_wall = Node(1, "chair", np.array([8.0, 5.0, 0.5]), 0.9, 1, 1)
    g = ObjectGraph(ROBUST, [table, behind_wall])
    params = LookAroundParams(dwell=1.5)
    facing_east = Pose2D(4.0, 5.0, 0.0)
    assert not plan_head_turns(g, facing_east, 2, grid, params, 60.0, 10.0).dwelling(10.0)  # no misses yet
    g.associate([], [0], 2, 9.5)
    assert g.pending() == [0]
    turns = plan_head_turns(g, facing_east, 2, grid, params, 60.0, 10.0)
    assert turns.dwelling(10.0) and turns.dwelling(11.4) and not turns.dwelling(11.5)
    assert not plan_head_turns(g, Pose2D(4.0, 5.0, math.pi), 2, grid, params, 60.0, 10.0).dwelling(10.0)
    g.associate([], [1], 2, 9.5)  # now only the chair behind the wall is being missed
    g.associate([Observation("table", table.position.copy(), 0.9)], [0], 2, 9.6)
    assert g.pending() == [1]
    assert not plan_head_turns(g, facing_east, 2, grid, params, 60.0, 10.0).dwelling(10.0)


def test_a_waypoint_turns_towards_an_object_the_camera_caught_once_on_the_way_not_through_a_wall():
    """A trash bin seen in one frame at (2, 5) and a chair at (8, 5), behind the wall, both
    unconfirmed: the waypoint at (5, 5), facing east, turns west to the bin and dwells there.
    With ``unconfirmed: false`` (or once a second frame confirmed the bin) it has no reason to turn."""
    g = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2))
    g.associate([Observation("trash bin", np.array([2.0, 5.0, 0.3]), 0.9),
                 Observation("chair", np.array([8.0, 6.5, 0.5]), 0.9)], [], 2, 11.0)
    pose = Pose2D(5.0, 5.0, 0.0)
    turns = plan_head_turns(g, pose, 2, open_room(), LookAroundParams(refresh_after=0.0), 60.0, 12.0)
    assert len(turns.headings) == 1 and abs(abs(turns.headings[0]) - math.pi) < 1e-6
    assert [t.category for t in turns.faced] == ["trash bin"]
    off = LookAroundParams(refresh_after=0.0, unconfirmed=False)
    assert plan_head_turns(g, pose, 2, open_room(), off, 60.0, 12.0).headings == []
    confirmed = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2))
    for t in (11.0, 12.0):
        confirmed.associate([Observation("trash bin", np.array([2.0, 5.0, 0.3]), 0.9)], [], 2, t)
    assert plan_head_turns(confirmed, pose, 2, open_room(), LookAroundParams(refresh_after=0.0), 60.0,
                           12.5).headings == []


def test_a_place_seen_once_gets_one_look_a_false_positive_does_not_turn_every_waypoint_near_it():
    """The look at (2, 5) saw nothing there (a false positive): the next waypoints, here and
    at (4, 6), do not turn to it again, and the refresh tour does not plan a stop for it."""
    g = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2, tentative_ttl=10.0))
    g.associate([Observation("trash bin", np.array([2.0, 5.0, 0.3]), 0.9)], [], 2, 11.0)
    params = LookAroundParams(refresh_after=0.0)
    turns = plan_head_turns(g, Pose2D(5.0, 5.0, 0.0), 2, open_room(), params, 60.0, 12.0)
    g.mark_sightings_looked(turns.faced)  # what the leaf does
    g.associate([], [], 2, 14.0)  # the dwell's frames: nothing there
    g.associate([], [], 2, 30.0)  # its ttl ran out
    assert plan_head_turns(g, Pose2D(5.0, 5.0, 0.0), 2, open_room(), params, 60.0, 31.0).headings == []
    assert plan_head_turns(g, Pose2D(4.0, 6.0, 0.0), 2, open_room(), params, 60.0, 31.0).headings == []
    assert g.unconfirmed_sightings() == []


def test_how_far_a_turn_faced_a_sighting_survives_a_resume_and_an_older_save_counts_as_near():
    """Two sightings of a cabinet's two ends, turned to from 3 m: they ask no other turn, but
    a look from within 2.5 m is still to come; a pass saved before distances were kept counts
    its turns as near. A lone sighting turned to from 3 m is settled."""
    g = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2))
    g.associate([Observation("cabinet", np.array([x, 5.0, 0.6]), 0.9) for x in (1.6, 2.4)], [], 2, 11.0)
    g.mark_sightings_looked(g.unconfirmed_sightings(), (5.0, 5.0))
    saved = g.policy.tentative.to_json()
    assert [round(e[2], 2) for e in saved["looked"]] == [3.4, 2.6]
    resumed = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2))
    resumed.policy.tentative.restore(saved)
    assert resumed.unconfirmed_sightings() == [] and len(resumed.unconfirmed_sightings(2.5)) == 2
    saved["looked"] = [entry[:2] for entry in saved["looked"]]  # a pass saved before distances were kept
    resumed.policy.tentative.restore(saved)
    assert resumed.unconfirmed_sightings(2.5) == []
    lone = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2))
    lone.associate([Observation("trash bin", np.array([2.0, 5.0, 0.3]), 0.9)], [], 2, 11.0)
    lone.mark_sightings_looked(lone.unconfirmed_sightings(), (5.0, 5.0))
    assert lone.unconfirmed_sightings(2.5) == []
