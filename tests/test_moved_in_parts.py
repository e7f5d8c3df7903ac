"""A big object carried across the floor and seen at its new place in two parts, never both
in one frame: the parts become one node, and that node is the object moved, its id kept
(bomc_bt.graph.parts.parts_of_gone, bomc_bt.graph.looks.coincidence)."""

from __future__ import annotations

import numpy as np

from bomc_bt.graph import AssociationParams, ObjectGraph, Observation
from bomc_bt.net_changes import net_changes

BLUE, RED, GREEN, ORANGE = (0.200, 0.233), (0.653, 0.184), (0.217, 0.522), (0.541, 0.351)


def seen(category: str, x0: float, x1: float, colour, truncated: bool = False, y0: float = -0.42,
         y1: float = 0.42) -> Observation:
    """A view of the floor box (x0, y0)-(x1, y1), its centre in the middle."""
    return Observation(category, np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.4]), 0.9, 500,
                       0.5 * max(x1 - x0, y1 - y0), box=np.array([x0, y0, x1, y1]), truncated=truncated,
                       colour=colour)


def carried_in_parts(ends: list[list[Observation]], sofas_elsewhere: int = 0) -> tuple[ObjectGraph, list, int]:
    """Pass 1 sees a blue 1.8 m sofa whole at the origin, and chairs of other colours far
    off (and ``sofas_elsewhere`` more blue sofas). In pass 2 the sofa's place is empty and
    the frames ``ends`` show sofa views 20 m away. Returns the graph after the pass ended,
    the net changes and how many sofa nodes stood just before it ended."""
    params = AssociationParams(confirm_misses=1, confirm_detections=1)
    first = ObjectGraph(params)
    history = []
    for t in (0.0, 1.0, 2.0):
        frame = [seen("sofa", -0.9, 0.9, BLUE)]
        frame += [seen("chair", -0.25, 0.25, c, y0=29.75 + 3 * k, y1=30.25 + 3 * k)
                  for k, c in enumerate((RED, GREEN, ORANGE))]
        frame += [seen("sofa", -0.9, 0.9, BLUE, y0=-20.42 - 3 * k, y1=-19.58 - 3 * k) for k in range(sofas_elsewhere)]
        history += first.associate(frame, sorted(first.nodes), 1, t)
    g = ObjectGraph(params, list(first.nodes.values()))
    t = 10.0
    for frame in ends:
        history += g.associate(frame, [], 2, t)
        t += 1.0
    for _ in range(12):  # the camera looks at the origin, where the sofa stood
        there = [v.id for v in g.nodes.values() if np.hypot(*v.position[:2]) < 0.1]
        history += g.associate([], there, 2, t)
        t += 1.0
    standing = sum(v.category == "sofa" for v in g.nodes.values())
    history += g.pair_relocations(2, t + 10.0)
    return g, [(c.kind, c.node_id) for c in net_changes(history, 1, lambda _c: 0.7)], standing


def test_a_sofa_carried_away_and_seen_there_end_by_end_is_one_sofa_moved():
    # Traced on a generated 36 x 28 m office (seed 7901, pass 2): the only sofa, carried
    # 17 m, was seen at its new place as a 0.55 m and a 1.28 m part, never in one frame; it
    # was reported taken away, and two sofas brought in.
    near, far = seen("sofa", 20.0, 20.55, BLUE, truncated=True), seen("sofa", 21.3, 21.8, BLUE, truncated=True)
    g, changes, standing = carried_in_parts([[near]] * 3 + [[far]] * 3)
    assert standing == 2  # the two ends (the old node is gone)
    sofas = [v for v in g.nodes.values() if v.category == "sofa"]
    assert changes == [("moved", 0)] and [v.id for v in sofas] == [0]
    assert np.allclose(sofas[0].position[:2], [20.9, 0.0], atol=0.05)


def test_parts_seen_in_one_frame_or_longer_than_the_sofa_stay_two_sofas():
    near, far = seen("sofa", 20.0, 20.55, BLUE, truncated=True), seen("sofa", 21.3, 21.8, BLUE, truncated=True)
    _, changes, _ = carried_in_parts([[near, far]] * 3)  # one frame shows two sofas
    assert sorted(k for k, _ in changes) == ["added", "added", "removed"]
    apart = seen("sofa", 21.95, 22.45, BLUE, truncated=True)  # together 2.45 m: longer than the sofa
    _, changes, _ = carried_in_parts([[near]] * 3 + [[apart]] * 3)
    assert sorted(k for k, _ in changes) == ["added", "added", "removed"]
    red = seen("sofa", 21.3, 21.8, RED, truncated=True)  # the far part another colour: another sofa
    _, changes, _ = carried_in_parts([[near]] * 3 + [[red]] * 3)
    assert sorted(k for k, _ in changes) == ["added", "moved"]  # the blue one is the sofa, by its look


def test_the_only_sofa_of_the_floor_keeps_its_id_by_its_look_where_two_alike_are_a_guess():
    whole = [[seen("sofa", 20.0, 21.8, BLUE)]] * 3
    _, changes, _ = carried_in_parts(whole)
    assert changes == [("moved", 0)]
    # two more blue sofas stand on the floor: a blue sofa gone and one new may be two sofas
    _, changes, _ = carried_in_parts(whole, sofas_elsewhere=2)
    assert sorted(k for k, _ in changes) == ["added", "removed"]
