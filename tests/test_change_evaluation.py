"""Change evaluation (issue 17, item 1): what a monitor pass reported as changed, against the
world's true changes since the previous pass; ``bomc evaluate`` table and ``--json``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from shared_data import local_world

from bomc_bt import cli, run
from bomc_bt.change_evaluation import raw_event_counts, reported_changes, score_changes, true_changes, undone_changes
from bomc_bt.config import Config
from bomc_bt.evaluate_changes import evaluate_changes
from bomc_bt.graph import AssociationParams, Event, Node
from bomc_bt.store import SiteStore
from bomc_bt.world import load_world


def d07(_category: str) -> float:
    return 0.7


def obj(cat: str, x: float, y: float = 0.0) -> tuple[str, np.ndarray]:
    return cat, np.array([x, y, 0.0])


def node(i: int, cat: str, x: float, y: float = 0.0) -> Node:
    return Node(i, cat, np.array([x, y, 0.0]), 0.9, 1, 1)


def ev(kind: str, i: int, cat: str, x: float, y: float = 0.0, session: int = 2) -> Event:
    return Event(kind, i, cat, np.array([x, y, 0.0]), session, 10.0)


def pass_two(nodes_before, nodes_after, events, threshold=d07):
    """Net changes of pass 2: session 1 added ``nodes_before``, pass 2 wrote ``events`` and
    left ``nodes_after`` present (checked: the replay must agree)."""
    history = [Event("added", n.id, n.category, n.position, 1, 0.0) for n in nodes_before] + list(events)
    last = {e.node_id: e for e in history}
    assert {i for i, e in last.items() if e.kind != "removed"} == {n.id for n in nodes_after}
    return reported_changes(history, 1, threshold)


def score(truth_before, truth_after, nodes_before, nodes_after, events, threshold=d07):
    truth = true_changes(truth_before, truth_after, threshold)
    net = pass_two(nodes_before, nodes_after, events, threshold)
    return score_changes(truth, net, threshold, 2, 1, raw_event_counts(events))


def counts(result, kind):
    s = result.overall if kind == "overall" else result.kinds[kind]
    return s.tp, s.fp, s.fn


# ------------------------------------------------------------------ pure functions
def test_a_removal_the_pass_found_is_a_true_positive():
    r = score({"chair-1": obj("chair", 1.0), "chair-2": obj("chair", 5.0)}, {"chair-2": obj("chair", 5.0)},
              [node(1, "chair", 1.2), node(2, "chair", 5.0)], [node(2, "chair", 5.05)],
              [ev("removed", 1, "chair", 1.2), ev("updated", 2, "chair", 5.05)])
    assert counts(r, "removed") == (1, 0, 0)
    assert r.kinds["removed"].precision == 1.0 and r.kinds["removed"].recall == 1.0
    assert [(m.kind, m.node_id, m.name) for m in r.matches] == [("removed", 1, "chair-1")]
    assert counts(r, "overall") == (1, 0, 0) and r.phantom == 0
    assert r.raw_events == {"added": 0, "removed": 1, "moved": 0, "updated": 1}
    # nothing else happened: the other kinds have nothing to score
    assert r.kinds["added"].f1 is None and r.kinds["moved"].precision is None


def test_a_removal_undone_within_the_pass_is_no_change():
    stay = {"chair-1": obj("chair", 1.0)}
    # the node was removed (missed while occluded), then found again and kept its id
    back = score(stay, stay, [node(1, "chair", 1.0)], [node(1, "chair", 1.1)],
                 [ev("removed", 1, "chair", 1.0), ev("moved", 1, "chair", 1.1)])
    assert counts(back, "overall") == (0, 0, 0) and back.phantom == 0
    assert back.raw_events["removed"] == 1  # the raw log still shows the flicker
    # the same flicker with a new id is a removal and an addition where nothing changed
    new_id = score(stay, stay, [node(1, "chair", 1.0)], [node(7, "chair", 1.1)],
                   [ev("removed", 1, "chair", 1.0), ev("added", 7, "chair", 1.1)])
    assert counts(new_id, "removed") == (0, 1, 0) and counts(new_id, "added") == (0, 1, 0)
    assert new_id.phantom == 2
    assert new_id.kinds["removed"].precision == 0.0 and new_id.kinds["removed"].recall is None


def test_a_node_added_and_removed_within_the_pass_is_no_change():
    r = score({}, {}, [], [], [ev("added", 3, "bin", 2.0), ev("removed", 3, "bin", 2.0)])
    assert counts(r, "overall") == (0, 0, 0) and r.phantom == 0


def test_a_move_that_keeps_the_id_is_a_true_move():
    r = score({"chair-1": obj("chair", 0.0)}, {"chair-1": obj("chair", 3.0, 1.0)},
              [node(4, "chair", 0.1)], [node(4, "chair", 2.9, 1.1)], [ev("moved", 4, "chair", 2.9, 1.1)])
    assert counts(r, "moved") == (1, 0, 0)
    assert counts(r, "removed") == (0, 0, 0) and counts(r, "added") == (0, 0, 0)
    assert r.matches[0].distance == pytest.approx(0.1 + np.hypot(0.1, 0.1))


def test_a_move_reported_as_removal_plus_addition_earns_no_credit_but_is_no_phantom():
    r = score({"chair-1": obj("chair", 0.0)}, {"chair-1": obj("chair", 6.0)},
              [node(4, "chair", 0.1)], [node(9, "chair", 6.1)],
              [ev("removed", 4, "chair", 0.1), ev("added", 9, "chair", 6.1)])
    assert counts(r, "moved") == (0, 0, 1)
    assert counts(r, "removed") == (0, 1, 0) and counts(r, "added") == (0, 1, 0)
    assert counts(r, "overall") == (0, 2, 1)
    assert r.phantom == 0  # both reports sit on the real move's ends
    assert [c.key for c in r.missed] == ["chair-1"] and sorted(c.key for c in r.wrong) == [4, 9]


def test_a_move_must_match_at_both_ends():
    # the map moved a *different* chair onto the moved chair's new place
    truth_before = {"chair-1": obj("chair", 0.0), "chair-2": obj("chair", 0.0, 4.0)}
    truth_after = {"chair-1": obj("chair", 3.0), "chair-2": obj("chair", 0.0, 4.0)}
    r = score(truth_before, truth_after, [node(1, "chair", 0.0), node(2, "chair", 0.0, 4.0)],
              [node(1, "chair", 0.0), node(2, "chair", 3.0)], [ev("moved", 2, "chair", 3.0)])
    assert counts(r, "moved") == (0, 1, 1)
    assert r.phantom == 0  # its new end is the real move's: a wrong story, not an invented one


def test_a_phantom_is_a_report_no_true_change_comes_near():
    before = {"chair-1": obj("chair", 0.0), "table-1": obj("table", 5.0), "table-2": obj("table", 9.0)}
    r = score(before, {"table-1": obj("table", 5.0)},
              [node(1, "chair", 0.0), node(2, "table", 5.0), node(3, "table", 0.3), node(4, "table", 9.0)],
              [node(2, "table", 5.0)],
              [ev("removed", 1, "chair", 0.0), ev("removed", 3, "table", 0.3), ev("removed", 4, "table", 9.0),
               ev("removed", 2, "table", 5.0), ev("moved", 2, "table", 5.0)])
    # node 3 sits where a chair vanished, but no *table* changed near it: a phantom removal
    assert counts(r, "removed") == (2, 1, 0)
    assert r.phantom == 1 and [c.key for c in r.phantoms] == [3]
    # a second report of a real removal is wrong, but not a phantom
    twice = score({"bin-1": obj("bin", 0.0)}, {}, [node(1, "bin", 0.0), node(2, "bin", 0.2)], [],
                  [ev("removed", 1, "bin", 0.0), ev("removed", 2, "bin", 0.2)])
    assert counts(twice, "removed") == (1, 1, 0) and twice.phantom == 0


def test_a_change_the_previous_pass_missed_reported_now_is_late_not_a_phantom():
    """A bin taken away during pass 1 after the robot had looked there is seen gone in pass 2:
    wrong for pass 2 (nothing changed since pass 1 ended) but no ghost; a removal where nothing
    ever changed stays a phantom."""
    truth = true_changes({"bin-1": obj("bin", 0.0), "bin-2": obj("bin", 4.0)},
                         {"bin-1": obj("bin", 0.0), "bin-2": obj("bin", 4.0)}, d07)
    net = pass_two([node(1, "bin", 0.0), node(2, "bin", 4.0), node(3, "bin", 8.0)],
                   [node(1, "bin", 0.0), node(2, "bin", 4.0)], [ev("removed", 3, "bin", 8.0)])
    missed_in_pass_1 = true_changes({"bin-3": obj("bin", 8.1)}, {}, d07)
    late = score_changes(truth, net, d07, 2, 1, missed_before=missed_in_pass_1)
    assert counts(late, "removed") == (0, 1, 0)  # still a false positive of pass 2
    assert late.phantom == 0 and [c.key for c in late.late] == [3]
    elsewhere = score_changes(truth, net, d07, 2, 1, missed_before=true_changes({"bin-3": obj("bin", 12.0)}, {}, d07))
    assert elsewhere.phantom == 1 and not elsewhere.late
    assert score_changes(truth, net, d07, 2, 1).phantom == 1


def test_what_the_world_undid_within_a_span_is_kept_only_where_neither_end_shows_it():
    start = {"chair-1": obj("chair", 0.0), "table-1": obj("table", 5.0)}
    states = [start,
              {**start, "bin-1": obj("bin", 3.0)},  # a bin brought in ...
              {**start, "bin-1": obj("bin", 3.0), "chair-1": obj("chair", 2.0)},  # a chair moved ...
              {"chair-1": obj("chair", 9.0), "table-1": obj("table", 7.0)}]  # ... and on; the bin taken away
    undone = undone_changes(states, d07)
    assert sorted((c.key, tuple(c.ends()[:, 0])) for c in undone) == [("bin-1", (3.0,)), ("bin-1", (3.0,)),
                                                                     ("chair-1", (2.0,)), ("chair-1", (2.0,))]
    assert undone_changes([start, states[-1]], d07) == []  # the net moves themselves are not undone
    # a name reused for another category at the same place: the bin in between was real
    swapped = undone_changes([{"x": obj("chair", 1.0)}, {"x": obj("bin", 1.0)}, {}], d07)
    assert [(c.category, tuple(c.ends()[:, 0])) for c in swapped] == [("bin", (1.0,)), ("bin", (1.0,))]


def test_a_change_undone_before_the_pass_ended_is_transient_not_a_phantom():
    """A bin brought in when the session began and taken away during the pass, after the
    robot had seen it: the pass reports it added, wrong against the net result (nothing
    changed) but no ghost; the same report where no bin ever stood stays a phantom."""
    ends = {"chair-1": obj("chair", 0.0)}
    truth = true_changes(ends, ends, d07)
    undone = undone_changes([ends, {**ends, "bin-1": obj("bin", 4.0)}, ends], d07)
    for at, transient in ((4.1, 1), (9.0, 0)):
        net = pass_two([node(1, "chair", 0.0)], [node(1, "chair", 0.0), node(2, "bin", at)],
                       [ev("added", 2, "bin", at)])
        r = score_changes(truth, net, d07, 2, 1, undone=undone)
        assert counts(r, "added") == (0, 1, 0)  # a false positive either way
        assert (len(r.transient), r.phantom) == (transient, 1 - transient) and not r.late


def test_thresholds_are_the_categories_association_distances():
    def per_category(cat: str) -> float:
        return {"door": 0.3, "table": 1.5}.get(cat, 0.7)

    before = {"door-1": obj("door", 0.0), "chair-1": obj("chair", 5.0), "table-1": obj("table", 10.0)}
    after = {"door-1": obj("door", 0.5), "chair-1": obj("chair", 5.5), "table-1": obj("table", 11.0)}
    truth = true_changes(before, after, per_category)
    # a door nudged 0.5 m moved (beyond 0.3 m); the chair's 0.5 m and the table's 1 m are not changes
    assert [(c.kind, c.key) for c in truth] == [("moved", "door-1")]
    # the same cut on the map's side, and gating: a removal 1.2 m off counts for a table, not for a chair
    nodes = [node(1, "door", 0.0), node(2, "table", 10.0), node(3, "chair", 20.0)]
    moved = [node(1, "door", 0.4), node(2, "table", 11.0)]
    net = pass_two(nodes, [*moved, nodes[2]], [ev("updated", 1, "door", 0.4), ev("updated", 2, "table", 11.0)],
                   per_category)
    assert [(c.kind, c.key) for c in net] == [("moved", 1)]
    gone = {"table-9": obj("table", 30.0), "chair-9": obj("chair", 40.0)}
    r = score(gone, {}, [node(5, "table", 31.2), node(6, "chair", 41.2)], [],
              [ev("removed", 5, "table", 31.2), ev("removed", 6, "chair", 41.2)], per_category)
    assert [m.node_id for m in r.matches] == [5]
    assert counts(r, "removed") == (1, 1, 1)


def test_an_object_replaced_under_its_name_by_another_category_is_removed_and_added():
    truth = true_changes({"thing": obj("chair", 1.0)}, {"thing": obj("table", 1.0)}, d07)
    assert sorted((c.kind, c.category) for c in truth) == [("added", "table"), ("removed", "chair")]


# ------------------------------------------------------------ site: truth windows
def _site_with_sessions(site: Path, ended: dict[int, float]) -> None:
    """A store whose passes saw nothing, ending at the given robot times."""
    with SiteStore(site / "site.db") as store:
        for n, stamp in ended.items():
            store.begin_session(n, {"stamp": 0.0})
            store.end_session(n, "succeeded", {"stamp": stamp})


def _missed(result) -> set[tuple[str, str]]:
    return {(c.kind, str(c.key)) for c in result.missed}


def test_intra_session_changes_count_in_the_pass_that_was_running_when_they_happened(tmp_path):
    # small_house: session 2 moves table-1 at 75.3 s; session 3 removes trash-bin-2 (and adds chair-3) at 36 s
    world = load_world(local_world("small_house"))
    config = Config()
    file_changes_2 = {("removed", "door-1"), ("moved", "chair-2"), ("added", "trash-bin-2"), ("added", "door-2")}
    file_changes_3 = {("removed", "trash-bin-1"), ("added", "cabinet-2")}

    early = tmp_path / "early"  # pass 2 ended before the table moved, pass 3 before the bin went
    _site_with_sessions(early, {1: 100.0, 2: 50.0, 3: 30.0})
    assert _missed(evaluate_changes(world, early, 2, config)) == file_changes_2
    r3 = evaluate_changes(world, early, 3, config)
    assert r3.previous == 2
    assert _missed(r3) == file_changes_3 | {("moved", "table-1")}

    late = tmp_path / "late"  # both passes ended after their intra-session changes
    _site_with_sessions(late, {1: 100.0, 2: 100.0, 3: 100.0})
    assert _missed(evaluate_changes(world, late, 2, config)) == file_changes_2 | {("moved", "table-1")}
    assert _missed(evaluate_changes(world, late, 3, config)) == file_changes_3 | {
        ("removed", "trash-bin-2"), ("added", "chair-3")}


def test_a_move_during_pass_2_that_pass_3_reports_is_late_in_bomc_evaluate(tmp_path):
    """small_house's table-1 moves 75.3 s into session 2. A pass 2 that ended after that and never
    saw it leaves the move to pass 3: pass 3's report is late, not a phantom; had pass 2 ended
    before the move, the same report is pass 3's true positive."""
    world = load_world(local_world("small_house"))
    old, new = np.array([-1.075, 0.225, 0.375]), np.array([1.525, 4.575, 0.375])
    for site, ended, late in ((tmp_path / "late", 100.0, 1), (tmp_path / "early", 50.0, 0)):
        _site_with_sessions(site, {1: 100.0, 2: ended, 3: 100.0})
        with SiteStore(site / "site.db") as store:
            table = Node(7, "table", old, 0.9, 1, 1)
            store.record([Event("added", 7, "table", old, 1, 10.0)], [table])
            store.record([Event("moved", 7, "table", new, 3, 20.0, previous=old)], [table])
        r = evaluate_changes(world, site, 3, Config())
        assert len(r.late) == late and r.phantom == 0
        assert counts(r, "moved") == ((0, 1, 0) if late else (1, 0, 0))


def test_an_object_the_first_pass_missed_reported_added_later_is_a_phantom_not_late(tmp_path):
    """Pass 1 is scored against the empty map: the table it missed never changed in the building."""
    world = load_world(local_world("small_house"))
    _site_with_sessions(tmp_path, {1: 100.0, 2: 50.0})
    with SiteStore(tmp_path / "site.db") as store:
        at = np.array([-1.075, 0.225, 0.375])
        store.record([Event("added", 3, "table", at, 2, 20.0)], [Node(3, "table", at, 0.9, 2, 2)])
    r = evaluate_changes(world, tmp_path, 2, Config())
    assert r.phantom == 1 and not r.late


def test_a_bin_there_and_gone_between_two_passes_is_transient_then_late_in_bomc_evaluate(tmp_path, capsys):
    """small_house's trash-bin-2 comes with session 2 and goes 36 s into session 3. Session 2
    is never run: pass 3 (ended at 100 s) sees the bin early and reports it added --
    transient, since it was gone when the pass ended; pass 4 finds it gone and reports the
    removal -- late, not a phantom. A removal where no bin ever stood stays a phantom."""
    path = local_world("small_house")
    world = load_world(path)
    _site_with_sessions(tmp_path, {1: 100.0, 3: 100.0, 4: 100.0})
    bin_at, elsewhere = np.array([1.625, 0.675, 0.3]), np.array([-6.0, 3.0, 0.3])
    with SiteStore(tmp_path / "site.db") as store:
        bins = [Node(5, "trash bin", bin_at, 0.9, 3, 3), Node(6, "trash bin", elsewhere, 0.9, 1, 1)]
        store.record([Event("added", 6, "trash bin", elsewhere, 1, 10.0)], bins[1:])
        store.record([Event("added", 5, "trash bin", bin_at, 3, 20.0)], bins)
        store.record([Event("removed", 5, "trash bin", bin_at, 4, 20.0),
                      Event("removed", 6, "trash bin", elsewhere, 4, 30.0)], bins)
    third = evaluate_changes(world, tmp_path, 3, Config())
    assert [c.key for c in third.transient] == [5] and third.phantom == 0
    fourth = evaluate_changes(world, tmp_path, 4, Config())
    assert [c.key for c in fourth.late] == [5] and [c.key for c in fourth.phantoms] == [6]
    out = json.loads(_evaluate_json(path, tmp_path, 3, capsys))["changes"]
    assert (out["transient"], out["phantom"], out["added"]["fp"]) == (1, 0, 1)
    assert cli.main(["evaluate", "--world", str(path), "--site", str(tmp_path), "--session", "3"]) == 0
    assert "  transient: added node 5 (trash bin)" in capsys.readouterr().out


def test_an_object_taken_away_during_pass_1_after_it_was_seen_is_transient_then_late(tmp_path):
    """Pass 1 is scored against the empty map, so a cabinet that stood when session 1 began
    and went 30 s into it is a change undone within pass 1: its report there is transient,
    and pass 2 finding it gone is late -- neither is a phantom."""
    source = local_world("small_house")
    text = source.read_text()
    line = next(x for x in text.splitlines() if x.startswith("map:"))
    text = text.replace(line, f"map: {load_world(source).map_path}")
    text = text.replace("during:\n", "during:\n- session: 1\n  at: 30.0\n  remove: [cabinet-1]\n", 1)
    path = tmp_path / "world.yaml"
    path.write_text(text)
    world = load_world(path)
    site = tmp_path / "site"
    _site_with_sessions(site, {1: 100.0, 2: 100.0})
    at = np.array([7.925, 2.025, 0.6])
    with SiteStore(site / "site.db") as store:
        cabinet = Node(4, "cabinet", at, 0.9, 1, 1)
        store.record([Event("added", 4, "cabinet", at, 1, 20.0)], [cabinet])
        store.record([Event("removed", 4, "cabinet", at, 2, 20.0)], [cabinet])
    first, second = (evaluate_changes(world, site, n, Config()) for n in (1, 2))
    assert [c.key for c in first.transient] == [4] and first.phantom == 0
    assert [c.key for c in second.late] == [4] and second.phantom == 0


def test_session_1_is_scored_against_the_empty_map_and_a_skipped_session_is_spanned(tmp_path):
    world = load_world(local_world("small_house"))
    _site_with_sessions(tmp_path, {1: 100.0, 3: 100.0})
    first = evaluate_changes(world, tmp_path, 1, Config())
    assert first.previous is None
    assert _missed(first) == {("added", name) for name in world.objects}
    spanned = evaluate_changes(world, tmp_path, 3, Config())
    assert spanned.previous == 1
    # door-1 went in session 2 and never came back: one removal since the last pass
    assert ("removed", "door-1") in _missed(spanned) and ("added", "door-2") in _missed(spanned)


def test_evaluate_of_an_unrecorded_session_is_one_line_and_exit_2(tmp_path, capsys):
    _site_with_sessions(tmp_path, {1: 100.0})
    code = cli.main(["evaluate", "--world", str(local_world("small_house")), "--site", str(tmp_path),
                     "--session", "2"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "session 2 was not recorded" in err


# --------------------------------------------------------------- end to end: lab-b
def test_lab_b_session_2_reports_its_removals_in_bomc_evaluate(shared, tmp_path, capsys):
    """lab-b session 2 removes two bins and the umbrella and moves the people 2.5 and 7 m.
    Measured (seed 0 build, passes seeded 1, 2, coverage plan): removed 3/3, both moves
    reported as removed + added (wrong kind, not phantoms), and one phantom: cabinet-2,
    which stands where it stood, removed at the end of the pass (issue 17: association at
    the end of a pass is not yet stable). The evaluation must name that phantom as the node
    whose object never changed."""
    world, site = shared / "worlds" / "lab-b.yaml", tmp_path / "site"
    config = run.build_config()
    run.run_build(world, site, seed=0, config=config, quiet=True)
    for n in (1, 2):
        assert run.run_monitor(world, site, n, seed=n, config=config, quiet=True).succeeded
    capsys.readouterr()
    assert cli.main(["evaluate", "--world", str(world), "--site", str(site), "--session", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {"session", "classes", "overall"} <= set(out) and out["overall"]["f1"] >= 0.9  # old keys unchanged
    changes = out["changes"]
    with capsys.disabled():
        print("\nlab-b session 2 changes:", json.dumps(changes))
    assert changes["previous_session"] == 1
    assert changes["removed"]["true"] == 3 and changes["removed"]["recall"] == 1.0
    assert changes["moved"]["true"] == 2
    assert changes["overall"]["recall"] >= 0.6
    assert changes["phantom"] <= 1 and changes["removed"]["fp"] >= changes["phantom"]
    assert changes["raw_events"]["removed"] >= changes["removed"]["net"]
    for kind in ("removed", "added", "moved", "overall"):
        s = changes[kind]
        assert s["tp"] + s["fn"] == s["true"] and s["tp"] + s["fp"] == s["net"]
    # the session report tells the operator the same net changes, each with its evidence
    report = json.loads((site / "sessions" / "2" / "report.json").read_text())["changes"]
    assert report["since_session"] == 1
    assert report["counts"] == {kind: changes[kind]["net"] for kind in ("removed", "added", "moved")}
    removed = [c for c in report["nodes"] if c["kind"] == "removed"]
    assert removed and all(c["missing_frames"] >= config.association.confirm_misses for c in removed)
    markdown = (site / "sessions" / "2" / "report.md").read_text()
    assert "## Changes since session 1" in markdown
    assert all(f"{c['category']} #{c['node']}" in markdown for c in report["nodes"])
    assert cli.main(["evaluate", "--world", str(world), "--site", str(site), "--session", "2"]) == 0
    table = capsys.readouterr().out
    assert "changes since session 1" in table and table.index("overall") < table.index("changes since")
    phantoms = [line for line in table.splitlines() if line.strip().startswith("phantom:")]
    assert len(phantoms) == changes["phantom"]
    assert all("(cabinet)" in line for line in phantoms)  # cabinet-2 stands where it stood
    # session 1 has no previous pass: everything it mapped is an addition
    first = json.loads(_evaluate_json(world, site, 1, capsys))["changes"]
    assert first["previous_session"] is None and first["removed"]["true"] == 0
    assert first["added"]["true"] == 12 and first["added"]["recall"] >= 0.9


def _evaluate_json(world: Path, site: Path, session: int, capsys) -> str:
    assert cli.main(["evaluate", "--world", str(world), "--site", str(site), "--session", str(session), "--json"]) == 0
    return capsys.readouterr().out


def test_association_params_reach_the_thresholds(tmp_path):
    """The change gate is the configuration's association distance, not a constant."""
    world = load_world(local_world("small_house"))
    _site_with_sessions(tmp_path, {1: 100.0, 2: 100.0})
    wide = Config(association=AssociationParams(per_category={"chair": 20.0}))
    # chair-2 moved 3.1 m in session 2: a move at 0.7 m, a nudge at 20 m
    assert ("moved", "chair-2") in _missed(evaluate_changes(world, tmp_path, 2, Config()))
    assert ("moved", "chair-2") not in _missed(evaluate_changes(world, tmp_path, 2, wide))
