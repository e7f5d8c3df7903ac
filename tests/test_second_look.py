"""Misses from one place, pass after pass (``association.miss_spacing``; bomc_bt.graph.evidence).

With ``miss_spacing`` a run of misses from one place is one look and waits for a second look
from elsewhere. Where the refresh tour finds no such place (a chair taken from between a table
and a wall, seen only from one stop), the next pass's run from that stop is the second look,
at another time: the chair goes a pass late, not never (36 x 28 m office, seed 10101: it
stayed on the map for ten passes, 13 clear misses a pass).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bomc_bt.graph import AssociationParams, Node, ObjectGraph, Observation
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitoring import Perception
from bomc_bt.pass_resume import earlier_looks
from bomc_bt.perception.projection import ProjectionParams
from bomc_bt.resume_rows import resume_key
from bomc_bt.store import SiteStore

SPACED = replace(AssociationParams(confirm_detections=1), miss_spacing=0.2)
STOP = np.array([0.0, -1.7])  # the one place the chair's place is seen from


def chair(node_id: int = 0) -> Node:
    return Node(node_id, "chair", np.array([0.0, 0.0, 0.45]), 0.9, 1, 1, observations=14)


def misses_from_the_stop(g: ObjectGraph, session: int, frames: int = 13, start: float = 0.0) -> list[str]:
    """``frames`` clear misses half a second apart, the robot turning on the spot; the events' kinds."""
    events = []
    for k in range(frames):
        events += g.associate([], [0], session, start + 0.5 * k, place=STOP + [0.01 * (k % 3), 0.0])
    return [e.kind for e in events]


def test_a_node_a_pass_left_awaiting_a_second_look_goes_at_the_next_pass_run_from_the_same_place():
    first = ObjectGraph(SPACED, [chair()])
    assert misses_from_the_stop(first, 2) == []  # one look: kept, waiting
    assert [n.id for n, _ in first.awaiting_second_look()] == [0]
    saved = first.pass_state()["second_looks"]
    assert saved == {"before": [], "awaiting": [0]}
    second = ObjectGraph(SPACED, [chair()])
    second.evidence.looked_before = set(saved["awaiting"])
    assert misses_from_the_stop(second, 3) == ["removed"]  # the second look, a pass later
    assert second.pass_state()["second_looks"] == {"before": [], "awaiting": []}
    alone = ObjectGraph(SPACED, [chair()])  # no earlier look: the same run only waits again
    assert misses_from_the_stop(alone, 3) == [] and 0 in alone.nodes


def test_a_detection_ends_the_earlier_look_and_a_resumed_pass_keeps_it():
    seen = ObjectGraph(SPACED, [chair()])
    seen.evidence.looked_before = {0}
    seen.associate([Observation("chair", np.array([0.0, 0.0, 0.45]), 0.9)], [0], 3, 0.0, place=STOP)
    assert misses_from_the_stop(seen, 3, start=1.0) == []  # the misses were the detector's: one look again
    waiting = ObjectGraph(SPACED, [chair()])
    waiting.evidence.looked_before = {0}
    resumed = ObjectGraph(SPACED, [chair()])
    resumed.restore_pass_state(waiting.pass_state(), {})  # a pass killed and resumed
    assert resumed.evidence.looked_before == {0}
    assert misses_from_the_stop(resumed, 3) == ["removed"]


def test_a_pass_starts_with_the_looks_the_latest_earlier_pass_ended_with(tmp_path):
    first = ObjectGraph(SPACED, [chair(), chair(1)])
    misses_from_the_stop(first, 1)
    first.evidence.looked_before = {1}  # carried from before pass 1 and never detected since
    with SiteStore(tmp_path / "site.db") as store:
        assert earlier_looks(store, 1) == set()
        store.begin_session(1, {"stamp": 0.0})
        store.end_session(1, "completed", {"stamp": 9.0}, (), {resume_key(1): {"graph": first.pass_state()}})
        assert earlier_looks(store, 2) == {0, 1}
        grid = OccupancyGrid(np.zeros((50, 50), dtype=np.int8), 0.1, (-2.5, -2.5))
        graph = ObjectGraph(SPACED, [chair()])  # node 1 is gone from the map since
        Perception(None, None, ["chair"], ProjectionParams(), graph, store, 2, grid)
        assert graph.evidence.looked_before == {0}
        assert misses_from_the_stop(graph, 2) == ["removed"]
