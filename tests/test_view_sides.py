"""Detection rates per viewing side, carried over passes (bomc_bt.graph.view_sides)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bomc_bt.graph import AssociationParams, Node, ObjectGraph, Observation
from bomc_bt.graph.view_sides import SideRates, side_of
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitoring import Perception
from bomc_bt.pass_resume import earlier_sides
from bomc_bt.perception.projection import ProjectionParams
from bomc_bt.resume_rows import resume_key
from bomc_bt.store import SiteStore

SIDES = AssociationParams(confirm_detections=1)  # the defaults: 8 sides, half the earlier passes' counts
ALONG = np.array([-3.0, 0.9])  # along the corridor: the door on its side wall seen edge-on
FACING = np.array([0.0, -2.0])  # across the corridor, facing the door


def door(seen: int = 86) -> Node:
    return Node(0, "door", np.array([0.0, 0.0, 1.0]), 0.9, 1, 1, observations=seen)


def leaf() -> Observation:
    return Observation("door", np.array([0.0, 0.0, 1.0]), 0.9)


def first_pass(params: AssociationParams) -> ObjectGraph:
    """Pass 1: face-on views always see the door; from along the corridor two frames in three miss it."""
    g = ObjectGraph(params, [door()])
    t = 0.0
    for _ in range(6):
        for place, seen in ((FACING, True), (ALONG, False), (ALONG, False), (ALONG, True)):
            g.associate([leaf()] if seen else [], [0], 1, t, place=place)
            t += 1.0
    assert 0 in g.nodes
    return g


def next_pass(params: AssociationParams, carried: dict | None) -> ObjectGraph:
    g = ObjectGraph(params, [door(100)])
    g.evidence.sides.carry(carried, set(g.nodes))
    return g


def removed_after(g: ObjectGraph, place: np.ndarray, misses: int, start: float = 100.0) -> bool:
    for k in range(misses):
        g.associate([], [0], 2, start + k, place=place)
    return 0 not in g.nodes


def test_a_door_missed_from_along_its_corridor_before_is_not_removed_by_three_misses_from_there():
    saved = first_pass(SIDES).pass_state()["sides"]
    # without what pass 1 learnt (each pass alone, as before), three edge-on misses remove it
    assert removed_after(next_pass(SIDES, None), ALONG, 3)
    # with it, three are no evidence; a run that long from there still is
    assert not removed_after(next_pass(SIDES, saved), ALONG, 3)
    assert removed_after(next_pass(SIDES, saved), ALONG, SIDES.max_misses)
    # a door taken away is still removed by three misses from where it was always seen
    assert removed_after(next_pass(SIDES, saved), FACING, 3)
    # nor from a side pass 1 never saw it from: that side borrows the door's rate over all sides
    assert not removed_after(next_pass(SIDES, saved), -FACING, 3)
    # side_memory 0: the pass starts afresh
    assert removed_after(next_pass(replace(SIDES, side_memory=0.0), saved), ALONG, 3)


def test_misses_a_removal_ends_are_not_counted_against_the_side():
    """A run that removes the node was the object gone, not the detector missing it: if it
    comes back (moved back in the same pass), that side keeps its rate."""
    g = ObjectGraph(SIDES, [door()])
    assert removed_after(g, ALONG, 3, start=0.0)
    assert g.evidence.sides.counts.get(0) is None
    rates = SideRates(8, 0.5)
    rates.missed(0, 2, 1.0)
    rates.end_run(0, refuted=False)
    assert rates.rate(0, [2], 0.8, 2.0) == 0.8
    rates.missed(0, 2, 1.0)
    rates.end_run(0, refuted=True)
    # a side never seen from borrows the node's rate over all its sides
    assert rates.rate(0, [2], 0.8, 2.0) < rates.rate(0, [3], 0.8, 2.0) < 0.8


def test_sides_are_sectors_of_bearing_from_the_node():
    assert side_of([0.0, 0.0], [1.0, 0.01], 8) == 4 and side_of([0.0, 0.0], [-1.0, -0.01], 8) == 0
    assert side_of([2.0, 2.0], [2.0, 3.0], 8) == 6 and side_of([0.0, 0.0], [0.0, -1.0], 4) == 1


def test_a_pass_starts_from_the_sides_the_latest_earlier_pass_saved(tmp_path):
    saved = first_pass(SIDES).pass_state()["sides"]
    with SiteStore(tmp_path / "site.db") as store:
        assert earlier_sides(store, 1) is None
        store.begin_session(1, {"stamp": 0.0})
        store.end_session(1, "completed", {"stamp": 1.0}, (), {resume_key(1): {"graph": {"sides": saved}}})
        store.begin_session(2, {"stamp": 2.0})  # killed before its first frame: no resume point
        store.end_session(2, "failed", {"stamp": 3.0}, (), {})
        grid = OccupancyGrid(np.zeros((50, 50), dtype=np.int8), 0.1, (0.0, 0.0))
        graph = ObjectGraph(SIDES, [door(100)])
        Perception(None, None, ["door"], ProjectionParams(), graph, store, 3, grid)
        counts = graph.evidence.sides.counts[0]
        assert np.allclose(counts, [0.5 * c for c in saved["counts"]["0"]])
        assert not removed_after(graph, ALONG, 3)
        unsided = ObjectGraph(replace(SIDES, miss_sides=0), [door(100)])
        Perception(None, None, ["door"], ProjectionParams(), unsided, store, 3, grid)
        assert unsided.evidence.sides is None and removed_after(unsided, ALONG, 3)


def test_a_node_that_moved_starts_its_sides_afresh_and_one_found_where_it_stood_keeps_them():
    g = first_pass(SIDES)
    assert removed_after(g, ALONG, 1, start=50.0) is False  # a miss from along the corridor: no run yet
    g.associate([leaf()], [0], 1, 60.0, place=FACING)
    counts = g.evidence.sides.counts[0]
    assert sum(counts[8:]) > 0  # pass 1 learnt that the corridor misses it
    for k in range(SIDES.max_misses):  # gone: removed, then seen 0.1 m off (the same place)
        g.associate([], [0], 1, 70.0 + k, place=FACING)
    assert 0 not in g.nodes
    g.associate([Observation("door", np.array([0.1, 0.0, 1.0]), 0.9)], [], 1, 90.0, place=FACING)
    assert g.nodes[0].state == "present" and sum(g.evidence.sides.counts[0][8:]) > 0
    # gone again a minute later (not moments after a sighting), and found 2 m along the wall: moved
    g.associate([], [0], 1, 151.0, place=FACING)
    for k in range(SIDES.max_misses):
        g.associate([], [0], 1, 152.0 + k, place=FACING)
    g.associate([Observation("door", np.array([2.0, 0.0, 1.0]), 0.9)], [], 1, 180.0, place=FACING)
    assert g.nodes[0].state == "present" and g.evidence.sides.counts.get(0) is None


def door_back_in_pass_3(params: AssociationParams) -> dict:
    """Pass 2 sees the door face-on, then three misses from along its corridor (a side no pass
    had seen it from) remove it; pass 3 finds a door at its place again. The sides pass 3 saves."""
    g = ObjectGraph(params, [door(100)])
    for k in range(6):
        g.associate([leaf()], [0], 2, float(k), place=FACING)
    assert removed_after(g, ALONG, 3, start=10.0)
    gone = list(g.removed_this_session())
    events = g.associate([leaf()], [], 3, 20.0, place=FACING)
    assert [e.kind for e in events] == ["added"] and 1 in g.nodes
    g.pair_relocations(3, 30.0, gone=gone)
    return g.pass_state()["sides"]


def test_a_door_brought_back_where_misses_removed_it_is_not_removed_by_them_again():
    """The door was there all along: the views along the corridor missed it. The node found at its
    place takes the removed node's sides, with the run that removed it counted as refuted misses,
    so in pass 4 three misses from along the corridor no longer remove it (a real door of a
    generated office, hard preset, was removed and found again pass after pass, session 99)."""
    def pass_4(saved: dict) -> ObjectGraph:
        g = ObjectGraph(SIDES, [Node(1, "door", np.array([0.0, 0.0, 1.0]), 0.9, 3, 3, observations=10)])
        g.evidence.sides.carry(saved, {1})
        return g

    def removed(g: ObjectGraph, place: np.ndarray, misses: int) -> bool:
        for k in range(misses):
            g.associate([], [1], 4, 100.0 + k, place=place)
        return 1 not in g.nodes

    saved = door_back_in_pass_3(SIDES)
    assert sum(saved["counts"]["1"][8:]) >= 3.0  # the removing run, now refuted misses
    assert not removed(pass_4(saved), ALONG, 3)
    assert removed(pass_4(saved), ALONG, SIDES.max_misses)  # a run that long still is evidence
    assert removed(pass_4(saved), FACING, 3)  # and from where it is always seen, three are
    # not brought back (return_radius 0: another door): it starts afresh, as before
    assert removed(pass_4(door_back_in_pass_3(replace(SIDES, return_radius=0.0))), ALONG, 3)


def test_counts_of_a_node_gone_for_many_passes_fade_out_of_the_saved_state():
    """Every node ever removed on evidence may come back, so its counts ride along; faded by
    ``side_memory`` each pass, they leave the state once worth less than a hundredth of a frame."""
    rates = SideRates(8, 0.5)
    rates.seen(0, 2)
    rates.missed(0, 3, 1.0)
    rates.end_run(0, refuted=False)  # removed: that run is kept for a return
    kept = []
    for _ in range(10):
        later = SideRates(8, 0.5)
        later.carry(rates.to_json(), {0})
        rates = later
        kept.append(0 in rates.counts and 0 in rates.removals)
    assert kept == [True] * 6 + [False] * 4  # 0.5 ** 7 of one frame < 0.01
