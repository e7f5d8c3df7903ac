"""The site store: persistence, history replay, atomic frames and clear errors."""

from __future__ import annotations

import sqlite3

import numpy as np
import pytest

from bomc_bt import store as store_module
from bomc_bt.errors import BomcError
from bomc_bt.graph import AssociationParams, Event, Node, Observation
from bomc_bt.store import SiteStore

# confirm_detections=1: these tests store single-frame additions (confirmation is tested in test_graph_extensions).
ROBUST = AssociationParams(mode="robust", confirm_misses=2, confirm_interval=0.5, confirm_detections=1)


def o(cat: str, x: float, y: float) -> Observation:
    return Observation(cat, np.array([x, y, 0.5]), 0.8)


def positions(nodes) -> dict[int, tuple[str, tuple[float, ...]]]:
    return {n.id: (n.category, tuple(np.round(n.position, 9))) for n in nodes}


def run_frame(store, graph, observations, expected, session, stamp):
    events = graph.associate(observations, expected, session, stamp)
    store.record(events, graph.drain_changed(), progress={"frame": stamp})
    return events


def test_round_trip_and_graph_after_three_sessions(tmp_path):
    path = tmp_path / "site.db"
    snapshots = {}
    store = SiteStore(path)
    graph = store.load_graph(ROBUST)
    # session 1: three objects
    store.begin_session(1, {"stamp": 0.0})
    run_frame(store, graph, [o("chair", 0, 0), o("chair", 4, 0), o("table", 8, 0)], [], 1, 0.0)
    run_frame(store, graph, [o("chair", 0.2, 0), o("chair", 4, 0), o("table", 8, 0)], [0, 1, 2], 1, 1.0)
    store.end_session(1, "succeeded", {"stamp": 1.0})
    snapshots[1] = positions(graph.nodes.values())
    store.close()
    # session 2 (reopened): the table is gone, a door appears
    store = SiteStore(tmp_path)
    graph = store.load_graph(ROBUST)
    assert positions(graph.nodes.values()) == snapshots[1]
    assert store.begin_session(2, {"stamp": 0.0}) is False
    for t in (0.0, 1.0):
        run_frame(store, graph, [o("chair", 0, 0), o("chair", 4, 0), o("door", 8, 3)], [0, 1, 2], 2, t)
    store.end_session(2, "succeeded", {"stamp": 1.0})
    snapshots[2] = positions(graph.nodes.values())
    assert sorted(graph.nodes) == [0, 1, 3]
    # session 3: chair 1 moved 2 m
    store.begin_session(3, {"stamp": 0.0})
    for t in (0.0, 1.0):
        run_frame(store, graph, [o("chair", 0, 0), o("door", 8, 3)], [0, 1, 3], 3, t)
    run_frame(store, graph, [o("chair", 4, 2)], [], 3, 2.0)
    store.end_session(3, "succeeded", {"stamp": 2.0})
    snapshots[3] = positions(graph.nodes.values())
    assert sorted(graph.nodes) == [0, 1, 3]
    for k in (1, 2, 3):
        assert positions(store.graph_after(k)) == snapshots[k]
    assert [e.kind for e in store.events(3) if e.node_id == 1] == ["removed", "moved"]
    sessions = store.sessions()
    assert [s.number for s in sessions] == [1, 2, 3] and all(s.ended for s in sessions)
    assert sessions[1].counts["removed"] == 1 and sessions[1].counts["added"] == 1
    assert sessions[2].outcome == "succeeded" and store.next_session() == 4
    assert store.get_progress("frame") == 2.0
    with pytest.raises(BomcError, match="already ended"):
        store.begin_session(2)
    store.close()


def test_record_is_atomic(tmp_path):
    store = SiteStore(tmp_path / "site.db")
    graph = store.load_graph(ROBUST)
    store.begin_session(1)
    events = graph.associate([o("chair", 0, 0), o("door", 3, 0)], [], 1, 0.0)
    bad = Event("added", 99, "chair", np.array([np.nan, 0.0, 0.0]), 1, 0.0)
    with pytest.raises(ValueError):
        store.record([events[0], bad, events[1]], graph.drain_changed(), progress={"waypoint": 4})
    assert store.events() == [] and store.nodes(include_removed=True) == []
    assert store.get_progress("waypoint") is None
    store.record(events, graph.nodes.values(), progress={"waypoint": 4})
    assert len(store.events()) == 2 and store.get_progress("waypoint") == 4
    store.close()


def test_a_frame_commit_without_a_disk_sync_is_atomic_and_leaves_later_commits_durable(tmp_path):
    """A pass's per-frame commits skip the disk sync (a kill loses nothing); a failed one
    still writes nothing, and the connection syncs again for every other commit."""
    store = SiteStore(tmp_path / "site.db")
    graph = store.load_graph(ROBUST)
    store.begin_session(1)
    events = graph.associate([o("chair", 0, 0)], [], 1, 0.0)
    bad = Event("added", 99, "chair", np.array([np.nan, 0.0, 0.0]), 1, 0.0)
    with pytest.raises(ValueError):
        store.record([events[0], bad], graph.drain_changed(), progress={"resume/1": {"frames": 1}}, durable=False)
    assert store.events() == [] and store.get_progress("resume/1") is None
    assert store._db.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL again
    store.record(events, graph.nodes.values(), progress={"resume/1": {"frames": 1}}, durable=False)
    assert store._db.execute("PRAGMA synchronous").fetchone()[0] == 2
    store.close()
    with SiteStore(tmp_path / "site.db") as again:  # another process sees the frame
        assert len(again.events()) == 1 and again.get_progress("resume/1") == {"frames": 1}


def test_resume_progress_and_unfinished_session(tmp_path):
    with SiteStore(tmp_path / "site.db") as store:
        store.begin_session(1, {"stamp": 5.0})
        store.set_progress("next_waypoint", 7)
        store.set_progress("plan", [[0.0, 1.0], [2.0, 3.0]])
    with SiteStore(tmp_path / "site.db") as store:
        assert store.begin_session(1) is True  # a killed pass resumes its session
        assert store.get_progress("next_waypoint") == 7
        assert store.get_progress("plan") == [[0.0, 1.0], [2.0, 3.0]]
        assert store.get_progress("missing", default=0) == 0
        assert store.sessions()[0].started_stamp == 5.0 and not store.sessions()[0].ended


def test_corrupt_and_foreign_files_are_refused_with_the_file_name(tmp_path):
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"this is not a database at all" * 100)
    with pytest.raises(BomcError, match="junk.db.*not a bomc site store"):
        SiteStore(junk)
    foreign = tmp_path / "foreign.db"
    con = sqlite3.connect(foreign)
    con.execute("CREATE TABLE other (x INTEGER)")
    con.commit()
    con.close()
    with pytest.raises(BomcError, match="foreign.db.*missing tables"):
        SiteStore(foreign)
    SiteStore(tmp_path / "old.db").close()
    con = sqlite3.connect(tmp_path / "old.db")
    con.execute("UPDATE schema_version SET version = 99")
    con.commit()
    con.close()
    with pytest.raises(BomcError, match="old.db.*version 99"):
        SiteStore(tmp_path / "old.db")


def test_locked_database_is_a_bomc_error(tmp_path):
    path = tmp_path / "site.db"
    store = SiteStore(path, busy_timeout=0.05)
    other = sqlite3.connect(path, isolation_level=None)
    other.execute("BEGIN IMMEDIATE")
    try:
        with pytest.raises(BomcError, match="site.db.*locked"):
            store.set_progress("k", 1)
    finally:
        other.execute("ROLLBACK")
        other.close()
    store.set_progress("k", 1)
    assert store.get_progress("k") == 1
    store.close()


def test_node_footprints_persist_and_a_version_1_store_is_upgraded(tmp_path):
    path = tmp_path / "site.db"
    con = sqlite3.connect(path)  # a store as version 1 wrote it: no footprint columns
    old = store_module._SCHEMA.replace(",\n    fx0 REAL, fy0 REAL, fx1 REAL, fy1 REAL,\n    cr REAL, cg REAL", "")
    con.executescript(old)
    con.execute("INSERT INTO schema_version VALUES (1)")
    con.execute("INSERT INTO nodes VALUES (3, 'chair', 1, 2, 0.4, 0.9, 1, 1, 'present', 4, 0)")
    con.commit()
    con.close()
    with SiteStore(path) as store:
        old = store.load_graph(AssociationParams())
        assert set(old.nodes) == {3} and old.nodes[3].footprint is None and old.next_id == 4
        table = Node(4, "table", np.array([5.0, 5.0, 0.6]), 0.9, 2, 2, footprint=np.array([4.4, 4.6, 5.6, 5.4]))
        store.record([], [table])
    with SiteStore(path) as store:
        graph = store.load_graph(AssociationParams(confirm_detections=1))
        assert np.allclose(graph.nodes[4].footprint, [4.4, 4.6, 5.6, 5.4])
        # the next session's association uses it: a sliver of the table's end (0.5 m from
        # the node, 0.9 m from where an end-on view would put it) is that table, not a new one
        graph.relocate(graph.nodes[4], np.array([5.4, 5.0, 0.6]))
        sliver = Observation("table", np.array([4.5, 5.0, 0.6]), 0.9, 400, 0.2, box=np.array([4.4, 4.7, 4.6, 5.3]))
        events = graph.associate([sliver], [], 3, 1.0)
        assert [e.kind for e in events] == ["updated"] and set(graph.nodes) == {3, 4}


def test_node_colours_persist_and_a_version_4_store_is_read_as_it_is_and_upgraded(tmp_path):
    path = tmp_path / "site.db"
    con = sqlite3.connect(path)  # a store as version 4 wrote it: no colour columns
    con.executescript(store_module._SCHEMA.replace(",\n    cr REAL, cg REAL", ""))
    con.execute("INSERT INTO schema_version VALUES (4)")
    con.execute("INSERT INTO nodes VALUES (3, 'chair', 1, 2, 0.4, 0.9, 1, 1, 'present', 4, 0, NULL, NULL, NULL, NULL)")
    con.commit()
    con.close()
    with SiteStore(path, readonly=True) as reader:  # read as it is: no colour, nothing written
        assert reader.version == 4 and reader.nodes()[0].colour is None
    with SiteStore(path) as store:
        assert store.load_graph(AssociationParams()).nodes[3].colour is None
        red = Node(4, "chair", np.array([5.0, 5.0, 0.45]), 0.9, 2, 2, colour=(0.65, 0.18))
        store.record([], [red])
    with SiteStore(path, readonly=True) as reader:
        colours = {n.id: n.colour for n in reader.nodes()}
        assert reader.version == 5 and colours[3] is None and np.allclose(colours[4], [0.65, 0.18])
