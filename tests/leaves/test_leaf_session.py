"""Session, map, perception and the small common leaves, tick by tick on a scripted robot."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import py_trees
import pytest
from fake_robot import tick
from py_trees.common import Status

from behaviours.common import Fail, FailParams, Wait, WaitParams
from behaviours.perceive import PerceiveAssociate
from behaviours.save_map import SaveMap
from behaviours.session import EndSession, EndSessionParams, PairRelocations, StartSession
from bomc_bt.first_seen import FIRST_SEEN, SIGHTED_IN, UNSEEN_SIDES, SeenBefore
from bomc_bt.graph import AssociationParams, Event, Node, ObjectGraph, Observation
from bomc_bt.grid import OccupancyGrid, inflate_mask
from bomc_bt.monitoring import FrameResult
from bomc_bt.net_changes import net_changes
from bomc_bt.robot import RGBDFrame
from bomc_bt.sightings import Sightings


def test_start_session_opens_the_session_in_the_store(ctx):
    leaf = StartSession("Start", None, ctx)
    assert tick(leaf) == Status.SUCCESS and leaf.feedback_message.startswith("session 1 started")
    assert [r.number for r in ctx.store.sessions()] == [1]


def test_end_session_closes_it_and_the_report_says_how_the_robot_localized(ctx):
    tick(StartSession("Start", None, ctx))
    py_trees.blackboard.Blackboard.set("/localized", "global")  # what Relocalize wrote
    assert tick(EndSession("End", EndSessionParams(outcome="completed"), ctx)) == Status.SUCCESS
    report = json.loads((ctx.site.session_dir(1) / "report.json").read_text())
    assert report["outcome"] == "completed" and report["localized"] == "global"
    assert ctx.store.sessions()[0].outcome == "completed"


def test_an_unlocalized_pass_reports_so(ctx):
    tick(StartSession("Start", None, ctx))
    tick(EndSession("Close", EndSessionParams(outcome="aborted"), ctx))
    assert json.loads((ctx.site.session_dir(1) / "report.json").read_text())["localized"] == "no"


def test_save_map_writes_the_map_and_the_build_record(ctx):
    leaf = SaveMap("Save", None, ctx)
    assert tick(leaf) == Status.SUCCESS
    assert ctx.site.map_yaml.exists() and ctx.site.build_json.exists()
    assert json.loads(ctx.site.build_json.read_text())["termination"] == "not started"


class CountingPerception:
    """Stands in for :class:`bomc_bt.monitoring.Perception`: counts the frames it is given."""

    def __init__(self):
        self.frames = 0
        self.events: list = []

    def process(self, frame):
        self.frames += 1
        return FrameResult(detections=2, observations=2, expected=1, events=[])


def frame() -> RGBDFrame:
    return RGBDFrame(0.0, None, np.zeros((4, 4), np.float32), np.eye(3), np.eye(4), np.eye(4))


def test_perceive_associate_runs_forever_and_processes_each_localized_frame(ctx, robot):
    ctx.perception = CountingPerception()
    leaf = PerceiveAssociate("Perceive", None, ctx)
    robot.distance_travelled = 2.5
    assert tick(leaf) == Status.RUNNING and ctx.perception.frames == 0  # no frame yet
    assert ctx.progress.path_length == 2.5  # the progress line and the viewer's header say how far (issue 19)
    robot.frames.append(frame())
    assert tick(leaf) == Status.RUNNING and ctx.perception.frames == 1 == ctx.progress.frames
    assert "2 detections, 1 expected" in leaf.feedback_message
    robot.place(None)
    robot.frames.append(frame())
    assert tick(leaf) == Status.RUNNING and ctx.perception.frames == 1
    assert leaf.feedback_message == "not localized: frame skipped"


def test_fail_gives_its_reason_to_the_mission_unless_it_has_one(ctx):
    assert tick(Fail("Fail", FailParams("exploration failed"), ctx)) == Status.FAILURE
    assert ctx.reason == "exploration failed"
    tick(Fail("Fail Again", FailParams("something else"), ctx))
    assert ctx.reason == "exploration failed"


def test_wait_waits_on_the_robot_clock(ctx, robot):
    leaf = Wait("Wait", WaitParams(duration=2.0), ctx)
    assert tick(leaf) == Status.RUNNING
    robot.advance(1.9)
    assert tick(leaf) == Status.RUNNING
    robot.advance(0.1)
    assert tick(leaf) == Status.SUCCESS


def chair_moved_4_m(ctx, first_seen: bool) -> None:
    """Session 2 of a site whose chair 0 (session 1, at the origin) now stands 4 m away:
    the pass added a node there and confirmed the chair's absence at the origin."""
    params = AssociationParams(confirm_misses=1, confirm_detections=1)
    ctx.graph = ObjectGraph(params, [Node(0, "chair", np.array([0.0, 0.0, 0.45]), 0.9, 1, 1, observations=9)])
    ctx.session = 2
    seen = Observation("chair", np.array([4.0, 0.0, 0.45]), 0.9, 500, 0.0)
    events = ctx.graph.associate([seen], [], 2, 10.0)
    if first_seen:
        events[0].detail = {**(events[0].detail or {}), "first_seen": True}
    events += ctx.graph.associate([], [0], 2, 11.0)
    ctx.store.record(events, ctx.graph.drain_changed())


def test_pair_relocations_makes_a_removal_and_an_addition_one_move_in_the_store(ctx):
    chair_moved_4_m(ctx, first_seen=False)
    leaf = PairRelocations("Pair", None, ctx)
    assert tick(leaf) == Status.SUCCESS and leaf.feedback_message.startswith("1 removal(s) paired")
    assert [(e.kind, e.node_id) for e in ctx.store.events(session=2)][-1] == ("moved", 0)
    assert [n.id for n in ctx.store.nodes()] == [0]


def test_pair_relocations_leaves_a_first_seen_node_as_it_is(ctx):
    chair_moved_4_m(ctx, first_seen=True)
    leaf = PairRelocations("Pair", None, ctx)
    assert tick(leaf) == Status.SUCCESS and leaf.feedback_message.startswith("0 removal(s)")
    assert "moved" not in [e.kind for e in ctx.store.events(session=2)] and 0 not in ctx.graph.nodes


def test_pair_relocations_reports_a_chair_back_where_an_earlier_pass_saw_it_go(ctx):
    """Pass 2 saw chair 5 go from (4, 0); in pass 3 chair 0 is gone from (0, 0) and a chair
    stands at (4.1, 0): chair 5 back, not chair 0 moved 4 m (within relocation_radius)."""
    params = AssociationParams(confirm_misses=1, confirm_detections=1)
    chairs = [Node(0, "chair", np.array([0.0, 0.0, 0.45]), 0.9, 1, 1, observations=9),
              Node(5, "chair", np.array([4.0, 0.0, 0.45]), 0.9, 1, 1, observations=9)]
    for n in (1, 2):
        ctx.store.begin_session(n, {"stamp": 0.0})
    ctx.store.record([Event("added", c.id, "chair", c.position, 1, 1.0) for c in chairs], chairs)
    ctx.graph = ObjectGraph(params, chairs, next_id=6)
    ctx.store.record(ctx.graph.associate([], [5], 2, 10.0), ctx.graph.drain_changed())  # chair 5 missed: gone
    ctx.session = 3
    events = ctx.graph.associate([Observation("chair", np.array([4.1, 0.0, 0.45]), 0.9, 500, 0.0)], [0], 3, 20.0)
    ctx.store.record(events, ctx.graph.drain_changed())
    assert [(e.kind, e.node_id) for e in events] == [("removed", 0), ("added", 6)]
    leaf = PairRelocations("Pair", None, ctx)
    assert tick(leaf) == Status.SUCCESS
    assert leaf.feedback_message == "0 removal(s) paired with an addition as moved; 1 brought back: chair #6"
    last = ctx.store.events(session=3)[-1]
    assert (last.kind, last.node_id, last.detail) == ("updated", 6, {"back_of": 5})
    assert "moved" not in [e.kind for e in ctx.store.events(session=3)] and 0 not in ctx.graph.nodes


def test_pair_relocations_takes_back_a_move_onto_a_neighbour_found_late(ctx):
    """Chair 0 (session 1) hidden behind its neighbour, which no pass had given a node:
    the pass moved chair 0's node onto the neighbour, then saw chair 0 where it stands."""
    params = AssociationParams(confirm_misses=1, confirm_detections=1)
    ctx.graph = ObjectGraph(params, [Node(0, "chair", np.array([0.0, 0.0, 0.45]), 0.9, 1, 1, observations=9)])
    ctx.session = 2

    def chair(x: float) -> Observation:
        return Observation("chair", np.array([x, 0.0, 0.45]), 0.9, 500, 0.0)

    events = ctx.graph.associate([chair(0.75)], [0], 2, 10.0)  # chair 0 missed, its neighbour seen
    events += ctx.graph.associate([chair(0.0), chair(0.75)], [0], 2, 20.0)
    ctx.store.record(events, ctx.graph.drain_changed())
    leaf = PairRelocations("Pair", None, ctx)
    assert tick(leaf) == Status.SUCCESS and leaf.feedback_message.endswith("1 move(s) taken back: chair #0")
    stored = {n.id: n.position[0] for n in ctx.store.nodes()}
    assert abs(stored[0]) < 1e-9 and abs(stored[1] - 0.75) < 1e-9


def test_pair_relocations_marks_a_table_seen_whole_after_one_end_as_refined_in_the_store(ctx):
    """Pass 1 saw a 2 m table's west 0.5 m; pass 2 sees it whole and its node goes 0.75 m to
    the middle. The leaf stores the refinement, so the pass reports no move."""
    from bomc_bt.graph.refinement import REFINED_FROM
    from bomc_bt.net_changes import net_changes

    table = Node(0, "table", np.array([0.25, 0.0, 0.375]), 0.9, 1, 1, observations=9,
                 footprint=np.array([0.0, -0.4, 0.5, 0.4]))
    ctx.store.record([ctx.graph.report("added", table, 1, 5.0)], [table])
    ctx.graph = ObjectGraph(AssociationParams(), [table])
    ctx.session = 2
    whole = Observation("table", np.array([1.0, 0.0, 0.375]), 0.9, 2000, 1.0, box=np.array([0.0, -0.4, 2.0, 0.4]))
    ctx.store.record(ctx.graph.associate([whole], [0], 2, 10.0), ctx.graph.drain_changed())
    assert tick(PairRelocations("Pair", None, ctx)) == Status.SUCCESS
    last = ctx.store.events(session=2)[-1]
    assert last.kind == "updated" and last.detail[REFINED_FROM][0] == 0.25
    assert net_changes(ctx.store.events(until=2), 1, ctx.graph.threshold) == []


def door_added_off_its_middle(ctx, seen) -> None:
    """Pass 2 of a site whose pass 1 (one chair far off) detected a door at (5.0, 5.0) without
    confirming it: pass 2's first view of the door put its node 0.55 m along the wall, beyond
    the sighting radius, so the frame marked it an addition; its later views brought it to
    5.05 m."""
    ctx.graph = ObjectGraph(AssociationParams(confirm_detections=1))
    for n in (1, 2):
        ctx.store.begin_session(n, {"stamp": 0.0})
    ctx.store.record([Event("added", 99, "chair", np.array([9.0, 9.0, 0.4]), 1, 1.0)], [])
    ctx.session = 2
    events = ctx.graph.associate([Observation("door", np.array([5.55, 5.0, 1.0]), 0.9, 500, 0.0)], [], 2, 10.0)
    seen.mark(events)
    ctx.store.record(events, ctx.graph.drain_changed())
    ctx.graph.nodes[0].position = np.array([5.05, 5.0, 1.0])
    ctx.perception = SimpleNamespace(seen_before=seen, events=[])


def door_sighted_in_pass_1() -> SeenBefore:
    grid = OccupancyGrid(np.zeros((100, 100), dtype=np.int8), 0.1, (0.0, 0.0))
    sightings = Sightings(grid)
    sightings.add([Observation("door", np.array([5.0, 5.0, 1.0]), 0.9, 500, 0.0)])
    return SeenBefore(grid, np.ones(grid.data.shape, dtype=bool),
                      {c: inflate_mask(m, 0.35 / grid.resolution) for c, m in sightings.masks.items()}, 1)


def net_kind(ctx, node_id: int) -> str:
    return {c.node_id: c.kind for c in net_changes(ctx.store.events(until=2), 1, lambda _c: 0.7)}[node_id]


def test_pair_relocations_judges_each_addition_again_where_it_stands(ctx):
    door_added_off_its_middle(ctx, door_sighted_in_pass_1())
    assert net_kind(ctx, 0) == "added"
    leaf = PairRelocations("Pair", None, ctx)
    assert tick(leaf) == Status.SUCCESS and "1 addition(s) judged again" in leaf.feedback_message
    assert net_kind(ctx, 0) == "first_seen"  # the door pass 1 had detected, not a change
    assert [e.detail for e in ctx.store.events(session=2) if e.kind == "updated"] == [
        {FIRST_SEEN: True, SIGHTED_IN: 1}]
    assert tick(PairRelocations("Pair Again", None, ctx)) == Status.SUCCESS  # a resumed pass ending again
    assert len([e for e in ctx.store.events(session=2) if e.kind == "updated"]) == 1


@pytest.mark.parametrize("looked_from, kind", [((0, 3, 4, 7), "first_seen"), ((0, 2), "added")])
def test_pair_relocations_calls_a_door_first_seen_that_pass_1_looked_at_only_edge_on(ctx, looked_from, kind):
    """Pass 1 looked at the whole floor from the sides ``looked_from`` (bomc_bt.looked_sides);
    the door this pass added, its leaf along x, faces sides 1, 2, 5 and 6. Looked at only
    edge-on, it is first seen; looked at from side 2 too, pass 1 would have seen it: added."""
    grid = OccupancyGrid(np.zeros((100, 100), dtype=np.int8), 0.1, (0.0, 0.0))
    bits = np.full(grid.data.shape, sum(1 << s for s in looked_from), np.uint8)
    door_added_off_its_middle(ctx, SeenBefore(grid, np.ones(grid.data.shape, dtype=bool), side_seen=bits,
                                              side_count=8, face_deg=45.0))
    ctx.graph.nodes[0].footprint = np.array([4.6, 4.97, 5.5, 5.03])
    assert tick(PairRelocations("Pair", None, ctx)) == Status.SUCCESS
    assert net_kind(ctx, 0) == kind
    judged = [e.detail for e in ctx.store.events(session=2) if e.kind == "updated"]
    assert judged == ([{FIRST_SEEN: True, UNSEEN_SIDES: [1, 2, 5, 6]}] if kind == "first_seen" else [])


def test_pair_relocations_judges_nothing_where_what_earlier_passes_saw_is_unknown(ctx):
    door_added_off_its_middle(ctx, door_sighted_in_pass_1())
    ctx.perception = SimpleNamespace(seen_before=None, events=[])
    leaf = PairRelocations("Pair", None, ctx)
    assert tick(leaf) == Status.SUCCESS and "judged again" not in leaf.feedback_message
    assert net_kind(ctx, 0) == "added"


def test_pair_relocations_saves_what_the_next_pass_carries_with_a_node_brought_back(ctx):
    """Pass 2 missed chair 5 from south of it (one miss removes at confirm_misses 1); pass 3
    finds a chair at its place. The pass end's state, the new node holding chair 5's sides
    with that miss counted against the south side, is what pass 4 reads (bomc_bt.graph.view_sides)."""
    from bomc_bt.graph.view_sides import side_of
    from bomc_bt.monitoring import Perception
    from bomc_bt.pass_resume import earlier_sides
    from bomc_bt.perception.projection import ProjectionParams

    params = AssociationParams(confirm_misses=1, confirm_detections=1)
    chair = Node(5, "chair", np.array([4.0, 0.0, 0.45]), 0.9, 1, 1, observations=9)
    for n in (1, 2, 3):
        ctx.store.begin_session(n, {"stamp": 0.0})
    ctx.store.record([Event("added", 5, "chair", chair.position, 1, 1.0)], [chair])
    ctx.graph = ObjectGraph(params, [chair], next_id=6)
    south = np.array([4.0, -2.0])
    ctx.store.record(ctx.graph.associate([], [5], 2, 10.0, place=south), ctx.graph.drain_changed())
    ctx.store.end_session(2, "completed", {"stamp": 11.0}, (), {})
    ctx.session = 3
    grid = OccupancyGrid(np.zeros((80, 80), dtype=np.int8), 0.1, (0.0, -4.0))
    ctx.perception = Perception(None, ctx.robot, ["chair"], ProjectionParams(), ctx.graph, ctx.store, 3, grid)
    events = ctx.graph.associate([Observation("chair", np.array([4.05, 0.0, 0.45]), 0.9, 500, 0.0)], [], 3, 20.0,
                                 place=np.array([4.0, 2.0]))
    ctx.store.record(events, ctx.graph.drain_changed())
    leaf = PairRelocations("Pair", None, ctx)
    assert tick(leaf) == Status.SUCCESS and leaf.feedback_message.endswith("1 brought back: chair #6")
    saved = earlier_sides(ctx.store, 4)
    missed = np.asarray(saved["counts"]["6"])[8:]
    assert missed.sum() == 1.0 and missed.argmax() == side_of(chair.position, south, 8)
    assert "5" not in saved["counts"] and "5" not in saved["removals"]
