"""Text a pass encodes piecewise is the text ``json.dumps`` writes (json_text).

A pass commits its resume point every frame with each view polygon and each unchanged
graph entry encoded once (:mod:`bomc_bt.resume_rows`, whose tests run whole passes); a
resume parses that text back. Any byte of difference from encoding the whole value (a
float written differently, a polygon lost when the pass starts a new list at a waypoint)
would resume a different pass.
"""

from __future__ import annotations

import json

import numpy as np

from bomc_bt.json_text import AppendOnlyJSON, JSONMemo, dumps_raw


def polygons(rng: np.random.Generator, count: int) -> list[list[list[float]]]:
    return [(rng.normal(size=(int(rng.integers(3, 12)), 2)) * 40.0).tolist() for _ in range(count)]


def test_a_growing_list_encodes_as_json_dumps_after_every_append_and_every_new_list():
    rng = np.random.default_rng(7)
    encoder = AppendOnlyJSON()
    items: list = []
    for frame in range(60):
        if frame in (20, 41):
            items = []  # a waypoint's commit starts a new list
        if frame == 50:
            items = polygons(rng, 5)  # a resume puts back a saved list
        items.extend(polygons(rng, int(rng.integers(0, 3))))
        assert encoder.text(items) == json.dumps(items)
    shorter = items[:2]
    assert encoder.text(shorter) == json.dumps(shorter)


def test_a_memo_keeps_an_entry_s_text_while_its_value_is_the_same_object():
    memo = JSONMemo()
    box, seen = np.array([0.5, 1.0]), 12.5
    assert memo.map("m", [(3, box), (4, seen)]).text == json.dumps({"3": [0.5, 1.0], "4": 12.5})
    box[0] = 9.0  # changed in place: the owner broke the contract, and the old text stays
    assert memo.map("m", [(3, box), (4, 12.5)]).text == '{"3": [0.5, 1.0], "4": 12.5}'
    moved = np.array([2.0, 1.0])  # replaced: encoded again; an equal float keeps its text
    assert memo.map("m", [(4, float("12.5")), (3, moved)]).text == '{"4": 12.5, "3": [2.0, 1.0]}'
    assert memo.map("m", [(4, 0.0)]).text == '{"4": 0.0}'
    assert memo.map("m", [(4, -0.0)]).text == '{"4": -0.0}'  # equal to 0.0, written otherwise
    items = [("chair", np.array([1.0, 2.0]), 0.5)]
    assert memo.list("l", items, lambda e: [e[0], e[1].tolist(), e[2]]).text == '[["chair", [1.0, 2.0], 0.5]]'
    assert memo.list("l", []).text == "[]" and memo.map("m", []).text == "{}"
    nested = {"a": memo.map("n", [(1, 2.5)]), "b": [1, 2], "c": {"d": None}}
    assert dumps_raw(nested) == json.dumps({"a": {"1": 2.5}, "b": [1, 2], "c": {"d": None}})
