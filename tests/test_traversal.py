"""Traversal plan: spacing and coverage of sampled waypoints, TSP order, 2-opt, I/O."""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shared_data import require_shared, shared_path

from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OCCUPIED, OccupancyGrid, load_map
from bomc_bt.traversal import (
    TraversalParams,
    TraversalPlan,
    greedy_tsp,
    load_trajectory,
    path_length,
    plan_traversal,
    sample_waypoints,
    snap_to_free,
    two_opt,
)

LAB = shared_path("worlds/lab-b-map.yaml")

coords = st.floats(min_value=-30, max_value=30, allow_nan=False, allow_infinity=False)
paths = st.lists(st.tuples(coords, coords), min_size=1, max_size=150)


@settings(max_examples=60, deadline=None)
@given(paths, st.floats(min_value=0.3, max_value=5.0))
def test_sampled_waypoints_are_spaced_and_cover_the_path(points, spacing):
    xy = np.array(points, dtype=float)
    wp = sample_waypoints(xy, spacing)
    assert len(wp) >= 1
    d = np.hypot(wp[:, None, 0] - wp[None, :, 0], wp[:, None, 1] - wp[None, :, 1])
    np.fill_diagonal(d, np.inf)
    assert d.min() >= spacing - 1e-9  # every pair at least `spacing` apart
    cover = np.hypot(xy[:, None, 0] - wp[None, :, 0], xy[:, None, 1] - wp[None, :, 1]).min(axis=1)
    assert cover.max() < spacing + 1e-9  # every trajectory point near some waypoint
    np.testing.assert_array_equal(wp[0], xy[0])  # the walk starts at the path's start


def test_sampling_a_straight_line_keeps_every_spacing():
    xy = np.column_stack([np.linspace(0, 10, 1001), np.zeros(1001)])
    wp = sample_waypoints(xy, 2.0)
    np.testing.assert_allclose(wp[:, 0], [0, 2, 4, 6, 8, 10])


def test_revisited_corridor_does_not_duplicate_waypoints():
    """Driving a corridor out and back yields one set of waypoints, not two."""
    out = np.column_stack([np.linspace(0, 20, 400), np.zeros(400)])
    back = np.column_stack([np.linspace(20, 0, 400), np.full(400, 0.3)])
    wp = sample_waypoints(np.vstack([out, back]), 2.0)
    assert len(wp) == 10  # 0, 2.005, ... 18.045; the end (20) is within 2 m of 18.045
    assert (wp[:, 1] == 0.0).all()  # the way back added nothing


def test_greedy_tsp_on_hand_made_points():
    pts = np.array([[10.0, 0.0], [1.0, 0.0], [5.0, 0.0], [2.0, 0.0], [0.0, 3.0]])
    # from near the origin: nearest is (1,0), then (2,0), then (0,3) at 3.6 vs (5,0) at 3.0
    assert greedy_tsp(pts, (0.4, 0.0)) == [1, 3, 2, 0, 4]
    assert greedy_tsp(pts, (11.0, 0.0))[0] == 0  # starts at the point nearest the start
    assert greedy_tsp(np.zeros((0, 2)), (0, 0)) == []


def test_two_opt_fixes_a_crossing():
    pts = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [2.0, 1.0], [2.0, 0.0]])
    crossing = [0, 1, 2, 3, 4]  # zig-zag whose middle legs cross
    before = path_length(pts[0], pts[crossing])
    improved = two_opt(pts, crossing)
    after = path_length(pts[improved[0]], pts[improved])
    assert sorted(improved) == crossing
    assert after < before - 0.1


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(coords, coords), min_size=2, max_size=40, unique=True), st.tuples(coords, coords))
def test_two_opt_never_lengthens(points, start):
    pts = np.array(points)
    order = greedy_tsp(pts, start)
    for anchor in (None, start):
        improved = two_opt(pts, order, start_xy=anchor)
        assert sorted(improved) == sorted(order)
        s = pts[order[0]] if anchor is None else np.array(anchor)
        s2 = pts[improved[0]] if anchor is None else np.array(anchor)
        assert path_length(s2, pts[improved]) <= path_length(s, pts[order]) + 1e-9


def test_two_opt_with_custom_distance_matrix():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    d = np.abs(pts[:, None, 0] - pts[None, :, 0])
    d[1, 2] = d[2, 1] = 100.0  # a wall between points 1 and 2
    order = two_opt(pts, [0, 1, 2, 3], distance=d)
    legs = sum(d[a, b] for a, b in zip(order[:-1], order[1:], strict=True))
    assert legs < 100.0


def _serpentine(n: int = 4000) -> np.ndarray:
    """A lawnmower exploration of a 20 x 12 m area with small jitter."""
    rng = np.random.default_rng(3)
    rows = []
    for k, y in enumerate(np.arange(0.0, 12.0, 1.5)):
        xs = np.linspace(0, 20, n // 8)
        rows.append(np.column_stack([xs if k % 2 == 0 else xs[::-1], np.full(len(xs), y)]))
    xy = np.vstack(rows) + rng.normal(0, 0.05, (n // 8 * 8, 2))
    t = np.arange(len(xy)) * 0.1
    return np.column_stack([t, xy, np.zeros(len(xy))])


def test_plan_traversal_orders_from_the_start_and_is_deterministic():
    traj = _serpentine()
    start = Pose2D(20.0, 12.0, 0.0)
    plan = plan_traversal(traj, start, TraversalParams())
    again = plan_traversal(traj, start, TraversalParams())
    assert plan == again
    first = plan.waypoints[0]
    dists = [math.hypot(w.x - start.x, w.y - start.y) for w in plan.waypoints]
    assert math.hypot(first.x - start.x, first.y - start.y) == pytest.approx(min(dists))
    greedy = plan_traversal(traj, start, TraversalParams(two_opt=False))
    assert plan.euclidean_length <= greedy.euclidean_length + 1e-9
    assert len(plan.waypoints) == len(greedy.waypoints)
    # headings face the next waypoint
    w0, w1 = plan.waypoints[0], plan.waypoints[1]
    assert w0.yaw == pytest.approx(math.atan2(w1.y - w0.y, w1.x - w0.x))
    assert plan.grid_length is None


def test_plan_uses_injected_grid_distance():
    traj = _serpentine(800)
    calls = []

    def manhattan(a, b):
        calls.append((a, b))
        return abs(a[0] - b[0]) + abs(a[1] - b[1])

    plan = plan_traversal(traj, Pose2D(0, 0, 0), TraversalParams(), grid_distance=manhattan)
    assert len(calls) == len(plan.waypoints)  # one leg per waypoint, from the start
    assert plan.grid_length >= plan.euclidean_length - 1e-9


def test_plan_on_lab_b_with_the_grid_planner():
    from bomc_bt import planner as planner_mod

    require_shared(LAB)
    grid = load_map(LAB)
    planner = planner_mod.GridPlanner(grid, planner_mod.PlannerParams())
    # a loop around the lab, clear of the walls
    t = np.linspace(0, 2 * math.pi, 600)
    xy = np.column_stack([4.5 + 3.0 * np.cos(t), 9.5 + 2.5 * np.sin(t)])
    traj = np.column_stack([t, xy, np.zeros(len(t))])
    plan = plan_traversal(traj, Pose2D(4.5, 9.5, 0.0), TraversalParams(), grid_distance=planner.distance)
    assert plan.grid_length is not None and math.isfinite(plan.grid_length)
    assert plan.grid_length >= plan.euclidean_length - 0.2


def test_snap_to_free_moves_or_drops_blocked_waypoints():
    data = np.zeros((100, 100), dtype=np.int8)  # 5 x 5 m, free
    data[:, 50:52] = OCCUPIED  # a wall at x = 2.5 .. 2.6
    data[90:, :] = -1  # unknown strip at the top
    grid = OccupancyGrid(data, 0.05)
    wps = [Pose2D(1.0, 1.0, 0.3), Pose2D(2.55, 2.0, 1.0), Pose2D(9.0, 9.0, 0.0), Pose2D(1.0, 4.9, 0.0)]
    out = snap_to_free(grid, wps, clearance=0.3)
    assert out[0] == wps[0]  # already clear: untouched
    moved = out[1]
    assert moved.yaw == 1.0 and abs(moved.y - 2.0) < 0.1
    assert abs(moved.x - 2.55) <= 0.45 and (moved.x <= 2.25 or moved.x >= 2.85)  # 0.3 m clear of the wall
    assert len(out) == 3  # outside the map: dropped
    assert out[2].y <= 4.5 - 0.3 + 0.05  # pushed out of (and away from) unknown space
    assert snap_to_free(grid, [Pose2D(2.55, 2.0)], clearance=0.3, max_shift=0.1) == []


def test_plan_json_round_trip(tmp_path):
    plan = plan_traversal(_serpentine(800), Pose2D(0, 0, 0), TraversalParams(),
                          grid_distance=lambda a, b: 1.0)
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan.to_json()))
    back = TraversalPlan.from_json(json.loads(path.read_text()), path)
    assert back == plan
    with pytest.raises(BomcError, match=r"plan.json: waypoints\[1\]"):
        TraversalPlan.from_json({"waypoints": [[0, 0, 0], [1, "a", 0]], "euclidean_length": 1.0}, path)
    unreachable = TraversalPlan([Pose2D(0, 0)], 0.0, math.inf)
    assert unreachable.to_json()["grid_length"] is None


def test_load_trajectory(tmp_path):
    good = tmp_path / "trajectory.csv"
    good.write_text("t,x,y,yaw\n0.0,1.0,2.0,0.5\n0.5,1.5,2.0,0.4\n\n")
    np.testing.assert_allclose(load_trajectory(good), [[0, 1, 2, 0.5], [0.5, 1.5, 2, 0.4]])
    cases = {
        "": "empty trajectory",
        "t,x,y,yaw\n": "no poses",
        "time,x,y,theta\n0,1,2,3\n": "line 1",
        "t,x,y,yaw\n0,1,2,3\n1,2,oops,3\n": "line 3",
        "t,x,y,yaw\n0,1,2\n": "line 2: expected 4 values",
        "t,x,y,yaw\n0,nan,2,3\n": "line 2",
    }
    for i, (text, msg) in enumerate(cases.items()):
        bad = tmp_path / f"bad{i}.csv"
        bad.write_text(text)
        with pytest.raises(BomcError, match=msg) as err:
            load_trajectory(bad)
        assert os.fspath(bad) in str(err.value)
    with pytest.raises(BomcError, match="not found"):
        load_trajectory(tmp_path / "missing.csv")


def test_sampling_ten_thousand_points_is_fast_enough_for_a_tick():
    """Spatial hashing: a long trajectory is sampled without n^2 work (checked by size, not time)."""
    rng = np.random.default_rng(0)
    xy = rng.normal(0, 0.05, (10000, 2)).cumsum(axis=0)
    wp = sample_waypoints(xy, 2.0)
    d = np.hypot(wp[:, None, 0] - wp[None, :, 0], wp[:, None, 1] - wp[None, :, 1])
    np.fill_diagonal(d, np.inf)
    assert d.min() >= 2.0
