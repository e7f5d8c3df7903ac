"""Choosing the next frontier: DWFE's local/global window, its cost, termination, the
explore_lite baseline and the blacklist of failed goals."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bomc_bt.errors import BomcError
from bomc_bt.exploration.dwfe import Blacklist, ExplorationParams, choose_frontier
from bomc_bt.exploration.frontiers import Frontier, find_frontiers
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from bomc_bt.params import from_mapping

ROBOT = (0.0, 0.0)


def frontier(x: float, y: float, size: int, resolution: float = 0.05) -> Frontier:
    """A frontier whose nearest cell is at (x, y), centroid 0.3 m further out along y."""
    return Frontier(cells=np.zeros((size, 2), np.int64), size=size, centroid=(x, y + 0.3),
                    nearest=(x, y), distance=math.hypot(x, y), resolution=resolution)


def params(**kw) -> ExplorationParams:
    base = dict(local_radius=4.0, local_threshold=1, alpha=1.0, beta=0.5)
    base.update(kw)
    return ExplorationParams(**base)


def test_local_window_wins_over_a_larger_far_frontier():
    near = frontier(2.0, 0.0, 10)  # 0.5 m long, 2 m away
    far = frontier(10.0, 0.0, 600)  # 30 m long, 10 m away: globally the cheapest
    choice = choose_frontier([far, near], ROBOT, params())
    assert choice.frontier is near
    assert choice.window == "local"
    assert choice.cost == pytest.approx(2.0 - 0.5 * 0.5)
    # without the window (everything local) the far one would have been chosen
    assert choose_frontier([far, near], ROBOT, params(local_radius=20.0)).frontier is far


def test_window_widens_when_local_count_is_below_threshold():
    near = frontier(2.0, 0.0, 10)
    far = frontier(10.0, 0.0, 600)
    choice = choose_frontier([near, far], ROBOT, params(local_threshold=2))
    assert choice.window == "global"
    assert choice.frontier is far
    assert "widened" in choice.reason
    # two local frontiers satisfy T_l = 2 and keep the robot local
    near2 = frontier(0.0, -3.0, 12)
    choice = choose_frontier([near, far, near2], ROBOT, params(local_threshold=2))
    assert choice.window == "local" and choice.frontier is near


def test_window_uses_distance_to_the_nearest_cell_not_the_centroid():
    edge = replace(frontier(3.9, 0.0, 10), centroid=(4.6, 0.0))  # nearest cell inside r_l = 4
    assert choose_frontier([edge], ROBOT, params()).window == "local"


def test_global_radius_limits_the_wide_window():
    far = frontier(50.0, 0.0, 600)
    choice = choose_frontier([far], ROBOT, params(global_radius=30.0))
    assert choice.frontier is None and choice.window == "none"
    assert "T_g" in choice.reason


def test_terminates_when_no_frontiers_left():
    for explorer in ("dwfe", "baseline"):
        choice = choose_frontier([], ROBOT, params(explorer=explorer))
        assert choice.frontier is None and choice.window == "none"
        assert choice.reason == "no frontiers left"
        assert choice.cost == math.inf


def test_terminates_below_global_threshold():
    fs = [frontier(8.0, 0.0, 20), frontier(-9.0, 0.0, 20)]
    assert choose_frontier(fs, ROBOT, params(global_threshold=3)).frontier is None
    assert choose_frontier(fs, ROBOT, params(global_threshold=2)).frontier is fs[0]


def test_terminates_at_the_time_limit():
    fs = [frontier(1.0, 0.0, 20)]
    p = params(max_time=900.0)
    assert choose_frontier(fs, ROBOT, p, elapsed=899.0).frontier is fs[0]
    late = choose_frontier(fs, ROBOT, p, elapsed=900.0)
    assert late.frontier is None and "time limit" in late.reason


def test_bigger_frontier_preferred_at_equal_distance():
    small, big = frontier(2.0, 0.0, 10), frontier(0.0, 2.0, 40)
    for explorer in ("dwfe", "baseline"):
        assert choose_frontier([small, big], ROBOT, params(explorer=explorer)).frontier is big
    # and beta = 0 leaves only distance
    closer = frontier(1.9, 0.0, 10)
    assert choose_frontier([big, closer], ROBOT, params(beta=0.0)).frontier is closer


def test_baseline_uses_explore_lite_cost_over_all_frontiers():
    near = frontier(2.0, 0.0, 10)
    far = frontier(30.0, 0.0, 100)
    p = params(explorer="baseline", potential_scale=3.0, gain_scale=1.0)
    choice = choose_frontier([near, far], ROBOT, p)
    # explore_lite: potential_scale * min_distance * resolution - gain_scale * size * resolution
    assert choice.cost == pytest.approx(3.0 * 30.0 * 0.05 - 100 * 0.05)
    assert choice.frontier is far and choice.window == "global"
    assert choose_frontier([near, far], ROBOT, params()).frontier is near  # DWFE stays local


def test_blacklist_skips_frontiers_near_failed_goals():
    a, b = frontier(1.0, 0.0, 30), frontier(3.0, 0.0, 10)
    bl = Blacklist(radius=0.5)
    bl.add((1.2, 0.1))  # near a's nearest cell
    assert bl.contains((1.0, 0.0)) and not bl.contains((3.0, 0.0))
    assert bl.filter([a, b]) == [b]
    assert choose_frontier([a, b], ROBOT, params(), bl).frontier is b
    centroid_only = Blacklist(radius=0.1)
    centroid_only.add(b.centroid)  # matched through the centroid alone
    assert centroid_only.filter([a, b]) == [a]
    bl.add((3.0, 0.0))
    done = choose_frontier([a, b], ROBOT, params(), bl)
    assert done.frontier is None and "blacklisted" in done.reason


def test_min_frontier_size_in_metres_becomes_cells():
    assert ExplorationParams(min_frontier_size=0.5).min_size_cells(0.05) == 10
    assert ExplorationParams(min_frontier_size=0.5).min_size_cells(0.03) == 17
    assert ExplorationParams(min_frontier_size=0.0).min_size_cells(0.05) == 1


def test_params_from_yaml_report_bad_values_with_file():
    p = from_mapping(ExplorationParams, {"local_radius": 3, "explorer": "baseline"}, "cfg.yaml", "explore")
    assert p.local_radius == 3.0 and p.explorer == "baseline"
    for bad in ({"local_radius": -1.0}, {"local_radius": 5.0, "global_radius": 2.0},
                {"local_threshold": 0}, {"beta": -0.1}, {"explorer": "greedy"}):
        with pytest.raises(BomcError) as err:
            from_mapping(ExplorationParams, bad, "cfg.yaml", "explore")
        assert str(err.value).startswith("cfg.yaml")
        assert next(iter(bad)) in str(err.value)


def corridor_map(door_open: bool) -> OccupancyGrid:
    """A 1 m corridor at 0.1 m leading east to a hall whose far side is a 10 m frontier,
    with an optional 0.5 m side door right next to the robot."""
    data = np.full((100, 220), UNKNOWN, np.int8)
    data[44:56, 0:150] = OCCUPIED
    data[45:55, 1:150] = FREE
    data[:, 149] = OCCUPIED
    data[45:55, 149] = FREE
    data[:, 150:200] = FREE  # the hall, seen up to x = 20 m; beyond is unknown
    if door_open:
        data[55, 30:35] = FREE  # gap in the north corridor wall, unknown behind it
    return OccupancyGrid(data, 0.1)


def test_on_a_map_dwfe_takes_the_side_door_and_baseline_the_hall():
    robot = (3.05, 5.05)
    p = ExplorationParams(local_threshold=1, beta=5.0, min_frontier_size=0.3)
    fs = find_frontiers(corridor_map(True), robot, min_size=p.min_size_cells(0.1))
    assert sorted(f.size for f in fs) == [5, 100]
    door = choose_frontier(fs, robot, p)
    assert door.window == "local" and door.frontier.size == 5
    hall = choose_frontier(fs, robot, ExplorationParams(explorer="baseline", min_frontier_size=0.3))
    assert hall.frontier.size == 100
    # with the door closed nothing is local, so DWFE widens to the hall
    fs = find_frontiers(corridor_map(False), robot, min_size=p.min_size_cells(0.1))
    widened = choose_frontier(fs, robot, p)
    assert widened.window == "global" and widened.frontier.size == 100
