"""Known nodes in the coverage plan: each is looked at once from where a miss counts fully
(projection.miss_full_range), so a removed object can be dropped from the graph."""

from __future__ import annotations

import math

import numpy as np
from test_coverage_plan import DOCK, RANGE, office, sees

from bomc_bt.algorithm_params import TraversalParams
from bomc_bt.coverage_plan import _leg, plan_coverage
from bomc_bt.planner import GridPlanner
from bomc_bt.sight import Sight, faced
from bomc_bt.viewpoints import floor_mask

CLOSE = 2.5  # projection.miss_full_range's default
FAR_CORNER = (6.6, 7.6)  # the middle room's far left corner: 4.6 m from its doorway


def nearest_look(grid, stops, point) -> float:
    """Distance from ``point`` to the nearest stop that sees it (inf when none does)."""
    return min((math.hypot(s[0] - point[0], s[1] - point[1]) for s in stops if sees(grid, s, point)),
               default=math.inf)


def test_a_node_the_floor_cover_sees_only_from_afar_gets_a_near_look():
    grid = office()
    floor_only = plan_coverage(grid, DOCK, RANGE)
    assert nearest_look(grid, floor_only.viewpoints, FAR_CORNER) > 4.0  # the case this guards: a far look only
    plan = plan_coverage(grid, DOCK, RANGE, known=np.array([FAR_CORNER]), close_range=CLOSE)
    assert nearest_look(grid, plan.viewpoints, FAR_CORNER) <= CLOSE
    assert (plan.known, plan.known_near, plan.known_unreachable) == (1, 1, 0)
    assert plan.covered.sum() >= floor_only.covered.sum() * 0.98  # the floor is still covered
    assert plan.plan.grid_length <= floor_only.plan.grid_length + 2 * 4.6  # one detour into the room at most


def test_a_node_already_seen_from_near_changes_nothing():
    grid = office()
    floor_only = plan_coverage(grid, DOCK, RANGE)
    near = (3.0, 5.0)  # just inside the first room's door, 1.3 m from a stop
    assert nearest_look(grid, floor_only.viewpoints, near) <= CLOSE
    plan = plan_coverage(grid, DOCK, RANGE, known=np.array([near]), close_range=CLOSE)
    assert plan.viewpoints == floor_only.viewpoints
    assert [(w.x, w.y, w.yaw) for w in plan.plan.waypoints] == [(w.x, w.y, w.yaw) for w in floor_only.plan.waypoints]
    assert plan.known_near == 1


def faced_floor(grid, plan) -> np.ndarray:
    """The plan's floor targets the camera faces driving it: along its legs facing ahead, and
    at each stop within the field of view of each heading it turns to (not all around)."""
    params = TraversalParams()
    k = max(1, round(params.target_step / grid.resolution))
    sight = Sight(grid, floor_mask(grid, params.shadow)[::k, ::k], k, RANGE, params.min_range, params.shadow)
    at = [np.asarray(DOCK.xy)] + [np.asarray(p) for p in plan.viewpoints]
    legs = [_leg(GridPlanner(grid), a, b) for a, b in zip(at[:-1], at[1:], strict=True)]
    poses = np.array([(w.x, w.y, w.yaw) for w in plan.plan.waypoints])
    seen = np.zeros(plan.covered.size, dtype=bool)
    seen[faced(sight, legs, poses, params.drive_by_step, math.radians(params.hfov_deg))] = True
    return seen.reshape(plan.covered.shape)


# Twelve objects across the rooms and the corridor: their near looks add stops, and the tour
# is ordered again, so its legs are not the ones the floor's cover counted on.
OBJECTS = [(9.7, 6.2), (10.2, 2.7), (14.2, 5.2), (13.7, 3.7), (7.2, 7.2), (13.2, 3.7), (17.2, 5.2), (9.7, 5.2),
           (3.7, 6.2), (14.7, 4.7), (4.7, 3.7), (0.7, 7.2)]


def test_after_near_looks_reorder_the_tour_its_stops_still_face_the_floor_it_covers():
    """The floor a stop is credited with decides which ways it turns. The near looks at known
    nodes add stops and order the tour again; floor the old legs saw facing ahead must then be
    faced by some stop, or a later pass leaves it to the gap viewpoints (a pass on a 93 x 90 m
    floor where nothing changed drove 8 gap viewpoints in its first pass and 33 in its third)."""
    grid = office()
    floor_only = plan_coverage(grid, DOCK, RANGE)
    plan = plan_coverage(grid, DOCK, RANGE, known=np.array(OBJECTS), close_range=CLOSE)
    assert len(plan.viewpoints) > len(floor_only.viewpoints)  # the case this guards: near looks added stops
    unfaced = plan.covered & ~faced_floor(grid, plan)
    unfaced_before = floor_only.covered & ~faced_floor(grid, floor_only)
    assert unfaced.sum() <= max(unfaced_before.sum(), 0.01 * plan.covered.sum())


def test_a_door_on_the_room_side_of_a_wall_gets_its_near_look_from_the_room():
    """A door on the middle room's face of the corridor wall (y 4.55 m, 2 m from the room's
    doorway). The corridor floor within ``known_radius`` of its centre lies behind the wall: a
    look from there faces the wall. Shown only by floor that sees a face of its footprint, the
    plan looks at it from the room, and its tour is no longer for it."""
    grid = office()
    door, footprint, face = (7.0, 4.62), np.array([6.55, 4.45, 7.45, 4.80]), (7.0, 4.75)
    across = plan_coverage(grid, DOCK, RANGE, known=np.array([door]), close_range=CLOSE)
    assert not any(sees(grid, s, face) and math.dist(s, face) <= CLOSE for s in across.viewpoints)
    plan = plan_coverage(grid, DOCK, RANGE, known=np.array([door]), close_range=CLOSE, known_footprints=[footprint])
    assert nearest_look(grid, plan.viewpoints, face) <= CLOSE
    assert (plan.known, plan.known_near) == (1, 1)
    assert plan.plan.grid_length < across.plan.grid_length
