"""The object graph's seams: floor boxes, the public mutation API, and the policies behind it."""

from __future__ import annotations

import numpy as np
import pytest

from bomc_bt.graph import (
    AssociationParams,
    Node,
    ObjectGraph,
    Observation,
    PaperPolicy,
    RobustPolicy,
    make_policy,
)
from bomc_bt.graph.footprints import box_gap, box_or_none, inside, overlapping, union


def node(i: int, category: str, x: float, y: float, z: float = 0.5) -> Node:
    return Node(i, category, np.array([x, y, z]), 0.9, 1, 1)


def obs(category: str, x: float, y: float, z: float = 0.5, box=None) -> Observation:
    return Observation(category, np.array([x, y, z]), 0.8, 200, 0.0, box)


# ---------------------------------------------------------------- footprints
def test_boxes_combine_contain_and_measure_gaps():
    table, chair = np.array([0.0, 0.0, 1.2, 0.8]), np.array([1.5, 0.0, 2.0, 0.4])
    np.testing.assert_array_equal(union(table, chair), [0.0, 0.0, 2.0, 0.8])
    assert union(None, chair) is chair and union(table, None) is table
    assert inside(np.array([0.1, 0.1, 1.25, 0.5]), table, pad=0.1)
    assert not inside(chair, table, pad=0.1)
    assert box_gap(table, chair) == pytest.approx(0.3) and box_gap(table, table) == 0.0
    assert box_or_none([1.0, 0.0, 0.0, 1.0]) is None  # inverted
    assert box_or_none([0.0, 0.0, np.inf, 1.0]) is None


def test_overlap_is_a_share_of_the_smaller_box_and_nan_never_overlaps():
    boxes = np.array([[0.0, 0.0, 2.0, 2.0], [1.9, 0.0, 4.0, 2.0], [np.nan] * 4, [0.5, 0.5, 0.5, 1.5]])
    view = np.array([0.0, 0.0, 1.0, 1.0])  # half of it lies on box 0, none on box 1
    assert overlapping(boxes, view, 0.5).tolist() == [True, False, False, True]  # 3: a sliver on the view
    assert overlapping(boxes, view, 0.0).tolist() == [True, False, False, True]


# ------------------------------------------------------------ mutation API
def test_mutations_keep_queries_and_change_log_in_step():
    g = ObjectGraph(AssociationParams(), [node(0, "chair", 0, 0), node(1, "chair", 5, 0)])
    assert g.drain_changed() == []  # loading is no change
    g.relocate(g.nodes[0], np.array([9.0, 9.0, 0.5]))
    assert g.nearest("chair", np.array([0.0, 0.0, 0.5]))[0].id == 1  # found where it is, not where it was
    assert [v.id for v in g.nodes_in_polygon(np.array([[8, 8], [10, 8], [10, 10]]))] == [0]
    event = g.remove(g.nodes[1], 2, 1.0)
    assert (event.kind, event.node_id, 1 in g.nodes) == ("removed", 1, False)
    assert [v.id for v in g.removed_this_session()] == [1]
    [moved] = g.removed_this_session()
    g.restore(moved, np.array([4.0, 0.0, 0.5]))
    assert g.within("chair", np.array([4.0, 0.0, 0.5]), 0.1)[0][0] is moved
    assert [v.id for v in g.drain_changed()] == [0, 1] and g.drain_changed() == []


def test_misses_count_once_per_interval_and_a_touch_clears_them():
    g = ObjectGraph(AssociationParams(), [node(0, "chair", 0, 0)])
    v = g.nodes[0]
    assert g.miss(v, 2, 0.0, interval=0.5) and not g.miss(v, 2, 0.3, interval=0.5)
    assert g.miss(v, 2, 0.6, interval=0.5) and v.misses == 2 and g.pending() == [0]
    assert g.miss(v, 3, 0.0, interval=0.5)  # a new session: a new miss
    g.touch(v, 3, 1.0, reset_misses=False)
    assert v.misses == 3 and g.pending() == [0] and v.observations == 2
    g.touch(v, 3, 2.0)
    assert v.misses == 0 and g.pending() == [] and (v.last_session, v.last_seen) == (3, 2.0)


def test_a_merged_node_is_never_a_move_candidate():
    g = ObjectGraph(AssociationParams(), [node(0, "chair", 0, 0), node(1, "chair", 1, 0)])
    g.remove(g.nodes[0], 2, 0.0, merged=True)
    g.remove(g.nodes[1], 2, 0.0)
    assert [v.id for v in g.removed_this_session()] == [1]
    g.begin(3, [])
    assert g.removed_this_session() == []  # an earlier session's removals are gone for good


# ---------------------------------------------------------------- policies
def test_the_mode_picks_the_policy_once():
    assert isinstance(make_policy(AssociationParams(mode="paper")), PaperPolicy)
    assert isinstance(ObjectGraph(AssociationParams()).policy, RobustPolicy)
    # robust distances weigh height by vertical_weight, the paper's are plain 3D
    assert ObjectGraph(AssociationParams(vertical_weight=0.25)).index.scale.tolist() == [1.0, 1.0, 0.25]
    assert ObjectGraph(AssociationParams(mode="paper")).index.scale.tolist() == [1.0, 1.0, 1.0]


@pytest.mark.parametrize("mode", ["paper", "robust"])
def test_a_policy_run_directly_on_a_graph_logs_every_change(mode):
    params = AssociationParams(mode=mode, confirm_misses=1, confirm_detections=1)
    g = ObjectGraph(params, [node(0, "chair", 0, 0), node(1, "bin", 4, 0)])
    policy = PaperPolicy(params) if mode == "paper" else RobustPolicy(params)
    events = policy.associate(g, [obs("chair", 0.2, 0), obs("cup", 2, 2)], [0, 1, 1, 7], 2, 1.0)
    assert [(e.kind, e.node_id) for e in events if e.kind != "updated"] == [("removed", 1), ("added", 2)]
    assert [v.id for v in g.drain_changed()] == [0, 1, 2]
    assert g.nearest("cup", np.array([2.0, 2.0, 0.5]))[0].id == 2 and g.next_id == 3
    moved_towards = g.nodes[0].position[0] > 0.0
    assert moved_towards == (mode == "robust")  # the paper never moves a matched node
