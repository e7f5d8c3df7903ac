"""The coverage tour's last touches: Or-opt moves a stop visited out of the way, and a stop
whose floor the tour's own legs and other stops see is dropped, never one only it sees."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bomc_bt.algorithm_params import TraversalParams
from bomc_bt.coverage_plan import plan_coverage, route_length
from bomc_bt.coverage_prune import drop_redundant_stops
from bomc_bt.traversal import or_opt_route
from tests.test_coverage_plan import DOCK, RANGE, office


def _euclid(pts: np.ndarray) -> np.ndarray:
    return np.hypot(pts[:, None, 0] - pts[None, :, 0], pts[:, None, 1] - pts[None, :, 1])


def test_or_opt_moves_a_stop_visited_out_of_the_way_to_where_it_lies():
    """Places 0..9 along a line, place 7 visited between 2 and 3: 2-opt cannot fix that by
    reversing one stretch without another detour, Or-opt moves the place back."""
    pts = np.column_stack([np.arange(10.0), np.zeros(10)])
    route = [0, 1, 2, 7, 3, 4, 5, 6, 8, 9]
    out = or_opt_route(_euclid(pts), route, fixed_first=True)
    assert out == list(range(10))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.booleans())
def test_or_opt_never_lengthens_and_keeps_the_ends(seed, closed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(0, 20, (12, 2))
    d = _euclid(pts)
    route = [0] + list(rng.permutation(np.arange(1, 11))) + ([11] if closed else [])
    if not closed:
        route.append(11)
    out = or_opt_route(d, route, fixed_first=True, fixed_last=closed)
    assert sorted(out) == sorted(route) and out[0] == 0
    assert not closed or out[-1] == 11
    assert route_length(d, out) <= route_length(d, route) + 1e-9


def _drop(views: list[list[int]], leg_seen: dict | None = None, min_count: int = 1, closed: bool = False):
    """Stops 1 m apart on a line east of the dock (node 0); the leg between nodes a and b
    sees what ``leg_seen[(a, b)]`` says, else nothing."""
    xy = np.column_stack([np.arange(len(views) + 1.0), np.zeros(len(views) + 1)])

    def leg_sight(a: int, b: int) -> np.ndarray:
        return np.asarray((leg_seen or {}).get((a, b), []), dtype=np.int64)

    return drop_redundant_stops([np.asarray(v, dtype=np.int64) for v in views], _euclid(xy), 10, leg_sight,
                                min_count, closed)


def test_a_stop_whose_floor_another_stop_sees_is_dropped_and_one_only_it_sees_is_kept():
    assert _drop([[0, 1, 2], [1, 2], [3, 4]], closed=True).kept == [0, 2]


def test_a_stop_is_dropped_when_the_leg_that_replaces_its_two_sees_its_floor():
    """Stop 1 (node 2) alone sees targets 5 and 6, but the leg from node 1 to node 3 that
    replaces its two legs sees them: the stop goes. Without that leg it stays."""
    views = [[0], [5, 6], [7]]
    pruned = _drop(views, {(1, 3): [5, 6]})
    assert pruned.kept == [0, 2]
    assert pruned.en_route[[5, 6]].all()
    assert _drop(views).kept == [0, 1, 2]


def test_a_leg_that_no_longer_runs_does_not_count():
    """Targets 5 and 6 are seen only on the leg into stop 1 (node 2): dropping stop 1 would
    lose them with that leg, so it stays although no stop needs its own view."""
    views = [[0], [1], [7]]
    pruned = _drop(views, {(1, 2): [5, 6]})
    assert pruned.kept == [0, 1, 2]
    assert pruned.en_route[[5, 6]].all()


def test_a_stop_that_loses_fewer_targets_than_min_count_is_dropped():
    assert _drop([[0, 1, 2, 3], [3, 4]], min_count=2).kept == [0]
    assert _drop([[0, 1, 2, 3], [3, 4, 5]], min_count=2).kept == [0, 1]


def test_dropping_stops_never_lengthens_the_office_tour_and_keeps_its_floor_seen():
    grid = office()
    keep = replace(TraversalParams(), drop_redundant=False)
    full = plan_coverage(grid, DOCK, RANGE, keep)
    pruned = plan_coverage(grid, DOCK, RANGE)
    assert set(pruned.viewpoints) <= set(full.viewpoints)
    assert pruned.plan.grid_length <= full.plan.grid_length + 1e-6
    # what the pruned plan counts as seen is what its own tour's legs and stops see
    assert pruned.covered.sum() >= 0.95 * pruned.seen_targets
