"""The change model (per region: rate, last seen, changes waiting) and the budget planner
(orienteering within a budget of robot time), and their rows in the site store."""

from __future__ import annotations

import sqlite3

import numpy as np
import pytest

from bomc_bt.algorithm_params import BudgetParams
from bomc_bt.budget_plan import orienteer
from bomc_bt.budget_stops import MarginalValue, StopCandidates, shortlist, target_weights
from bomc_bt.change_model import ChangeModel, RegionGrid, region_rows, skipped_regions
from bomc_bt.grid import OccupancyGrid
from bomc_bt.net_changes import NetChange
from bomc_bt.store import SiteStore
from bomc_bt.store_schema import SCHEMA, SCHEMA_VERSION


def floor(width_m: float = 12.0, height_m: float = 8.0) -> OccupancyGrid:
    return OccupancyGrid(np.zeros((int(height_m / 0.1), int(width_m / 0.1)), dtype=np.int8), 0.1, (0.0, 0.0))


def rows_for(session: int, seen: dict, changes: dict, shape=(2, 3), size=4.0) -> list[tuple]:
    return [(session, size, i, j, seen.get((i, j), 1.0), changes.get((i, j), 0), None)
            for i in range(shape[0]) for j in range(shape[1])]


def test_without_history_every_region_has_the_prior_rate_and_waits_in_proportion_to_time():
    params = BudgetParams(prior_rate=0.3)
    model = ChangeModel(RegionGrid(floor(), 4.0), params)
    assert model.rate.shape == (2, 3) and np.allclose(model.rate, 0.3)
    assert np.allclose(model.waiting(5), 0.3 * 5)


def test_a_region_that_changes_every_pass_gets_a_high_rate_and_one_that_never_does_a_low_one():
    params = BudgetParams(prior_rate=0.3, prior_weight=1.0)
    history = rows_for(1, {}, {})
    for s in range(2, 8):
        history += rows_for(s, {}, {(0, 0): 2})
    model = ChangeModel(RegionGrid(floor(), 4.0), params, history)
    assert model.rate[0, 0] == pytest.approx((12 + 0.3) / 7)
    assert model.rate[1, 2] == pytest.approx(0.3 / 7)
    waiting = model.waiting(8)
    assert waiting[0, 0] > 10 * waiting[1, 2]


def test_a_region_left_unseen_accumulates_waiting_changes_until_max_wait():
    params = BudgetParams(max_wait=3)
    history = rows_for(1, {}, {}) + rows_for(2, {(1, 1): 0.0}, {})
    model = ChangeModel(RegionGrid(floor(), 4.0), params, history)
    assert model.passes_since(3)[1, 1] == 2 and model.passes_since(3)[0, 0] == 1
    assert model.waiting(10)[1, 1] == pytest.approx(model.rate[1, 1] * 3)


def test_pass_rows_count_changes_only_where_an_earlier_pass_looked():
    grid = floor()
    regions = RegionGrid(grid, 4.0)
    model = ChangeModel(regions, BudgetParams(), rows_for(1, {(0, 1): 0.0}, {}))
    def change(kind, node, old, new):
        return NetChange(kind, node, "chair", None if old is None else np.array([*old, 0.4]),
                         None if new is None else np.array([*new, 0.4]), 0.0, None, None, 2, 5.0, 1)

    changes = [change("added", 1, None, (1.0, 1.0)),  # region (0, 0): seen before
               change("added", 2, None, (5.0, 1.0)),  # region (0, 1): first look
               change("moved", 3, (1.5, 1.5), (9.0, 5.0))]
    seen = np.ones(grid.data.shape, dtype=bool)
    rows = {(r[2], r[3]): r for r in region_rows(regions, seen, changes, 2, 7.0, model)}
    assert rows[(0, 0)][5] == 2  # the add and the move's old place
    assert rows[(0, 1)][5] == 0
    assert rows[(1, 2)][5] == 1  # the move's new place
    assert all(r[4] == 1.0 for r in rows.values())


def test_skipped_regions_name_the_regions_a_pass_did_not_see_stalest_first():
    grid = floor()
    regions = RegionGrid(grid, 4.0)
    model = ChangeModel(regions, BudgetParams(), rows_for(1, {}, {}) + rows_for(2, {(1, 2): 0.0}, {}))
    seen = np.zeros(grid.data.shape, dtype=bool)
    seen[:40, :80] = True  # the two lower-left regions
    rows = region_rows(regions, seen, [], 3, None, model)
    skipped = skipped_regions(model, rows, 3)
    assert len(skipped) == 4
    assert skipped[0]["passes_since_seen"] == 3 and (skipped[0]["x"], skipped[0]["y"]) == (10.0, 6.0)


def ring(n: int, radius: float = 10.0) -> np.ndarray:
    """Distances between a dock at the centre and n stops on a circle (straight lines)."""
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = np.vstack([[0.0, 0.0], np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)])
    return np.hypot(*(pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))


def tour_seconds(dist, order, service, speed) -> float:
    route = [0, *[i + 1 for i in order], 0]
    return sum(dist[a, b] for a, b in zip(route[:-1], route[1:], strict=True)) / speed + sum(service[i] for i in order)


def test_a_budget_too_small_to_leave_the_dock_gives_the_empty_tour():
    dist = ring(6)
    tour = orienteer(dist, np.ones(6), np.full(6, 5.0), speed=0.5, budget=39.0)  # 10 m there and back: 40 s
    assert tour.order == [] and tour.seconds == 0.0


@pytest.mark.parametrize("seed", range(5))
def test_the_tours_driving_and_dwell_never_exceed_the_budget(seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-20, 20, size=(25, 2))
    dist = np.hypot(*(pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1)) * rng.uniform(1.0, 1.3)
    values, service = rng.uniform(0, 3, 24), rng.uniform(2, 12, 24)
    for budget in (30.0, 80.0, 200.0, 400.0):
        tour = orienteer(dist, values, service, speed=0.5, budget=budget)
        spent = tour_seconds(dist, tour.order, service, 0.5)
        assert spent <= budget + 1e-6 and tour.seconds == pytest.approx(spent)
        assert len(set(tour.order)) == len(tour.order)


def test_high_churn_stops_come_first_and_a_big_budget_takes_everything():
    dist = ring(8)
    values = np.array([0.1, 0.1, 5.0, 0.1, 0.1, 0.1, 4.0, 0.1])
    service = np.full(8, 4.0)
    small = orienteer(dist, values, service, speed=0.5, budget=60.0)
    assert small.order in ([2], [6])
    two = orienteer(dist, values, service, speed=0.5, budget=110.0)
    assert sorted(two.order) == [2, 6] or 2 in two.order
    everything = orienteer(dist, values, service, speed=0.5, budget=1e4)
    assert sorted(everything.order) == list(range(8))


def candidates(views: list[list[int]], shape=(1, 8), k: int = 1) -> StopCandidates:
    xy = np.array([[float(i), 0.0] for i in range(len(views))])
    return StopCandidates(xy, [np.array(v, dtype=np.int64) for v in views], shape, k, 0.25)


def test_target_weights_share_a_regions_waiting_changes_over_the_floor_seen_there():
    cands = candidates([[0, 1, 2, 3], [4, 5], [3, 4]])  # raster 1 x 8; region = col // 4; 6, 7 unseen
    weights = target_weights(cands, 4, np.array([[4.0, 2.0]]))
    assert weights.tolist() == [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0]  # region 1: 2 changes over 2 seen targets
    assert target_weights(cands, 4, None).tolist() == [0.0625] * 6 + [0.0, 0.0]


def test_a_stop_is_worth_only_what_the_tour_does_not_see_yet():
    value = MarginalValue([np.array([0, 1, 2, 3]), np.array([2, 3]), np.array([5])], np.array([1, 1, 1, 1, 0, 4.0]))
    assert value.values([]).tolist() == [4.0, 2.0, 4.0]
    assert value.values([0]).tolist() == [0.0, 0.0, 4.0]  # the second stop sees nothing new
    cands = candidates([[0, 1, 2, 3], [2, 3], [5]], shape=(1, 6))
    assert shortlist(cands, np.array([1, 1, 1, 1, 0, 4.0]), 5, (0.0, 0.0), 100.0) == [0, 2]


def test_two_stops_that_see_one_room_are_not_worth_two_rooms():
    """Stops 0 and 1 see the same hot room, stop 2 another: with the budget for two stops
    the tour takes one of each (with fixed values it would take both views of one room)."""
    dist = ring(3)
    value = MarginalValue([np.array([0, 1]), np.array([0, 1]), np.array([2])], np.array([3.0, 3.0, 4.0]))
    tour = orienteer(dist, value.values([]), np.full(3, 1.0), speed=1.0, budget=42.0, marginal=value.values)
    assert sorted(tour.order) in ([0, 2], [1, 2]) and tour.value == pytest.approx(10.0)


def test_a_version_3_store_is_upgraded_with_an_empty_region_history_and_read_as_it_is(tmp_path):
    path = tmp_path / "site.db"
    db = sqlite3.connect(path)
    db.executescript(SCHEMA.split("CREATE TABLE IF NOT EXISTS region_passes")[0]
                     + "INSERT INTO schema_version VALUES (3);")
    db.close()
    with SiteStore(path, readonly=True) as reader:
        assert reader.version == 3 and reader.region_rows() == []
    with SiteStore(path) as writer:
        assert writer.version == SCHEMA_VERSION and writer.region_rows() == []
        writer.begin_session(1, {"stamp": 0.0})
        writer.end_session(1, "completed", {"stamp": 9.0}, [(1, 4.0, 0, 0, 0.5, 0, 9.0)])
    with SiteStore(path, readonly=True) as reader:
        assert reader.region_rows() == [(1, 4.0, 0, 0, 0.5, 0, 9.0)]


def test_a_hot_region_only_glimpsed_keeps_its_rate_and_a_half_look_counts_half():
    params = BudgetParams(prior_rate=0.3, prior_weight=1.0, seen_share=0.3)
    history = rows_for(1, {}, {})
    for s in range(2, 5):  # full passes: two changes a pass in region (0, 0)
        history += rows_for(s, {}, {(0, 0): 2})
    hot = ChangeModel(RegionGrid(floor(), 4.0), params, history).rate[0, 0]
    glimpses = history + [r for s in range(5, 9) for r in rows_for(s, {(0, 0): 0.1}, {})]
    assert ChangeModel(RegionGrid(floor(), 4.0), params, glimpses).rate[0, 0] == pytest.approx(hot)
    half = ChangeModel(RegionGrid(floor(), 4.0), params, history + rows_for(5, {(0, 0): 0.5}, {})).rate[0, 0]
    assert half == pytest.approx((6 + 0.3) / (3 + 0.5 + 1))  # a full look finding nothing: (6.3) / 5


def test_coverage_counts_as_looked_at_only_the_floor_within_near_range():
    from bomc_bt.monitoring import Coverage
    grid = floor()
    coverage = Coverage(grid, near_range=3.0)
    coverage.add(np.array([[1.0, 4.0], [9.0, 1.0], [9.0, 7.0]]))  # a fan from (1, 4) reaching 8 m
    seen_x = np.nonzero(coverage.seen[40])[0] * 0.1
    near_x = np.nonzero(coverage.near[40])[0] * 0.1
    assert seen_x.max() > 8.5 and 3.5 < near_x.max() < 4.2 and near_x.min() == pytest.approx(seen_x.min())
    everything = Coverage(grid)
    everything.add(np.array([[1.0, 4.0], [9.0, 1.0], [9.0, 7.0]]))
    assert np.array_equal(everything.near, everything.seen)


def test_a_look_at_a_rooms_empty_half_does_not_count_where_its_objects_stand():
    grid = floor()
    regions = RegionGrid(grid, 4.0)
    model = ChangeModel(regions, BudgetParams(), rows_for(1, {}, {}))
    seen = np.zeros(grid.data.shape, dtype=bool)
    seen[:40, :20] = True  # the left half of region (0, 0), none of region (0, 1)
    objects = np.array([[3.5, 1.0], [3.5, 3.0], [6.0, 6.0]])  # two in the unseen half of (0, 0), one in (1, 1)
    rows = {(r[2], r[3]): r[4] for r in region_rows(regions, seen, [], 2, None, model, objects)}
    assert rows[(0, 0)] == 0.0  # half its floor seen, none of its objects: not a look
    seen[:40, :40] = True
    rows = {(r[2], r[3]): r[4] for r in region_rows(regions, seen, [], 2, None, model, objects)}
    assert rows[(0, 0)] == 1.0 and rows[(1, 1)] == 0.0
    assert {(r[2], r[3]): r[4] for r in region_rows(regions, seen, [], 2, None, model)}[(0, 0)] == 1.0


def test_a_door_added_and_taken_off_in_one_pass_or_a_chair_found_again_is_no_change_in_the_model():
    from bomc_bt.graph import Event
    from bomc_bt.net_changes import net_changes
    grid = floor()
    regions = RegionGrid(grid, 4.0)
    model = ChangeModel(regions, BudgetParams(), rows_for(1, {}, {}))
    history = [Event("added", 1, "chair", np.array([1.0, 1.0, 0.4]), 1, 1.0),
               Event("added", 2, "door", np.array([9.0, 5.0, 1.0]), 2, 5.0),  # a door seen from its other side
               Event("removed", 2, "door", np.array([9.0, 5.0, 1.0]), 2, 9.0),
               Event("removed", 1, "chair", np.array([1.0, 1.0, 0.4]), 2, 6.0),  # misses ran out behind a table
               Event("moved", 1, "chair", np.array([1.05, 1.0, 0.4]), 2, 7.0, np.array([1.0, 1.0, 0.4])),
               Event("added", 3, "bin", np.array([5.0, 1.0, 0.3]), 2, 8.0)]  # the one change
    changes = net_changes(history, 1, lambda _category: 0.5)
    seen = np.ones(grid.data.shape, dtype=bool)
    found = {(r[2], r[3]): r[5] for r in region_rows(regions, seen, changes, 2, 9.0, model)}
    assert found == {(0, 0): 0, (0, 1): 1, (0, 2): 0, (1, 0): 0, (1, 1): 0, (1, 2): 0}
