"""Retract, not remove: a node the map held only on the sightings that confirmed it (a look-alike, a label
confusion) that later passes find nothing at is dropped without telling the operator that an
object went; an object seen often and then gone is still a removal."""

from __future__ import annotations

import numpy as np

from bomc_bt.change_evaluation import reported_changes, score_changes, true_changes
from bomc_bt.cli import main
from bomc_bt.graph import AssociationParams, ObjectGraph, Observation
from bomc_bt.net_changes import RETRACTED, net_changes, only_changes
from bomc_bt.store import SiteStore


def d07(_category: str) -> float:
    return 0.7


def chair(x: float) -> Observation:
    return Observation("chair", np.array([x, 0.0, 0.45]), 0.9)


def two_passes(tmp_path, sightings_of_the_ghost: int):
    """Pass 1 sees a real chair at x=0 in 12 frames and a 'chair' at x=3 in its last
    ``sightings_of_the_ghost`` frames; pass 2 expects both and sees neither (the real chair was
    taken away)."""
    graph = ObjectGraph(AssociationParams(confirm_misses=2))
    events, t = [], 0.0
    for i in range(12):
        frame = [chair(0.0)] + ([chair(3.0)] if i >= 12 - sightings_of_the_ghost else [])
        events += graph.associate(frame, list(graph.nodes), 1, t)
        t += 1.0
    with SiteStore(tmp_path / "site.db") as store:
        store.begin_session(1, {"stamp": 0.0})
        store.record(events, graph.drain_changed())
        store.end_session(1, "succeeded", {"stamp": t})
        store.begin_session(2, {"stamp": 0.0})
        gone = [e for s in range(1, 8) for e in graph.associate([], list(graph.nodes), 2, 100.0 + s)]
        store.record(gone, graph.drain_changed())
        store.end_session(2, "succeeded", {"stamp": 110.0})
        return store.events(until=2)


def test_a_node_never_seen_again_after_its_confirmation_is_retracted_and_a_well_seen_one_removed(
        tmp_path, capsys):
    history = two_passes(tmp_path, sightings_of_the_ghost=2)
    changes = net_changes(history, 1, d07)
    assert sorted((c.kind, round(float(c.old[0]))) for c in changes) == [("removed", 0), (RETRACTED, 3)]
    assert [c.kind for c in only_changes(changes)] == ["removed"]
    # the evaluation scores the real removal and leaves the retraction out: no phantom
    truth = true_changes({"chair-1": ("chair", np.array([0.0, 0.0, 0.45]))}, {}, d07)
    r = score_changes(truth, reported_changes(history, 1, d07), d07, 2, 1)
    assert (r.overall.tp, r.overall.fp, r.phantom) == (1, 0, 0)
    # what `bomc changes` prints: one change, one retracted, each described
    assert main(["changes", str(tmp_path), "--since", "1"]) == 0
    text = capsys.readouterr().out
    assert "1 change(s), 1 retracted" in text and "seen in too few frames to trust" in text


def test_with_retraction_off_the_ghost_is_a_removal(tmp_path):
    history = two_passes(tmp_path, sightings_of_the_ghost=2)
    # the same history read as if no removal had been marked: both are removals
    for e in history:
        if e.detail:
            e.detail.pop("retracted", None)
    assert sorted(c.kind for c in net_changes(history, 1, d07)) == ["removed", "removed"]


def test_a_node_matched_again_after_its_confirmation_makes_a_removal(tmp_path):
    history = two_passes(tmp_path, sightings_of_the_ghost=3)
    assert sorted(c.kind for c in net_changes(history, 1, d07)) == ["removed", "removed"]
