"""The coverage plan of a monitor pass: few viewpoints that together see all the floor.

The paper samples waypoints every 2 m along the build trajectory. Exploration wanders,
so on a large floor that trajectory is many kilometres and its waypoints are many and
redundant: a pass then costs more than the build. A pass has one job, to see every place
where an object can be, so this plan starts from the saved map and the camera instead:

1. Floor to see: free cells and unknown ones within ``shadow`` of them (furniture's lidar
   shadow), sampled every ``target_step``.
2. Candidate viewpoints: lattice places ``candidate_step`` apart that the robot can reach
   from the dock (the planner's costmap: traversable, in the dock's component) with
   ``clearance`` from obstacles.
3. What a viewpoint sees (:mod:`bomc_bt.sight`): floor between ``min_range`` and the
   camera's planned reach (``projection.expect_range``) along a free line of sight, all
   around -- at a stop the robot turns in place through up to ``max_headings`` headings,
   each an ``hfov_deg`` window facing the floor it was chosen for. Floor no candidate sees
   is not reachable by sight and is left out (reported).
4. Greedy set cover: the next viewpoint is the one with most newly seen floor per cost,
   the cost being ``stop_cost`` plus the straight-line distance to the nearest viewpoint
   already chosen (or the dock), until none adds a ``min_gain``-wide square. A room seen through its door
   from the corridor gets no viewpoint inside: the one in the corridor sees it for nothing.
5. Tour: nearest neighbour from the dock, then 2-opt, Or-opt (moving runs of up to three
   stops), 2-opt again and ``tour_kicks`` rounds of iterated local search
   (:mod:`bomc_bt.tour_search`), over grid path lengths (:mod:`bomc_bt.path_matrix`), from
   and back to the dock (``closed_tour``).
6. With ``drive_by``: the floor the camera sees while driving that tour (facing ahead) is
   counted as seen and steps 4-5 run once more, dropping stops that only looked along
   corridors.
7. With ``drop_redundant`` (:mod:`bomc_bt.coverage_prune`): the new tour's legs differ
   from the ones credited, so what they see is computed again, and each stop whose floor
   those legs and the other stops see is dropped (most costly detour first); each kept
   stop faces what it sees first. On a 93 x 90 m floor this drops about a sixth of the
   stops and a tenth of the headings, and the floor left for Cover Gaps halves. Without
   it, what the new legs miss, Cover Gaps finds.

The visibility runs on the target lattice, not the 0.05 m map, which keeps a 93 x 90 m
floor to seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from bomc_bt.algorithm_params import PlannerParams, TraversalParams
from bomc_bt.coverage_known import KnownTargets, index_ranges
from bomc_bt.coverage_prune import drop_redundant_stops
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.path_matrix import path_length_matrix
from bomc_bt.planner import GridPlanner
from bomc_bt.sight import Sight, headings_for
from bomc_bt.tour_search import improve_cycle, open_path_matrix
from bomc_bt.traversal import TraversalPlan, or_opt_route, path_length, two_opt_route
from bomc_bt.turn_order import end_direction, turn_order
from bomc_bt.viewpoints import floor_mask


@dataclass
class CoveragePlan:
    """The plan, and what it covers (for the leaf's message and the tests)."""

    plan: TraversalPlan
    viewpoints: list[tuple[float, float]]  # stop positions in tour order (each with one or more headings)
    floor_targets: int  # floor samples on the map
    seen_targets: int  # of them, seen by some candidate (reachable by sight)
    covered: np.ndarray = field(repr=False)  # (H, W) bool target raster: what the chosen stops see
    target_step: float = 0.25  # m between target samples (the raster's cell)
    known: int = 0  # known nodes given
    known_near: int = 0  # of them, seen from within close_range by a chosen stop or leg
    known_unreachable: int = 0  # of them, seen from that near by no candidate (left to the far looks)


def plan_coverage(grid: OccupancyGrid, start: Pose2D, view_range: float, params: TraversalParams | None = None,
                  planner_params: PlannerParams | None = None, known: np.ndarray | None = None,
                  close_range: float = 0.0, known_radius: float = 0.5,
                  known_footprints: list | None = None) -> CoveragePlan:
    """Viewpoints that see the floor, each with the headings to face, in tour order.

    ``known`` (N, 2): the graph's nodes; each is also looked at once from within
    ``close_range`` (``projection.miss_full_range``): a place sees it when it sees floor within
    ``known_radius`` of it and facing it (``known_footprints``, one per node, each None or a
    box; :mod:`bomc_bt.coverage_known`)."""
    params = params or TraversalParams()
    planner = GridPlanner(grid, planner_params)
    k = max(1, int(round(params.target_step / grid.resolution)))
    m = max(1, int(round(params.candidate_step / (k * grid.resolution))))
    floor = floor_mask(grid, params.shadow)[::k, ::k]
    places = candidate_places(grid, planner, start, floor.shape, k, m, params.clearance)
    sight = Sight(grid, floor, k, view_range, params.min_range, params.shadow)
    views = sight.visible(places)
    seeable = np.zeros(floor.size, dtype=bool)
    for v in views:
        seeable[v] = True
    xy = _world(grid, places[:, 0] * k, places[:, 1] * k)
    min_count = max(1, int(math.ceil((params.min_gain / (k * grid.resolution)) ** 2 - 1e-9)))
    hfov = math.radians(params.hfov_deg)
    nodes = KnownTargets.build(grid, sight, np.zeros((0, 2)) if known is None or close_range <= 0 else known,
                               known_radius, close_range, min_count, params.min_range, known_footprints)
    views = nodes.extend_views(views, xy)
    n_targets = nodes.n_targets
    chosen, credited = greedy_cover(views, xy, n_targets, start.xy, params.stop_cost, min_count)
    order, dist = tour_order(planner, start.xy, xy[chosen], params)
    en_route = np.zeros(n_targets, dtype=bool)
    if params.drive_by and chosen:
        # What the camera sees between stops, facing ahead, needs no stop: cover again with
        # it seen, which drops the stops (and headings) that only looked along corridors.
        stops = [np.asarray(start.xy, dtype=float)] + [xy[chosen[j]] for j in order]
        paths = [_leg(planner, a, b) for a, b in zip(stops[:-1], stops[1:], strict=True)]
        en_route[nodes.along(sight, paths, params.drive_by_step, hfov)] = True
        chosen, credited = greedy_cover(views, xy, n_targets, start.xy, params.stop_cost, min_count, en_route)
        order, dist = tour_order(planner, start.xy, xy[chosen], params)
        if params.drop_redundant and chosen:
            chosen, credited, order, dist, en_route = _drop_redundant(planner, sight, nodes, start.xy, views, xy,
                                                                      chosen, order, dist, params, hfov, min_count)
    covered = en_route.copy()
    for i in chosen:
        covered[views[i]] = True
    if params.drive_by and chosen:
        chosen, credited, order, dist, covered = _look_near_at_nodes(planner, sight, nodes, start.xy, views, xy,
                                                                     chosen, credited, order, dist, covered,
                                                                     params, hfov)
    headings: list[list[float]] = []
    for j in order:
        p = xy[chosen[j]]
        targets = nodes.target_xy(credited[j], lambda flat: _raster_world(grid, flat, floor.shape[1], k))
        bearings = np.arctan2(targets[:, 1] - p[1], targets[:, 0] - p[0])
        headings.append(headings_for(bearings, hfov, min_count, params.max_headings))
    pts = np.array([xy[chosen[j]] for j in order], dtype=float).reshape(-1, 2)
    # after the last stop come Cover Gaps' viewpoints, not yet planned: no departure direction
    waypoints = [pose for poses in turned_stops(planner, start, pts, headings) for pose in poses]
    stops = [(float(x), float(y)) for x, y in pts]
    legs = [0] + [j + 1 for j in order]
    grid_length = float(sum(dist[a, b] for a, b in zip(legs[:-1], legs[1:], strict=True)))
    plan = TraversalPlan(waypoints, path_length(start.xy, pts), grid_length)
    near = covered[floor.size:].reshape(-1, min_count).any(axis=1)
    return CoveragePlan(plan, stops, int(floor.sum()), int(seeable.sum()), covered[:floor.size].reshape(floor.shape),
                        k * grid.resolution, len(near), int(near.sum()), int((~nodes.seeable(views)).sum()))


def _drop_redundant(planner: GridPlanner, sight: Sight, nodes: KnownTargets, start_xy, views: list[np.ndarray],
                    xy: np.ndarray, chosen: list[int], order: list[int], dist: np.ndarray, params: TraversalParams,
                    hfov: float, min_count: int
                    ) -> tuple[list[int], list[np.ndarray], list[int], np.ndarray, np.ndarray]:
    """The tour less the stops its own legs and other stops see for (:mod:`bomc_bt.coverage_prune`);
    chosen, credited, order and dist as :func:`plan_coverage` keeps them, and what the legs see."""
    tour = [chosen[j] for j in order]
    at = [np.asarray(start_xy, dtype=float)] + [xy[i] for i in tour]

    def leg_sight(a: int, b: int) -> np.ndarray:
        return nodes.along(sight, [_leg(planner, at[a], at[b])], params.drive_by_step, hfov)

    rows = [0] + [j + 1 for j in order]
    pruned = drop_redundant_stops([views[i] for i in tour], dist[np.ix_(rows, rows)], nodes.n_targets,
                                  leg_sight, min_count, params.closed_tour)
    kept = [tour[t] for t in pruned.kept]
    credited = _faced(views, xy, kept, nodes.n_targets, start_xy, params.stop_cost, pruned.en_route)
    keep_rows = [0] + [rows[t + 1] for t in pruned.kept]
    return kept, credited, list(range(len(kept))), dist[np.ix_(keep_rows, keep_rows)], pruned.en_route


def _look_near_at_nodes(planner: GridPlanner, sight: Sight, nodes: KnownTargets, start_xy, views: list[np.ndarray],
                        xy: np.ndarray, chosen: list[int], credited: list[np.ndarray], order: list[int],
                        dist: np.ndarray, covered: np.ndarray, params: TraversalParams, hfov: float, rounds: int = 3
                        ) -> tuple[list[int], list[np.ndarray], list[int], np.ndarray, np.ndarray]:
    """Stops added for the known nodes no stop or leg of the final tour sees from near.

    The legs the cover credited (the first tour's) are not the final tour's, so a node seen
    from near only on a leg that is gone would get no near look: each round adds the stops
    that see such nodes (greedy, every node worth a stop), orders the tour again and
    computes what its legs see. The floor the old legs saw may lie off the new ones, so the
    stops are then credited again with what each is to face (planned with the 437 objects of
    a 93 x 90 m floor as nodes, the tour left 278 m² of its covered floor unfaced, against
    71 m² without them: floor the gap viewpoints then drove to, pass after pass). Returns
    chosen, credited, order (the tour's, then 0..n-1), dist, and what stops and legs see."""
    node_views = [v[v >= nodes.n_floor] for v in views]
    en_route = None
    for _ in range(rounds):
        extra, gained = greedy_cover(node_views, xy, nodes.n_targets, start_xy, params.stop_cost, 1, covered)
        if not extra:
            break
        chosen, credited = chosen + extra, credited + gained
        order, dist = tour_order(planner, start_xy, xy[chosen], params)
        at = [np.asarray(start_xy, dtype=float)] + [xy[chosen[j]] for j in order]
        paths = [_leg(planner, a, b) for a, b in zip(at[:-1], at[1:], strict=True)]
        en_route = np.zeros(nodes.n_targets, dtype=bool)
        en_route[nodes.along(sight, paths, params.drive_by_step, hfov)] = True
        covered = en_route.copy()
        for i in chosen:
            covered[views[i]] = True
    if en_route is not None:  # the tour was ordered again: its legs are not the ones credited
        tour, rows = [chosen[j] for j in order], [0] + [j + 1 for j in order]
        credited = _faced(views, xy, tour, nodes.n_targets, start_xy, params.stop_cost, en_route)
        chosen, order, dist = tour, list(range(len(tour))), dist[np.ix_(rows, rows)]
    return chosen, credited, order, dist, covered


def _faced(views: list[np.ndarray], xy: np.ndarray, tour: list[int], n_targets: int, start_xy, stop_cost: float,
           en_route: np.ndarray) -> list[np.ndarray]:
    """Which stop of ``tour`` faces which targets (its headings turn to them): each the ones it
    sees first in a cover of what the tour's legs, facing ahead, do not see."""
    picked, gained = greedy_cover([views[i] for i in tour], xy[tour], n_targets, start_xy, stop_cost, 1, en_route)
    by_stop = dict(zip(picked, gained, strict=True))
    return [by_stop.get(t, np.zeros(0, dtype=np.int64)) for t in range(len(tour))]


_LEG_MARGIN = 4.0  # m of map around a leg's two ends that its path is first searched in


def _leg(planner: GridPlanner, a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """The path the robot drives from a to b: straight when that is clear (most legs along a
    corridor), else planned in a window around the two ends, else on the whole map. An A*
    search on the whole map per leg would dominate the plan's time on a large floor."""
    straight = np.array([a, b], dtype=float)
    if planner.path_is_clear(straight):
        return straight
    grid = planner.grid
    lo, hi = np.minimum(a, b) - _LEG_MARGIN, np.maximum(a, b) + _LEG_MARGIN
    rlo, clo = grid.world_to_cell(lo[0], lo[1])
    rhi, chi = grid.world_to_cell(hi[0], hi[1])
    rlo, clo = max(int(rlo), 0), max(int(clo), 0)
    rhi, chi = min(int(rhi) + 1, grid.height), min(int(chi) + 1, grid.width)
    path = GridPlanner(grid.crop(rlo, rhi, clo, chi), planner.params).plan(a, b)
    return path if path is not None else planner.plan(a, b)


def _raster_world(grid: OccupancyGrid, flat: np.ndarray, width: int, k: int) -> np.ndarray:
    """(M, 2) map points of flat target-raster indices."""
    rows, cols = np.divmod(flat, width)
    return _world(grid, rows * k, cols * k)


def _world(grid: OccupancyGrid, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    x, y = grid.cell_to_world(rows, cols)
    return np.stack([np.asarray(x, float), np.asarray(y, float)], axis=-1).reshape(-1, 2)


def candidate_places(grid: OccupancyGrid, planner: GridPlanner, start: Pose2D, shape: tuple[int, int],
                     k: int, m: int, clearance: float) -> np.ndarray:
    """(K, 2) target-lattice (i, j) of places every ``m`` targets that the robot can stand
    on with ``clearance`` and reach from ``start`` (the planner's component of the dock)."""
    ii, jj = np.mgrid[0:shape[0]:m, 0:shape[1]:m]
    ii, jj = ii.ravel(), jj.ravel()
    xy = _world(grid, ii * k, jj * k)
    pr, pc = planner.planning_grid.world_to_cell(xy[:, 0], xy[:, 1])
    inside = (pr >= 0) & (pr < planner.shape[0]) & (pc >= 0) & (pc < planner.shape[1])
    pr, pc = np.clip(pr, 0, planner.shape[0] - 1), np.clip(pc, 0, planner.shape[1] - 1)
    ok = inside & ~planner.lethal[pr, pc] & (planner.clearance[pr, pc] >= clearance)
    ok &= grid.free_mask()[np.minimum(ii * k, grid.height - 1), np.minimum(jj * k, grid.width - 1)]
    dock = planner.nearest_traversable(start.xy, planner.params.escape_radius)
    if dock is None:
        return np.zeros((0, 2), dtype=np.int64)
    _, labels = cv2.connectedComponents((~planner.lethal).astype(np.uint8), connectivity=8)
    ok &= labels[pr, pc] == labels[planner.cell(dock)]
    return np.stack([ii[ok], jj[ok]], axis=1).astype(np.int64)


def greedy_cover(views: list[np.ndarray], xy: np.ndarray, n_targets: int, start_xy, stop_cost: float,
                 min_count: int, seen: np.ndarray | None = None) -> tuple[list[int], list[np.ndarray]]:
    """Chosen candidates (in the order picked) and the targets each newly saw.

    Targets in ``seen`` (seen on the way) need no viewpoint. Each round takes the candidate
    with the most targets not yet seen per cost (``stop_cost``
    plus the straight-line distance to the nearest chosen viewpoint or the start), while
    one still sees ``min_count`` new targets. Gains are kept current through the targets'
    list of the candidates that see them, so a round costs a few vector operations.
    """
    n = len(views)
    if n == 0:
        return [], []
    lens = np.array([len(v) for v in views], dtype=np.int64)
    indptr = np.concatenate([[0], np.cumsum(lens)])
    indices = np.concatenate(views).astype(np.int64) if lens.sum() else np.zeros(0, dtype=np.int64)
    seers = np.repeat(np.arange(n), lens)[np.argsort(indices, kind="stable")]  # by target
    t_ptr = np.concatenate([[0], np.cumsum(np.bincount(indices, minlength=n_targets))])
    covered = np.zeros(n_targets, dtype=bool) if seen is None else seen.astype(bool).copy()
    gain = (lens - np.bincount(seers[index_ranges(t_ptr[:-1][covered], t_ptr[1:][covered])], minlength=n)).astype(float)
    near = np.hypot(xy[:, 0] - start_xy[0], xy[:, 1] - start_xy[1])
    chosen: list[int] = []
    credited: list[np.ndarray] = []
    while True:
        score = np.where(gain >= min_count, gain / np.maximum(stop_cost + near, 1e-6), -1.0)
        i = int(np.argmax(score))  # ties: the lowest index (raster order), so the plan is deterministic
        if score[i] < 0:
            break
        new = indices[indptr[i]:indptr[i + 1]]
        new = new[~covered[new]]
        covered[new] = True
        gain -= np.bincount(seers[index_ranges(t_ptr[new], t_ptr[new + 1])], minlength=n)
        near = np.minimum(near, np.hypot(xy[:, 0] - xy[i, 0], xy[:, 1] - xy[i, 1]))
        chosen.append(i)
        credited.append(new)
    return chosen, credited


def nearest_neighbour(dist: np.ndarray) -> list[int]:
    """Greedy order over a distance matrix from place 0 (ties: the lowest index)."""
    n = len(dist)
    visited = np.zeros(n, dtype=bool)
    visited[0] = True
    route, at = [0], 0
    for _ in range(n - 1):
        row = np.where(visited, np.inf, dist[at])
        at = int(np.argmin(row))
        visited[at] = True
        route.append(at)
    return route


def route_length(dist: np.ndarray, route: list[int]) -> float:
    return float(sum(dist[a, b] for a, b in zip(route[:-1], route[1:], strict=True)))


def tour_order(planner: GridPlanner, start_xy, points: np.ndarray, params: TraversalParams
               ) -> tuple[list[int], np.ndarray]:
    """Visiting order of ``points`` and the (n + 1)-square path-length matrix (start first).

    Nearest neighbour from the start, then 2-opt with the start fixed (and, for a closed
    tour, a copy of it fixed at the end, so the way back counts).
    """
    pts = np.vstack([np.asarray(start_xy, dtype=float)[:2], np.asarray(points, dtype=float).reshape(-1, 2)])
    dist = path_length_matrix(planner, pts, params.path_resolution)
    finite = np.where(np.isfinite(dist), dist, 1e6)  # a place cut off is visited last, not never
    if params.closed_tour:
        finite = np.vstack([np.hstack([finite, finite[:, :1]]), np.hstack([finite[:1], [[0.0]]])])
    route = nearest_neighbour(finite[: len(pts), : len(pts)])
    if params.closed_tour:
        route.append(len(pts))
    if params.two_opt and len(route) > 3:
        route = two_opt_route(finite, route, params.max_two_opt_passes, fixed_first=True,
                              fixed_last=params.closed_tour)
        route = or_opt_route(finite, route, max_passes=params.max_two_opt_passes, fixed_first=True,
                             fixed_last=params.closed_tour)
        route = two_opt_route(finite, route, params.max_two_opt_passes, fixed_first=True,
                              fixed_last=params.closed_tour)
    if params.two_opt and params.tour_kicks and len(pts) > 4:
        route = _kicked(finite[: len(pts), : len(pts)], route, params)
    return [i - 1 for i in route[1:] if 0 < i < len(pts)], dist


def _kicked(d: np.ndarray, route: list[int], params: TraversalParams) -> list[int]:
    """``route`` (from place 0; with a copy of it last for a closed tour) shortened by
    iterated local search (:mod:`bomc_bt.tour_search`)."""
    n = len(d)
    if params.closed_tour:
        return improve_cycle(d, route[:-1], params.tour_kicks) + [n]
    cycle = improve_cycle(open_path_matrix(d), route + [n], params.tour_kicks)
    if cycle[1] == n:  # the free end read first: the other way round
        cycle = cycle[:1] + cycle[1:][::-1]
    return cycle[:-1] if cycle[-1] == n else route


def order_stops(planner: GridPlanner, start_xy, views: list[Pose2D], params: TraversalParams) -> list[Pose2D]:
    """``views`` in the order of a short open path from ``start_xy`` over path lengths on
    the grid (:func:`tour_order` without the way back): a later phase's stops (gap
    viewpoints) are driven to as one tour, not hopped between by straight-line distance."""
    if len(views) < 2:
        return list(views)
    points = np.array([[v.x, v.y] for v in views], dtype=float)
    order, _ = tour_order(planner, start_xy, points, replace(params, closed_tour=False))
    return [views[i] for i in order]


def turned_stops(planner: GridPlanner, start: Pose2D, stops: np.ndarray, headings: list[list[float]],
                 end_xy=None) -> list[list[Pose2D]]:
    """Per stop of a tour, the poses it turns through: its ``headings`` in the order that
    turns least (:func:`bomc_bt.turn_order.turn_order`) from the direction the leg into it
    arrives in to the direction the leg out of it leaves in (to ``end_xy`` after the last
    stop, if given). A stop with no heading faces the way it arrived."""
    pts = [np.asarray(start.xy, dtype=float)] + [np.asarray(p, dtype=float)[:2] for p in stops]
    if end_xy is not None:
        pts.append(np.asarray(end_xy, dtype=float)[:2])
    legs = [_leg(planner, a, b) if np.hypot(*(b - a)) > 1e-9 else None for a, b in zip(pts[:-1], pts[1:], strict=True)]
    out: list[list[Pose2D]] = []
    facing = start.yaw
    for i, hs in enumerate(headings):
        p = pts[i + 1]
        arrive = _direction(legs[i], pts[i], p, at_start=False)
        arrive = facing if arrive is None else arrive
        depart = _direction(legs[i + 1], p, pts[i + 2], at_start=True) if i + 1 < len(legs) else None
        ordered = turn_order(hs, arrive, depart) if hs else [arrive]
        out.append([Pose2D(float(p[0]), float(p[1]), h) for h in ordered])
        facing = ordered[-1]
    return out


def _direction(leg: np.ndarray | None, a: np.ndarray, b: np.ndarray, at_start: bool) -> float | None:
    """The direction a leg from a to b leaves (``at_start``) or arrives in; the straight line's
    when no path was found; None for a leg of no length."""
    if np.hypot(*(b - a)) <= 1e-9:
        return None
    if leg is not None:
        d = end_direction(leg, at_start)
        if d is not None:
            return d
    return math.atan2(b[1] - a[1], b[0] - a[0])
