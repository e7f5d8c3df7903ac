"""Two nodes a pass saw side by side in one frame stay two in the passes after it."""

from __future__ import annotations

import numpy as np

from bomc_bt.graph import AssociationParams, Node, ObjectGraph, Observation
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitoring import Perception
from bomc_bt.pass_resume import earlier_co_observed, resume_key
from bomc_bt.perception.projection import ProjectionParams
from bomc_bt.store import SiteStore


def chair(i: int, x: float, seen: int) -> Node:
    return Node(i, "chair", np.array([x, 0.0, 0.4]), 0.9, 1, 1, observations=seen)


def view(x: float) -> Observation:
    return Observation("chair", np.array([x, 0.0, 0.4]), 0.9, 500, 0.0)


def pass_sees_a_view_between_them(graph: ObjectGraph, session: int = 2) -> set[int]:
    """A later pass's frame: one chair view between the two, matched by chair 0; chair 1 in the
    view but hidden behind it (not expected). The view covers both: the duplicate fold."""
    graph.associate([view(0.25)], [0], session, 5.0, in_view=[0, 1])
    return set(graph.nodes)


def test_two_chairs_an_earlier_pass_saw_side_by_side_are_not_folded_by_a_later_one():
    # two chairs pushed together, 0.6 m apart (delta_c 0.7 m); pass 1 matched both in one
    # frame, each with its own view, so they are two objects
    one = ObjectGraph(AssociationParams(), [chair(0, 0.0, 30), chair(1, 0.6, 26)])
    one.associate([view(0.0), view(0.6)], [0, 1], 1, 1.0)
    saved = one.pass_state()["co_observed"]["pairs"]
    assert saved == [[0, 1]]

    # pass 2 in a new process, graph loaded from the store: without pass 1's pairs a view
    # bleeding over both folds chair 1 into chair 0, and chair 1 vanishes as no change
    forgetful = ObjectGraph(AssociationParams(), [chair(0, 0.0, 31), chair(1, 0.6, 27)])
    assert pass_sees_a_view_between_them(forgetful) == {0}

    # starting from pass 1's pairs, both stay; a pair with a node gone since is dropped
    remembering = ObjectGraph(AssociationParams(), [chair(0, 0.0, 31), chair(1, 0.6, 27)])
    remembering.keep_apart(2, [(a, b) for a, b in saved] + [(1, 9)])
    assert remembering.policy.co_observed.pairs == {(0, 1)}
    assert pass_sees_a_view_between_them(remembering) == {0, 1}
    # and pass 2 saves them on for pass 3
    assert remembering.pass_state()["co_observed"] == {"session": 2, "pairs": [[0, 1]]}


def test_a_pass_starts_from_the_pairs_the_latest_earlier_pass_saved(tmp_path):
    with SiteStore(tmp_path / "site.db") as store:
        assert earlier_co_observed(store, 1) == []  # the first pass: nothing before it
        store.begin_session(1, {"stamp": 0.0})
        point = {"graph": {"co_observed": {"session": 1, "pairs": [[0, 1], [1, 5]]}}}
        store.end_session(1, "completed", {"stamp": 1.0}, (), {resume_key(1): point})
        store.begin_session(2, {"stamp": 2.0})  # a pass with no resume point (killed before its first frame)
        store.end_session(2, "failed", {"stamp": 3.0}, (), {})
        assert earlier_co_observed(store, 3) == [(0, 1), (1, 5)]  # from pass 1, the latest that saved some

        grid = OccupancyGrid(np.zeros((50, 50), dtype=np.int8), 0.1, (0.0, 0.0))
        graph = ObjectGraph(AssociationParams(), [chair(0, 0.0, 30), chair(1, 0.6, 26)])
        Perception(None, None, ["chair"], ProjectionParams(), graph, store, 3, grid)
        assert graph.policy.co_observed.pairs == {(0, 1)}  # node 5 is no longer present
        paper = ObjectGraph(AssociationParams(mode="paper"), [chair(0, 0.0, 30), chair(1, 0.6, 26)])
        Perception(None, None, ["chair"], ProjectionParams(), paper, store, 3, grid)  # nothing to carry
        assert pass_sees_a_view_between_them(graph, 3) == {0, 1}

