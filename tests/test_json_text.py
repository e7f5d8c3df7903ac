"""The resume point a pass encodes piecewise is the text ``json.dumps`` writes (json_text).

A pass commits its resume point every frame with each view polygon encoded once
(:class:`bomc_bt.pass_resume.ResumeText`); a resume parses that text back. Any byte of
difference from encoding the whole point (a float written differently, a polygon lost
when the pass starts a new list at a waypoint) would resume a different pass.
"""

from __future__ import annotations

import json

import numpy as np

from bomc_bt.json_text import AppendOnlyJSON, encoded_object, to_jsonable


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
