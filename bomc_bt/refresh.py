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

The nodes the pass left unresolved come first (:meth:`~bomc_bt.graph.ObjectGraph.unresolved`):
neither confirmed nor removed, because every view the pass had of them was past another
object (a table against a wall, the chair pushed in at it in front) or it had none, or
missed by a near, clear view since they were last seen. A stop with a clear view of each
decides: the detector confirms it, or its misses run on to a removal in this pass
instead of one or more passes later. So does a node the pass added on its confirming
sightings alone and matched in no frame since (two false detections at one place). A
look that must decide stands within ``look_range`` (``projection.miss_full_range``), where
a frame's miss weighs in full: from 4.5 m each weighs a fifth, and six frames of such a
look left a false trash bin on the map (issue 17, 36 x 28 m office, seed 7717, pass 3).

So do the nodes an earlier pass mapped that may have moved to one this pass added
(:func:`displaced_nodes`): a node of their kind added within ``association.relocation_radius``
after they were last seen. A bin moved 1.1 m during a pass, after the robot had seen it, was
seen at its new place later on and added; its old node was never looked at again and stayed
on the map, an addition reported in place of a move and the removal a pass late (36 x 28 m
office, seed 7421, pass 10). A look decides: the old node confirmed (two objects), or its
misses remove it and the pass's end pairs the removal with the addition as one move.

So do the first sightings the pass never confirmed
(:meth:`~bomc_bt.graph.ObjectGraph.unconfirmed_sightings`): a new object must be seen in two
frames to be added, and one the camera caught once while turning is lost until the next pass.
On a generated Environment-A-size floor (seed 9191) five of pass 1's six never-mapped
objects (a chair, a table, three trash bins) had been detected exactly once, from 2.4-4.1
m. A stop that faces the place either sees it again (a node) or not (a false positive,
dropped). Look Around has turned to most of them already; what is left comes here.

With ``association.miss_spacing``, a node whose run of misses would remove it, all seen
from one place (a robot turning at a doorway), waits for a look from a second place
(:meth:`~bomc_bt.graph.ObjectGraph.awaiting_second_look`). Those nodes are planned
first, from reached places or free places round the node, at least ``miss_spacing`` plus
the goal tolerance from where their misses were seen, and never past another object;
without that look the object, if taken away, would stay in the map for another pass.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.graph import PRESENT, Event, Node, ObjectGraph
from bomc_bt.grid import OccupancyGrid
from bomc_bt.node_sight import camera_clear, sees_target
from bomc_bt.viewpoints import best_heading


@dataclass(frozen=True)
class SightingLook:
    """An unconfirmed first sighting as a target of the refresh tour: it has no node, so its
    ``id`` is negative (no object's box is its own)."""

    id: int
    position: np.ndarray
    footprint: None = None  # no box: looked at by the centre rule (node_sight.sees_target)


def sighting_looks(sightings: Sequence) -> list[SightingLook]:
    """The refresh targets of ``sightings`` (each with a ``position``), ids -1, -2, ..."""
    return [SightingLook(-1 - k, np.asarray(t.position, dtype=float)) for k, t in enumerate(sightings)]


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
    # [m] a look that must decide a node or sighting stands this near it, where a miss weighs in
    # full (the leaf takes projection.miss_full_range; a value at or below min_range means view_range).
    # From 4.5 m a miss weighs a fifth, and a look there left a false trash bin on the map (issue 17)
    look_range: float = 2.5
    min_range: float = 0.5  # m: nearer, the node is below the tilted camera's image
    stop_cost: float = 3.0  # m of driving that one stop's turning and dwelling are worth
    max_viewpoints: int = 20
    hfov_deg: float = 50.0  # planned field of view: the camera's, less a margin
    # [m] how far from a goal the robot may stop and count it reached (the leaf takes
    # sim.planner.goal_tolerance): a second look is planned at least miss_spacing plus this
    # from the place of the misses, or it may be taken from that same spot again
    arrival_tolerance: float = 0.3
    # [m] besides reached places, a second look may be taken from places this far from the
    # node (12 bearings each) that are free with second_look_clearance of room round them
    second_look_radii: tuple[float, ...] = (1.5, 2.5)
    second_look_clearance: float = 0.45  # [m] room a second-look place needs (FindDetour's clearance)
    # look first at the nodes the pass left unresolved (neither confirmed nor removed: seen
    # only past other objects, or not at all, or missed up close since), from places with a
    # clear view of them; False: only stale nodes and second looks, as before
    unresolved: bool = True
    # look also at the first sightings the pass never confirmed (seen in one frame only, no node
    # near): the object caught once while turning, or a false positive; False: not
    unconfirmed: bool = True

    def __post_init__(self) -> None:
        if min(self.stale_after, self.budget, self.stop_cost, self.max_viewpoints, self.arrival_tolerance) < 0:
            raise ValueError("need stale_after, budget, stop_cost, max_viewpoints and arrival_tolerance >= 0")
        if not 0 <= self.min_range < self.view_range or self.look_range < 0:
            raise ValueError("need 0 <= min_range < view_range and look_range >= 0")
        if any(not self.min_range <= r <= self.view_range for r in self.second_look_radii):
            raise ValueError("second_look_radii must lie within [min_range, view_range]")
        if self.second_look_clearance < 0:
            raise ValueError("second_look_clearance must be >= 0")
        if not 0 < self.hfov_deg <= 360:
            raise ValueError("hfov_deg must be in (0, 360]")


def stale_nodes(nodes: Iterable[Node], now: float, stale_after: float) -> list[Node]:
    """Nodes this pass confirmed, but more than ``stale_after`` seconds before ``now``."""
    return [n for n in nodes if n.last_seen is not None and now - n.last_seen > stale_after]


def added_times(events: Iterable[Event]) -> dict[int, float]:
    """Node id -> robot time of its first "added" event among ``events`` (a pass's, in order)."""
    out: dict[int, float] = {}
    for e in events:
        if e.kind == "added":
            out.setdefault(e.node_id, e.stamp)
    return out


def displaced_nodes(nodes: Iterable[Node], added_at: dict[int, float], session: int,
                    radius: float) -> list[Node]:
    """Present nodes of earlier passes last seen before a node of their category was added
    within ``radius`` m of them in pass ``session`` (``added_at``: node id -> robot time of its
    "added" event this pass): the object may have moved there. A node this pass has not seen
    at all was last seen before any addition of the pass (its ``last_seen`` is a robot time
    of an earlier pass, on that pass's clock)."""
    nodes = [n for n in nodes if n.state == PRESENT]
    arrivals = [(u, added_at[u.id]) for u in nodes if u.first_session == session and u.id in added_at]

    def seen_before(v: Node, t: float) -> bool:
        return v.last_session < session or (v.last_seen is not None and v.last_seen < t)

    return [v for v in nodes if v.first_session < session and any(
        u.category == v.category and seen_before(v, t) and np.linalg.norm(u.position[:2] - v.position[:2]) <= radius
        for u, t in arrivals)]


def object_boxes(graph: ObjectGraph, skip: Iterable[int] = (), half: float = 0.25) -> np.ndarray:
    """(M, 4) floor boxes x0, y0, x1, y1 of the graph's present objects but ``skip``: each
    node's footprint, or a square ``half`` m either side of it where it has none."""
    boxes, _ = object_boxes_by_id(graph, skip, half)
    return boxes


def object_boxes_by_id(graph: ObjectGraph, skip: Iterable[int] = (), half: float = 0.25
                       ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`object_boxes` and the id of each box's node, (M,)."""
    skip = set(skip)
    nodes = [n for n in graph.nodes.values() if n.state == PRESENT and n.id not in skip]
    boxes = [n.footprint if n.footprint is not None else
             np.array([n.position[0] - half, n.position[1] - half, n.position[0] + half, n.position[1] + half])
             for n in nodes]
    return np.array(boxes, dtype=float).reshape(-1, 4), np.array([n.id for n in nodes], dtype=np.int64)


def refresh_viewpoints(grid: OccupancyGrid, stale: Sequence[Node], now: float, candidates: np.ndarray,
                       start: Pose2D, budget: float, distances: DistanceField,
                       params: RefreshParams | None = None,
                       second_looks: Sequence[tuple[Node | SightingLook, tuple[float, float] | None]] = (),
                       spacing: float = 0.0, occluders: np.ndarray | None = None,
                       occluder_ids: np.ndarray | None = None) -> list[Pose2D]:
    """Stops (with the heading to face) that bring the stalest nodes back into sight.

    ``candidates`` (K, 2) are places the robot has reached; ``budget`` is in metres of
    driving; ``distances`` gives path lengths on the grid. ``second_looks``: nodes a look
    decides, each with a place or None. A node given a place waits for a look from at least
    ``spacing`` (plus ``arrival_tolerance``) from it
    (:meth:`~bomc_bt.graph.ObjectGraph.awaiting_second_look`); one given None was left
    unresolved by the pass (:meth:`~bomc_bt.graph.ObjectGraph.unresolved`), or is a
    :class:`SightingLook`, and may be looked at from anywhere. Their stops are chosen first,
    the most of them per metre, then the stale nodes' by age, and none looks at them past one
    of ``occluders`` (M, 4: the objects' boxes x0, y0, x1, y1; with ``occluder_ids`` (M,), a
    node's own box is not in its way; a miss counts only where the view is clear). The stops
    come in driving order.
    """
    params = params or RefreshParams()
    reached = np.asarray(candidates, dtype=float).reshape(-1, 2)
    around = second_look_places(grid, [n for n, _ in second_looks], params)
    candidates = np.concatenate([reached, around])
    waiting = {n.id for n, _ in second_looks}
    stale = [n for n in stale if n.id not in waiting]
    nodes = [n for n, _ in second_looks] + stale
    if not nodes or len(candidates) == 0 or budget <= 0 or params.max_viewpoints == 0:
        return []
    targets = np.array([n.position[:2] for n in nodes])
    age = np.array([0.0] * len(second_looks) + [now - n.last_seen for n in stale])
    sight = _sight(grid, candidates, targets, [n.footprint for n in nodes], params)
    if second_looks:
        places = np.array([(np.nan, np.nan) if place is None else place for _, place in second_looks],
                          dtype=float).reshape(-1, 2)
        apart = np.hypot(candidates[:, None, 0] - places[None, :, 0], candidates[:, None, 1] - places[None, :, 1])
        sight[:, :len(second_looks)] &= np.isnan(apart) | (apart >= spacing + params.arrival_tolerance)
        if params.look_range > params.min_range:  # else no place would be both near enough and in the image
            looked = targets[:len(second_looks)]
            sight[:, :len(second_looks)] &= np.hypot(candidates[:, None, 0] - looked[None, :, 0],
                                                     candidates[:, None, 1] - looked[None, :, 1]) \
                <= params.look_range + 1e-6
        if occluders is not None and len(occluders):
            k, n = np.nonzero(sight[:, :len(second_looks)])  # only the pairs in sight: memory stays small
            own = None if occluder_ids is None else \
                np.asarray(occluder_ids)[None, :] == np.array([nodes[i].id for i in n])[:, None]
            hidden = _behind(candidates[k], targets[n], occluders, own=own)
            sight[k[hidden], n[hidden]] = False
        sight[len(reached):, len(second_looks):] = False  # places round a node are for its second look only
    covered = np.zeros(len(nodes), dtype=bool)
    hfov = math.radians(params.hfov_deg)
    route = _Route(distances, candidates, (start.x, start.y))
    headings: dict[int, float] = {}
    first = np.arange(len(nodes)) < len(second_looks)
    for weight in (first.astype(float), np.where(first, 0.0, age)):  # second looks first, then by age
        while len(headings) < params.max_viewpoints:
            gain = (sight & ~covered) @ weight
            extra, after = route.insertion_costs()
            score = np.where((gain > 0) & (route.length + extra <= budget), gain / (extra + params.stop_cost), 0.0)
            k = int(np.argmax(score))
            if score[k] <= 0:
                break
            seen = sight[k] & ~covered & (weight > 0)
            bearings = np.arctan2(targets[seen, 1] - candidates[k, 1], targets[seen, 0] - candidates[k, 0])
            headings[k], _ = best_heading(bearings, weight[seen], hfov)
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


def _sight(grid: OccupancyGrid, candidates: np.ndarray, targets: np.ndarray, footprints: list,
           params: RefreshParams) -> np.ndarray:
    """(K, N): candidate k sees target n -- in range, and a line the camera sees along
    (:func:`~bomc_bt.node_sight.camera_clear`) to a face of its footprint (None: to half a
    metre short of it; :func:`~bomc_bt.node_sight.sees_target`)."""
    free = camera_clear(grid)
    d = np.hypot(targets[None, :, 0] - candidates[:, None, 0], targets[None, :, 1] - candidates[:, None, 1])
    sight = (d >= params.min_range) & (d <= params.view_range)
    for k, n in zip(*np.nonzero(sight), strict=True):
        sight[k, n] = sees_target(grid, free, (candidates[k, 0], candidates[k, 1]), targets[n], footprints[n])
    return sight


def second_look_places(grid: OccupancyGrid, nodes: Sequence[Node | SightingLook], params: RefreshParams) -> np.ndarray:
    """(K, 2) free places round ``nodes`` (``second_look_radii`` x 12 bearings) with
    ``second_look_clearance`` of room: where a second look may stand besides reached places."""
    if not nodes:
        return np.zeros((0, 2))
    bearings = np.arange(12) * (np.pi / 6.0)
    ring = np.array([(r * np.cos(b), r * np.sin(b)) for r in params.second_look_radii for b in bearings]).reshape(-1, 2)
    places = (np.array([n.position[:2] for n in nodes])[:, None, :] + ring[None, :, :]).reshape(-1, 2)
    room = cv2.distanceTransform(grid.free_mask().astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    rows, cols = grid.world_to_cell(places[:, 0], places[:, 1])
    inside = grid.in_bounds(rows, cols)
    ok = np.zeros(len(places), dtype=bool)
    ok[inside] = room[rows[inside], cols[inside]] >= params.second_look_clearance
    return places[ok]


def _behind(starts: np.ndarray, ends: np.ndarray, boxes: np.ndarray, short: float = 0.3,
            own: np.ndarray | None = None) -> np.ndarray:
    """(P,): the line from ``starts[p]`` to ``ends[p]`` (less its last ``short`` m) crosses one
    of ``boxes`` (M, 4: x0, y0, x1, y1), by the slab test; ``own`` (P, M) marks boxes a line
    does not count (its target's own)."""
    a = starts[:, None, :]  # (P, 1, 2)
    step = ends[:, None, :] - a  # (P, 1, 2)
    length = np.linalg.norm(step, axis=-1)
    end = np.clip(1.0 - short / np.maximum(length, 1e-9), 0.0, 1.0)  # (P, 1)
    lo, hi = boxes[None, :, :2], boxes[None, :, 2:]
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - a) / step, (hi - a) / step
    inside = (a >= lo) & (a <= hi)  # a parallel line crosses only if it starts inside the slab
    near = np.where(step == 0, np.where(inside, -np.inf, np.inf), np.minimum(t0, t1))
    far = np.where(step == 0, np.where(inside, np.inf, -np.inf), np.maximum(t0, t1))
    enter, leave = near.max(axis=-1), far.min(axis=-1)  # (P, M)
    crossed = (enter <= leave) & (leave >= 0.0) & (enter <= end)
    return (crossed & ~own if own is not None else crossed).any(axis=-1)
