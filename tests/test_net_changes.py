"""Net changes per node (issue 17, item 2): what an operator is told changed over a pass,
with the evidence, from the raw per-frame history; and the store keeping that evidence."""

from __future__ import annotations

import sqlite3

import numpy as np
import pytest

from bomc_bt import store as store_module
from bomc_bt import store_schema
from bomc_bt.graph import AssociationParams, Event, ObjectGraph, Observation
from bomc_bt.net_changes import NetChange, net_changes, summarize
from bomc_bt.store import SiteStore


def d07(_category: str) -> float:
    return 0.7


def ev(kind: str, i: int, x: float, session: int = 2, stamp: float = 10.0, cat: str = "chair",
       misses: int | None = None, last_seen: float | None = None, merged_into: int | None = None) -> Event:
    event = Event(kind, i, cat, np.array([x, 0.0, 0.4]), session, stamp)
    if misses is not None:
        event.removal_evidence(misses, merged_into is not None, last_seen, merged_into)
    return event


def kinds(changes: list[NetChange]) -> list[tuple[str, int]]:
    return [(c.kind, c.node_id) for c in changes]


SESSION_1 = [ev("added", i, 2.0 * i, session=1) for i in range(5)]


def test_flickers_and_merges_are_no_change_and_real_changes_carry_their_evidence():
    pass_2 = [
        ev("removed", 0, 0.0, stamp=5.0, misses=3, last_seen=3.5), ev("moved", 0, 0.1, stamp=7.0),  # flicker
        ev("removed", 1, 2.0, stamp=8.0, misses=4, last_seen=6.0),  # gone
        ev("removed", 2, 4.0, stamp=9.0, misses=0, merged_into=3),  # a duplicate folded into node 3
        ev("updated", 3, 6.3, stamp=9.0),  # drift, not a move
        ev("moved", 4, 11.0, stamp=12.0), ev("updated", 4, 11.2, stamp=13.0),  # moved 3.2 m
        ev("added", 5, 20.0, stamp=14.0), ev("added", 6, 30.0, stamp=15.0), ev("removed", 6, 30.0, stamp=16.0),
    ]
    changes = net_changes(SESSION_1 + pass_2, 1, d07)
    assert kinds(changes) == [("removed", 1), ("added", 5), ("moved", 4)]
    gone = changes[0]
    assert (gone.missing_frames, gone.last_seen, gone.session, gone.stamp) == (4, 6.0, 2, 8.0)
    assert np.allclose(gone.old, [2.0, 0.0, 0.4]) and gone.new is None
    assert "missing in 4 frames, last seen t=6.0 s" in gone.describe()
    moved = changes[2]
    assert moved.distance == pytest.approx(3.2) and moved.events == 2 and np.allclose(moved.old[:2], [8.0, 0.0])
    assert summarize(changes) == {"removed": 1, "added": 1, "moved": 1}
    # a record survives the report's JSON
    assert NetChange.from_json(gone.to_json()).describe() == gone.describe()


def test_the_period_starts_where_since_says():
    history = SESSION_1 + [ev("removed", 1, 2.0, misses=3)]
    assert kinds(net_changes(history, None, d07)) == [("added", 0), ("added", 2), ("added", 3), ("added", 4)]
    assert kinds(net_changes(history, 1, d07)) == [("removed", 1)]
    assert net_changes(history, 2, d07) == []
    # a session never run in between does not split a change: removed in 2, the period 1 -> 3 has it
    assert kinds(net_changes(history + [ev("updated", 0, 0.0, session=3)], 1, d07)) == [("removed", 1)]


def test_a_removal_is_reported_where_the_map_had_the_object_not_where_a_revival_left_it():
    # PAL hospital, pass 3: a cabinet taken away was removed, then a neighbour's detection
    # 2.8 m off was taken for it moved there, and it was removed again. The operator's map
    # had it at x=2.0; reporting x=4.8 pointed at the neighbour, which stands
    pass_2 = [ev("removed", 1, 2.0, stamp=5.0, misses=8), ev("moved", 1, 4.8, stamp=8.0),
              ev("removed", 1, 4.8, stamp=12.0, misses=20, last_seen=8.0)]
    [gone] = net_changes(SESSION_1 + pass_2, 1, d07)
    assert (gone.kind, gone.node_id, gone.missing_frames, gone.last_seen) == ("removed", 1, 20, 8.0)
    assert np.allclose(gone.old, [2.0, 0.0, 0.4])
    assert "at (2.00, 0.00)" in gone.describe()


def test_moves_are_cut_at_the_category_threshold():
    history = SESSION_1 + [ev("moved", 0, 0.6), ev("moved", 1, 2.9)]
    assert kinds(net_changes(history, 1, d07)) == [("moved", 1)]
    assert kinds(net_changes(history, 1, lambda c: 0.5)) == [("moved", 0), ("moved", 1)]


def test_the_graph_writes_the_evidence_and_the_store_keeps_it(tmp_path):
    graph = ObjectGraph(AssociationParams(confirm_detections=1, confirm_misses=2, confirm_interval=0.0))
    graph.associate([Observation("chair", np.array([1.0, 0.0, 0.4]), 0.9)], [], 1, 1.0)
    events = [e for t in (2.0, 3.0) for e in graph.associate([], [0], 1, t)]
    (gone,) = events
    assert gone.kind == "removed" and gone.misses == 2 and gone.last_seen == 1.0
    with SiteStore(tmp_path) as store:
        store.begin_session(1, {"stamp": 0.0})
        store.record(events, graph.drain_changed())
        back = store.events(session=1)[-1]
    assert (back.misses, back.last_seen, back.merged_into) == (gone.misses, 1.0, None)


def test_a_version_2_store_is_read_as_it_is_and_upgraded_by_a_writer(tmp_path):
    path = tmp_path / "site.db"
    con = sqlite3.connect(path)  # the history as version 2 wrote it: no evidence columns
    con.executescript(store_module._SCHEMA.replace(", detail TEXT", ""))
    con.execute("INSERT INTO schema_version VALUES (2)")
    con.execute("INSERT INTO node_history (id, session, stamp, kind, category, x, y, z, confidence)"
                " VALUES (0, 1, 1.0, 'removed', 'chair', 1, 2, 0.4, 0.9)")
    con.commit()
    con.close()
    before = path.read_bytes()
    with SiteStore(path, readonly=True) as store:
        (old,) = store.events()
    assert old.kind == "removed" and old.misses is None and path.read_bytes() == before
    with SiteStore(path) as store:
        store.record([ev("removed", 1, 3.0, session=1, misses=5, last_seen=0.5)], [])
        assert [(e.node_id, e.misses) for e in store.events()] == [(0, None), (1, 5)]
    with sqlite3.connect(path) as con:
        assert con.execute("SELECT version FROM schema_version").fetchone()[0] == store_schema.SCHEMA_VERSION


def test_a_door_whose_centroid_only_sank_has_not_moved():
    """A door's centroid height follows how much of it the camera saw (its top cut off by
    the image edge): 0.65 m lower and 0.4 m along the wall is the same door, not a move."""
    door_1 = Event("added", 7, "door", np.array([25.41, 23.97, 1.25]), 1, 5.0)
    door_2 = Event("updated", 7, "door", np.array([25.0, 24.03, 0.6]), 2, 9.0)
    assert net_changes([door_1, door_2], 1, d07) == []
    away = Event("updated", 7, "door", np.array([24.6, 24.03, 1.25]), 2, 9.0)  # 0.81 m along the floor
    assert kinds(net_changes([door_1, away], 1, d07)) == [("moved", 7)]
