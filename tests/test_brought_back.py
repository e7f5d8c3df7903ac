"""Objects brought back where an earlier pass saw them go are additions, never another's
move (bomc_bt.graph.brought_back, bomc_bt.first_seen.gone_before, the pass end)."""

from __future__ import annotations

import numpy as np

from bomc_bt.first_seen import gone_before
from bomc_bt.graph import AssociationParams, Event, Node, ObjectGraph, Observation
from bomc_bt.graph.brought_back import brought_back
from bomc_bt.net_changes import net_changes
from bomc_bt.store import SiteStore

RED, BLUE, GREY, GREEN = (0.653, 0.184), (0.184, 0.245), (0.327, 0.327), (0.217, 0.522)


def node(i: int, x: float, y: float = 0.0, colour=None, category: str = "chair", session: int = 3) -> Node:
    return Node(i, category, np.array([x, y, 0.45]), 0.9, session, session, observations=10, colour=colour)


def test_a_new_node_at_the_place_one_of_its_kind_and_look_went_is_that_one_back():
    gone = [node(1, 0.0, colour=RED, session=1), node(2, 10.0, colour=None, session=1),
            node(3, 20.0, colour=RED, category="trash bin", session=1)]
    arrivals = [node(10, 0.2, colour=(0.66, 0.19)),  # 0.2 m off, the same red: back
                node(11, 0.1, 5.0, colour=RED),  # red, but 5 m away: another story
                node(12, 10.3, colour=BLUE),  # where a chair of unknown look went: the place decides
                node(13, 20.0, colour=RED),  # a chair where a bin went: not it
                node(14, 0.0, 0.25, colour=BLUE)]  # where the red chair went, but blue: another chair
    assert [(a.id, g.id) for a, g in brought_back(arrivals, gone, 0.35, 0.04)] == [(10, 1), (12, 2)]
    # a chair set at the next seat of the table, 0.7 m from where one of its model went, is not it
    assert brought_back([node(15, 0.7, colour=RED)], gone, 0.35, 0.04) == []
    assert brought_back(arrivals, gone, 0.0, 0.04) == []  # return_radius 0: off
    # colours off: the place alone
    assert [a.id for a, _ in brought_back(arrivals, gone, 0.35, 0.0)] == [10, 12, 14]


def passes(return_radius: float) -> tuple[list[tuple[str, bool]], list, int]:
    """Seed 7503's pass 11 on a small scale: two navy (blue) chairs among chairs of other
    models; pass 2 sees chair B gone. Before pass 3, chair A is carried 20 m and B is brought
    back to its old place: the pass sees A gone and two navy chairs new. The net changes of
    pass 3, with the nodes pass 2 saw go as the pass end's ``gone``."""
    params = AssociationParams(confirm_misses=1, confirm_detections=1, return_radius=return_radius)
    a, b = np.array([0.0, 0.0, 0.45]), np.array([6.0, 0.0, 0.45])
    others = [(np.array([-10.0 * (k + 1), 30.0, 0.45]), c) for k, c in enumerate((RED, GREY, GREEN, RED, GREY))]
    g, history = ObjectGraph(params), []
    for t in (0.0, 1.0, 2.0):  # pass 1: every chair seen in three frames
        seen = [Observation("chair", p, 0.9, 500, colour=BLUE) for p in (a, b)]
        seen += [Observation("chair", p, 0.9, 500, colour=c) for p, c in others]
        history += g.associate(seen, sorted(g.nodes), 1, t)
    b_id = min(g.nodes, key=lambda i: np.hypot(*(g.nodes[i].position - b)[:2]))
    for k in range(12):  # pass 2: B's place in view, B not there
        history += g.associate([], [b_id] if b_id in g.nodes else [], 2, 10.0 + k)
    assert b_id not in g.nodes
    gone = [v for v in g.removed_this_session()]
    a_id = min(g.nodes, key=lambda i: np.hypot(*(g.nodes[i].position - a)[:2]))
    carried = np.array([0.0, 20.0, 0.45])
    for t in (40.0, 41.0):  # pass 3: A at its new place and B back at its old one
        history += g.associate([Observation("chair", p, 0.9, 500, colour=BLUE) for p in (carried, b + 0.1)],
                               [], 3, t)
    for k in range(12):  # A's old place in view, A not there
        history += g.associate([], [a_id] if a_id in g.nodes else [], 3, 45.0 + k)
    history += g.pair_relocations(3, 80.0, gone=gone)
    changes = net_changes(history, 2, lambda _c: 0.7)
    return sorted((c.kind, c.node_id == a_id) for c in changes), changes, b_id


def test_a_chair_brought_back_leaves_the_move_of_its_look_alike_to_be_found():
    # with the return known: A moved (its id kept), B's return an addition, reported as B back
    kinds, changes, b_id = passes(0.35)
    assert kinds == [("added", False), ("moved", True)]
    back = next(c for c in changes if c.kind == "added")
    assert back.back_of == b_id and f"back where #{b_id} went" in back.describe()
    assert back.to_json()["back_of"] == b_id and type(back).from_json(back.to_json()).back_of == b_id
    # without: two navy chairs new and one gone, which one moved a guess: nothing paired
    kinds, changes, _ = passes(0.0)
    assert kinds == [("added", False), ("added", False), ("removed", True)]
    assert all(c.back_of is None for c in changes)


def test_the_nodes_gone_before_a_pass_are_those_removed_on_evidence_and_not_seen_since(tmp_path):
    def removal(nid: int, session: int, **detail) -> Event:
        return Event("removed", nid, "chair", np.array([float(nid), 0.0, 0.45]), session, 1.0,
                     detail={"misses": 0, "merged": False, **detail})

    nodes = [node(i, float(i), colour=RED, session=1) for i in range(1, 8)]
    for n in nodes[:6]:
        n.state = "removed"
    events = {1: [Event("added", n.id, "chair", n.position, 1, 0.0) for n in nodes],
              2: [removal(1, 2, misses=4),  # missed: gone
                  removal(2, 2, merged=True, merged_into=6),  # a duplicate folded into its twin
                  removal(3, 2, misses=3, retracted=True),  # a sighting the map no longer trusts
                  removal(4, 2, misses=5), Event("moved", 4, "chair", np.array([4.0, 9.0, 0.45]), 2, 2.0),
                  removal(6, 2, misses=4)],  # seen go, then deleted by the operator before pass 3: never there
              3: [removal(5, 3, misses=4),  # removed in the pass at hand: not before it
                  Event("deleted", 6, "chair", np.array([6.0, 0.0, 0.45]), 3, 0.0)]}  # the operator's
    with SiteStore(tmp_path / "site.db") as store:
        for n in (1, 2, 3):
            store.begin_session(n, {"stamp": 0.0})
            store.record(events[n], nodes if n == 1 else [])
            if n < 3:
                store.end_session(n, "succeeded", {"stamp": 1.0})
        gone = gone_before(store, 3)
        assert [v.id for v in gone] == [1]
        assert np.allclose(gone[0].colour, RED) and np.allclose(gone[0].position[:2], [1.0, 0.0])
        assert gone_before(store, 2) == []


def pass_with_return_beside(gone_known: bool) -> tuple[ObjectGraph, list, int, int]:
    """Seed 9105's pass 11 on a small scale: navy chairs A at (0, 0) and B 1.4 m from it; pass
    2 sees B go. Before pass 3, A is carried 1.6 m the other way and B is brought back to
    its place: pass 3 sees both navy chairs new before it sees A's place empty. The policy
    knows the nodes earlier passes saw go when ``gone_known`` (as a monitor pass gives them)."""
    params = AssociationParams(confirm_misses=1, confirm_detections=1)
    a, b, carried = np.array([0.0, 0.0, 0.45]), np.array([1.4, 0.0, 0.45]), np.array([-1.6, 0.0, 0.45])
    others = [(np.array([-10.0 * (k + 1), 30.0, 0.45]), c) for k, c in enumerate((RED, GREY, GREEN))]
    g, history = ObjectGraph(params), []
    for t in (0.0, 1.0, 2.0):
        seen = [Observation("chair", p, 0.9, 500, colour=BLUE) for p in (a, b)]
        seen += [Observation("chair", p, 0.9, 500, colour=c) for p, c in others]
        history += g.associate(seen, sorted(g.nodes), 1, t)
    a_id, b_id = (min(g.nodes, key=lambda i, p=p: np.hypot(*(g.nodes[i].position - p)[:2])) for p in (a, b))
    for k in range(12):  # pass 2: B's place in view, B not there
        history += g.associate([], [b_id] if b_id in g.nodes else [], 2, 10.0 + k)
    gone = list(g.removed_this_session())
    if gone_known:
        g.policy.gone = gone
    for t in (40.0, 41.0):  # pass 3: B back (0.1 m off its old place) and A at its new place
        history += g.associate([Observation("chair", p, 0.9, 500, colour=BLUE) for p in (b + 0.1, carried)], [], 3, t)
    for k in range(12):  # A's old place in view, A not there
        history += g.associate([], [a_id] if a_id in g.nodes and g.nodes[a_id].position[0] == 0.0 else [], 3,
                               45.0 + k)
    history += g.pair_relocations(3, 80.0, gone=gone)
    return g, net_changes(history, 2, lambda _c: 0.7), a_id, b_id


def test_a_chair_brought_back_beside_one_that_moved_is_not_where_that_one_went():
    g, changes, a_id, b_id = pass_with_return_beside(gone_known=True)
    moved = next(c for c in changes if c.kind == "moved")
    added = next(c for c in changes if c.kind == "added")
    assert len(changes) == 2 and moved.node_id == a_id and added.back_of == b_id
    assert np.allclose(g.nodes[a_id].position[:2], [-1.6, 0.0])  # A's id went with A
    # not knowing what earlier passes saw go, A's node takes the nearer navy chair, B, for its
    # move (1.4 m against 1.6 m), and A at its new place is reported new
    g, changes, a_id, _ = pass_with_return_beside(gone_known=False)
    assert np.allclose(g.nodes[a_id].position[:2], [1.5, 0.1])
    assert all(c.back_of is None for c in changes)


def test_the_place_a_node_left_when_its_removal_was_paired_as_a_move_is_a_place_gone_from(tmp_path):
    """Seed 9201: pass 3 removed chair-11 on its misses and paired the removal with chair-13's
    arrival 6.3 m off (one look), so chair-11's node stood at chair-13's place. Chair-11 came
    back in pass 4: an object of that look new where the node was removed is another one back."""
    def removal(nid: int, x: float) -> Event:
        return Event("removed", nid, "chair", np.array([x, 0.0, 0.45]), 2, 5.0, detail={"misses": 3, "merged": False})

    far, near, gone_twice = node(7, 6.3, 0.0, colour=RED, session=1), node(8, 20.5, colour=RED, session=1), \
        node(9, 40.0, colour=RED, session=1)
    events = {1: [Event("added", n.id, "chair", np.array([x, 0.0, 0.45]), 1, 0.0)
                  for n, x in ((far, 0.0), (near, 20.0), (gone_twice, 30.0))],
              2: [removal(7, 0.0), Event("moved", 7, "chair", far.position, 2, 9.0),  # paired 6.3 m off
                  removal(8, 20.0), Event("moved", 8, "chair", near.position, 2, 9.0),  # 0.5 m: the same place
                  removal(9, 30.0), Event("moved", 9, "chair", gone_twice.position, 2, 9.0)]}
    gone_twice.state = "removed"  # no longer on the map: it leaves no place (nor is its last event a removal)
    with SiteStore(tmp_path / "site.db") as store:
        for n in (1, 2):
            store.begin_session(n, {"stamp": 0.0})
            store.record(events[n], [far, near, gone_twice] if n == 1 else [])
            store.end_session(n, "succeeded", {"stamp": 10.0})
        gone = gone_before(store, 3)
    assert [(g.id, g.position[0]) for g in gone] == [(7, 0.0)]  # where node 7 was removed, with its look
    assert np.allclose(gone[0].colour, RED) and gone[0].state == "removed"
    # pass 3: a red chair new where node 7 was removed is another one back, and no other red
    # chair's removal pairs with it; node 7 itself may go back there
    arrival = node(20, 0.1, colour=RED)
    assert [(a.id, g.id) for a, g in brought_back([arrival], gone, 0.35, 0.04)] == [(20, 7)]


def test_a_node_missing_where_it_stands_may_go_back_to_the_place_it_left():
    # node 0 was removed at (0, 0) in pass 2 and paired with an arrival at (2.5, 0); in pass 3
    # its place is empty and a chair of its look stands at (0.1, 0): the node gone back
    params = AssociationParams(confirm_misses=1, confirm_detections=1)
    moved = node(0, 2.5, colour=RED, session=1)
    others = [node(1 + k, -10.0 * (k + 1), 30.0, colour=c, session=1) for k, c in enumerate((BLUE, GREY, GREEN))]
    g = ObjectGraph(params, [moved, *others])
    left = [Node(0, "chair", np.array([0.0, 0.0, 0.45]), 0.9, 1, 2, observations=10, colour=RED, state="removed")]
    g.policy.gone = left
    history = [Event("added", v.id, "chair", v.position.copy(), 1, 0.0) for v in (moved, *others)]
    history += g.associate([Observation("chair", np.array([0.1, 0.0, 0.45]), 0.9, 500, colour=RED)], [], 3, 10.0)
    for k in range(6):  # node 0's place in view, nothing there
        history += g.associate([], [0] if 0 in g.nodes and g.nodes[0].position[0] > 2.0 else [], 3, 11.0 + k)
    history += g.pair_relocations(3, 40.0, gone=left)
    changes = net_changes(history, 2, lambda _c: 0.7)
    assert [(c.kind, c.node_id, c.back_of) for c in changes] == [("moved", 0, None)]
    assert np.allclose(g.nodes[0].position[:2], [0.1, 0.0])
