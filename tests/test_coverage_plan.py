"""The coverage plan: viewpoints that together see the floor, in a short tour; the paper's
trajectory-sampled plan stays as it was."""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import replace

import numpy as np

from bomc_bt.algorithm_params import TraversalParams
from bomc_bt.coverage_plan import nearest_neighbour, plan_coverage, route_length, tour_order
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.path_matrix import path_length_matrix
from bomc_bt.planner import GridPlanner
from bomc_bt.traversal import plan_traversal, snap_to_free

RES = 0.05
RANGE = 5.0
DOCK = Pose2D(1.5, 3.0, 0.0)
# sha256 of the paper plan's JSON for _lawnmower() on the map of the last test, computed
# with the code as it was before the coverage plan (commit 5c8b2f0)
PAPER_DIGEST = "7485446d5ceaf3fb0217f47acbd31c3a02898d7019c3fc33ae699c6434317329"


def office(blocked: bool = False) -> OccupancyGrid:
    """18 x 9.5 m: a 2.25 m corridor (y 2-4.25 m) along the bottom, three 6 x 3.45 m rooms
    above it (y 4.55-8 m) with a 1.2 m door each (centred on x = 3, 9, 15 m) and a 1.15 m
    back passage (y 8.3-9.45 m) joining the rooms' far ends through 1.2 m doors. From a
    doorway a room's far corners are 4.6 m away: the camera (5 m) sees the whole room.
    ``blocked`` closes the corridor between the first and second room."""
    h, w = 190, 360
    data = np.full((h, w), 100, np.int8)
    data[40:85, 1:-1] = 0  # corridor, y 2.0-4.25
    for x0 in (0, 6, 12):
        c0 = int(x0 / RES)
        data[91:160, c0 + 1:c0 + 119] = 0  # room (walls 0.3 m thick below and above)
        dc = int((x0 + 3) / RES)
        data[85:91, dc - 12:dc + 12] = 0  # door to the corridor
        data[160:166, dc - 12:dc + 12] = 0  # door to the back passage
    data[166:189, 1:-1] = 0  # back passage
    if blocked:
        data[40:85, 115:125] = 100  # the corridor closed at x 5.75-6.25
    return OccupancyGrid(data, RES, (0.0, 0.0))


def sees(grid: OccupancyGrid, at, point) -> bool:
    """Independent check of one look: in range and a 1 cm-sampled line of sight that crosses
    no occupied cell before the last 15 cm (the target may stand by a wall)."""
    d = math.hypot(point[0] - at[0], point[1] - at[1])
    if not TraversalParams().min_range <= d <= RANGE:
        return False
    t = np.arange(0.0, max(d - 0.15, 0.0), 0.01) / d
    rows, cols = grid.world_to_cell(at[0] + t * (point[0] - at[0]), at[1] + t * (point[1] - at[1]))
    return not (grid.data[rows, cols] == 100).any()


def floor_points(grid: OccupancyGrid, step: float = 0.5, margin: float = 0.2) -> np.ndarray:
    """Free floor at least ``margin`` from any wall, every ``step`` metres."""
    rows, cols = np.nonzero(grid.free_mask())
    x, y = grid.cell_to_world(rows, cols)
    pts = np.stack([x, y], axis=1)
    pts = pts[(np.abs(np.remainder(pts, step) - step / 2) < RES / 2).all(axis=1)]
    occ_r, occ_c = np.nonzero(grid.occupied_mask())
    ox, oy = grid.cell_to_world(occ_r, occ_c)
    occ = np.stack([ox, oy], axis=1)
    keep = [np.min(np.hypot(*(occ - p).T)) >= margin for p in pts]
    return pts[np.asarray(keep, bool)]


def test_every_reachable_floor_cell_is_seen_from_some_viewpoint():
    grid = office()
    params = replace(TraversalParams(), min_gain=RES * 5, drive_by=False)  # down to one target sample
    plan = plan_coverage(grid, DOCK, RANGE, params)
    stops = plan.viewpoints
    unseen = [p for p in floor_points(grid) if not any(sees(grid, s, p) for s in stops)]
    assert not unseen, f"{len(unseen)} floor points unseen, e.g. {unseen[:3]}"
    assert plan.seen_targets / plan.floor_targets > 0.95


def test_a_room_seen_from_its_door_gets_no_viewpoint_inside():
    """Each room is seen whole from its doorway (the camera sees 5 m), so no stop need
    drive into it; the rooms' floor is still covered."""
    grid = office()
    plan = plan_coverage(grid, DOCK, RANGE)
    inside = [s for s in plan.viewpoints if 4.55 + 0.75 < s[1] < 8.0 - 0.75]
    assert not inside, f"stops inside rooms: {inside}"
    assert plan.covered.sum() >= 0.95 * plan.seen_targets


def test_the_tour_is_no_longer_than_the_greedy_order():
    grid = office()
    planner = GridPlanner(grid)
    rng = np.random.default_rng(7)
    pts = np.array([p for p in floor_points(grid, step=0.25, margin=0.5)])
    pts = pts[rng.choice(len(pts), 25, replace=False)]
    params = TraversalParams()
    order, dist = tour_order(planner, DOCK.xy, pts, params)
    closed = np.vstack([np.hstack([dist, dist[:, :1]]), np.hstack([dist[:1], [[0.0]]])])
    greedy = nearest_neighbour(dist) + [len(pts) + 1]
    tour = [0] + [i + 1 for i in order] + [len(pts) + 1]
    assert sorted(order) == list(range(len(pts)))
    assert route_length(closed, tour) <= route_length(closed, greedy) + 1e-9


def test_path_lengths_follow_the_corridors_not_straight_lines():
    grid = office()
    planner = GridPlanner(grid)
    a, b = (3.0, 6.5), (9.0, 6.5)  # two rooms side by side: through the doors and the corridor
    dist = path_length_matrix(planner, np.array([a, b]))
    field = planner.distances_from(a)
    exact = planner.lookup(field, b)
    assert math.hypot(b[0] - a[0], b[1] - a[1]) < exact <= dist[0, 1] <= 1.1 * exact
    assert dist[0, 1] == dist[1, 0]


def test_a_blocked_corridor_still_gives_a_tour_round_it():
    grid = office(blocked=True)
    plan = plan_coverage(grid, DOCK, RANGE)
    assert plan.plan.grid_length is not None and math.isfinite(plan.plan.grid_length)
    xs = [s[0] for s in plan.viewpoints]
    assert min(xs) < 6 < max(xs)  # stops on both sides of the closure, reached round the back
    assert plan.plan.grid_length < 1e5  # no leg priced as cut off


def test_the_plan_is_deterministic_and_every_stop_has_headings():
    grid = office()
    a = plan_coverage(grid, DOCK, RANGE)
    b = plan_coverage(grid, DOCK, RANGE)
    assert json.dumps(a.plan.to_json()) == json.dumps(b.plan.to_json())
    stops = {(w.x, w.y) for w in a.plan.waypoints}
    assert stops == set(a.viewpoints) and len(a.plan.waypoints) <= len(stops) * TraversalParams().max_headings


def _lawnmower() -> np.ndarray:
    rng = np.random.default_rng(3)
    rows = []
    for k, y in enumerate(np.arange(1.0, 11.0, 1.5)):
        xs = np.linspace(1.0, 19.0, 300)
        rows.append(np.column_stack([xs if k % 2 == 0 else xs[::-1], np.full(len(xs), y)]))
    xy = np.vstack(rows) + rng.normal(0, 0.05, (len(rows) * 300, 2))
    return np.column_stack([np.arange(len(xy)) * 0.1, xy, np.zeros(len(xy))])


def test_the_paper_plan_is_unchanged_byte_for_byte():
    """plan: paper samples the trajectory as before the coverage plan existed: the digest is
    the one the code before it gave for the same trajectory and map."""
    data = np.zeros((240, 400), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[100:140, 180:220] = 100
    grid = OccupancyGrid(data, RES, (0.0, 0.0))
    params = replace(TraversalParams(), plan="paper")
    plan = plan_traversal(_lawnmower(), Pose2D(1.0, 1.0, 0.0), params, grid_distance=GridPlanner(grid).distance)
    plan.waypoints = snap_to_free(grid, plan.waypoints, 0.45)
    text = json.dumps(plan.to_json(), sort_keys=True)
    assert len(plan.waypoints) == 38
    assert hashlib.sha256(text.encode()).hexdigest() == PAPER_DIGEST
