"""A node of an earlier pass is judged by the floor its views covered this pass (graph/pass_views.py)."""

from __future__ import annotations

import numpy as np

from bomc_bt.graph import AssociationParams, Event, Node, ObjectGraph, Observation
from bomc_bt.net_changes import net_changes

# Bookstore map at 0.04 m, generated world seed 9005, pass 5: table-3 (1.2 x 0.8 m) pushed from
# (-4.74, -2.30) to (-3.90, -2.86). The pass's views of its node, then of the node added for its
# east end (robot time, floor box, cut off by an occluder or the image border).
OLD_VIEWS = [(200.5, (-4.6, -3.21, -4.17, -2.84), True), (201.5, (-4.58, -3.45, -3.54, -2.77), True),
             (210.0, (-4.58, -3.44, -3.36, -2.6), True), (228.5, (-4.62, -3.04, -3.9, -2.27), False),
             (235.5, (-4.63, -3.04, -3.84, -2.27), False)]
EAST_END = [(324.5, (-3.78, -3.46, -3.17, -2.65)), (325.5, (-3.77, -3.41, -3.19, -2.62)),
            (327.5, (-4.3, -3.43, -3.2, -2.3)), (328.0, (-4.31, -3.43, -3.2, -2.29))]


def view(box: tuple[float, float, float, float], truncated: bool) -> Observation:
    x0, y0, x1, y1 = box
    return Observation("table", np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.4]), 0.85, 4000,
                       0.5 * max(x1 - x0, y1 - y0), box=np.array(box), truncated=truncated)


def bookstore_graph() -> tuple[ObjectGraph, list[Event]]:
    """The table's node as pass 4 left it, and another table the pass sees whole (1.38 m:
    the kind's length)."""
    table = Node(0, "table", np.array([-4.75, -2.31, 0.4]), 0.9, 1, 4, observations=30,
                 footprint=np.array([-5.46, -2.91, -4.04, -1.71]))
    other = Node(1, "table", np.array([5.47, 0.96, 0.4]), 0.9, 1, 4, observations=30,
                 footprint=np.array([4.78, 0.56, 6.16, 1.36]))
    graph = ObjectGraph(AssociationParams(), [table, other])
    events = [Event("added", n.id, "table", n.position.copy(), 1, 5.0) for n in (table, other)]
    for t in (190.0, 190.5):
        events += graph.associate([view((4.78, 0.56, 6.16, 1.36), False)], [1], 5, t)
    return graph, events


def pass_end(graph: ObjectGraph, events: list[Event]) -> list[Event]:
    return events + graph.pair_relocations(5, 400.0) + graph.mark_refinements(5, 400.0)


def test_a_table_pushed_less_than_its_length_is_one_table_moved_not_a_second_one():
    graph, events = bookstore_graph()
    for t, box, truncated in OLD_VIEWS:
        events += graph.associate([view(box, truncated)], [0], 5, t)
    # the node kept its old floor and grew over the new one; the east end became a node of its own
    assert graph.nodes[0].footprint[0] < -5.4 and graph.nodes[0].footprint[3] > -1.8
    for t, box in EAST_END:
        events += graph.associate([view(box, True)], [], 5, t)
    assert len(graph.nodes) == 3
    events = pass_end(graph, events)
    assert sorted(graph.nodes) == [0, 1]  # one table where table-3 now stands, with its old id
    assert np.allclose(graph.nodes[0].position[:2], (-3.9, -2.86), atol=0.1)
    assert [(c.kind, c.node_id) for c in net_changes(events, 4, lambda _c: 0.7)] == [("moved", 0)]


def test_the_floor_a_pass_saw_survives_a_resume():
    graph, events = bookstore_graph()
    for t, box, truncated in OLD_VIEWS:
        events += graph.associate([view(box, truncated)], [0], 5, t)
    state = graph.pass_state()
    resumed = ObjectGraph(AssociationParams(), [Node(i, n.category, n.position.copy(), n.confidence, n.first_session,
                                                     n.last_session, observations=n.observations,
                                                     footprint=n.footprint.copy()) for i, n in graph.nodes.items()])
    resumed.restore_pass_state(state, {})
    seen = resumed.policy.extents.views.moved_off(resumed, resumed.nodes[0], 5)
    assert seen is not None and np.allclose(seen, (-4.63, -3.45, -3.36, -2.27))
    for t, box in EAST_END:
        events += resumed.associate([view(box, True)], [], 5, t)
    pass_end(resumed, events)
    assert sorted(resumed.nodes) == [0, 1]


def test_a_table_left_in_place_keeps_a_new_table_beside_it_apart():
    # the same table not moved: seen where it stood, its views 0.15 m beyond the old
    # footprint's east edge (the mask bled); a second table brought and set end to end
    # with it, 0.3 m further east and never in one frame with it, is a table of its own
    graph, events = bookstore_graph()
    for t in (200.0, 200.5, 201.0):
        events += graph.associate([view((-5.4, -2.85, -3.89, -1.75), False)], [0], 5, t)
    assert graph.policy.extents.views.moved_off(graph, graph.nodes[0], 5) is not None
    for t in (210.0, 210.5, 211.0):
        events += graph.associate([view((-3.6, -2.85, -2.4, -1.75), False)], [], 5, t)
    assert len(graph.nodes) == 3
    events = pass_end(graph, events)
    assert len(graph.nodes) == 3
    assert [c.kind for c in net_changes(events, 4, lambda _c: 0.7)] == ["added"]
