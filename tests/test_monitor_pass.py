"""The monitor pass's bookkeeping: plan or resume, save, extend, the loop's look-ahead, detours."""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitor_pass import (
    DetourFinder,
    DetourParams,
    extend_pass,
    open_pass,
    pass_exhausted,
    progress_key,
    reached_by_detour,
)
from bomc_bt.monitoring import GAPS, MISSED, VISITED, TraversalState
from bomc_bt.store import SiteStore
from bomc_bt.traversal import TraversalPlan


def plan(*points) -> TraversalPlan:
    return TraversalPlan([Pose2D(x, y, 0.0) for x, y in points], euclidean_length=10.0)


def test_a_new_pass_is_saved_and_a_resumed_one_continues_where_it_stopped(tmp_path):
    with SiteStore(tmp_path / "site.db") as store:
        state = open_pass(store, 3, resume=False, make_plan=lambda: plan((1, 1), (2, 2)))
        assert store.get_progress(progress_key(3))["index"] == 0
        state.mark(state.next(), VISITED)
        extend_pass(store, 3, state, GAPS, [Pose2D(4, 4, 0.0)])
        resumed = open_pass(store, 3, resume=True, make_plan=lambda: plan((9, 9)))
        assert resumed.index == 1 and resumed.states == [VISITED, "pending", "pending"]
        assert resumed.planned(GAPS) and resumed.waypoint(2) == Pose2D(4, 4, 0.0)
        fresh = open_pass(store, 4, resume=True, make_plan=lambda: plan((9, 9)))  # nothing saved: plan anew
        assert [w.x for w in fresh.plan.waypoints] == [9]


def test_the_look_ahead_agrees_with_next_including_one_retry_of_each_missed():
    state = TraversalState(plan((1, 1), (2, 2), (3, 3)))
    handed = []
    while not pass_exhausted(state):
        i = state.next()
        handed.append(i)
        state.mark(i, MISSED if i == 1 else VISITED)
    assert handed == [0, 1, 2, 1] and state.next() is None


def test_a_long_way_round_is_a_detour():
    assert not reached_by_detour(driven=5.0, expected=3.0, ratio=1.3, margin=2.0)
    assert reached_by_detour(driven=6.0, expected=3.0, ratio=1.3, margin=2.0)
    assert not reached_by_detour(driven=100.0, expected=math.inf, ratio=1.3, margin=2.0)


def test_detours_are_nearest_first_never_repeated_and_face_the_waypoint():
    data = np.zeros((200, 200), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    grid = OccupancyGrid(data, 0.05, (0.0, 0.0))
    finder = DetourFinder(DetourParams(radius=2.0, count=6, clearance=0.45))
    target = Pose2D(5.0, 5.0, 0.0)
    goals = [finder.next(grid, 0, target) for _ in range(3)]
    distances = [math.hypot(g.x - 5, g.y - 5) for g in goals]
    assert distances == sorted(distances) and len({(g.x, g.y) for g in goals}) == 3
    assert all(abs(math.atan2(5 - g.y, 5 - g.x) - g.yaw) < 1e-9 for g in goals)
    assert finder.tried[0] == [(g.x, g.y) for g in goals]
