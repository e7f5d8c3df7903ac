"""The monitor pass as plain objects: waypoint bookkeeping, detours, perception, coverage.

The monitor tree's leaves are thin wrappers around these. :class:`TraversalState` knows
which waypoint is next, which were visited, reached by a detour or missed, and retries
missed ones once at the end of the pass (the paper's robot lost objects when a bin
blocked a corridor; ours comes back). :func:`detour_viewpoints` proposes other places
near a blocked waypoint that still see it. :class:`Perception` runs one RGB-D frame
through detector, segmenter, back-projection and association (Algorithm 2), writes the
events to the store, and accumulates the area the camera actually observed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import InitVar, dataclass, field
from typing import Any

import cv2
import numpy as np

from bomc_bt.first_seen import gone_before
from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.graph.robust import RobustPolicy
from bomc_bt.graph.walls import Walls
from bomc_bt.grid import OccupancyGrid
from bomc_bt.looked_sides import LookedSides, looked_sides_for
from bomc_bt.node_sight import line_of_sight, sees_node, sees_target
from bomc_bt.pass_resume import earlier_co_observed, earlier_looks, earlier_sides, frame_progress
from bomc_bt.perception.expected import expected_nodes, miss_weights
from bomc_bt.perception.frames import Detector, Segmenter
from bomc_bt.perception.looked import looked_polygon
from bomc_bt.perception.projection import ProjectionParams, detections_to_observations, fov_polygon
from bomc_bt.resume_rows import ResumeRows
from bomc_bt.robot import RGBDFrame
from bomc_bt.sightings import Sightings
from bomc_bt.traversal import TraversalPlan

PENDING, VISITED, DETOURED, MISSED = "pending", "visited", "detoured", "missed"
GAPS, REFRESH, LAST_LOOKS = "gaps", "refresh", "last_looks"  # phases a pass adds to its plan after the waypoints
PHASE_ORDER = (GAPS, REFRESH, LAST_LOOKS)  # the order the pass adds them in (trees/traverse.yaml)


@dataclass
class TraversalState:
    """Where the pass is in its plan; JSON-able so a killed pass can resume.

    The plan grows in phases: the sampled waypoints, then the gap viewpoints, then the
    refresh stops (``phases`` maps each added phase to the index of its first entry).
    """

    plan: TraversalPlan
    states: list[str] = field(default_factory=list)
    index: int = 0  # next position in the plan's order
    retried: list[int] = field(default_factory=list)  # missed waypoints already tried again
    current: int | None = None
    phases: dict[str, int] = field(default_factory=dict)  # "gaps" / "refresh" / "last_looks" -> first index
    # what the refresh stops were planned to decide: {"nodes": [ids]}
    looked_for: dict[str, list] = field(default_factory=dict)

    def add_viewpoints(self, phase: str, viewpoints: list[Pose2D]) -> None:
        """Append the viewpoints of ``phase``, planned once per pass after what came before."""
        self.phases[phase] = len(self.states)
        self.plan.waypoints.extend(viewpoints)
        self.states.extend([PENDING] * len(viewpoints))

    @property
    def gaps_from(self) -> int | None:
        """Index of the first gap viewpoint, once they were planned."""
        return self.phases.get(GAPS)

    def planned(self, phase: str) -> bool:
        return phase in self.phases

    def phase_count(self, phase: str) -> int:
        """How many entries ``phase`` added (0 if not planned)."""
        if phase not in self.phases:
            return 0
        # in the order the pass adds them: an empty phase shares its start with the next one
        names = sorted(self.phases, key=lambda n: (self.phases[n], PHASE_ORDER.index(n) if n in PHASE_ORDER else 0))
        k = names.index(phase)
        end = self.phases[names[k + 1]] if k + 1 < len(names) else len(self.states)
        return end - self.phases[phase]

    def __post_init__(self) -> None:
        if not self.states:
            self.states = [PENDING] * len(self.plan.waypoints)

    def next(self) -> int | None:
        """The next waypoint to visit; missed ones come back once after the last. Those
        marked before their turn (skipped behind obstacles) are passed over in order."""
        while self.index < len(self.states):
            self.index += 1
            if self.states[self.index - 1] == PENDING:
                self.current = self.index - 1
                return self.current
        for i, state in enumerate(self.states):
            if state == MISSED and i not in self.retried:
                self.retried.append(i)
                self.current = i
                return i
        self.current = None
        return None

    def mark(self, i: int, state: str) -> None:
        if state == MISSED and self.states[i] in (VISITED, DETOURED):
            return
        self.states[i] = state

    def waypoint(self, i: int) -> Pose2D:
        return self.plan.waypoints[i]

    def reached(self) -> np.ndarray:
        """(K, 2) positions of the waypoints and viewpoints visited so far (the robot fit there)."""
        xy = [(p.x, p.y) for p, s in zip(self.plan.waypoints, self.states, strict=True) if s == VISITED]
        return np.array(xy, dtype=float).reshape(-1, 2)

    @property
    def done_count(self) -> int:
        return sum(s != PENDING for s in self.states)

    def summary(self) -> dict[str, Any]:
        counts = {s: self.states.count(s) for s in (VISITED, DETOURED, MISSED, PENDING)}
        missed = [{"index": i, "x": round(self.waypoint(i).x, 2), "y": round(self.waypoint(i).y, 2)}
                  for i, s in enumerate(self.states) if s == MISSED]
        return {"waypoints": len(self.states), **counts, "missed_waypoints": missed,
                "gap_viewpoints": self.phase_count(GAPS), "refresh_stops": self.phase_count(REFRESH),
                "last_looks": self.phase_count(LAST_LOOKS)}

    def to_json(self) -> dict[str, Any]:
        return {"states": self.states, "index": self.index, "retried": self.retried, "phases": self.phases,
                "looked_for": self.looked_for}

    def restore(self, data: dict[str, Any]) -> None:
        if len(data.get("states", [])) == len(self.states):
            self.states = list(data["states"])
            self.index = int(data["index"])
            self.retried = list(data.get("retried", []))
            phases = data.get("phases") or ({GAPS: data["gaps_from"]} if "gaps_from" in data else {})
            self.phases = {str(k): int(v) for k, v in phases.items()
                           if isinstance(v, int) and 0 <= v <= len(self.states)}
            looked_for = data.get("looked_for")
            self.looked_for = dict(looked_for) if isinstance(looked_for, dict) else {}


def detour_viewpoints(grid: OccupancyGrid, target: tuple[float, float], radius: float, count: int,
                      clearance: float, avoid: list[tuple[float, float]] = (),
                      avoid_radius: float = 0.5) -> list[tuple[float, float]]:
    """Free places within ``radius`` of a blocked waypoint that still see it.

    Candidates lie on rings around the target; each keeps ``clearance`` from obstacles
    (so the robot fits there) and has a clear line of sight to the target through known
    free cells (so the camera sees the same area). Nearest first; places near ``avoid``
    (detours already tried) are left out.
    """
    free = grid.free_mask()
    dist = cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    rings = np.linspace(min(0.75, radius), radius, max(2, int(radius / 0.5)))
    angles = np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)
    rr, aa = np.meshgrid(rings, angles, indexing="ij")
    xs = target[0] + (rr * np.cos(aa)).ravel()
    ys = target[1] + (rr * np.sin(aa)).ravel()
    rows, cols = grid.world_to_cell(xs, ys)
    ok = grid.in_bounds(rows, cols)
    ok[ok] = dist[rows[ok], cols[ok]] >= clearance
    for ax, ay in avoid:
        ok &= np.hypot(xs - ax, ys - ay) > avoid_radius
    picks = [(float(x), float(y)) for x, y in zip(xs[ok], ys[ok], strict=True)
             if line_of_sight(grid, free, (x, y), target)]
    picks.sort(key=lambda p: (math.hypot(p[0] - target[0], p[1] - target[1]), p))
    return picks[:count]


def unverified_headings(graph, pose: Pose2D, session: int, grid: OccupancyGrid, radius: float,
                        fov: float, max_turns: int, now: float | None = None,
                        stale_after: float = 0.0, sightings: Sequence[np.ndarray] = ()) -> list[float]:
    """Headings to turn to so the camera checks nearby nodes this pass has not confirmed.

    A node not matched in this session (or with misses pending) is either still there,
    missed by the detector, or gone; the paper's robot only learns which if the camera
    happens to look. Turning towards such nodes from a waypoint lets the graph confirm
    them or count misses until removal is confirmed. Nodes behind a wall (no face of
    their footprint in a line of sight on the map, :func:`~bomc_bt.node_sight.sees_target`)
    are left for another waypoint.
    Headings are grouped into camera-wide windows, nearest turn first.

    With ``stale_after`` > 0 and the robot time ``now``, a node this pass confirmed more
    than ``stale_after`` seconds ago counts as unconfirmed again: an object can be taken
    away after the camera passed it (an intra-session change), and the paper's robot
    never looks back. Where the pass brings the robot near such a node again, a turn of
    the head shows whether it is still there (the paper's future work: revisit regions
    where change is expected).

    ``sightings``: places (x, y[, z]) of first sightings the pass has not confirmed
    (:meth:`~bomc_bt.graph.ObjectGraph.unconfirmed_sightings`): an object the camera caught in
    one frame on the way here; a turn towards it and the dwell after it add it, or not.
    """
    square = np.array([[pose.x - radius, pose.y - radius], [pose.x + radius, pose.y - radius],
                       [pose.x + radius, pose.y + radius], [pose.x - radius, pose.y + radius]])
    pending = set(graph.pending())
    free = grid.free_mask()
    bearings = []
    for node in graph.nodes_in_polygon(square):
        dx, dy = node.position[0] - pose.x, node.position[1] - pose.y
        distance = math.hypot(dx, dy)
        if distance > radius or distance < 0.5 or (node.last_session == session and node.id not in pending
                                                     and not _stale(node, now, stale_after)):
            continue
        if sees_target(grid, free, (pose.x, pose.y), node.position, node.footprint):
            bearings.append(math.atan2(dy, dx))
    for place in sightings:
        dx, dy = float(place[0]) - pose.x, float(place[1]) - pose.y
        if 0.5 <= math.hypot(dx, dy) <= radius and sees_node(grid, free, (pose.x, pose.y), (place[0], place[1])):
            bearings.append(math.atan2(dy, dx))
    headings: list[float] = []
    for b in sorted(bearings, key=lambda b: abs(wrap_angle(b - pose.yaw))):
        if all(abs(wrap_angle(b - h)) > 0.4 * fov for h in headings):
            headings.append(b)
    return headings[:max_turns]


def _stale(node, now: float | None, stale_after: float) -> bool:
    """Confirmed by this pass, but longer than ``stale_after`` seconds ago."""
    seen = node.last_seen
    return stale_after > 0 and now is not None and seen is not None and now - seen > stale_after


class Coverage:
    """The map area the camera actually observed during a pass (issue: coverage accounting).

    ``seen`` is all the camera's view reached; ``near`` only what it saw within
    ``near_range`` m (0: the same as ``seen``), near enough to detect an object and confirm a
    change there: a room glimpsed through a doorway from the corridor is seen, not looked
    at, and the change model (:mod:`bomc_bt.change_model`) counts only looks."""

    def __init__(self, grid: OccupancyGrid, near_range: float = 0.0):
        self.grid = grid
        self.free = grid.free_mask()
        self.seen = np.zeros(grid.data.shape, dtype=np.uint8)
        self.near_range = near_range
        self.near = np.zeros(grid.data.shape, dtype=np.uint8) if near_range > 0 else self.seen

    def add(self, polygon: np.ndarray) -> None:
        if polygon is None or len(polygon) < 3:
            return
        polygon = np.asarray(polygon, dtype=float)
        self._fill(self.seen, polygon)
        if self.near is not self.seen:  # the fan from the camera (vertex 0), each ray cut at near_range
            ray = polygon[1:] - polygon[0]
            scale = np.minimum(1.0, self.near_range / np.maximum(np.hypot(ray[:, 0], ray[:, 1]), 1e-9))
            self._fill(self.near, np.vstack([polygon[:1], polygon[0] + ray * scale[:, None]]))

    def _fill(self, mask: np.ndarray, polygon: np.ndarray) -> None:
        rows, cols = self.grid.world_to_cell(polygon[:, 0], polygon[:, 1])
        pts = np.stack([cols, rows], axis=1).astype(np.int32)
        cv2.fillPoly(mask, [pts], 1)

    @property
    def observed_area(self) -> float:
        return float(np.count_nonzero(self.seen.astype(bool) & self.free)) * self.grid.resolution**2

    @property
    def fraction(self) -> float:
        total = np.count_nonzero(self.free)
        return float(np.count_nonzero(self.seen.astype(bool) & self.free)) / total if total else 0.0

    def unobserved_regions(self, min_area: float = 2.0) -> list[dict[str, float]]:
        """Connected free regions the camera never saw, largest first."""
        missing = (self.free & ~self.seen.astype(bool)).astype(np.uint8)
        n, _, stats, centroids = cv2.connectedComponentsWithStats(missing, connectivity=8)
        cell = self.grid.resolution**2
        regions = []
        for i in range(1, n):
            area = float(stats[i, cv2.CC_STAT_AREA]) * cell
            if area >= min_area:
                x, y = self.grid.cell_to_world(centroids[i, 1], centroids[i, 0])
                regions.append({"x": round(float(x), 2), "y": round(float(y), 2), "area_m2": round(area, 2)})
        return sorted(regions, key=lambda r: -r["area_m2"])


@dataclass(frozen=True)
class FrameSeen:
    """What the last frame showed: the pass's timeline records it (:mod:`bomc_bt.timeline`)."""

    stamp: float  # [s] robot time of the image
    size: tuple[int, int]  # [count] image width, height in pixels
    detections: list  # perception.frames.Detection: category, pixel box, score
    observations: list  # graph.Observation: their points in the map


@dataclass
class FrameResult:
    detections: int
    observations: int
    expected: int
    events: list


@dataclass
class Perception:
    """One RGB-D frame through the whole Perceive-Associate pipeline.

    ``graph`` and ``store`` are the pass's :class:`~bomc_bt.graph.ObjectGraph` and
    :class:`~bomc_bt.store.SiteStore` (the store may be None: nothing is persisted);
    ``grid`` is the saved map the observed area is counted on; with ``seen_before``
(:mod:`bomc_bt.first_seen`) an addition at a place no earlier pass saw is marked first
seen before it is written. With a store, every frame
    is committed with the pass's resume point (:mod:`bomc_bt.pass_resume`), taken from
    ``robot`` where it can give its state.
    """

    detector: Detector
    segmenter: Segmenter | None
    categories: list[str]
    params: ProjectionParams
    graph: Any
    store: Any
    session: int
    grid: InitVar[OccupancyGrid]
    occlusion_check: bool = True
    robot: Any = None  # the robot whose state a frame's commit saves (None: none saved)
    seen_before: Any = None  # first_seen.SeenBefore: what earlier passes saw (None: unknown, nothing marked)
    near_range: float = 0.0  # [m] the coverage's ``near`` reach (budget.view_range; 0: all it sees)
    coverage: Coverage = field(init=False)
    # the floor seen within projection.expect_range (where a missed object is evidence of its
    # absence): what later passes tell first-seen objects from added ones by (bomc_bt.first_seen)
    looked: Coverage = field(init=False)
    looked_sides: LookedSides | None = field(init=False)  # and from which sides (bomc_bt.looked_sides)
    sightings: Sightings = field(init=False)  # where detections put objects (bomc_bt.sightings)
    fov_since: list = field(default_factory=list)  # view polygons since the last coverage snapshot
    looked_since: list = field(default_factory=list)  # their parts within expect_range, likewise
    frames: int = 0  # frames processed
    events: list = field(default_factory=list)  # every event of the pass, in order
    last_frame: FrameSeen | None = None  # the latest frame's detections, for the timeline
    resume_rows: ResumeRows = field(default_factory=ResumeRows, repr=False, compare=False)  # the resume point's rows

    def __post_init__(self, grid: OccupancyGrid) -> None:
        self.coverage = Coverage(grid, self.near_range)
        self.looked = Coverage(grid)
        self.looked_sides = looked_sides_for(grid, getattr(self.graph, "params", None))
        self.sightings = Sightings(grid)
        if isinstance(getattr(self.graph, "policy", None), RobustPolicy):  # no object's end across a wall
            self.graph.policy.walls = Walls(grid)
        if self.seen_before is not None:  # a place new to the map is no moved object's new place
            self.graph.never_looked = self.seen_before.never_looked
            self.graph.sighted_before = self.seen_before.sighted_here
        if self.store is not None:  # two objects an earlier pass saw side by side stay two
            self.graph.keep_apart(self.session, earlier_co_observed(self.store, self.session))
            gone: list = []
            if isinstance(getattr(self.graph, "policy", None), RobustPolicy):  # one back is no other's new place
                gone = self.graph.policy.gone = gone_before(self.store, self.session)
            sides = self.graph.evidence.sides  # where an object was missed from before (graph.view_sides)
            if sides is not None:  # of the nodes on the map and those gone, which may come back
                sides.carry(earlier_sides(self.store, self.session), set(self.graph.nodes) | {g.id for g in gone})
            # a node an earlier pass looked at from one place only: that look counts (miss_spacing)
            self.graph.evidence.looked_before = earlier_looks(self.store, self.session) & set(self.graph.nodes)

    def process(self, frame: RGBDFrame) -> FrameResult:
        detections = self.detector.detect(frame, self.categories)
        if self.segmenter is not None and detections:
            detections = self.segmenter.segment(frame, detections)
        observations = detections_to_observations(frame, detections, self.params)
        self.sightings.add(observations)
        polygon = fov_polygon(frame, self.params)
        self.coverage.add(polygon)
        if polygon is not None and len(polygon) >= 3:
            self.fov_since.append(np.asarray(polygon, dtype=float).tolist())
            near = looked_polygon(frame, self.params, self.params.expect_range)
            if len(near) >= 3:
                self.looked.add(near)
                if self.looked_sides is not None:
                    self.looked_sides.add(near)
                self.looked_since.append(near.tolist())
        candidates = self.graph.nodes_in_polygon(polygon) if polygon is not None and len(polygon) >= 3 else []
        expected = expected_nodes(frame, candidates, self.params) if self.occlusion_check else candidates
        weights = (miss_weights(frame, expected, self.params, detections, observations,
                                self.graph.params.relabel_radius) if self.occlusion_check else None)
        events = self.graph.associate(observations, [n.id for n in expected], self.session, frame.stamp,
                                      in_view=[n.id for n in candidates], miss_weights=weights,
                                      place=frame.T_map_base[:2, 3])
        if self.seen_before is not None:  # an addition where no earlier pass looked is new to the map
            self.seen_before.mark(events)
        changed = self.graph.drain_changed()
        self.frames += 1
        self.last_frame = FrameSeen(frame.stamp, frame.shape[::-1], detections, observations)
        if self.store is not None:  # every frame: the resume point moves on even without events
            self.commit(events, changed, durable=False)
        self.events.extend(events)
        return FrameResult(len(detections), len(observations), len(expected), events)

    def commit(self, events: list, changed: list, durable: bool = True) -> None:
        """Write ``events`` and the ``changed`` nodes with the pass's resume point as it stands, in
        one transaction (each frame; and the pass end, whose state the next pass carries)."""
        self.store.record(events, changed, frame_progress(self, self.robot), durable=durable)
        self.resume_rows.written()
