"""Frontier search: the vectorised search agrees with the breadth-first reference, and the
frontiers it reports are the ones a user would draw on the map."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bomc_bt.exploration.frontiers import (
    Frontier,
    find_frontiers,
    find_frontiers_reference,
    start_cell,
)
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid


def blob_grid(seed: int, h: int, w: int, resolution: float = 0.05,
              origin: tuple[float, float] = (0.0, 0.0)) -> OccupancyGrid:
    """Random map: unknown background with free discs/rectangles, walls and unknown holes."""
    rng = np.random.default_rng(seed)
    data = np.full((h, w), UNKNOWN, np.int8)
    rr, cc = np.mgrid[0:h, 0:w]
    for value, count in ((FREE, rng.integers(1, 6)), (OCCUPIED, rng.integers(0, 6)),
                         (UNKNOWN, rng.integers(0, 4)), (FREE, rng.integers(0, 3))):
        for _ in range(count):
            r, c = rng.integers(0, h), rng.integers(0, w)
            if rng.random() < 0.5:
                rad = rng.uniform(0.5, 1 + max(h, w) / 3)
                data[(rr - r) ** 2 + (cc - c) ** 2 <= rad * rad] = value
            else:
                data[r:r + rng.integers(1, h + 1), c:c + rng.integers(1, w + 1)] = value
    noise = rng.random((h, w))
    data[noise < 0.03] = OCCUPIED  # isolated obstacle cells, like laser speckle
    data[(noise > 0.985)] = UNKNOWN
    return OccupancyGrid(data, resolution, origin)


def assert_same(fast: list[Frontier], ref: list[Frontier]) -> None:
    assert len(fast) == len(ref)
    for a, b in zip(fast, ref, strict=True):
        assert a.size == b.size == len(a.cells)
        assert np.array_equal(a.cells, b.cells)
        assert a.centroid == pytest.approx(b.centroid, abs=1e-9)
        assert a.nearest == pytest.approx(b.nearest, abs=1e-9)
        assert a.distance == pytest.approx(b.distance, abs=1e-9)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), h=st.integers(1, 48), w=st.integers(1, 48),
       fx=st.floats(-0.2, 1.2), fy=st.floats(-0.2, 1.2), min_size=st.integers(1, 6),
       reachable_only=st.booleans())
def test_fast_matches_reference_on_random_grids(seed, h, w, fx, fy, min_size, reachable_only):
    grid = blob_grid(seed, h, w, resolution=0.1, origin=(-1.3, 2.7))
    robot = (-1.3 + fx * w * 0.1, 2.7 + fy * h * 0.1)  # sometimes outside the grid
    fast = find_frontiers(grid, robot, min_size=min_size, reachable_only=reachable_only)
    ref = find_frontiers_reference(grid, robot, min_size=min_size, reachable_only=reachable_only)
    assert_same(fast, ref)


def test_fast_matches_reference_on_a_larger_map():
    grid = blob_grid(7, 160, 200)
    free = np.argwhere(grid.data == FREE)
    r, c = free[len(free) // 2]
    robot = tuple(float(v) for v in grid.cell_to_world(r, c))
    fast = find_frontiers(grid, robot)
    assert len(fast) > 0
    assert_same(fast, find_frontiers_reference(grid, robot))


def room_grid() -> OccupancyGrid:
    """A 4 x 3 m walled room at 0.1 m with an open 1 m doorway on the east wall to unknown."""
    data = np.full((40, 60), UNKNOWN, np.int8)
    data[5:35, 5:45] = OCCUPIED
    data[6:34, 6:44] = FREE
    data[15:25, 44] = FREE  # doorway cells, the unknown beyond them is the frontier
    return OccupancyGrid(data, 0.1, (0.0, 0.0))


def test_doorway_is_one_frontier_with_correct_geometry():
    grid = room_grid()
    robot = (2.0, 2.02)
    (f,) = find_frontiers(grid, robot)
    assert f.size == 10
    assert f.length == pytest.approx(1.0)
    assert set(map(tuple, f.cells)) == {(r, 44) for r in range(15, 25)}
    assert f.centroid == pytest.approx((4.45, 2.0))
    assert f.nearest == pytest.approx((4.45, 2.05))
    assert f.distance == pytest.approx(np.hypot(2.45, 0.03))


def test_frontier_behind_a_wall_is_not_reachable():
    grid = room_grid()
    grid.data[10:14, 50:55] = FREE  # a free pocket outside the room touching unknown
    inside = find_frontiers(grid, (2.0, 2.0))
    everywhere = find_frontiers(grid, (2.0, 2.0), reachable_only=False)
    assert len(inside) == 1
    assert len(everywhere) == 2


def test_min_size_drops_small_frontiers():
    grid = room_grid()
    grid.data[6, 30:33] = FREE
    grid.data[5, 30:33] = UNKNOWN  # a 3-cell gap in the south wall (row 5 is the bottom one)
    sizes = sorted(f.size for f in find_frontiers(grid, (2.0, 2.0)))
    assert sizes == [3, 10]
    assert [f.size for f in find_frontiers(grid, (2.0, 2.0), min_size=4)] == [10]
    assert find_frontiers(grid, (2.0, 2.0), min_size=11) == []
    with pytest.raises(ValueError):
        find_frontiers(grid, (2.0, 2.0), min_size=0)


def test_sorted_by_distance():
    grid = room_grid()
    grid.data[6, 10:14] = FREE
    grid.data[5, 10:14] = UNKNOWN  # a gap near the west end of the south wall
    frontiers = find_frontiers(grid, (1.0, 1.0))
    assert [f.size for f in frontiers] == [4, 10]
    assert [f.distance for f in frontiers] == sorted(f.distance for f in frontiers)


def test_clusters_are_8_connected_but_reachability_is_4_connected():
    data = np.full((10, 10), OCCUPIED, np.int8)
    for i in range(9):  # free cells on a diagonal, each with an unknown cell to its right
        data[i, i] = FREE
        data[i, i + 1] = UNKNOWN
    grid = OccupancyGrid(data, 0.1)
    (everywhere,) = find_frontiers(grid, (0.05, 0.05), reachable_only=False)
    assert everywhere.size == 9  # diagonal neighbours join one frontier
    (reachable,) = find_frontiers(grid, (0.05, 0.05))
    assert reachable.size == 1  # but the robot cannot squeeze diagonally between walls
    assert_same([reachable], find_frontiers_reference(grid, (0.05, 0.05)))


def test_robot_in_unknown_starts_from_nearest_free_cell():
    grid = room_grid()
    grid.data[18:22, 18:22] = UNKNOWN  # robot stands in a not yet cleared patch
    robot = (2.0, 2.0)
    assert start_cell(grid, robot) is not None
    frontiers = find_frontiers(grid, robot)
    # the patch itself is a frontier (the robot is on it) and the doorway is still found
    assert sorted(f.size for f in frontiers) == [10, 16]
    assert frontiers[0].size == 16 and frontiers[0].distance < 0.3


def test_robot_far_from_free_space_finds_nothing():
    grid = room_grid()
    assert find_frontiers(grid, (5.5, 0.2)) == []  # outside the room, in unknown space
    assert find_frontiers(grid, (100.0, 100.0)) == []  # outside the grid
    assert find_frontiers_reference(grid, (5.5, 0.2)) == []


def test_fully_known_map_has_no_frontiers():
    data = np.full((30, 30), OCCUPIED, np.int8)
    data[1:29, 1:29] = FREE
    assert find_frontiers(OccupancyGrid(data, 0.05), (0.7, 0.7)) == []


def test_map_edge_is_not_a_frontier():
    grid = OccupancyGrid(np.zeros((20, 20), np.int8), 0.05)
    assert find_frontiers(grid, (0.5, 0.5)) == []
