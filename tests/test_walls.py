"""A cut-off view across a wall is no part of a big object (graph level, with a small map).

The traced case (a generated 36 x 28 m office, seed 8904, pass 1): a sofa 1.8 m long stands
against the north face of a wall; a false "sofa" box on the wall's south face, 0.07 m from
the sofa's footprint, was taken for its hidden end and stretched the footprint along the
wall, moving the node 0.77 m off the sofa for the rest of the run."""

from __future__ import annotations

import numpy as np

from bomc_bt.graph import AssociationParams, ObjectGraph, Observation
from bomc_bt.graph.walls import Walls, nearest_points
from bomc_bt.grid import OccupancyGrid

RES = 0.05


def room_with_a_wall(y_wall: float = 0.0) -> OccupancyGrid:
    """A 6 x 4 m map from (-1, -2): free floor, one wall 0.1 m thick from y_wall along x."""
    data = np.zeros((int(4 / RES), int(6 / RES)), dtype=np.int8)
    grid = OccupancyGrid(data, RES, (-1.0, -2.0))
    rows, _ = grid.world_to_cell(np.zeros(2), np.array([y_wall + 0.01, y_wall + 0.09]))
    data[rows[0]:rows[1] + 1, :] = 100
    return grid


def view(x0: float, x1: float, y0: float, y1: float, z: float = 0.5, truncated: bool = False) -> Observation:
    return Observation("sofa", np.array([(x0 + x1) / 2, (y0 + y1) / 2, z]), 0.9, 500, 0.5 * max(x1 - x0, y1 - y0),
                       box=np.array([x0, y0, x1, y1]), truncated=truncated)


def sofa_north_of_the_wall(walls: Walls | None) -> tuple[ObjectGraph, float]:
    """A sofa (0..1.8, 0.13..0.98) seen in cut-off views from its room, north of the wall."""
    graph = ObjectGraph(AssociationParams())
    graph.policy.walls = walls
    t = 0.0
    for x0, x1 in ((0.0, 1.2), (0.6, 1.8), (0.0, 1.8)):
        graph.associate([view(x0, x1, 0.13, 0.98, truncated=True)], list(graph.nodes), 1, t)
        t += 1.0
    return graph, t


def test_the_nearest_points_of_two_boxes():
    a, b = nearest_points(np.array([0.0, 0.0, 1.0, 1.0]), np.array([2.0, 0.5, 3.0, 2.0]))
    assert np.allclose(a, [1.0, 0.75]) and np.allclose(b, [2.0, 0.75])
    a, b = nearest_points(np.array([0.0, 0.0, 1.0, 1.0]), np.array([0.5, 0.5, 2.0, 2.0]))
    assert np.allclose(a, b)


def test_a_wall_stands_between_boxes_on_its_two_sides_and_not_between_boxes_on_one():
    walls = Walls(room_with_a_wall())
    sofa = np.array([0.0, 0.13, 1.8, 0.98])
    assert walls.between(sofa, np.array([-0.8, -0.06, 0.0, 0.06]))  # on the wall's south face
    assert walls.between(sofa, np.array([0.2, -0.8, 1.2, -0.3]))  # in the corridor south of it
    assert not walls.between(sofa, np.array([1.85, 0.2, 2.4, 0.9]))  # beyond its east end, same room
    assert not walls.between(sofa, np.array([1.0, 0.5, 2.4, 0.9]))  # overlapping it


def test_a_false_box_on_the_far_side_of_a_wall_does_not_stretch_the_sofa_against_it():
    graph, t = sofa_north_of_the_wall(Walls(room_with_a_wall()))
    sofa = next(iter(graph.nodes.values()))
    before = sofa.footprint.copy()
    for _ in range(3):  # cut off by the image border, 1.39 m up the wall, 0.07 m from the sofa
        graph.associate([view(-1.0, 0.0, -0.07, 0.06, z=1.39, truncated=True)], [], 1, t)
        t += 1.0
    assert np.allclose(sofa.footprint, before)
    assert abs(sofa.position[0] - 0.9) < 0.05


def test_without_the_map_the_same_box_is_taken_for_the_sofas_hidden_end():
    """What the pass did before the map was given to association: the sofa's footprint grew
    over the wall patch and its node went west (the test above fails without walls)."""
    graph, t = sofa_north_of_the_wall(None)
    sofa = next(iter(graph.nodes.values()))
    for _ in range(3):
        graph.associate([view(-1.0, 0.0, -0.07, 0.06, z=1.39, truncated=True)], [], 1, t)
        t += 1.0
    assert sofa.footprint[0] <= -0.99 and sofa.position[0] < 0.5


def test_the_hidden_end_in_the_same_room_still_grows_the_footprint():
    graph, t = sofa_north_of_the_wall(Walls(room_with_a_wall()))
    sofa = next(iter(graph.nodes.values()))
    for _ in range(3):
        graph.associate([view(2.2, 2.5, 0.13, 0.98, truncated=True)], [], 1, t)
        t += 1.0
    assert len(graph.nodes) == 1 and sofa.footprint[2] >= 2.5 - 1e-9
