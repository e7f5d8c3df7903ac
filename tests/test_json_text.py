"""The resume point a pass encodes piecewise is the text ``json.dumps`` writes (json_text).

A pass commits its resume point every frame with each view polygon encoded once
(:class:`bomc_bt.pass_resume.ResumeText`); a resume parses that text back. Any byte of
difference from encoding the whole point (a float written differently, a polygon lost
when the pass starts a new list at a waypoint) would resume a different pass.
"""

from __future__ import annotations

import json

import numpy as np

from bomc_bt import monitoring, run
from bomc_bt.json_text import AppendOnlyJSON, JSONMemo, dumps_raw, encoded_object, to_jsonable
from bomc_bt.officegen import OfficeParams, generate_office
from bomc_bt.pass_resume import resume_key, resume_point


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


def test_an_encoded_point_equals_json_dumps_of_the_whole_point():
    rng = np.random.default_rng(3)
    fov, looked = polygons(rng, 4), polygons(rng, 3) + [[[float("nan"), 1e-300], [2.5, -0.0], [1e17, 3.0]]]
    robot = {"steps": np.int64(12), "pose": np.array([1.25, -3.5, 0.1]), "rng": {"state": 2**80}}
    graph = {"last_seen": {"3": 12.5}, "reported": {"4": [1.0, 2.0, 0.3]}, "extents": None}
    point = {"robot": robot, "graph": graph, "frames": 17, "fov_since": fov, "looked_since": looked}
    parts = {"robot": json.dumps(robot, default=to_jsonable), "graph": json.dumps(graph, default=to_jsonable),
             "frames": "17", "fov_since": AppendOnlyJSON().text(fov), "looked_since": AppendOnlyJSON().text(looked)}
    text = encoded_object(parts).text
    assert text == json.dumps(point, default=to_jsonable)
    assert json.loads(text)["fov_since"] == fov


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


def test_every_frame_of_two_passes_writes_the_resume_point_json_dumps_would(tmp_path, monkeypatch):
    """The graph's maps are written from the memo: any value changed in place would part the
    memo's text from the state (a resumed pass would restore a stale entry)."""
    world = tmp_path / "office.yaml"
    generate_office(OfficeParams(width=16, height=12, seed=3, sessions=2), world)
    config = run.build_config()
    site = tmp_path / "site"
    assert run.run_build(world, site, seed=0, config=config).succeeded
    frames, differ = [], []
    original = monitoring.frame_progress

    def checked(perception, robot):
        progress = original(perception, robot)
        text = progress[resume_key(perception.session)].text
        plain = json.dumps(resume_point(perception, robot), default=to_jsonable)
        frames.append(len(perception.graph.nodes))
        if text != plain:
            differ.append(perception.frames)
        return progress

    monkeypatch.setattr(monitoring, "frame_progress", checked)
    for session in (1, 2):
        assert run.run_monitor(world, site, session, seed=session, config=config).succeeded
    assert len(frames) > 100 and max(frames) >= 10
    assert differ == []
