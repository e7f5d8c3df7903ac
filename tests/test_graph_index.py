"""The spatial index answers like a scan over every node, whatever was inserted, moved or deleted."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bomc_bt.graph import SpatialIndex, points_in_polygon

CATS = ["a", "b"]
coord = st.floats(-4, 4, allow_nan=False)
position = st.tuples(coord, coord, st.floats(0, 2)).map(np.array)
# an operation: ("put", id, category, position) inserts or moves, ("drop", id) deletes
op_st = st.one_of(
    st.tuples(st.just("put"), st.integers(0, 150), st.sampled_from(CATS), position),
    st.tuples(st.just("drop"), st.integers(0, 150)),
)
# enough nodes that queries read grid cells rather than every member of a category
ops_st = st.tuples(st.lists(position, min_size=40, max_size=120), st.lists(op_st, max_size=40)).map(
    lambda t: [("put", i, CATS[i % 2], p) for i, p in enumerate(t[0])] + t[1])
SCALE = np.array([1.0, 1.0, 0.5])


def replay(ops) -> tuple[SpatialIndex, dict[int, tuple[str, np.ndarray]]]:
    """An index (small capacity and cells, so slots are reused and arrays grow) and the truth."""
    index = SpatialIndex(0.5, SCALE, capacity=2)
    truth: dict[int, tuple[str, np.ndarray]] = {}
    for op in ops:
        node_id = op[1]
        if op[0] == "put" and node_id in truth:
            category, old = truth[node_id]
            index.move(node_id, category, old, op[3])
            truth[node_id] = (category, op[3])
        elif op[0] == "put":
            index.insert(node_id, op[2], op[3], None)
            truth[node_id] = (op[2], op[3])
        elif node_id in truth:
            index.delete(node_id, truth[node_id][0], truth[node_id][1])
            del truth[node_id]
    return index, truth


def scaled_d2(a: np.ndarray, b: np.ndarray) -> float:
    """Squared distance on (x, y, 0.5 z), computed as the index does, so boundaries agree exactly."""
    d = a * SCALE - b * SCALE
    return float(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])


@settings(max_examples=200, deadline=None)
@given(ops_st, position, st.sampled_from(CATS), st.floats(0.05, 1.5))
def test_within_and_nearest_equal_brute_force(ops, p, category, radius):
    index, truth = replay(ops)
    ids, d2 = index.within(category, p, radius)
    candidates = sorted((scaled_d2(q, p), i) for i, (c, q) in truth.items() if c == category)
    expected = [(d, i) for d, i in candidates if d <= radius * radius]
    assert list(ids) == [i for _, i in expected] and d2.tolist() == [d for d, _ in expected]
    found, dist = index.nearest(category, p)
    if candidates:
        assert found == candidates[0][1] and dist == math.sqrt(candidates[0][0])
    else:
        assert (found, dist) == (-1, math.inf)
    found, _ = index.nearest(category, p, max_distance=radius)
    near_enough = [i for d, i in candidates if math.sqrt(d) <= radius]
    assert found == (near_enough[0] if near_enough else -1)


@settings(max_examples=200, deadline=None)
@given(ops_st,
       st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), min_size=3, max_size=6).map(np.array))
def test_polygon_query_equals_brute_force(ops, polygon):
    index, truth = replay(ops)
    inside = [i for i, (_, q) in truth.items() if points_in_polygon(q[None, :2], polygon)[0]]
    assert sorted(index.ids_in_polygon(polygon).tolist()) == sorted(inside)


def test_a_nodes_own_gate_and_footprint_widen_what_matches_it():
    index = SpatialIndex(0.7, SCALE)
    index.insert(0, "table", np.array([0.0, 0.0, 0.5]), None)
    index.insert(1, "table", np.array([3.0, 0.0, 0.5]), np.array([2.0, -0.5, 4.0, 0.5]))
    query = ([np.array([1.0, 0.0, 0.5])], [3.0], [0.7])
    assert [ids.tolist() for ids, _ in index.within_many(["table"], *query)] == [[]]
    index.widen_gate(0, 1.2)  # the table showed itself big: a view 1 m off is still it
    index.widen_gate(0, 0.3)  # gates never shrink
    assert [ids.tolist() for ids, _ in index.within_many(["table"], *query)] == [[0]]
    # a view whose box lies on node 1's footprint matches it however far the centroids are
    view_box = [np.array([1.9, -0.2, 2.3, 0.2])]
    matched = index.within_many(["table"], *query, boxes=view_box, overlap=0.5)
    assert sorted(matched[0][0].tolist()) == [0, 1]
    index.set_box(1, None)
    assert index.within_many(["table"], *query, boxes=view_box, overlap=0.5)[0][0].tolist() == [0]
    assert index.within_many(["chair"], *query)[0][0].tolist() == []
