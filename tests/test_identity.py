"""Two nodes found to be one object: the one an earlier pass had keeps its id
(bomc_bt.graph.identity), so an object the map holds is never reported as new."""

from __future__ import annotations

import numpy as np

from bomc_bt.graph import AssociationParams, Event, Node, ObjectGraph, Observation
from bomc_bt.graph.identity import keeper
from bomc_bt.net_changes import net_changes


def table(i: int, x0: float, x1: float, first_session: int, seen: int) -> Node:
    return Node(i, "table", np.array([(x0 + x1) / 2, 0.0, 0.6]), 0.9, first_session, first_session,
                observations=seen, footprint=np.array([x0, -0.4, x1, 0.4]))


def view(x0: float, x1: float) -> Observation:
    return Observation("table", np.array([(x0 + x1) / 2, 0.0, 0.6]), 0.9, 500, 0.5 * (x1 - x0),
                       box=np.array([x0, -0.4, x1, 0.4]))


def test_a_table_the_map_holds_keeps_its_id_when_a_second_node_this_pass_started_is_folded_in():
    """Seed 7605, pass 5 on a small scale: the table's node from pass 1 (46 views) and a
    second node pass 2 started at its far end (300 views in a minute); a view covering both
    folds them. Before, the node seen more often kept its id: the table was reported added
    (and its old node's history ended in a merge)."""
    g = ObjectGraph(AssociationParams(confirm_detections=1), [table(0, -0.6, 0.2, 1, 46)], next_id=1)
    g.insert(table(1, 0.0, 0.6, 2, 300))
    history = g.associate([view(-0.6, 0.6)], [0, 1], 2, 10.0, in_view=[0, 1])
    assert set(g.nodes) == {0}  # the map's id lives on
    assert g.nodes[0].observations == 347
    assert g.nodes[0].position[0] > 0.2  # where it stands: weighted by the views, the new node's mostly
    before = [Event("added", 0, "table", np.array([-0.2, 0.0, 0.6]), 1, 1.0),
              Event("added", 1, "table", np.array([0.3, 0.0, 0.6]), 2, 5.0)]
    assert [c.kind for c in net_changes(before + history, 1, lambda _c: 1.0)] == []  # nothing changed


def test_between_two_nodes_of_one_age_the_one_seen_more_often_keeps_its_id():
    old, new = table(0, 0.0, 1.0, 1, 5), table(1, 0.0, 1.0, 2, 50)
    assert keeper(old, new, 2) == (old, new) and keeper(new, old, 2) == (old, new)
    a, b = table(3, 0.0, 1.0, 1, 5), table(2, 0.0, 1.0, 1, 9)
    assert keeper(a, b, 2) == (b, a)
    tie, other = table(4, 0.0, 1.0, 2, 5), table(7, 0.0, 1.0, 2, 5)
    assert keeper(other, tie, 2) == (tie, other)  # then the lower id
