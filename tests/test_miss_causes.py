"""The recall breakdown: every missed object gets the cause an engineer would fix."""

from __future__ import annotations

import numpy as np

from bomc_bt.evaluation import evaluate
from bomc_bt.graph import Node
from bomc_bt.miss_causes import cause_counts, miss_causes


def node(i: int, category: str, x: float, y: float) -> Node:
    return Node(i, category, np.array([x, y, 0.4]), 0.9, 1, 1)


def test_each_missed_object_gets_its_cause():
    truth = [("chair", np.array([0.0, 0.0, 0.4])), ("chair", np.array([0.8, 0.0, 0.4])),  # one node for both
             ("chair", np.array([5.0, 0.0, 0.4])),  # removed though still there
             ("door", np.array([10.0, 0.0, 1.0])),  # mapped as a table
             ("table", np.array([15.0, 0.0, 0.4])),  # mapped 1 m off
             ("sofa", np.array([20.0, 0.0, 0.4]))]  # nothing near
    nodes = [node(1, "chair", 0.35, 0.0), node(2, "table", 10.1, 0.0), node(3, "table", 16.0, 0.0)]
    removed = [("chair", np.array([5.1, 0.0, 0.4]))]
    result = evaluate(nodes, truth, 0.7, 1)
    misses = miss_causes(result, nodes, removed, truth, lambda _c: 0.7)
    assert {(m.category, m.cause) for m in misses} == {
        ("chair", "merged"), ("chair", "removed"), ("door", "mislabelled"), ("table", "displaced"), ("sofa", "unseen")}
    assert cause_counts(misses) == {"removed": 1, "mislabelled": 1, "displaced": 1, "merged": 1, "unseen": 1}


def test_a_perfect_map_has_no_misses():
    truth = [("chair", np.array([0.0, 0.0, 0.4]))]
    nodes = [node(1, "chair", 0.1, 0.0)]
    assert miss_causes(evaluate(nodes, truth, 0.7, 1), nodes, [], truth, lambda _c: 0.7) == []
