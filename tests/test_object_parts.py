"""Two ends of one object, each seen alone, become one node when the pass ends; two whole
objects side by side do not (bomc_bt.graph.parts)."""

from __future__ import annotations

import numpy as np
from test_association_neighbours import view

from bomc_bt.graph import AssociationParams, ObjectGraph


def _see(graph: ObjectGraph, frames: list, t0: float = 0.0) -> float:
    t = t0
    for frame in frames:
        graph.associate(frame, [], 1, t)  # nothing expected: no misses, only sightings
        t += 1.0
    return t


def _whole_table_elsewhere() -> list:
    """A 1.6 m table across the room, seen whole: what a table looks like on this floor."""
    return [[view("table", 9.2, 10.8, y0=-0.4, y1=0.4)]] * 3


def test_the_two_ends_of_a_table_whose_middle_is_hidden_become_one_table_in_its_middle():
    graph = ObjectGraph(AssociationParams())
    t = _see(graph, _whole_table_elsewhere())
    t = _see(graph, [[view("table", -0.8, -0.3, truncated=True, y0=-0.4, y1=0.4)]] * 3, t)
    _see(graph, [[view("table", 0.3, 0.8, truncated=True, y0=-0.4, y1=0.4)]] * 3, t)
    assert len(graph.nodes) == 3  # during the pass: the whole table and two half tables
    events = graph.pair_relocations(1, 99.0)
    tables = sorted(graph.nodes.values(), key=lambda v: v.position[0])
    assert len(tables) == 2, [np.round(v.position, 2).tolist() for v in tables]
    assert abs(tables[0].position[0]) < 0.05 and np.allclose(tables[0].footprint[[0, 2]], [-0.8, 0.8])
    assert [e.kind for e in events] == ["removed", "updated"] and events[0].merged_into == tables[0].id


def test_ends_seen_in_one_frame_as_two_objects_and_whole_chairs_side_by_side_stay_apart():
    graph = ObjectGraph(AssociationParams())
    t = _see(graph, _whole_table_elsewhere())
    ends = [view("table", -0.8, -0.3, truncated=True, y0=-0.4, y1=0.4),
            view("table", 0.3, 0.8, truncated=True, y0=-0.4, y1=0.4)]
    _see(graph, [ends] * 3, t)  # one frame matched both: two objects (two small tables)
    graph.pair_relocations(1, 99.0)
    assert len(graph.nodes) == 3

    graph = ObjectGraph(AssociationParams())
    _see(graph, [[view("chair", -0.6, -0.1)]] * 3 + [[view("chair", 0.2, 0.7)]] * 3)
    graph.pair_relocations(1, 99.0)
    assert len(graph.nodes) == 2  # each the size a chair is seen whole at: no parts
