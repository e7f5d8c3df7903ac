"""Known nodes in the coverage plan: each is looked at once from where a miss counts fully
(projection.miss_full_range), so a removed object can be dropped from the graph."""

from __future__ import annotations

import math

import numpy as np
from test_coverage_plan import DOCK, RANGE, office, sees

from bomc_bt.coverage_plan import plan_coverage

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
