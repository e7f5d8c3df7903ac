"""The gain explorer's kept standoff goals and gains equal a computation from scratch.

:mod:`bomc_bt.exploration.decision_cache` reuses a frontier's standoff goal and a goal's
visible-unknown gain while the map around them is unchanged, and computes standoffs on a
window of the map. Any difference from :class:`Standoffs` over the whole map or from
:func:`visible_unknown` would change which frontier a build drives to. Checked on a
generated office seen from a few places, then after the robot maps more of it.
"""

from __future__ import annotations

import numpy as np
import pytest

from bomc_bt.algorithm_params import ExplorationParams
from bomc_bt.exploration.decision_cache import DecisionCache
from bomc_bt.exploration.frontiers import find_frontiers
from bomc_bt.exploration.gain import Standoffs, visible_unknown
from bomc_bt.exploration.reachability import Reachability
from bomc_bt.grid import UNKNOWN, OccupancyGrid
from bomc_bt.officegen import OfficeParams, generate_office
from bomc_bt.planner import PlannerParams
from bomc_bt.world import load_world

CLEARANCE, MAX_STANDOFF, RADIUS = 0.35, 1.0, 6.0


@pytest.fixture(scope="module")
def office(tmp_path_factory) -> OccupancyGrid:
    path = tmp_path_factory.mktemp("office") / "world.yaml"
    generate_office(OfficeParams(width=30, height=24, seed=11, sessions=1), path)
    return load_world(path).grid


def seen_from(truth: OccupancyGrid, places: list[tuple[float, float]], radius: float = 7.0) -> OccupancyGrid:
    """The true map where within ``radius`` of a place, unknown elsewhere."""
    rows, cols = np.indices(truth.data.shape)
    xs, ys = truth.cell_to_world(rows, cols)
    known = np.zeros(truth.data.shape, dtype=bool)
    for x, y in places:
        known |= (xs - x) ** 2 + (ys - y) ** 2 <= radius ** 2
    return OccupancyGrid(np.where(known, truth.data, UNKNOWN).astype(np.int8), truth.resolution, truth.origin)


def free_places(truth: OccupancyGrid, count: int, seed: int) -> list[tuple[float, float]]:
    rows, cols = np.nonzero(truth.free_mask())
    pick = np.random.default_rng(seed).choice(rows.size, count, replace=False)
    xs, ys = truth.cell_to_world(rows[pick], cols[pick])
    return [(float(x), float(y)) for x, y in zip(xs, ys, strict=True)]


def decide(cache: DecisionCache, grid: OccupancyGrid, robot: tuple[float, float]) -> int:
    """One decision's standoffs and gains from the cache, each checked against the reference;
    returns how many frontiers were compared."""
    reach = Reachability(grid, PlannerParams(), robot)
    frontiers = [f for f, _ in reach.split(find_frontiers(grid, robot, ExplorationParams().min_size_cells(0.05)))[0]]
    cache.update(grid, reach)
    reference = Standoffs(grid, reach, CLEARANCE, MAX_STANDOFF)
    goals = []
    for f in frontiers:
        got = cache.standoff(f)
        assert got == reference.goal(f)
        if got is not None:
            goals.append(got[0])
    assert np.array_equal(cache.gains(goals), visible_unknown(grid, goals, RADIUS))
    return len(frontiers)


def test_kept_standoffs_and_gains_equal_the_whole_map_computation_as_the_map_grows(office):
    places = free_places(office, 9, seed=2)
    cache = DecisionCache(CLEARANCE, MAX_STANDOFF, RADIUS)
    compared = 0
    for seen in (3, 4, 6, 6, 9):  # a decision with an unchanged map reuses everything
        compared += decide(cache, seen_from(office, places[:seen]), places[0])
    assert compared > 40
    assert cache.reused["standoff"] > 10 and cache.reused["gain"] > 10  # the cache was exercised
