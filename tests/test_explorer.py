"""The exploration loop's memory, driven without a tree on scripted grids (with the DWFE
ranking: the loop is the same for every explorer): blacklist re-admission, back-out
before stuck, the progress guard, and planner reachability."""

from __future__ import annotations

import numpy as np

from bomc_bt.exploration.blacklist import Blacklist
from bomc_bt.exploration.dwfe import ExplorationParams
from bomc_bt.exploration.explorer import DONE, EXPLORING, NO_PROGRESS, STUCK, Explorer
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from bomc_bt.planner import PlannerParams

RES = 0.05


def grid_of(data: np.ndarray) -> OccupancyGrid:
    return OccupancyGrid(data.astype(np.int8), RES, (0.0, 0.0))


def corridor(length_m: float = 12.0) -> np.ndarray:
    """A 1.5 m wide free corridor along x, walled, with a 1 m unknown alcove every 1.5 m on
    its north side: many reachable frontiers."""
    w = int(length_m / RES)
    data = np.full((60, w), OCCUPIED, np.int8)
    data[10:40, 2:w - 2] = FREE
    for x0 in range(10, w - 30, 30):
        data[40:55, x0:x0 + 20] = UNKNOWN
    return data


def test_failed_goal_is_readmitted_when_the_map_around_it_changes():
    data = np.full((100, 100), UNKNOWN, np.int8)
    data[:, :50] = FREE
    grid = grid_of(data)
    bl = Blacklist(radius=0.5, readmit_radius=1.0, readmit_area=0.25, near_radius=1.5, max_retries=2)
    bl.add((2.5, 2.5), grid=grid, robot_xy=(2.0, 2.5))  # robot was near: the near rule does not apply
    assert bl.contains((2.5, 2.5))
    assert bl.readmit(grid, (2.0, 2.5)) == 0 and bl.contains((2.5, 2.5))  # nothing changed
    data2 = data.copy()
    data2[40:60, 50:60] = FREE  # 200 cells = 0.5 m² newly known beside it
    assert bl.readmit(grid_of(data2), (2.0, 2.5)) == 1
    assert not bl.contains((2.5, 2.5)) and bl.readmitted == 1
    # it fails again: blacklisted again, same place, retry count kept; after max_retries it stays
    bl.add((2.5, 2.5), grid=grid_of(data2), robot_xy=(2.0, 2.5))
    data3 = data2.copy()
    data3[40:60, 60:70] = FREE
    assert bl.readmit(grid_of(data3), (2.0, 2.5)) == 1
    bl.add((2.5, 2.5), grid=grid_of(data3), robot_xy=(2.0, 2.5))
    data4 = data3.copy()
    data4[40:60, 70:80] = FREE
    assert bl.readmit(grid_of(data4), (2.0, 2.5)) == 0 and bl.contains((2.5, 2.5))


def test_failed_goal_is_readmitted_when_the_robot_comes_near():
    grid = grid_of(np.zeros((100, 100), np.int8))
    bl = Blacklist(radius=0.5, near_radius=1.5)
    bl.add((4.0, 4.0), grid=grid, robot_xy=(0.5, 0.5))  # failed from afar
    assert bl.readmit(grid, (1.0, 1.0)) == 0
    assert bl.readmit(grid, (3.0, 3.5)) == 1 and not bl.contains((4.0, 4.0))


def test_reached_but_open_goal_is_never_readmitted():
    grid = grid_of(np.full((100, 100), UNKNOWN, np.int8))
    bl = Blacklist()
    bl.add((2.5, 2.5), grid=grid, robot_xy=(0.0, 0.0), permanent=True)
    assert bl.readmit(grid_of(np.zeros((100, 100), np.int8)), (2.5, 2.5)) == 0 and bl.contains((2.5, 2.5))


def test_robot_that_stops_moving_backs_out_along_its_trail_before_stuck():
    grid = grid_of(corridor())
    params = ExplorationParams(explorer="dwfe", planner_reachable=False, max_backouts=2, backout_distance=1.5)
    ex = Explorer(params, start_time=0.0, max_consecutive_failures=5)
    t = 0.0
    for x in np.arange(1.0, 6.01, 0.1):  # it drove east along the corridor
        ex.observe((float(x), 1.25), t)
        t += 0.2
    here = (6.0, 1.25)
    kinds = []
    while ex.status == EXPLORING and len(kinds) < 30:
        goal = ex.next_goal(grid, here, t)
        if goal is None:
            break
        kinds.append("backout" if goal.backout else "frontier")
        t += 20.0
        ex.goal_failed(goal, "blocked: no progress for 15 s", here, t, grid)  # never moves
    assert ex.status == STUCK, (ex.status, ex.reason, kinds)
    # two failures, a back-out, ... and stuck only after max_backouts back-outs
    assert kinds[:3] == ["frontier", "frontier", "backout"]
    assert kinds.count("backout") == 2 and ex.backouts == 2
    assert "after 2 back-out(s)" in ex.reason
    backout = ex.trail.back(here, 1.5)  # the first trail point 1.5 m or more back along the way
    assert backout is not None and 4.2 <= backout[0] <= 4.5 and backout[1] == 1.25


def test_backout_that_frees_the_robot_resets_the_streak():
    grid = grid_of(corridor())
    ex = Explorer(ExplorationParams(explorer="dwfe", planner_reachable=False), start_time=0.0)
    for x in np.arange(1.0, 6.01, 0.1):
        ex.observe((float(x), 1.25), 0.0)
    here, t = (6.0, 1.25), 0.0
    for _ in range(2):
        goal = ex.next_goal(grid, here, t)
        t += 20.0
        ex.goal_failed(goal, "blocked", here, t, grid)
    goal = ex.next_goal(grid, here, t)
    assert goal.backout and goal.xy[0] < 5.0
    ex.goal_reached(goal)  # backed out: free again
    assert ex.consecutive_failures == 0 and ex.status == EXPLORING
    assert not ex.next_goal(grid, goal.xy, t).backout  # replans a frontier from there


def test_progress_guard_ends_an_exploration_that_maps_nothing():
    grid = grid_of(corridor(30.0))  # ~19 alcoves: goals outlast the guard
    params = ExplorationParams(explorer="dwfe", planner_reachable=False, no_progress_time=120.0, min_progress_area=2.0)
    ex = Explorer(params, start_time=0.0)
    t = 0.0
    for i in range(100):
        here = (1.0 + 0.5 * i, 1.25)  # it drives on, so it is not stuck, but the map never grows
        goal = ex.next_goal(grid, here, t)
        if goal is None:
            break
        t += 10.0
        ex.goal_failed(goal, "no progress", (here[0] + 0.5, 1.25), t, grid)
    assert ex.status == NO_PROGRESS, (ex.status, ex.reason)
    assert 120.0 <= t <= 140.0 and "newly mapped in 120 s" in ex.reason


def test_frontier_behind_a_gap_narrower_than_the_robot_is_never_chosen_and_is_reported_unreachable():
    data = np.full((80, 160), OCCUPIED, np.int8)
    data[5:75, 5:75] = FREE  # the robot's room, 3.5 m square
    data[60:75, 5:25] = UNKNOWN  # a corner not yet seen: reachable
    data[36:44, 75:80] = FREE  # a 0.4 m gap: the lidar sees through, the 0.3 m-radius robot does not fit
    data[20:60, 80:120] = UNKNOWN  # beyond it, unknown: a frontier at the gap
    data[36:44, 80:82] = FREE
    grid = grid_of(data)
    robot = (1.0, 2.0)
    naive = Explorer(ExplorationParams(explorer="dwfe", planner_reachable=False), 0.0)
    naive.next_goal(grid, robot, 0.0)
    assert len(naive.frontiers) == 2  # explore_lite's free-cell reachability counts the gap's frontier
    ex = Explorer(ExplorationParams(explorer="dwfe"), 0.0, planner=PlannerParams())
    first = ex.next_goal(grid, robot, 0.0)
    assert first.xy[0] < 1.5 and first.xy[1] > 2.5  # the corner
    assert len(ex.frontiers) == 1 and len(ex.unreachable) == 1
    ex.goal_failed(first, "no progress", robot, 20.0, grid)
    assert ex.next_goal(grid, robot, 21.0) is None and ex.status == DONE
    assert "1 more the planner cannot reach" in ex.reason
    border = ex.border(grid, robot)
    assert (border["reachable"], border["blacklisted"], border["unreachable"]) == (1, 1, 1)
    assert border["unreachable_m"] > 0.3
