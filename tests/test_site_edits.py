"""Operator corrections (issue 19, item 4): ``bomc edit``, its history, and later passes.

The graph-level rules run on hand-made observations in both association modes; the end
to end test corrects a lab-b site after session 1 and runs session 2 twice: with
detections below ``association.readd_confidence`` (a deleted cabinet stays deleted, its
neighbour is not dragged onto its place) and with confident ones (it comes back).
"""

from __future__ import annotations

import sqlite3
import subprocess

import numpy as np
import pytest
from site_files import LAB_B, bomc, copy_site, error_line, snapshot

from bomc_bt import cli, run
from bomc_bt.graph import AssociationParams, Event, Node, ObjectGraph, Observation
from bomc_bt.graph.operator_edits import OperatorEdits
from bomc_bt.site import open_site
from bomc_bt.store import SiteStore
from bomc_bt.store_schema import SCHEMA, SCHEMA_VERSION
from bomc_bt.world import load_world

PERFECT = "detector: {preset: perfect}\n"
# every object seen as the perfect detector sees it, but scored 0.85: below readd_confidence
UNSURE = ("detector: {miss_base: 0.0, miss_per_metre: 0.0, miss_occlusion: 0.0, score_mean: 0.85, score_std: 0.0,"
          " score_drop: 0.0, false_positive_rate: 0.0, confusion_rate: 0.0, mask_bleed: 0.0, box_jitter: 0.0}\n")


def config(tmp, text: str):
    path = tmp / f"extra-{abs(hash(text))}.yaml"
    path.write_text(text)
    return run.build_config([str(path)])


def chair(x: float, y: float, confidence: float = 0.9, category: str = "chair") -> Observation:
    return Observation(category, np.array([x, y, 0.45]), confidence, 300, 0.2)


def bomc_here(capsys, *args: str) -> subprocess.CompletedProcess:
    """``bomc ARGS`` in this process (no interpreter start-up): exit code, stdout, stderr."""
    capsys.readouterr()
    try:
        code = cli.main(list(args))
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    out = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, out.out, out.err)


# ------------------------------------------------------------------ graph rules
@pytest.mark.parametrize("mode", ["paper", "robust"])
def test_a_deleted_spot_ignores_unsure_sightings_and_takes_confident_ones(mode):
    params = AssociationParams(mode=mode, confirm_detections=1, readd_confidence=0.95)
    spot = Event("deleted", 4, "chair", np.array([2.0, 0.0, 0.45]), 2, 0.0)
    added = Event("added", 4, "chair", np.array([2.0, 0.0, 0.45]), 1, 0.0)
    graph = ObjectGraph(params, edits=OperatorEdits.from_history([added, spot]), next_id=5)
    assert graph.associate([chair(2.1, 0.0, 0.9)], [], 2, 0.0) == []  # a look-alike, unsure: ignored
    graph.associate([chair(0.0, 0.0, 0.9)], [], 2, 1.0)  # a real chair elsewhere is added as usual
    assert [n.position[0] for n in graph.nodes.values()] == [0.0]
    events = graph.associate([chair(2.1, 0.0, 0.97)], [], 2, 2.0)  # confident: the object is back
    assert [e.kind for e in events] == ["added"] and events[0].node_id == 6
    graph.associate([chair(2.05, 0.0, 0.8)], [6], 2, 3.0)  # back on the map: unsure views confirm it
    assert set(graph.nodes) == {5, 6}


def test_an_unsure_sighting_of_a_deleted_object_does_not_drag_its_neighbour():
    """Nearer the deleted place than the neighbour: the deleted object's, ignored; the
    neighbour, expected and unseen in that frame, is not pulled over (robust gate 0.7 m)."""
    params = AssociationParams(confirm_detections=1, confirm_misses=5)
    history = [Event("added", 0, "chair", np.array([0.0, 0.0, 0.45]), 1, 0.0),
               Event("deleted", 0, "chair", np.array([0.0, 0.0, 0.45]), 2, 0.0)]
    beside = Node(1, "chair", np.array([0.6, 0.0, 0.45]), 0.9, 1, 1)  # a real chair beside the deleted one
    graph = ObjectGraph(params, [beside], edits=OperatorEdits.from_history(history))
    graph.associate([chair(0.1, 0.0)], [1], 2, 1.0)
    assert graph.nodes[1].position[0] == pytest.approx(0.6) and set(graph.nodes) == {1}
    graph.associate([chair(0.55, 0.0)], [1], 2, 2.0)  # nearer the neighbour: its own
    assert graph.nodes[1].misses == 0


def test_a_relabelled_node_is_confirmed_by_the_detectors_old_label():
    history = [Event("added", 3, "chair", np.array([1.0, 1.0, 0.45]), 1, 0.0),
               Event("relabelled", 3, "stool", np.array([1.0, 1.0, 0.45]), 2, 0.0)]
    edits = OperatorEdits.from_history(history)
    assert edits.detected_as == {3: "chair"} and not edits.deleted
    stool = Node(3, "stool", np.array([1.0, 1.0, 0.45]), 0.9, 1, 1)
    graph = ObjectGraph(AssociationParams(confirm_detections=1), [stool], edits=edits)
    events = graph.associate([chair(1.1, 1.0), chair(4.0, 1.0)], [3], 2, 0.0)
    assert {(e.kind, e.category) for e in events} == {("updated", "stool"), ("added", "chair")}
    assert graph.nodes[3].category == "stool" and graph.nodes[3].misses == 0


# ----------------------------------------------------------------- bomc edit
@pytest.fixture(scope="module")
def session_one(tmp_path_factory):
    if not LAB_B.exists():
        pytest.skip(f"shared data not found at {LAB_B} (set BOMC_SHARED to the shared folder)")
    root = tmp_path_factory.mktemp("edits")
    site = root / "site"
    cfg = config(root, PERFECT)
    assert run.run_build(LAB_B, site, seed=0, config=cfg, quiet=True).succeeded
    assert run.run_monitor(LAB_B, site, 1, seed=1, config=cfg, quiet=True).succeeded
    return site


def node_near(site, category: str, xy) -> int:
    with open_site(site) as reader:
        objects = reader.objects(category=category, near=tuple(xy), radius=1.0)
    assert objects, (category, xy)
    return objects[0].id


def test_edits_are_operator_events_in_the_history(session_one, tmp_path):
    site = copy_site(session_one, tmp_path / "site")
    with SiteStore(site / "site.db", readonly=True) as store:
        robot_events = len(store.events())
    with open_site(site) as reader:
        first = reader.objects()[0]
    for args, words in ((("relabel", str(first.id), "office", "chair"), "'office chair'"),
                        (("note", str(first.id), "wobbly", "leg"), "'wobbly leg'"),
                        (("delete", str(first.id)), "deleted"), (("restore", str(first.id)), "restored")):
        result = bomc("edit", str(site), *args)
        assert result.returncode == 0 and words in result.stdout and "session 2" in result.stdout, result.stderr
    with SiteStore(site / "site.db", readonly=True) as store:
        assert store.version == SCHEMA_VERSION
        assert len(store.events()) == robot_events  # a pass's events stay the robot's
        edits = [e for e in store.events(operator=True) if e.by_operator]
        assert [e.kind for e in edits] == ["relabelled", "noted", "deleted", "restored"]
        assert all(e.session == 2 and e.detail["after_session"] == 1 for e in edits)
        assert edits[0].detail["from"] == first.category and edits[1].detail["text"] == "wobbly leg"
    with open_site(site) as reader:
        again = {o.id: o for o in reader.objects()}[first.id]
        pending = reader.changes(since=1)
    assert again.category == "office chair" and again.notes == ("wobbly leg",)
    assert pending[0].pending and [e.kind for e in pending[0].edits] == [e.kind for e in edits]
    assert bomc("edit", str(site), "relabel", str(first.id), "office", "chair").stdout.startswith(
        f"node {first.id} is already labelled")


@pytest.mark.parametrize("args, words", [
    (("relabel", "999", "chair"), "no node 999"),
    (("relabel", "x1", "chair"), "not a node id"),
    (("relabel", "-3", "chair"), "out of range"),
    (("relabel", "1", "a" * 65), "1 to 64 printable characters"),
    (("relabel", "1", "bad\tname"), "printable"),
    (("note", "1", "x" * 501), "1 to 500 printable"),
    (("restore", "1"), "is on the map: nothing to restore"),
    (("delete", "1", "now"), "unrecognized arguments"),
    (("rename", "1"), "invalid choice"),
])
def test_bad_edits_are_one_line_exit_2_and_change_nothing(session_one, tmp_path, capsys, args, words):
    site = copy_site(session_one, tmp_path / "site")
    before = snapshot(site, mtimes=True)
    assert words in error_line(bomc_here(capsys, "edit", str(site), *args))
    assert snapshot(site, mtimes=True) == before


def test_editing_a_removed_node_or_a_missing_site_is_refused(session_one, tmp_path):
    site = copy_site(session_one, tmp_path / "site")
    assert bomc("edit", str(site), "delete", "1").returncode == 0
    before = snapshot(site, mtimes=True)
    assert "is not on the map" in error_line(bomc("edit", str(site), "relabel", "1", "stool"))
    assert "is not on the map" in error_line(bomc("edit", str(site), "delete", "1"))
    assert snapshot(site, mtimes=True) == before
    assert "not a site directory" in error_line(bomc("edit", str(tmp_path / "none"), "delete", "1"))


def test_a_version_2_store_is_read_as_it_is_and_upgraded_by_an_edit(session_one, tmp_path):
    site = copy_site(session_one, tmp_path / "site")
    with open_site(site) as reader:
        count = len(reader.objects())
    assert count > 0
    db = sqlite3.connect(site / "site.db")
    db.execute("ALTER TABLE node_history DROP COLUMN detail")  # as schema 2 wrote it
    db.execute("UPDATE schema_version SET version = 2")
    db.commit()
    db.close()
    assert "detail TEXT" in SCHEMA
    before = snapshot(site, mtimes=True)
    with open_site(site) as reader:
        assert len(reader.objects()) == count and reader.store.version == 2
        assert all(c.missing_frames is None for s in reader.changes() for c in s.changes)
    assert snapshot(site, mtimes=True) == before  # read as it is, not upgraded by a reader
    assert bomc("edit", str(site), "note", "2", "checked").returncode == 0
    with SiteStore(site / "site.db", readonly=True) as store:
        assert store.version == SCHEMA_VERSION and store.events(operator=True)[-1].detail["text"] == "checked"


# ---------------------------------------------------------- later passes respect them
def test_a_later_pass_keeps_the_label_and_leaves_the_deleted_cabinet_out(session_one, tmp_path):
    world = load_world(LAB_B)
    truth = world.ground_truth(2)
    chair3, cabinet2, cabinet3 = (truth[n].position[:2] for n in ("chair-3", "cabinet-2", "cabinet-3"))
    site = copy_site(session_one, tmp_path / "site")
    stool, deleted, neighbour = (node_near(site, c, p) for c, p in
                                 (("chair", chair3), ("cabinet", cabinet2), ("cabinet", cabinet3)))
    assert bomc("edit", str(site), "relabel", str(stool), "stool").returncode == 0
    assert bomc("edit", str(site), "delete", str(deleted)).returncode == 0
    confident = copy_site(site, tmp_path / "confident")
    with open_site(site) as reader:
        neighbour_at = {o.id: o for o in reader.objects()}[neighbour].position

    assert run.run_monitor(LAB_B, site, 2, seed=2, config=config(tmp_path, UNSURE), quiet=True).succeeded
    with open_site(site) as reader:
        objects = {o.id: o for o in reader.objects()}
        chairs_there = reader.objects(category="chair", near=tuple(chair3), radius=0.7)
        cabinets_there = reader.objects(category="cabinet", near=tuple(cabinet2), radius=0.7)
    assert objects[stool].category == "stool" and objects[stool].last_seen == 2  # seen, and still a stool
    assert chairs_there == []  # and the detector's "chair" did not come back beside it
    assert deleted not in objects and cabinets_there == []
    assert np.hypot(*np.subtract(objects[neighbour].position[:2], neighbour_at[:2])) < 0.3  # not dragged over

    assert run.run_monitor(LAB_B, confident, 2, seed=2, config=config(tmp_path, PERFECT), quiet=True).succeeded
    with open_site(confident) as reader:
        back = reader.objects(category="cabinet", near=tuple(cabinet2), radius=0.7)
        assert {o.id: o for o in reader.objects()}[stool].category == "stool"
    assert len(back) == 1 and back[0].id not in (deleted, neighbour) and back[0].first_seen == 2
