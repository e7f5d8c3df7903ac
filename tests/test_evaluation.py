"""Object-level evaluation: matching, scores, JSON (CONTRACTS.md section 4) and tables."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bomc_bt.evaluation import (
    counts_table,
    counts_table_data,
    evaluate,
    scores_table,
    scores_table_data,
    to_json,
)
from bomc_bt.graph import Node


def n(i: int, cat: str, x: float, y: float = 0.0) -> Node:
    return Node(i, cat, np.array([x, y, 0.0]), 0.9, 1, 1)


def gt(cat: str, x: float, y: float = 0.0) -> tuple[str, np.ndarray]:
    return cat, np.array([x, y, 0.0])


def test_two_nodes_on_one_object_are_one_tp_and_one_fp():
    r = evaluate([n(0, "chair", 0.1), n(1, "chair", -0.2)], [gt("chair", 0.0)], 0.7, 1)
    c = r.classes["chair"]
    assert (c.gt, c.mapped, c.tp, c.fp, c.fn) == (1, 2, 1, 1, 0)
    assert c.precision == 0.5 and c.recall == 1.0 and c.f1 == pytest.approx(2 / 3)
    assert [(m.node_id, m.gt_index) for m in r.matches] == [(0, 0)]  # the nearer node


def test_matching_is_maximum_and_independent_of_node_order():
    # greedy-by-node-order would give node 0 the GT at 0.5 and leave the GT at -0.4 unmatched
    nodes = [n(0, "door", 0.0), n(1, "door", 0.9)]
    truth = [gt("door", 0.5), gt("door", -0.4)]
    for order in (nodes, nodes[::-1]):
        c = evaluate(order, truth, 0.6, 1).classes["door"]
        assert (c.tp, c.fp, c.fn) == (2, 0, 0)


def test_ties_are_broken_deterministically():
    nodes = [n(3, "bin", 0.0), n(7, "bin", 1.0)]
    truth = [gt("bin", 0.5)]  # equidistant from both nodes
    a = evaluate(nodes, truth, 0.7, 1)
    b = evaluate(nodes[::-1], truth, 0.7, 1)
    assert [(m.node_id, m.gt_index) for m in a.matches] == [(m.node_id, m.gt_index) for m in b.matches]
    assert (a.classes["bin"].tp, a.classes["bin"].fp) == (1, 1)


def test_class_without_ground_truth_and_class_never_mapped():
    r = evaluate([n(0, "umbrella", 0.0)], [gt("cabinet", 5.0), gt("cabinet", 9.0)], lambda c: 0.7, 3)
    u, cab = r.classes["umbrella"], r.classes["cabinet"]
    assert (u.gt, u.tp, u.fp, u.fn, u.precision, u.recall) == (0, 0, 1, 0, 0.0, None)
    assert u.f1 == 0.0  # the paper prints 0.00 for "Trash Bin" with TP 0 / FP 1 / FN 0
    assert (cab.mapped, cab.tp, cab.fn, cab.precision, cab.recall, cab.f1) == (0, 0, 2, None, 0.0, 0.0)
    assert (r.overall.tp, r.overall.fp, r.overall.fn) == (0, 1, 2)


def test_empty_everything_and_removed_nodes_are_ignored():
    r = evaluate([], [], 0.7, 2)
    assert r.classes == {} and (r.overall.precision, r.overall.recall, r.overall.f1) == (None, None, None)
    assert to_json(r)["overall"]["f1"] is None
    gone = n(0, "chair", 0.0)
    gone.state = "removed"
    assert evaluate([gone], [], 0.7, 2).classes == {}


def test_category_thresholds_and_json_contract():
    nodes = [n(0, "chair", 0.0), n(1, "chair", 3.0), n(2, "door", 0.0, 5.0)]
    truth = [gt("chair", 0.5), gt("chair", 3.6), gt("door", 0.3, 5.0)]
    r = evaluate(nodes, truth, {"chair": 0.55, "door": 0.2}.get, 2)
    out = to_json(r)
    json.dumps(out)  # JSON-able
    assert out["session"] == 2
    assert out["classes"]["chair"] == {"gt": 2, "mapped": 2, "tp": 1, "fp": 1, "fn": 1,
                                       "precision": 0.5, "recall": 0.5, "f1": 0.5}
    assert out["classes"]["door"]["f1"] == 0.0
    assert out["overall"] == {"gt": 3, "mapped": 3, "tp": 1, "fp": 2, "fn": 2,
                              "precision": 0.333, "recall": 0.333, "f1": 0.333}


def test_tables_match_the_papers_layout():
    mapped = [n(0, "chair", 0), n(1, "chair", 2), n(2, "tv", 9)]
    s1 = evaluate(mapped, [gt("chair", 0), gt("chair", 2)], 0.7, 1)
    s2 = evaluate([n(0, "chair", 0)], [gt("chair", 0)], 0.7, 2)
    counts = counts_table_data({2: s2, 1: s1})
    assert counts["reference_session"] == 1
    assert counts["classes"]["chair"] == [{"session": 1, "gt": 2, "map": 2},
                                          {"session": 2, "delta_gt": -1, "delta_map": -1}]
    assert counts["classes"]["tv"][1] == {"session": 2, "delta_gt": 0, "delta_map": -1}
    md = counts_table([s1, s2])
    assert "| Class | S1 GT | S1 Map | S2 ΔGT | S2 ΔMap |" in md and "| chair | 2 | 2 | -1 | -1 |" in md
    scores = scores_table_data([s1, s2])
    assert scores["classes"]["tv"][1]["f1"] is None
    md = scores_table([s1, s2])
    assert "| tv | 0 | 1 | 0 | 0.00 | 0 | 0 | 0 | - |" in md
    assert "| chair | 2 | 0 | 0 | 1.00 | 1 | 0 | 0 | 1.00 |" in md
    assert counts_table([]) == "(no sessions)\n"


def test_large_crowded_category_is_fast_and_maximal():
    rng = np.random.default_rng(0)
    truth_xy = rng.uniform(0, 15, (300, 2))
    nodes = [n(i, "door", *(xy + rng.normal(0, 0.2, 2))) for i, xy in enumerate(truth_xy)]
    r = evaluate(nodes, [gt("door", *xy) for xy in truth_xy], 0.7, 1)
    assert r.classes["door"].tp == 300  # every node has its own object within reach
