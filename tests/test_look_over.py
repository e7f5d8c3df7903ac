"""Looking over furniture: Look Around turns to a chair the camera caught once behind the chair in front."""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.graph import AssociationParams, Node, ObjectGraph, Observation
from bomc_bt.grid import OccupancyGrid
from bomc_bt.look_around import LookAroundParams, plan_head_turns
from bomc_bt.look_over import low_furniture_cells, object_tops, over_furniture_clear

RES = 0.05


def cells(x0: float, x1: float, y0: float, y1: float) -> tuple[slice, slice]:
    """Rows and columns of the map box x0..x1, y0..y1 (m) on a 0.05 m grid at the origin."""
    return slice(round(y0 / RES), round(y1 / RES) + 1), slice(round(x0 / RES), round(x1 / RES) + 1)


def room_with_a_table() -> OccupancyGrid:
    """10 x 10 m inside walls, a wall at x = 7 m. A table at (4.2, 6.6) with a chair at its
    side at (5, 7): the lidar saw the chair's outline (occupied, y = 7.25) and left the floor
    round them unknown, as it does round furniture."""
    data = np.zeros((200, 200), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[:, 140] = 100
    data[cells(3.7, 5.5, 5.7, 7.2)] = -1
    data[cells(4.75, 5.25, 7.25, 7.25)] = 100
    return OccupancyGrid(data, RES, (0.0, 0.0))


def graph_with_a_sighting(sighting_xy: tuple[float, float]) -> ObjectGraph:
    """The chair and the table as nodes, and a chair seen once at ``sighting_xy``."""
    chair = Node(0, "chair", np.array([5.0, 7.0, 0.45]), 0.9, 2, 2, footprint=np.array([4.75, 6.75, 5.25, 7.25]))
    table = Node(1, "table", np.array([4.2, 6.6, 0.375]), 0.9, 2, 2, footprint=np.array([3.8, 5.8, 4.6, 7.4]))
    g = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2), [chair, table])
    g.associate([Observation("chair", np.array([*sighting_xy, 0.8]), 0.9)], [], 2, 11.0)
    return g


def test_a_chairs_lidar_outline_is_looked_over_a_wall_never_even_under_a_bled_box():
    grid = room_with_a_table()
    boxes = np.array([[4.75, 6.75, 5.25, 7.25],  # the chair: its outline on the box's edge
                      [6.5, 3.0, 7.5, 4.0],  # a table whose box bled across the wall at x = 7
                      [1.0, 1.0, 1.5, 1.5]])  # a cabinet, as high as the camera
    grid.data[cells(1.0, 1.5, 1.0, 1.0)] = 100
    tops = object_tops(np.array([0.45, 0.375, 0.6]))
    assert np.allclose(tops, [0.9, 0.75, 1.2])
    over = low_furniture_cells(grid, boxes, tops, camera_height=1.1)
    assert over[cells(4.75, 5.25, 7.25, 7.25)].all()
    assert not over[:, 140].any()  # the wall, inside the bled box
    assert not over[cells(1.0, 1.5, 1.0, 1.0)].any()  # the cabinet hides what is behind it
    assert over.sum() == over[cells(4.75, 5.25, 7.25, 7.25)].sum()


def test_a_chair_caught_once_behind_the_chair_in_front_gets_a_turn_over_it():
    """The robot at (5, 8.5) facing east; a chair seen once at (5, 6.2), behind the chair in
    front of it at the table's side, in the lidar shadow: Look Around turns south to it and
    dwells. Over free cells only (``look_over: false``, the old rule) no line reaches it, and
    the robot drove off. A turn over furniture is Look Around's one look at the place, but
    the refresh tour, which looks from near and clear, still has the sighting to decide."""
    pose = Pose2D(5.0, 8.5, 0.0)
    g = graph_with_a_sighting((5.0, 6.2))
    assert [t.category for t in g.unconfirmed_sightings()] == ["chair"]
    params = LookAroundParams(refresh_after=0.0)
    turns = plan_head_turns(g, pose, 2, room_with_a_table(), params, 60.0, 12.0)
    assert [round(math.degrees(h)) for h in turns.headings] == [-90]
    assert turns.faced == [] and [t.category for t in turns.faced_past] == ["chair"]
    g.mark_sightings_looked(turns.faced_past, (pose.x, pose.y), past=True)  # what the leaf does
    g.associate([], [], 2, 14.0)  # the dwell's frames: not seen again
    assert plan_head_turns(g, Pose2D(5.2, 8.4, 0.0), 2, room_with_a_table(), params, 60.0, 15.0).headings == []
    assert [t.category for t in g.unconfirmed_sightings(2.5)] == ["chair"]  # the refresh tour's targets
    old = LookAroundParams(refresh_after=0.0, look_over=False)
    assert plan_head_turns(g, pose, 2, room_with_a_table(), old, 60.0, 12.0).headings == []
    low_camera = LookAroundParams(refresh_after=0.0, camera_height=0.8)  # below the chair: it hides
    assert plan_head_turns(g, pose, 2, room_with_a_table(), low_camera, 60.0, 12.0).headings == []


def test_a_sighting_behind_a_wall_gets_no_turn_over_furniture_or_not():
    g = graph_with_a_sighting((8.0, 8.5))
    turns = plan_head_turns(g, Pose2D(5.0, 8.5, math.pi), 2, room_with_a_table(), LookAroundParams(refresh_after=0.0),
                            60.0, 12.0)
    assert turns.headings == []


def test_clearing_round_the_robot_only_matches_the_whole_map_there_and_keeps_a_cut_wall():
    """Look Around clears outlines within its radius only (a window 2 m wider): the same
    cells there as over the whole map, and a wall the window cuts short is still a wall."""
    grid = room_with_a_table()
    nodes = list(graph_with_a_sighting((5.0, 6.2)).nodes.values())
    bled = Node(2, "table", np.array([7.0, 9.0, 0.375]), 0.9, 2, 2, footprint=np.array([6.5, 8.5, 7.5, 9.5]))
    whole = over_furniture_clear(grid, [*nodes, bled], 1.1)
    near = over_furniture_clear(grid, [*nodes, bled], 1.1, around=(5.0, 8.5, 2.0))
    rows, cols = cells(3.0, 7.0, 6.5, 9.95)
    assert (near[rows, cols] == whole[rows, cols]).all()
    assert near[cells(4.75, 5.25, 7.25, 7.25)].all()  # the chair's outline
    assert not near[:, 140].any() and not whole[:, 140].any()  # the wall, under the bled box


def test_a_look_over_furniture_survives_a_resume_and_an_older_save_settles_as_before():
    """A lone sighting turned to past furniture stays a refresh target after a resume; a pass
    saved before the flag was kept reads its looks as clear ones (a lone sighting settled)."""
    g = graph_with_a_sighting((5.0, 6.2))
    g.mark_sightings_looked(g.unconfirmed_sightings(), (5.0, 8.5), past=True)
    saved = g.policy.tentative.to_json()
    assert [e[3] for e in saved["looked"]] == [True]
    resumed = graph_with_a_sighting((5.0, 6.2))
    resumed.policy.tentative.restore(saved)
    assert resumed.unconfirmed_sightings() == [] and len(resumed.unconfirmed_sightings(2.5)) == 1
    saved["looked"] = [entry[:3] for entry in saved["looked"]]
    resumed.policy.tentative.restore(saved)
    assert resumed.unconfirmed_sightings(2.5) == []
