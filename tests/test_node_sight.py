"""Whether a place sees a node: a line to a face of its footprint, not through the wall it stands against."""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.graph import AssociationParams, Node, ObjectGraph
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitoring import unverified_headings
from bomc_bt.node_sight import FACE_INSET, camera_clear, face_points, sees_faces, sees_node, sees_target
from bomc_bt.refresh import refresh_viewpoints

FOV = math.radians(60.0)
WEST, EAST = (5.0, 5.0), (9.5, 5.0)  # places on either side of the wall at x = 7.0-7.15 m


def two_rooms() -> OccupancyGrid:
    """10 x 10 m inside walls, split by a closed wall 0.15 m thick at x = 7.0-7.15 m."""
    data = np.zeros((200, 200), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[:, 140:143] = 100
    return OccupancyGrid(data, 0.05, (0.0, 0.0))


def with_table(grid: OccupancyGrid, box: tuple[float, float, float, float]) -> OccupancyGrid:
    """``grid`` with a table's lidar outline occupied and its inside unknown (the lidar's shadow)."""
    data = grid.data.copy()
    r0, c0 = grid.world_to_cell(box[0], box[1])
    r1, c1 = grid.world_to_cell(box[2] - 1e-6, box[3] - 1e-6)
    data[r0:r1 + 1, c0:c1 + 1] = 100
    data[r0 + 1:r1, c0 + 1:c1] = -1
    return OccupancyGrid(data, grid.resolution, grid.origin)


def node(i: int, x: float, y: float, footprint, category: str = "door", session: int = 1) -> Node:
    n = Node(i, category, np.array([x, y, 0.8]), 0.9, session, session)
    n.footprint = None if footprint is None else np.array(footprint, dtype=float)
    return n


# A door on the wall's east face (x 7.15-7.20 m), its footprint as robust association keeps
# it: the door's points and the depth that bled onto the wall, 0.35 m deep in all.
DOOR = node(0, 7.2, 5.0, (7.05, 4.45, 7.40, 5.55))


def test_a_door_on_the_far_face_of_a_wall_is_out_of_sight_from_behind_the_wall():
    grid = two_rooms()
    clear = camera_clear(grid)
    # half a metre short of its centre lies in the west room: the old rule saw it through the wall
    assert sees_node(grid, clear, WEST, (7.2, 5.0))
    assert not sees_target(grid, clear, WEST, DOOR.position, DOOR.footprint)
    assert sees_target(grid, clear, EAST, DOOR.position, DOOR.footprint)
    # and from an angle, through the east room
    assert sees_target(grid, clear, (9.0, 8.0), DOOR.position, DOOR.footprint)


def test_a_table_against_a_wall_is_seen_from_its_own_room_over_its_own_outline():
    """A footprint no wider than the table's lidar outline: the outline is the table's own."""
    box = (7.15, 4.4, 7.75, 5.6)
    grid = with_table(two_rooms(), box)
    clear = camera_clear(grid)
    assert sees_target(grid, clear, EAST, (7.45, 5.0), box)
    assert sees_target(grid, clear, (7.45, 8.0), (7.45, 5.0), box)  # from the north, along the wall
    assert not sees_target(grid, clear, WEST, (7.45, 5.0), box)
    assert sees_node(grid, clear, WEST, (7.45, 5.0))  # the old rule: half a metre short is west of the wall
    # a chair standing between the place and the table hides it
    blocked = with_table(grid, (8.4, 4.3, 8.9, 5.7))
    assert not sees_target(blocked, camera_clear(blocked), EAST, (7.45, 5.0), box)


def test_a_node_without_a_footprint_or_outside_its_own_keeps_the_centre_rule():
    grid = two_rooms()
    clear = camera_clear(grid)
    for place, centre in ((WEST, (7.2, 5.0)), (EAST, (7.2, 5.0)), (WEST, (7.7, 5.0)), ((9.0, 9.0), (8.0, 6.0))):
        assert sees_target(grid, clear, place, centre, None) == sees_node(grid, clear, place, centre)
    # a box a metre off the node's place describes another view: the centre rule decides
    off = (6.55, 4.45, 6.95, 5.55)  # in the west room, while the node stands east of the wall
    assert sees_faces(grid, clear, WEST, off)
    assert not sees_target(grid, clear, WEST, (8.0, 5.0), off)


def test_face_points_lie_on_the_footprint_shrunk_by_the_inset():
    points = face_points((1.0, 2.0, 2.0, 2.06))
    assert points.shape == (12, 2)
    assert np.isclose(points[:, 0].min(), 1.0 + FACE_INSET) and np.isclose(points[:, 0].max(), 2.0 - FACE_INSET)
    assert np.allclose(points[:, 1], 2.03)  # a side thinner than twice the inset shrinks to its middle


def test_look_around_does_not_turn_to_a_door_behind_the_wall():
    """A door on the east room's side of the wall, not yet confirmed this pass: from the west
    room the camera would face a wall, so no turn; from the east room, one turn."""
    graph = ObjectGraph(AssociationParams(mode="robust"), [node(0, 7.2, 5.0, DOOR.footprint)])
    grid = two_rooms()
    assert unverified_headings(graph, Pose2D(*WEST, 0.0), 2, grid, 5.0, FOV, 4) == []
    headings = unverified_headings(graph, Pose2D(*EAST, 0.0), 2, grid, 5.0, FOV, 4)
    assert [round(math.degrees(h)) for h in headings] == [180]


def test_a_refresh_stop_for_a_door_stands_on_the_door_s_side_of_the_wall():
    """The west place is nearer the start; the tour drives round to the east one instead."""
    door = node(0, 7.2, 5.0, DOOR.footprint)
    door.last_seen = 0.0
    candidates = np.array([[5.5, 5.0], [9.0, 5.0]])
    def euclidean(at):
        return lambda points: np.hypot(points[:, 0] - at[0], points[:, 1] - at[1])

    stops = refresh_viewpoints(two_rooms(), [door], 1000.0, candidates, Pose2D(4.0, 5.0, 0.0), 100.0, euclidean)
    assert [(s.x, s.y) for s in stops] == [(9.0, 5.0)]
