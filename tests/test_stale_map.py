"""Furniture the saved map holds that has gone since the build (bomc_bt/stale_map.py), and the
``stale_map`` diagnosis it gives a stuck pass (bomc_bt/stuck.py)."""

from __future__ import annotations

import numpy as np
from test_stuck import BEYOND, PARAMS, RADIUS, ROBOT, cast, two_rooms, with_box

from bomc_bt.stale_map import FloorSeen, floor_seen, furniture_cells, with_floor
from bomc_bt.stuck import BOXED_IN, STALE_MAP, diagnose


def doorway_scene():
    """The saved map: a table stood in the doorway's lower part at the build (y 1.0 to 1.35,
    clear of the jambs). Now it has gone and a cabinet stands in the upper part (y 1.65 to
    2.05): 0.75 m of doorway are open below the cabinet, enough for the 0.6 m robot, but the
    map's table and the cabinet leave 0.3 m."""
    empty = two_rooms()
    saved = with_box(empty, 4.85, 1.0, 5.3, 1.35)
    now = with_box(empty, 4.85, 1.65, 5.3, 2.05)
    return saved, now


def inside(grid, cells, x0, y0, x1, y1) -> bool:
    x, y = grid.cell_to_world(cells[:, 0], cells[:, 1])
    return bool(np.all((x >= x0 - 0.05) & (x <= x1 + 0.05) & (y >= y0 - 0.05) & (y <= y1 + 0.05)))


def test_the_floor_where_a_table_stood_is_seen_and_walls_never_are():
    saved, now = doorway_scene()
    floor = floor_seen(saved, ROBOT, cast(now, ROBOT), furniture_area=2.0, max_range=6.0)
    assert len(floor) * saved.resolution ** 2 > 0.05  # a good part of the table's 0.16 m2
    assert inside(saved, floor, 4.85, 1.0, 5.3, 1.35)  # nothing but the table's cells
    walls = two_rooms().occupied_mask()
    assert not furniture_cells(saved, 2.0)[walls].any()  # the walls are one big blob: never furniture
    still_there = floor_seen(saved, ROBOT, cast(saved, ROBOT), 2.0, 6.0)
    assert len(still_there) == 0  # a table that is still there stops the beams on its face
    assert len(floor_seen(saved, ROBOT, cast(now, ROBOT), 0.0, 6.0)) == 0  # furniture_area 0: off


def test_floor_counts_after_min_seen_scans_and_a_return_off_it_starts_again():
    saved, now = doorway_scene()
    watch = FloorSeen(saved, furniture_area=2.0, max_range=6.0, min_seen=2)
    watch.add(ROBOT, cast(now, ROBOT))
    assert len(watch.cells()) == 0  # one scan is not enough
    watch.add(ROBOT, cast(now, ROBOT))
    seen = watch.cells()
    assert len(seen) > 0 and inside(saved, seen, 4.85, 1.0, 5.3, 1.35)
    watch.add(ROBOT, cast(saved, ROBOT))  # the table is back: the cells its face returns from count no more
    x, y = saved.cell_to_world(seen[:, 0], seen[:, 1])
    x_again, _ = saved.cell_to_world(watch.cells()[:, 0], watch.cells()[:, 1])
    assert len(watch.cells()) < len(seen)
    assert np.count_nonzero(x < 4.85) >= 6 and np.count_nonzero(x_again < 4.85) == 0  # its near face


def test_a_robot_hemmed_in_by_a_table_gone_since_the_build_is_told_so_and_the_way_opens():
    saved, now = doorway_scene()
    scan = cast(now, ROBOT)
    blind = diagnose(saved, ROBOT, scan, BEYOND, BEYOND, PARAMS, RADIUS)
    assert blind.cause == BOXED_IN  # as before: the map's table and the cabinet shut the doorway
    floor = floor_seen(saved, ROBOT, scan, 2.0, 6.0)
    found = diagnose(saved, ROBOT, scan, BEYOND, BEYOND, PARAMS, RADIUS, floor=floor)
    assert found.cause == STALE_MAP, found
    assert "with it cleared 1 of the 1 waypoint(s) that failed" in found.detail
    assert np.array_equal(found.floor, floor)
    assert found.agreement > 0.6 and found.blockers  # the cabinet is still the nearest return off the map
    refreshed = with_floor(saved, found.floor)
    assert diagnose(refreshed, ROBOT, scan, BEYOND, BEYOND, PARAMS, RADIUS, floor=floor).cause != STALE_MAP


def test_floor_seen_that_opens_nothing_changes_no_diagnosis():
    saved, now = doorway_scene()
    shut = with_box(now, 4.85, 0.9, 5.3, 1.6)  # the doorway is really shut now, below the cabinet too
    scan = cast(shut, ROBOT)
    floor = floor_seen(saved, ROBOT, cast(now, ROBOT), 2.0, 6.0)  # seen free earlier in the pass
    assert diagnose(saved, ROBOT, scan, BEYOND, BEYOND, PARAMS, RADIUS, floor=floor).cause == BOXED_IN
