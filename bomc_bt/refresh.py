"""Refresh tour: before a pass ends, look again where the graph has gone longest unchecked.

Algorithm 2 reflects a change only when the camera sees it. An object taken away after
the pass looked at it (an intra-session change) stays in the graph until some frame shows
its place empty, and the paper's robot never looks back: the map it leaves can be stale
in exactly the places it covered first. The paper names the remedy as future work:
traversal planning that revisits regions where change is expected.

After the planned waypoints and gap viewpoints, the pass knows when it last confirmed
each node (:attr:`~bomc_bt.graph.Node.last_seen`). Changes arrive at random times, so the
chance that a node has changed since grows with the time since it was seen; its *age*
is the weight. Nodes older than ``stale_after`` are the targets. The candidates are
places this pass has already reached (visited waypoints and viewpoints, so the robot fits
there); a candidate sees a target within ``view_range`` along a line through free map
cells. Greedily, the next stop is the one with the most age newly in sight per metre of
extra driving (path length on the grid, plus ``stop_cost`` for turning and dwelling),
inserted where it lengthens the tour least, while the whole tour stays within ``budget``
times the length of the pass's plan (an orienteering problem; greedy cheapest insertion). Each stop faces the
``hfov``-wide window holding most of that age; Look Around, on arrival, turns to the rest.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.graph import Node
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitoring import line_of_sight
from bomc_bt.viewpoints import best_heading

DistanceField = Callable[[tuple[float, float]], Callable[[np.ndarray], np.ndarray]]
"""``field(start)(points)``: path lengths (m) from ``start`` to each of ``points`` (K, 2)."""


@dataclass
class RefreshParams:
    """Settings of the refresh tour (a leaf's ``params`` in ``trees/traverse.yaml``)."""

    # [s] robot time since a node was last confirmed that makes it worth another look; the
    # leaf takes it from mission.stale_after, as Look Around does, so both see the same nodes
    stale_after: float = 600.0
    # the tour drives at most this fraction of the plan's path length (0: no tour)
    budget: float = 0.3
    view_range: float = 5.0  # m: projection.expect_range, where a frame counts a miss
    min_range: float = 0.5  # m: nearer, the node is below the tilted camera's image
    stop_cost: float = 3.0  # m of driving that one stop's turning and dwelling are worth
    max_viewpoints: int = 20
    hfov_deg: float = 50.0  # planned field of view: the camera's, less a margin

    def __post_init__(self) -> None:
        if self.stale_after < 0 or self.budget < 0 or self.stop_cost < 0 or self.max_viewpoints < 0:
            raise ValueError("need stale_after, budget, stop_cost and max_viewpoints >= 0")
        if not 0 <= self.min_range < self.view_range:
            raise ValueError("need 0 <= min_range < view_range")
        if not 0 < self.hfov_deg <= 360:
            raise ValueError("hfov_deg must be in (0, 360]")


def stale_nodes(nodes: Iterable[Node], now: float, stale_after: float) -> list[Node]:
    """Nodes this pass confirmed, but more than ``stale_after`` seconds before ``now``."""
    return [n for n in nodes if n.last_seen is not None and now - n.last_seen > stale_after]


def refresh_viewpoints(grid: OccupancyGrid, stale: Sequence[Node], now: float, candidates: np.ndarray,
                       start: Pose2D, budget: float, distances: DistanceField,
                       params: RefreshParams | None = None) -> list[Pose2D]:
    """Stops (with the heading to face) that bring the stalest nodes back into sight.

    ``candidates`` (K, 2) are places the robot has reached; ``budget`` is in metres of
    driving; ``distances`` gives path lengths on the grid. The stops come in driving order.
    """
    params = params or RefreshParams()
    candidates = np.asarray(candidates, dtype=float).reshape(-1, 2)
    if not stale or len(candidates) == 0 or budget <= 0 or params.max_viewpoints == 0:
        return []
    targets = np.array([n.position[:2] for n in stale])
    age = np.array([now - n.last_seen for n in stale])
    sight = _sight(grid, candidates, targets, params)
    covered = np.zeros(len(stale), dtype=bool)
    hfov = math.radians(params.hfov_deg)
    route = _Route(distances, candidates, (start.x, start.y))
    headings: dict[int, float] = {}
    while len(headings) < params.max_viewpoints:
        gain = (sight & ~covered) @ age
        extra, after = route.insertion_costs()
        score = np.where((gain > 0) & (route.length + extra <= budget), gain / (extra + params.stop_cost), 0.0)
        k = int(np.argmax(score))
        if score[k] <= 0:
            break
        seen = sight[k] & ~covered
        bearings = np.arctan2(targets[seen, 1] - candidates[k, 1], targets[seen, 0] - candidates[k, 0])
        headings[k], _ = best_heading(bearings, age[seen], hfov)
        covered |= sight[k]
        route.insert(k, int(after[k]))
    return [Pose2D(float(candidates[k, 0]), float(candidates[k, 1]), headings[k]) for k in route.stops]


class _Route:
    """An open path from the start through chosen candidates, grown by cheapest insertion.

    ``rows[j]`` holds the path lengths from route position j (0: the start) to every
    candidate, one distance field per position; the path is symmetric on the grid, so
    these rows price every insertion.
    """

    def __init__(self, distances: DistanceField, candidates: np.ndarray, start: tuple[float, float]):
        self.distances, self.candidates = distances, candidates
        self.stops: list[int] = []
        self.rows = [np.asarray(distances(start)(candidates), dtype=float)]

    @property
    def length(self) -> float:
        return float(sum(self.rows[j][k] for j, k in enumerate(self.stops)))

    def insertion_costs(self) -> tuple[np.ndarray, np.ndarray]:
        """Per candidate: the least extra length of visiting it, and the position to go after."""
        extra = self.rows[-1].copy()  # appended at the end of the open path
        after = np.full(len(extra), len(self.stops))
        for j, k in enumerate(self.stops):
            between = self.rows[j] + self.rows[j + 1] - self.rows[j][k]
            better = between < extra
            extra[better], after[better] = between[better], j
        return extra, after

    def insert(self, k: int, after: int) -> None:
        xy = (float(self.candidates[k, 0]), float(self.candidates[k, 1]))
        self.stops.insert(after, k)
        self.rows.insert(after + 1, np.asarray(self.distances(xy)(self.candidates), dtype=float))


def _sight(grid: OccupancyGrid, candidates: np.ndarray, targets: np.ndarray, params: RefreshParams) -> np.ndarray:
    """(K, N): candidate k sees target n -- in range, and a free line to half a metre short."""
    free = grid.free_mask()
    d = np.hypot(targets[None, :, 0] - candidates[:, None, 0], targets[None, :, 1] - candidates[:, None, 1])
    sight = (d >= params.min_range) & (d <= params.view_range)
    for k, n in zip(*np.nonzero(sight), strict=True):
        a, b = candidates[k], targets[n]
        stop = a + (b - a) * (1.0 - 0.5 / d[k, n]) if d[k, n] > 0.5 else a
        sight[k, n] = line_of_sight(grid, free, (a[0], a[1]), (stop[0], stop[1]))
    return sight
