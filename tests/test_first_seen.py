"""First seen or added (issue 17): an object appearing where no earlier pass looked is new to
the map, not a change; only one appearing where an earlier pass saw the floor is "added"."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from bomc_bt.algorithm_params import ProjectionParams
from bomc_bt.change_evaluation import reported_changes, score_changes, true_changes
from bomc_bt.errors import BomcError
from bomc_bt.first_seen import (
    FIRST_SEEN,
    SeenBefore,
    is_first_seen,
    load_seen_before,
    previous_sightings,
    saved_coverage,
)
from bomc_bt.graph import AssociationParams, Event, ObjectGraph
from bomc_bt.grid import OccupancyGrid, inflate_mask
from bomc_bt.monitoring import Perception
from bomc_bt.net_changes import net_changes, summarize
from bomc_bt.pass_resume import coverage_key, looked_key, pack_mask
from bomc_bt.store import SiteStore


def d07(_category: str) -> float:
    return 0.7


def grid_10m() -> OccupancyGrid:
    """A 10 x 10 m free floor at 0.1 m per cell, origin (0, 0)."""
    return OccupancyGrid(np.zeros((100, 100), dtype=np.int8), 0.1, (0.0, 0.0))


def left_half(grid: OccupancyGrid) -> np.ndarray:
    """The mask of what a pass saw: x < 5 m."""
    mask = np.zeros(grid.data.shape, dtype=np.uint8)
    mask[:, :50] = 1
    return mask


def added(i: int, x: float, session: int = 2, cat: str = "chair") -> Event:
    return Event("added", i, cat, np.array([x, 5.0, 0.4]), session, 10.0 + i)


def stored_site(path: Path, masks: dict[int, np.ndarray | None]) -> SiteStore:
    """A store whose sessions ended with the given coverage masks (None: no mask saved)."""
    store = SiteStore(path)
    for n, mask in masks.items():
        store.begin_session(n, {"stamp": 0.0})
        store.end_session(n, "succeeded", {"stamp": 1.0}, (),
                          {} if mask is None else {coverage_key(n): pack_mask(mask)})
    return store


# ---------------------------------------------------------------- marking and netting
def test_an_addition_beyond_the_floor_earlier_passes_saw_is_first_seen_within_the_margin_added():
    grid = grid_10m()
    seen = SeenBefore(grid, inflate_mask(left_half(grid).astype(bool), 0.3 / grid.resolution))
    events = [added(1, 2.0), added(2, 5.2), added(3, 8.0), added(4, 50.0),
              Event("moved", 5, "chair", np.array([9.0, 5.0, 0.4]), 2, 20.0, np.array([1.0, 5.0, 0.4]))]
    assert seen.mark(events) == 2
    marked = [e.node_id for e in events if (e.detail or {}).get(FIRST_SEEN)]
    assert marked == [3, 4]  # beyond the margin and off the map; not a move, whatever its end


def test_never_looked_is_the_floor_no_earlier_pass_saw_and_perception_hands_it_to_the_graph():
    """What the robust policy asks before it takes an object for a removed one's new place
    (:func:`bomc_bt.graph.robust._never_looked`): the same mask the marking uses."""
    grid = grid_10m()
    seen = SeenBefore(grid, inflate_mask(left_half(grid).astype(bool), 0.3 / grid.resolution))
    assert not seen.never_looked(np.array([2.0, 5.0, 0.4])) and not seen.never_looked(np.array([5.2, 5.0]))
    assert seen.never_looked(np.array([8.0, 5.0])) and seen.never_looked(np.array([50.0, 5.0]))
    graph = ObjectGraph(AssociationParams())
    Perception(None, None, [], ProjectionParams(), graph, None, 2, grid, seen_before=seen)
    assert graph.never_looked(np.array([8.0, 5.0])) and not graph.never_looked(np.array([2.0, 5.0]))
    Perception(None, None, [], ProjectionParams(), other := ObjectGraph(AssociationParams()), None, 2, grid)
    assert other.never_looked is None  # nothing known: every place counts as looked at


def test_net_changes_lists_first_seen_nodes_apart_and_evaluation_does_not_score_them():
    session_1 = [added(0, 1.0, session=1)]
    new_place, old_place = added(1, 8.0), added(2, 2.0)
    new_place.detail = {FIRST_SEEN: True}
    history = session_1 + [new_place, old_place]
    changes = net_changes(history, 1, d07)
    assert [(c.kind, c.node_id) for c in changes] == [("added", 2), ("first_seen", 1)]
    assert summarize(changes) == {"removed": 0, "added": 1, "moved": 0}  # the counts are changes only
    assert "first seen chair #1 at (8.00, 5.00)" in changes[1].describe()
    # against the empty map everything is an addition, marked or not (session 1's protocol)
    assert [c.kind for c in net_changes(history, None, d07)] == ["added"] * 3
    # the evaluation: the first-seen node was always there (no true change), so it is no false positive
    truth = true_changes({"chair-a": ("chair", np.array([1.0, 5.0, 0.4])),
                          "chair-b": ("chair", np.array([8.0, 5.0, 0.4]))},
                         {"chair-a": ("chair", np.array([1.0, 5.0, 0.4])),
                          "chair-b": ("chair", np.array([8.0, 5.0, 0.4])),
                          "chair-c": ("chair", np.array([2.0, 5.0, 0.4]))}, d07)
    result = score_changes(truth, reported_changes(history, 1, d07), d07, 2, 1)
    assert (result.overall.tp, result.overall.fp, result.overall.fn, result.phantom) == (1, 0, 0, 0)
    # without the mark (the old behaviour) the same history has a phantom addition
    new_place.detail = None
    old = score_changes(truth, reported_changes(history, 1, d07), d07, 2, 1)
    assert (old.overall.fp, old.phantom) == (1, 1)


# ---------------------------------------------------------------- the store
def test_the_masks_saved_at_session_ends_are_what_the_next_pass_loads(tmp_path):
    grid = grid_10m()
    right = 1 - left_half(grid)
    with stored_site(tmp_path / "site.db", {1: left_half(grid)}) as store:
        assert load_seen_before(store, 1, grid, 0.3) is None  # the first pass: nothing marked
        seen = load_seen_before(store, 2, grid, 0.3)
        assert seen.saw(np.array([[4.0, 5.0], [4.95, 5.0], [5.2, 5.0]])).tolist() == [True, True, False]
        store.begin_session(2, {"stamp": 0.0})
        store.end_session(2, "succeeded", {"stamp": 1.0}, (), {coverage_key(2): pack_mask(right)})
        assert load_seen_before(store, 3, grid, 0.0).seen.all()  # the union of both passes
    # read back read-only, as another process would: the same mask
    with SiteStore(tmp_path / "site.db", readonly=True) as store:
        assert np.array_equal(saved_coverage(store, 2, grid.data.shape), right.astype(bool))


def test_an_object_just_beyond_the_looked_floor_is_first_seen_one_in_a_wall_beside_it_is_added(tmp_path):
    """The fan stops at whatever stands on the floor, so an undetected chair cuts it at its
    near face and its centre lies 0.1-0.3 m beyond: the floor is not widened, and finding the
    chair later is "first seen". A door's centre lies in its wall, where no fan reaches: the
    wall within the margin of the looked floor counts as seen, and a new door there is "added"."""
    grid = grid_10m()
    grid.data[:60, 50:52] = 100  # a wall 0.2 m thick at x = 5.0-5.2 m, for y < 6 m
    with stored_site(tmp_path / "site.db", {1: left_half(grid)}) as store:
        seen = load_seen_before(store, 2, grid, 0.3)
    chair, door, behind_the_wall = added(1, 5.15), added(2, 5.1), added(3, 5.35)
    chair.position[1], door.position[1], behind_the_wall.position[1] = 8.0, 3.0, 3.0
    assert seen.mark([chair, door, behind_the_wall]) == 2
    assert [is_first_seen(e) for e in (chair, door, behind_the_wall)] == [True, False, True]
    # widening the floor too (the old rule) would have called the chair an addition
    old = SeenBefore(grid, inflate_mask(left_half(grid).astype(bool), 3))
    chair.detail = None
    assert old.mark([chair]) == 0


def test_an_earlier_pass_without_a_saved_mask_means_unknown_and_nothing_is_marked(tmp_path):
    grid = grid_10m()
    with stored_site(tmp_path / "site.db", {1: None, 2: left_half(grid)}) as store:
        assert load_seen_before(store, 3, grid, 0.3) is None  # an old site: additions stay "added"


def test_a_mask_that_is_not_of_this_map_is_one_line_naming_the_key(tmp_path):
    grid = grid_10m()
    with stored_site(tmp_path / "site.db", {1: np.ones((20, 20), dtype=np.uint8)}) as store, \
            pytest.raises(BomcError) as err:
        load_seen_before(store, 2, grid, 0.3)
    assert err.value.field == "progress.coverage/1" and "not a mask of this map" in str(err.value)
    with sqlite3.connect(tmp_path / "site.db") as con:
        con.execute("UPDATE progress SET value=? WHERE key='coverage/1'", (json.dumps("not base64!"),))
    with SiteStore(tmp_path / "site.db", readonly=True) as store, pytest.raises(BomcError):
        saved_coverage(store, 1, grid.data.shape)


def test_end_session_writes_the_mask_in_the_transaction_that_closes_the_pass(tmp_path):
    grid = grid_10m()
    with stored_site(tmp_path / "site.db", {}) as store:
        store.begin_session(1, {"stamp": 0.0})
        with pytest.raises(BomcError):  # a session never begun: nothing of the end is written
            store.end_session(7, "succeeded", {"stamp": 1.0}, (), {coverage_key(7): pack_mask(left_half(grid))})
        assert store.get_progress(coverage_key(7)) is None


# ---------------------------------------------------------------- a pass in the simulator
def _place_in(seen: np.ndarray, grid: OccupancyGrid, objects: np.ndarray) -> tuple[float, float]:
    """The free floor cell pass 1 saw that lies deepest inside what it saw, 1.5 m or more from
    every object: where a new object is a change the map can tell."""
    import cv2

    inside = (seen & grid.free_mask()).astype(np.uint8)
    depth = cv2.distanceTransform(inside, cv2.DIST_L2, 5)
    ys, xs = np.nonzero(depth > 0)
    x, y = grid.cell_to_world(ys, xs)
    far = np.min(np.hypot(x[:, None] - objects[None, :, 0], y[:, None] - objects[None, :, 1]), axis=1) >= 1.5
    best = np.argmax(np.where(far, depth[ys, xs], -1.0))
    assert far[best], "pass 1 saw no free floor away from the objects"
    return round(float(x[best]), 2), round(float(y[best]), 2)


def test_objects_pass_1_never_saw_are_first_seen_and_a_new_bin_where_it_looked_is_added(tmp_path):
    """A pass 1 with a short budget sees a third of a generated office; before pass 2 a trash
    bin is put in the middle of what it saw. Pass 2 (full) must report the bin as added and
    the objects pass 1 could not see as first seen: not as changes, in the report, in ``bomc
    changes`` and in ``bomc evaluate``'s scores (the old code reported them all as added)."""
    import yaml

    from bomc_bt import run
    from bomc_bt.evaluate_changes import changes_to_json, evaluate_changes
    from bomc_bt.grid import load_map
    from bomc_bt.officegen import OfficeParams, generate_office
    from bomc_bt.site.formats import format_changes
    from bomc_bt.site.query import open_site
    from bomc_bt.viewer.site import SiteView
    from bomc_bt.world import load_world

    world_path, site = tmp_path / "office.yaml", tmp_path / "site"
    generate_office(OfficeParams(width=16, height=12, seed=3, sessions=2, static=True), world_path)
    config = run.build_config()
    assert run.run_build(world_path, site, seed=0, config=config).succeeded
    config.budget.seconds = 60.0  # about a third of the floor
    assert run.run_monitor(world_path, site, 1, seed=1, config=config).succeeded
    grid = load_map(site / "map.yaml")
    with SiteStore(site, readonly=True) as store:  # what pass 1 saw within the camera's reach
        seen_1 = saved_coverage(store, 1, grid.data.shape, looked_key(1))
    objects = load_world(world_path).ground_truth(1)
    xy = np.array([o.position[:2] for o in objects.values()])
    rows, cols = grid.world_to_cell(xy[:, 0], xy[:, 1])
    unseen = {name for name, s in zip(objects, seen_1[rows, cols], strict=True) if not s}
    assert len(unseen) >= 3, "the budget must leave objects pass 1 cannot see"
    bin_xy = _place_in(seen_1, grid, xy)
    data = yaml.safe_load(world_path.read_text())
    data["sessions"] = {2: {"add": [{"name": "bin-new", "category": "trash bin", "position": [*bin_xy, 0.3],
                                     "size": [0.4, 0.4, 0.6]}]}}
    world_path.write_text(yaml.safe_dump(data))
    config.budget.seconds = 0.0
    assert run.run_monitor(world_path, site, 2, seed=2, config=config).succeeded

    report = json.loads((site / "sessions" / "2" / "report.json").read_text())["changes"]
    by_kind = {k: [c for c in report["nodes"] if c["kind"] == k] for k in ("added", "first_seen")}
    assert [c["category"] for c in by_kind["added"]
            if np.hypot(c["new"][0] - bin_xy[0], c["new"][1] - bin_xy[1]) < 0.7] == ["trash bin"]
    assert report["first_seen"] == len(by_kind["first_seen"]) >= 2
    assert report["counts"]["added"] == len(by_kind["added"])  # the counts are changes only
    markdown = (site / "sessions" / "2" / "report.md").read_text()
    assert f"## First seen: {report['first_seen']}" in markdown
    # every first-seen node is an object that stood there in session 1 and that pass 1 did not map
    with SiteStore(site, readonly=True) as store:
        mapped_1 = store.graph_after(1)
        sighted_1 = previous_sightings(store, 1, grid, 0.35)  # where pass 1's detections put objects
    for n in mapped_1:  # every node pass 1 mapped stands where its detections were
        assert SeenBefore(grid, seen_1).saw(n.position[:2], sighted_1[n.category])[0], n
    for c in by_kind["first_seen"]:  # the nearest object of its category (two chairs may stand 0.8 m apart)
        there = sorted((np.hypot(o.position[0] - c["new"][0], o.position[1] - c["new"][1]), name)
                       for name, o in objects.items() if o.category == c["category"])
        assert there and there[0][0] < 0.7, c
        obj = objects[there[0][1]]
        assert not [n for n in mapped_1 if n.category == c["category"] and np.hypot(
            *(n.position[:2] - obj.position[:2])) < 0.7], c
    # bomc changes says the same
    with open_site(site) as reader:
        (pass_2,) = reader.changes(since=1)
    assert sorted(c.kind for c in pass_2.changes) == sorted(c["kind"] for c in report["nodes"])
    assert format_changes([pass_2], "table").splitlines()[0] == \
        f"session 2 (since session 1): {len(by_kind['added'])} change(s), {report['first_seen']} first seen"
    # the viewer's difference of sessions 1 and 2 lists them apart from the additions
    diff = SiteView(site).diff(1, 2)
    assert [n["id"] for n in diff["first_seen"]] == [c["node"] for c in by_kind["first_seen"]]
    assert [n["id"] for n in diff["added"]] == [c["node"] for c in by_kind["added"]]
    # bomc evaluate: the first-seen objects were always there; they are no false additions
    result = evaluate_changes(world_path, site, 2, config)
    assert result.first_seen == report["first_seen"] and result.kinds["added"].tp == 1
    assert result.kinds["added"].fp == len(by_kind["added"]) - 1
    assert changes_to_json(result)["first_seen"] == report["first_seen"]
    # session 1, against the empty map, is scored as before: all it found is added
    first = evaluate_changes(world_path, site, 1, config)
    assert first.first_seen == 0 and first.kinds["added"].mapped == first.kinds["added"].tp + first.kinds["added"].fp


def test_the_change_model_does_not_count_a_first_seen_object_as_a_change_of_its_region():
    from bomc_bt.algorithm_params import BudgetParams
    from bomc_bt.change_model import ChangeModel, RegionGrid, region_rows

    grid = grid_10m()
    regions = RegionGrid(grid, 4.0)
    everything = np.ones(grid.data.shape, dtype=np.uint8)
    model = ChangeModel(regions, BudgetParams(), region_rows(regions, everything, [], 1, 1.0,
                                                             ChangeModel(regions, BudgetParams())))
    new_to_map, really_new = added(1, 1.0), added(2, 9.0)
    new_to_map.detail = {FIRST_SEEN: True}
    changes = net_changes([added(3, 5.0, session=1), new_to_map, really_new], 1, lambda _c: 0.7)
    assert [c.kind for c in changes] == ["added", "first_seen"]
    rows = region_rows(regions, everything, changes, 2, 2.0, model)
    changes = {(i, j): c for _s, _z, i, j, _seen, c, _t in rows}
    (ri,), (rj,), _ = regions.index(np.array([[9.0, 5.0]]))
    (fi,), (fj,), _ = regions.index(np.array([[1.0, 5.0]]))
    assert changes[(int(ri), int(rj))] == 1 and changes[(int(fi), int(fj))] == 0
    assert sum(changes.values()) == 1
