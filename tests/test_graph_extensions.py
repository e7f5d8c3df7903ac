"""Robust association beyond Algorithm 2: big objects, hidden duplicates, truncated views."""

from __future__ import annotations

import numpy as np

from bomc_bt.graph import AssociationParams, Node, ObjectGraph, Observation


def node(i: int, category: str, x: float, y: float, z: float = 0.4, seen: int = 1) -> Node:
    return Node(i, category, np.array([x, y, z]), 0.9, 1, 1, observations=seen)


def obs(category: str, x: float, y: float, z: float = 0.4, extent: float = 0.0) -> Observation:
    return Observation(category, np.array([x, y, z]), 0.9, 500, extent)


def test_a_big_objects_spread_widens_its_gate_but_a_small_ones_does_not():
    g = ObjectGraph(AssociationParams(), [node(0, "table", 0.0, 0.0)])
    events = g.associate([obs("table", 1.0, 0.0, extent=0.6)], [0], 1, 0.0)
    assert [e.kind for e in events] != ["added"]  # 1.0 m away, but within the table's own spread
    assert set(g.nodes) == {0}
    small = ObjectGraph(AssociationParams(confirm_detections=1), [node(0, "cup", 0.0, 0.0)])
    events = small.associate([obs("cup", 1.0, 0.0, extent=0.05)], [], 1, 0.0)
    assert [e.kind for e in events] == ["added"]


def test_a_new_object_is_added_only_once_a_second_frame_confirms_it():
    g = ObjectGraph(AssociationParams(confirm_detections=2, confirm_interval=0.5, tentative_ttl=10.0))
    assert g.associate([obs("bin", 3.0, 1.0)], [], 1, 0.0) == []  # first sighting waits
    assert g.associate([obs("bin", 3.1, 1.0)], [], 1, 0.2) == []  # same burst: no new evidence
    events = g.associate([obs("bin", 3.05, 1.0)], [], 1, 1.0)
    assert [e.kind for e in events] == ["added"]
    assert abs(g.nodes[events[0].node_id].position[0] - 3.025) < 1e-9  # mean of the sightings
    # a false positive seen once is forgotten after the ttl
    g.associate([obs("door", 9.0, 9.0)], [], 1, 2.0)
    assert g.associate([obs("door", 9.0, 9.0)], [], 1, 20.0) == []
    assert all(n.category != "door" for n in g.nodes.values())


def test_the_paper_mode_keeps_the_plain_threshold():
    g = ObjectGraph(AssociationParams(mode="paper"), [node(0, "table", 0.0, 0.0)])
    events = g.associate([obs("table", 1.0, 0.0, extent=0.6)], [], 1, 0.0)
    assert [e.kind for e in events] == ["added"]


def test_a_hidden_duplicate_inside_the_observed_object_is_folded_in():
    g = ObjectGraph(AssociationParams(), [node(0, "table", 0.0, 0.0, seen=10), node(1, "table", 0.6, 0.0, seen=2)])
    # node 1 is inside the field of view but hidden (not expected): the observation covers both
    events = g.associate([obs("table", 0.1, 0.0, extent=0.6)], [0], 1, 5.0, in_view=[0, 1])
    assert set(g.nodes) == {0}
    assert ("removed", 1) in [(e.kind, e.node_id) for e in events]
    assert g.nodes[0].observations == 13  # 10 + 1 match + 2 folded in


def test_an_expected_neighbour_is_not_merged_but_counted_as_missed():
    g = ObjectGraph(AssociationParams(), [node(0, "chair", 0.0, 0.0), node(1, "chair", 0.6, 0.0)])
    g.associate([obs("chair", 0.0, 0.0)], [0, 1], 1, 0.0, in_view=[0, 1])
    assert set(g.nodes) == {0, 1} and g.nodes[1].misses == 1


def test_nodes_outside_the_view_are_never_merged():
    g = ObjectGraph(AssociationParams(), [node(0, "table", 0.0, 0.0), node(1, "table", 0.6, 0.0)])
    g.associate([obs("table", 0.1, 0.0, extent=0.6)], [0], 1, 0.0, in_view=[0])
    assert set(g.nodes) == {0, 1}


def test_height_counts_half_in_robust_mode():
    # a person cut off by the top of the image: centroid 0.7 m low, same place on the floor
    g = ObjectGraph(AssociationParams(), [node(0, "person", 2.0, 3.0, z=1.2)])
    assert g.associate([obs("person", 2.1, 3.0, z=0.5)], [0], 1, 0.0)[0].kind == "updated"
    paper = ObjectGraph(AssociationParams(mode="paper"), [node(0, "person", 2.0, 3.0, z=1.2)])
    assert [e.kind for e in paper.associate([obs("person", 2.1, 3.0, z=0.5)], [], 1, 0.0)] == ["added"]


def test_a_node_remembers_how_big_its_object_is():
    # seen side-on (spread 0.6 m: gate 0.9 m), then end-on 0.85 m away with a narrow spread
    g = ObjectGraph(AssociationParams(confirm_detections=1))
    g.associate([obs("table", 0.0, 0.0, extent=0.6)], [], 1, 0.0)
    events = g.associate([obs("table", 0.85, 0.0, extent=0.1)], [], 1, 1.0)
    assert len(g.nodes) == 1 and [e.kind for e in events] != ["added"]
    # a small object does not earn a wider gate
    small = ObjectGraph(AssociationParams(confirm_detections=1))
    small.associate([obs("cup", 0.0, 0.0, extent=0.05)], [], 1, 0.0)
    small.associate([obs("cup", 0.85, 0.0, extent=0.05)], [], 1, 1.0)
    assert len(small.nodes) == 2
