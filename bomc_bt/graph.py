"""The persistent semantic object graph and its per-frame association (the paper's Algorithm 2).

A node is one object: id, category, mean 3D position in the map frame, detection
confidence. Each RGB-D frame brings a list of observations (category + map-frame centroid)
and the caller's list of *expected* nodes (those inside the field-of-view polygon that the
depth image says are not occluded). :meth:`ObjectGraph.associate` then updates the graph
and returns the events (added / removed / moved / updated) for the site store.

Two modes, chosen by :attr:`AssociationParams.mode`:

``paper`` -- Algorithm 2 as written, so its behaviour can be reproduced and compared.
  Every expected node with no same-category observation within delta_c is removed at once;
  every observation within delta_c of an expected same-category node leaves the unmatched
  set; an unmatched observation becomes a new node only when no same-category node (the
  graph as it stands, including nodes added earlier in the same frame) lies within
  delta_c. Matched nodes keep their position and confidence (the algorithm never updates
  them); only the bookkeeping fields ``last_session`` and ``observations`` change.

``robust`` (default) -- our extension where the paper names its own limitations
  (occlusion, missed detections, relocated objects):

  * *One-to-one matching.* Observations and nodes of a category are paired greedily by
    distance (shortest pair first, ties by node id then observation order) among pairs
    within delta_c. In the paper one detection can keep two nearby nodes alive; here a
    duplicate node that never gets its own detection is eventually removed.
  * *Refresh.* A matched node moves towards the observation by a running average with
    weight ``position_smoothing`` (centroids from single frames are noisy, a moving
    average converges on the object), keeps the maximum confidence seen (the paper's
    attribute is the detection score; the best view is the most informative), and
    records ``last_session``, ``observations`` and resets ``misses``.
  * *Confirm before deleting.* An expected node that is not matched gains a miss, at most
    one per ``confirm_interval`` seconds of robot time (so a burst of frames at one spot
    counts once), and is removed only at ``confirm_misses`` consecutive misses. A single
    missed detection (motion blur, a person walking past) no longer deletes an object.
  * *No duplicates.* An unmatched observation within delta_c of a same-category node
    (which then has been matched by a closer observation) is absorbed, as in the paper.
  * *Moves keep their id.* An unmatched observation farther than delta_c from every
    same-category node but within ``move_radius`` of a same-category node that was removed
    earlier in this session, or is pending removal (has misses), is taken to be that
    object moved: it keeps its id and the event is ``moved`` with the previous position.
    Identity across a relocation is what lets a user ask "where did chair 12 go?".
    A wrong guess costs little: the object left behind gets a new id when it is seen.
  * *Updated events are sparse.* A refresh emits ``updated`` only the first time a node is
    matched in a session or when its position drifted more than ``report_distance`` since
    the last report, so the history does not grow by one row per node per frame; the
    store reconciles exact values at the end of each session.

Ids continue from ``max id + 1`` as in the paper and are never reused, also not the ids of
removed nodes (the store passes the next id; ids are what the history is keyed on).

Performance: the paper scans all nodes for every unmatched observation and every FoV
query. The graph keeps a uniform hash grid (cell size = the largest association
distance) over a contiguous numpy array of positions, one grid per category plus one
over all categories, so a delta-query reads at most 3 x 3 cells and a FoV query reads the
cells under the polygon's bounding box. :func:`associate_linear_scan` is the naive paper
reference over all nodes, used as the benchmark baseline and as a test oracle.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

PRESENT = "present"
REMOVED = "removed"
EVENT_KINDS = ("added", "removed", "moved", "updated")


@dataclass
class Node:
    """One object in the graph; ``position`` is (3,) in the map frame."""

    id: int
    category: str
    position: np.ndarray
    confidence: float
    first_session: int
    last_session: int
    state: str = PRESENT  # "present" | "removed" (removed nodes live on in the store's history)
    observations: int = 1  # times matched
    misses: int = 0  # consecutive expected-but-unseen frames (robust mode)
    # robust: floor-plane box (xmin, ymin, xmax, ymax) the object's points have covered, None unknown
    footprint: np.ndarray | None = None
    # robot time of the latest frame that matched (or added) the node in this process; None
    # when it was loaded from the store and not seen since. Not persisted: it only says how
    # stale a node has grown during the pass at hand (see monitoring.unverified_headings).
    last_seen: float | None = None

    def __post_init__(self) -> None:
        self.position = np.asarray(self.position, dtype=float).reshape(3)
        self.footprint = _box_or_none(self.footprint)


@dataclass
class Observation:
    """One detected object in one frame: category and map-frame centroid of its points."""

    category: str
    position: np.ndarray
    confidence: float
    n_points: int = 0
    extent: float = 0.0  # horizontal spread (m) of the object's points about the centroid
    box: np.ndarray | None = None  # floor-plane box (xmin, ymin, xmax, ymax) of those points
    truncated: bool = False  # cut by the image border or an occluder: part of the object is missing

    def __post_init__(self) -> None:
        self.position = np.asarray(self.position, dtype=float).reshape(3)
        self.box = _box_or_none(self.box)


@dataclass
class Event:
    """A change of the graph, as recorded in the store's history."""

    kind: str  # "added" | "removed" | "moved" | "updated"
    node_id: int
    category: str
    position: np.ndarray
    session: int
    stamp: float
    previous: np.ndarray | None = None  # position before a move
    confidence: float = 0.0


@dataclass
class AssociationParams:
    """Tunables of association (``config/*.yaml`` key ``association``)."""

    default_distance: float = 0.7  # [m] delta: an observation this near a node of its category is that node
    per_category: dict[str, float] = field(default_factory=dict)  # [m] delta_c: per-category overrides of delta
    mode: Literal["paper", "robust"] = "robust"  # [choice] the paper's Algorithm 2, or the robust variant
    confirm_misses: int = 3  # [count] robust: misses before a node is removed
    confirm_interval: float = 0.5  # [s] robust: robot time between two counted misses
    move_radius: float = 3.0  # [m] robust: how far a removed/pending object may have moved
    position_smoothing: float = 0.3  # [-] robust: running-average weight of a new observation
    report_distance: float = 0.1  # [m] robust: drift that makes a refresh an "updated" event
    vertical_weight: float = 0.5  # [-] robust: weight of height differences in distances (paper: 1)
    extent_gate: float = 2.0  # [-] robust: a big object's own spread widens its gate, up to this times delta
    confirm_detections: int = 2  # [count] robust: frames (confirm_interval apart) that must see a new object
    tentative_ttl: float = 10.0  # [s] robust: how long a first sighting waits for its confirmation
    footprint_overlap: float = 0.5  # [-] robust: box overlap (of the smaller box) that makes the same object; 0: off
    # [m] robust: gap between a truncated view's box and a big object's footprint that still touch
    # (about the width of what hides the rest: a chair in front of a table)
    footprint_touch: float = 0.5

    def __post_init__(self) -> None:
        if not self.default_distance > 0:
            raise ValueError("default_distance must be > 0")
        for cat, d in self.per_category.items():
            if not d > 0:
                raise ValueError(f"per_category distance for {cat!r} must be > 0")
        if self.mode not in ("paper", "robust"):
            raise ValueError(f"mode must be 'paper' or 'robust', got {self.mode!r}")
        if self.confirm_misses < 1:
            raise ValueError("confirm_misses must be >= 1")
        if self.confirm_interval < 0 or self.move_radius < 0 or self.report_distance < 0:
            raise ValueError("confirm_interval, move_radius and report_distance must be >= 0")
        if self.confirm_detections < 1 or self.tentative_ttl < 0:
            raise ValueError("confirm_detections must be >= 1 and tentative_ttl >= 0")
        if self.extent_gate < 1.0:
            raise ValueError("extent_gate must be >= 1 (1 turns it off)")
        if not 0.0 <= self.vertical_weight <= 1.0:
            raise ValueError("vertical_weight must be in [0, 1]")
        if not 0.0 < self.position_smoothing <= 1.0:
            raise ValueError("position_smoothing must be in (0, 1]")
        if not 0.0 <= self.footprint_overlap <= 1.0:
            raise ValueError("footprint_overlap must be in [0, 1] (0 turns it off)")
        if self.footprint_touch < 0:
            raise ValueError("footprint_touch must be >= 0")


def points_in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule, vectorised over points: bool mask of ``points`` (M, 2) inside ``polygon`` (K, 2)."""
    x, y = points[:, 0], points[:, 1]
    inside = np.zeros(len(points), dtype=bool)
    xj, yj = polygon[-1]
    for xi, yi in polygon:
        if yi != yj:
            crosses = (yi > y) != (yj > y)
            with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # near-horizontal edges
                x_at = (xj - xi) * (y - yi) / (yj - yi) + xi
            inside ^= crosses & (x < x_at)
        xj, yj = xi, yi
    return inside


def _check_polygon(polygon: np.ndarray) -> np.ndarray:
    poly = np.asarray(polygon, dtype=float)
    if poly.ndim != 2 or poly.shape[1] != 2 or len(poly) < 3:
        raise ValueError(f"polygon must be (K >= 3, 2), got shape {poly.shape}")
    return poly


class ObjectGraph:
    """The live object graph (present nodes) with a spatial index and Algorithm 2."""

    def __init__(self, params: AssociationParams, nodes: Iterable[Node] = (), next_id: int | None = None):
        self.params = params
        self.nodes: dict[int, Node] = {}
        self._cell = max([params.default_distance, *params.per_category.values()])
        # Distances are measured on (x, y, w*z): robust mode down-weights height, since a
        # tall object seen cut off by the image edge has its centroid too low.
        w = params.vertical_weight if params.mode == "robust" else 1.0
        self._scale = np.array([1.0, 1.0, w])
        self._pos = np.zeros((1024, 3))
        self._slot_id = np.full(1024, -1, dtype=np.int64)
        # robust: per slot, the gate its node's own size earns (0: delta_c), see _grow_gate
        self._gate_slot = np.zeros(1024)
        self._node_gates = params.mode == "robust"
        # robust: per slot, the node's footprint box (NaN: unknown), see _grow_extent
        self._box_slot = np.full((1024, 4), np.nan)
        self._boxes = params.mode == "robust" and params.footprint_overlap > 0.0
        self._slot_of: dict[int, int] = {}
        self._free: list[int] = []
        self._used = 0  # high-water mark of slots
        self._cat_cells: dict[tuple[str, int, int], list[int]] = {}
        self._cells: dict[tuple[int, int], list[int]] = {}
        self._cat_slots: dict[str, set[int]] = {}
        self._pending: set[int] = set()  # robust: present nodes with misses > 0
        self._last_miss: dict[int, tuple[int, float]] = {}  # id -> (session, stamp) of last counted miss
        self._removed_now: dict[int, Node] = {}  # removed in the current session (move candidates)
        # robust: first sightings awaiting confirmation: (category, position, count, last, first stamp)
        self._tentative: list[tuple[str, np.ndarray, int, float, float]] = []
        self._session: int | None = None
        self._changed: dict[int, Node] = {}
        self._reported: dict[int, np.ndarray] = {}  # position at the last event of a node
        max_id = -1
        for node in nodes:
            max_id = max(max_id, node.id)
            if node.state != PRESENT:
                continue
            if node.id in self.nodes:
                raise ValueError(f"duplicate node id {node.id}")
            self._insert(node)
            if node.misses > 0:
                self._pending.add(node.id)
        self.next_id = max(max_id + 1, next_id if next_id is not None else 0)

    # ------------------------------------------------------------------ queries
    def threshold(self, category: str) -> float:
        """delta_c: the association distance of ``category``."""
        return self.params.per_category.get(category, self.params.default_distance)

    def __len__(self) -> int:
        return len(self.nodes)

    def nodes_in_polygon(self, polygon: np.ndarray, z_range: tuple[float, float] | None = None) -> list[Node]:
        """Present nodes whose xy lies inside ``polygon`` (K, 2) (and z inside ``z_range``), by id."""
        poly = _check_polygon(polygon)
        slots = self._slots_in_box(poly.min(axis=0), poly.max(axis=0))
        if len(slots) == 0:
            return []
        pos = self._pos[slots]
        mask = points_in_polygon(pos[:, :2], poly)
        if z_range is not None:
            z = np.array([self.nodes[int(i)].position[2] for i in self._slot_id[slots]])
            mask &= (z >= z_range[0]) & (z <= z_range[1])
        ids = np.sort(self._slot_id[slots[mask]])
        return [self.nodes[int(i)] for i in ids]

    def nearest(
        self, category: str, position: np.ndarray, max_distance: float | None = None
    ) -> tuple[Node | None, float]:
        """Closest present node of ``category`` (and its distance), or (None, inf)."""
        p = np.asarray(position, dtype=float).reshape(3) * self._scale
        members = self._cat_slots.get(category)
        if not members:
            return None, math.inf
        if max_distance is not None:
            slots = self._cat_candidates(category, p, max_distance)
        else:
            slots = self._ring_search(category, p, len(members))
        if len(slots) == 0:
            return None, math.inf
        d2 = _dist2(self._pos[slots], p)
        k = int(np.lexsort((self._slot_id[slots], d2))[0])
        dist = math.sqrt(float(d2[k]))
        if max_distance is not None and dist > max_distance:
            return None, math.inf
        return self.nodes[int(self._slot_id[slots[k]])], dist

    def within(self, category: str, position: np.ndarray, radius: float) -> list[tuple[Node, float]]:
        """Present nodes of ``category`` within ``radius`` of ``position``, nearest first."""
        ids, d2 = self._within(category, np.asarray(position, dtype=float).reshape(3) * self._scale, radius)
        order = np.lexsort((ids, d2))
        return [(self.nodes[int(ids[k])], math.sqrt(float(d2[k]))) for k in order]

    def drain_changed(self) -> list[Node]:
        """Nodes changed (incl. removed ones) since the last call, by id: what the store persists."""
        changed = [self._changed[i] for i in sorted(self._changed)]
        self._changed.clear()
        return changed

    def pending(self) -> list[int]:
        """Ids of present nodes awaiting confirmation of their removal (robust mode)."""
        return sorted(self._pending)

    # -------------------------------------------------------------- association
    def associate(
        self, observations: list[Observation], expected: list[int], session: int, stamp: float,
        in_view: list[int] | None = None,
    ) -> list[Event]:
        """Update the graph with one frame (Algorithm 2); returns the events in order.

        ``expected``: nodes in the field of view that the frame can confirm or deny.
        ``in_view`` (robust mode): all nodes inside the field-of-view polygon, hidden ones
        included; only these may be folded into an observed node as hidden duplicates.
        Nodes in neither list are never touched.
        """
        self._begin(session)
        exp = [i for i in dict.fromkeys(expected) if i in self.nodes]
        if self.params.mode == "paper":
            return self._associate_paper(observations, exp, session, stamp)
        return self._associate_robust(observations, exp, session, stamp, set(in_view or ()))

    def _associate_paper(
        self, obs: Sequence[Observation], expected: list[int], session: int, stamp: float
    ) -> list[Event]:
        events: list[Event] = []
        unmatched = np.ones(len(obs), dtype=bool)
        hits = self._expected_hits(obs, expected)
        for row, vid in enumerate(expected):
            v = self.nodes[vid]
            if not hits[row].any():
                events.append(self._remove(v, session, stamp))
                continue
            unmatched &= ~hits[row]
            self._touch(v, session, stamp)
        candidates = [obs[j] for j in np.nonzero(unmatched)[0]]
        near = self._within_many(candidates)
        added: list[Node] = []  # V' grows inside the loop: later observations see earlier additions
        for o, (ids, _) in zip(candidates, near, strict=True):
            if len(ids) == 0 and not self._near_any(o, added):
                events.append(self._add(o, session, stamp))
                added.append(self.nodes[events[-1].node_id])
        return events

    def _associate_robust(
        self, obs: Sequence[Observation], expected: list[int], session: int, stamp: float, in_view: set[int]
    ) -> list[Event]:
        events: list[Event] = []
        near = self._within_many(obs)  # one vectorised pass, graph as it stood at the frame's start
        pairs: list[tuple[float, int, int]] = []
        for j, (ids, d2) in enumerate(near):
            pairs.extend(zip(d2.tolist(), ids.tolist(), [j] * len(ids), strict=True))
        pairs.sort()
        matched_nodes: set[int] = set()
        matched_obs: set[int] = set()
        for _, vid, j in pairs:
            if vid in matched_nodes or j in matched_obs:
                continue
            matched_nodes.add(vid)
            matched_obs.add(j)
            event = self._refresh(self.nodes[vid], obs[j], session, stamp)
            if event is not None:
                events.append(event)
        for vid in expected:
            if vid not in matched_nodes:
                event = self._miss(self.nodes[vid], session, stamp)
                if event is not None:
                    events.append(event)
        placed: list[Node] = []  # nodes added or moved in this frame
        for j, o in enumerate(obs):
            if j in matched_obs or len(near[j][0]) or self._near_any(o, placed):
                continue  # matched, or absorbed: a closer observation already matched that node
            if o.truncated and (v := self._touched_node(o)) is not None:
                # a part of a known object, cut off by an occluder (see _touched_node)
                event = self._refresh(v, o, session, stamp, restart=False)
                if event is not None:
                    events.append(event)
                continue
            if not self._confirmed(o, stamp):
                continue
            moved = self._move_candidate(o)
            events.append(self._move(moved, o, session, stamp) if moved else self._add(o, session, stamp))
            placed.append(self.nodes[events[-1].node_id])
        hidden = in_view - set(expected)
        events.extend(self._merge_hidden_duplicates(pairs, matched_nodes, hidden, obs, session, stamp))
        return events

    def _merge_hidden_duplicates(self, pairs: list[tuple[float, int, int]], matched: set[int], hidden: set[int],
                                 obs: Sequence[Observation], session: int, stamp: float) -> list[Event]:
        """Fold into the matched node any same-category node that the same observation also
        covers: unmatched and either hidden (in view, not expected) or lying on the floor
        area the observation's own points cover.

        Two views of a big object from opposite sides can leave two nodes a little over
        delta_c apart; as their running averages converge, the second ends up *inside* the
        object, where the depth image hides it, so it is never expected and never missed.
        Likewise a sliver of a table seen past an obstacle can start a node at one end of
        a table whose node sits at the other. An observation that covers both settles it:
        the node seen more often keeps its id (position averaged by observations), the
        other is removed. A node that was expected but unmatched and lies elsewhere is not
        touched: it may be a second object, and the miss count decides.
        """
        events: list[Event] = []
        best: dict[int, int] = {}
        for _, vid, j in pairs:  # sorted by distance: the observation each matched node got
            if vid in matched and j not in best.values() and vid not in best:
                best[vid] = j
        for vid, j in best.items():
            covered = set(self._box_overlaps(obs[j]))
            covered |= {v.id for v, _ in self.within(obs[j].category, obs[j].position, self.gate(obs[j]))
                        if v.id in hidden}
            for oid in sorted(covered):
                v, other = self.nodes.get(vid), self.nodes.get(oid)
                if v is None or other is None or oid == vid or oid in matched:
                    continue
                keep, drop = (v, other) if (v.observations, -v.id) >= (other.observations, -other.id) else (other, v)
                total = max(keep.observations + drop.observations, 1)
                self._relocate(keep, (keep.position * keep.observations + drop.position * drop.observations) / total)
                keep.observations += drop.observations
                keep.confidence = max(keep.confidence, drop.confidence)
                self._set_footprint(keep, _union(keep.footprint, drop.footprint))
                self._changed[keep.id] = keep
                events.append(self._remove(drop, session, stamp))
                del self._removed_now[drop.id]  # merged, not gone: never "moved" back
                events.append(self._event("updated", keep, session, stamp))
                matched.add(keep.id)
        return events

    def _expected_hits(self, obs: Sequence[Observation], expected: list[int]) -> np.ndarray:
        """(E, M) bool: observation j has expected node i's category and lies within its delta."""
        if not expected or not obs:
            return np.zeros((len(expected), len(obs)), dtype=bool)
        codes: dict[str, int] = {}
        ocode = np.array([codes.setdefault(o.category, len(codes)) for o in obs])
        vcode = np.array([codes.get(self.nodes[i].category, -1) for i in expected])
        delta = np.array([self.threshold(self.nodes[i].category) for i in expected])
        obs_pos = np.array([o.position for o in obs]) * self._scale
        d = self._pos[[self._slot_of[i] for i in expected]][:, None, :] - obs_pos
        d2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
        return (vcode[:, None] == ocode[None, :]) & (d2 <= (delta * delta)[:, None])

    def gate(self, o: Observation) -> float:
        """How far a node may be from ``o`` and still be the same object.

        delta_c in the paper. In robust mode a large object widens it to the spread of its
        own points (capped at ``extent_gate`` * delta_c): seen from another side, a table's
        visible-surface centroid moves by up to half its length, and without this the
        same table becomes two nodes. Small objects keep delta_c.
        """
        delta = self.threshold(o.category)
        if self.params.mode != "robust":
            return delta
        return max(delta, min(1.5 * o.extent, self.params.extent_gate * delta))

    def _near_any(self, o: Observation, nodes: list[Node]) -> bool:
        delta = self.gate(o)
        return any(
            v.category == o.category
            and _dist2_scalar(v.position * self._scale, o.position * self._scale) <= delta * delta
            for v in nodes
        )

    def _is_big(self, v: Node) -> bool:
        """Whether the node's footprint is longer than delta_c on a side: a table, not a cup."""
        fp = v.footprint
        return self._boxes and fp is not None and max(fp[2] - fp[0], fp[3] - fp[1]) > self.threshold(v.category)

    def _grow_extent(self, v: Node, o: Observation, restart: bool = False) -> None:
        """Remember how big this node's object has shown itself: its widest spread (the
        gate) and the floor area its points covered (the footprint, union of boxes).

        An end-on view of a long table shows little of it and its centroid sits ~0.6 m off
        the middle; the node, having seen the table side-on, knows it is big and accepts
        that view instead of starting a second table. The footprint goes further: any view
        whose points lie mostly on floor the node's object already covered is that object,
        however far its centroid is from the node's. ``restart`` (the first match of a
        session) starts the footprint over from this view if it is near enough to have a
        box and sticks out of the old footprint, so an object nudged between visits does not
        keep the floor it stood on last time. A first view that lies inside the old footprint
        says the object is where it was: a table seen past its chairs shows one end, and
        shrinking it to that end would make a duplicate of the other end when it comes into
        view. A far first match keeps the old footprint for the session. (Restarting at the
        first *boxed* view instead shrank tables to partial views and let a sliver become a
        duplicate again: office-s perfect session 3, 0.984 -> 0.977.)
        """
        slot = self._slot_of.get(v.id)
        if slot is not None and self._node_gates:
            self._gate_slot[slot] = max(self._gate_slot[slot], self.gate(o))
        if self._boxes and o.box is not None:
            if restart and v.footprint is not None and _inside(o.box, v.footprint, _NOISE_PAD):
                restart = False
            self._set_footprint(v, o.box.copy() if restart else _union(v.footprint, o.box))

    def _touched_node(self, o: Observation) -> Node | None:
        """The big same-category node whose footprint a truncated view lies against, if any.

        A table behind chairs may only ever show its two ends, from two sides: views whose
        boxes are a chair's width apart. That is also what two tables side by side look
        like, but the second table, seen whole, is a view that is not truncated; a view
        that is cut off by an occluder near a big known object's edge is taken to be more
        of that object, not a new one (at worst a second object is added later, when seen
        whole). Only big objects (a footprint side longer than delta_c) count: small ones
        are seen whole often enough, and chairs around a table are a chair's width apart.
        The view then extends that node's footprint: a table whose far end was hidden by a
        chair until the chair went away grows to its whole length as the end comes into
        view, a sliver at a time, instead of the next sliver becoming a second table.
        """
        if not self._boxes or o.box is None:
            return None
        touch = self.params.footprint_touch
        grown = o.box + np.array([-touch, -touch, touch, touch])
        reach = max(self.params.extent_gate * self.threshold(o.category), _half_diagonal(grown))
        slots = self._cat_candidates(o.category, o.position * self._scale, reach)
        if len(slots) == 0:
            return None
        boxes = self._box_slot[slots]
        with np.errstate(invalid="ignore"):
            big = np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]) > self.threshold(o.category)
        hits = np.nonzero(big & _overlapping(boxes, grown, 1e-9))[0]
        if len(hits) == 0:
            return None
        gaps = [_box_gap(boxes[k], o.box) for k in hits]
        best = min(range(len(hits)), key=lambda i: (gaps[i], int(self._slot_id[slots[hits[i]]])))
        return self.nodes[int(self._slot_id[slots[hits[best]]])]

    def _set_footprint(self, v: Node, box: np.ndarray | None) -> None:
        v.footprint = box
        slot = self._slot_of.get(v.id)
        if slot is not None:
            self._box_slot[slot] = np.nan if box is None else box

    def _box_overlaps(self, o: Observation) -> list[int]:
        """Ids of same-category nodes whose footprint shares ``footprint_overlap`` of the
        smaller of the two boxes with the observation's box."""
        if not self._boxes or o.box is None:
            return []
        reach = max(self.params.extent_gate * self.threshold(o.category), _half_diagonal(o.box))
        slots = self._cat_candidates(o.category, o.position * self._scale, reach)
        if len(slots) == 0:
            return []
        hit = _overlapping(self._box_slot[slots], o.box, self.params.footprint_overlap)
        return sorted(int(i) for i in self._slot_id[slots[hit]])

    def _refresh(self, v: Node, o: Observation, session: int, stamp: float,
                 restart: bool | None = None) -> Event | None:
        w = self.params.position_smoothing
        first_in_session = v.last_session != session
        self._grow_extent(v, o, restart=first_in_session if restart is None else restart)
        target = (1.0 - w) * v.position + w * o.position
        if self._is_big(v):  # the middle of the floor it covers, not of its visible faces
            target[:2] = (v.footprint[:2] + v.footprint[2:]) / 2.0
        self._relocate(v, target)
        v.confidence = max(v.confidence, float(o.confidence))
        self._seen(v, session, stamp)
        reported = self._reported.get(v.id)
        drift = math.inf if reported is None else float(np.linalg.norm(v.position - reported))
        if first_in_session or drift > self.params.report_distance:
            return self._event("updated", v, session, stamp)
        return None

    def _miss(self, v: Node, session: int, stamp: float) -> Event | None:
        last = self._last_miss.get(v.id)
        if last is not None and last[0] == session and stamp - last[1] < self.params.confirm_interval:
            return None
        v.misses += 1
        self._last_miss[v.id] = (session, stamp)
        self._pending.add(v.id)
        self._changed[v.id] = v
        if v.misses >= self.params.confirm_misses:
            return self._remove(v, session, stamp)
        return None

    def _move_candidate(self, o: Observation) -> Node | None:
        """Nearest same-category node removed this session or pending removal, within move_radius."""
        best: tuple[float, int, Node] | None = None
        pending = (self.nodes[i] for i in self._pending)
        for v in (*self._removed_now.values(), *pending):
            if v.category != o.category:
                continue
            d = float(np.linalg.norm((v.position - o.position) * self._scale))
            if d <= self.params.move_radius and (best is None or (d, v.id) < best[:2]):
                best = (d, v.id, v)
        return None if best is None else best[2]

    def _move(self, v: Node, o: Observation, session: int, stamp: float) -> Event:
        previous = v.position.copy()
        if v.state == REMOVED:
            del self._removed_now[v.id]
            v.state = PRESENT
            v.position = o.position.copy()
            self._insert(v)
        else:
            self._relocate(v, o.position.copy())
        if self._boxes:  # where it stood before says nothing about its size here
            self._set_footprint(v, o.box)
        v.confidence = float(o.confidence)
        self._seen(v, session, stamp)
        return self._event("moved", v, session, stamp, previous)

    def _seen(self, v: Node, session: int, stamp: float) -> None:
        """Bookkeeping of a node an observation just confirmed: no removal pending."""
        v.last_session = session
        v.last_seen = stamp
        v.observations += 1
        v.misses = 0
        self._pending.discard(v.id)
        self._last_miss.pop(v.id, None)
        self._changed[v.id] = v

    # --------------------------------------------------------- shared mutations
    def _confirmed(self, o: Observation, stamp: float) -> bool:
        """Confirm before adding: a new object must be seen in ``confirm_detections`` frames.

        A false positive (a shadow taken for a door, a box for a bin) rarely repeats at the
        same place in the next frames, a real object does. First sightings wait here, off
        the graph, for ``tentative_ttl`` seconds; the observation that confirms one becomes
        the node (at the mean of the sightings).
        """
        need = self.params.confirm_detections
        if need <= 1:
            return True
        ttl, gate = self.params.tentative_ttl, self.gate(o)
        self._tentative = [t for t in self._tentative if stamp - t[3] <= ttl]
        for k, (cat, pos, count, last, first) in enumerate(self._tentative):
            if cat != o.category or np.linalg.norm((pos - o.position) * self._scale) > gate:
                continue
            if stamp - last < self.params.confirm_interval:
                return False  # the same burst of frames: not independent evidence
            count += 1
            mean = (pos * (count - 1) + o.position) / count
            if count >= need:
                del self._tentative[k]
                o.position = mean
                return True
            self._tentative[k] = (cat, mean, count, stamp, first)
            return False
        self._tentative.append((o.category, o.position.copy(), 1, stamp, stamp))
        return False

    def _begin(self, session: int) -> None:
        if session != self._session:
            self._removed_now.clear()
            self._tentative = []
            self._session = session

    def _touch(self, v: Node, session: int, stamp: float) -> None:
        v.last_session = session
        v.last_seen = stamp
        v.observations += 1
        self._changed[v.id] = v

    def _add(self, o: Observation, session: int, stamp: float) -> Event:
        node = Node(self.next_id, o.category, o.position.copy(), float(o.confidence), session, session,
                    last_seen=stamp)
        self.next_id += 1
        self._insert(node)
        self._grow_extent(node, o)
        self._changed[node.id] = node
        return self._event("added", node, session, stamp)

    def _remove(self, v: Node, session: int, stamp: float) -> Event:
        self._delete(v)
        v.state = REMOVED
        self._removed_now[v.id] = v
        self._pending.discard(v.id)
        self._last_miss.pop(v.id, None)
        self._changed[v.id] = v
        return self._event("removed", v, session, stamp)

    def _event(
        self, kind: str, v: Node, session: int, stamp: float, previous: np.ndarray | None = None
    ) -> Event:
        self._reported[v.id] = v.position.copy()
        return Event(kind, v.id, v.category, v.position.copy(), session, float(stamp), previous, v.confidence)

    # ------------------------------------------------------------- the index
    def _key(self, x: float, y: float) -> tuple[int, int]:
        return math.floor(x / self._cell), math.floor(y / self._cell)

    def _insert(self, node: Node) -> None:
        if self._free:
            slot = self._free.pop()
        else:
            if self._used == len(self._pos):
                self._pos = np.concatenate([self._pos, np.zeros_like(self._pos)])
                self._slot_id = np.concatenate([self._slot_id, np.full(len(self._slot_id), -1, np.int64)])
                self._gate_slot = np.concatenate([self._gate_slot, np.zeros(len(self._gate_slot))])
                self._box_slot = np.concatenate([self._box_slot, np.full_like(self._box_slot, np.nan)])
            slot = self._used
            self._used += 1
        self._pos[slot] = node.position * self._scale
        self._slot_id[slot] = node.id
        self._gate_slot[slot] = 0.0
        self._box_slot[slot] = np.nan if node.footprint is None or not self._boxes else node.footprint
        self._slot_of[node.id] = slot
        self.nodes[node.id] = node
        kx, ky = self._key(node.position[0], node.position[1])
        self._cells.setdefault((kx, ky), []).append(slot)
        self._cat_cells.setdefault((node.category, kx, ky), []).append(slot)
        self._cat_slots.setdefault(node.category, set()).add(slot)

    def _delete(self, node: Node) -> None:
        slot = self._slot_of.pop(node.id)
        self._unlink(node.category, slot, self._key(node.position[0], node.position[1]))
        self._cat_slots[node.category].discard(slot)
        self._slot_id[slot] = -1
        self._free.append(slot)
        del self.nodes[node.id]

    def _unlink(self, category: str, slot: int, key: tuple[int, int]) -> None:
        for table, k in ((self._cells, key), (self._cat_cells, (category, *key))):
            members = table[k]
            members.remove(slot)
            if not members:
                del table[k]

    def _relocate(self, node: Node, position: np.ndarray) -> None:
        slot = self._slot_of[node.id]
        old = self._key(node.position[0], node.position[1])
        new = self._key(position[0], position[1])
        if old != new:
            self._unlink(node.category, slot, old)
            self._cells.setdefault(new, []).append(slot)
            self._cat_cells.setdefault((node.category, *new), []).append(slot)
        node.position = np.asarray(position, dtype=float)
        self._pos[slot] = node.position * self._scale

    def _cat_candidates(self, category: str, p: np.ndarray, radius: float) -> np.ndarray:
        r = max(1, math.ceil(radius / self._cell))
        kx, ky = self._key(p[0], p[1])
        if (2 * r + 1) ** 2 > len(self._cat_slots.get(category, ())):
            return np.fromiter(self._cat_slots.get(category, ()), dtype=np.int64)
        out: list[int] = []
        cells = self._cat_cells
        for ix in range(kx - r, kx + r + 1):
            for iy in range(ky - r, ky + r + 1):
                members = cells.get((category, ix, iy))
                if members:
                    out.extend(members)
        return np.array(out, dtype=np.int64)

    def _within_many(self, queries: Sequence[Observation]) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per observation: ids and squared distances of same-category nodes within its delta.

        Candidates of all observations are gathered from the grid first and measured in one
        numpy pass, which is what keeps a 20-observation frame well under a millisecond.
        """
        empty = (np.zeros(0, np.int64), np.zeros(0))
        counts: list[int] = []
        gathered: list[np.ndarray] = []
        for o in queries:
            reach = self.params.extent_gate * self.threshold(o.category) if self._node_gates else self.gate(o)
            if self._boxes and o.box is not None:
                reach = max(reach, _half_diagonal(o.box))
            slots = self._cat_candidates(o.category, o.position * self._scale, max(reach, self.gate(o)))
            counts.append(len(slots))
            gathered.append(slots)
        if not queries or sum(counts) == 0:
            return [empty] * len(queries)
        slots = np.concatenate(gathered)
        owner = np.repeat(np.arange(len(queries)), counts)
        qpos = np.array([o.position for o in queries]) * self._scale
        radius = np.array([self.gate(o) for o in queries])[owner]
        if self._node_gates:  # a big object's node carries its own, wider gate (robust mode)
            radius = np.maximum(radius, self._gate_slot[slots])
        d = self._pos[slots] - qpos[owner]
        d2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
        keep = d2 <= radius * radius
        if self._boxes:  # or the view lies on floor the node's object has covered (robust mode)
            boxes = np.array([np.full(4, np.nan) if o.box is None else o.box for o in queries])[owner]
            keep |= _overlapping(self._box_slot[slots], boxes, self.params.footprint_overlap)
        bounds = np.concatenate([[0], np.cumsum(counts)])
        out = []
        for j in range(len(queries)):
            k = keep[bounds[j]:bounds[j + 1]]
            out.append((self._slot_id[slots[bounds[j]:bounds[j + 1]][k]], d2[bounds[j]:bounds[j + 1]][k]))
        return out

    def _within(self, category: str, p: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Ids and squared distances of ``category`` nodes with distance <= radius."""
        slots = self._cat_candidates(category, p, radius)
        if len(slots) == 0:
            return np.zeros(0, np.int64), np.zeros(0)
        d2 = _dist2(self._pos[slots], p)
        keep = d2 <= radius * radius
        return self._slot_id[slots[keep]], d2[keep]

    def _ring_search(self, category: str, p: np.ndarray, n_members: int) -> np.ndarray:
        """Candidate slots that surely contain the nearest ``category`` node to ``p``."""
        kx, ky = self._key(p[0], p[1])
        found: list[int] = []
        r = 0
        while (2 * r + 1) ** 2 <= 4 * n_members:
            for ix in range(kx - r, kx + r + 1):
                for iy in range(ky - r, ky + r + 1):
                    if max(abs(ix - kx), abs(iy - ky)) == r:
                        found.extend(self._cat_cells.get((category, ix, iy), ()))
            if found:
                # a node in ring r is within (r + 1) * sqrt(2) cells; one more sweep to that radius is exact
                reach = math.ceil((r + 1) * math.sqrt(2))
                return self._cat_candidates(category, p, reach * self._cell)
            r += 1
        return np.fromiter(self._cat_slots[category], dtype=np.int64)

    def _slots_in_box(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        x0, y0 = self._key(lo[0], lo[1])
        x1, y1 = self._key(hi[0], hi[1])
        out: list[int] = []
        if (x1 - x0 + 1) * (y1 - y0 + 1) > len(self._cells):
            for (ix, iy), members in self._cells.items():
                if x0 <= ix <= x1 and y0 <= iy <= y1:
                    out.extend(members)
        else:
            for ix in range(x0, x1 + 1):
                for iy in range(y0, y1 + 1):
                    members = self._cells.get((ix, iy))
                    if members:
                        out.extend(members)
        return np.array(out, dtype=np.int64)


def _box_or_none(box) -> np.ndarray | None:
    if box is None:
        return None
    b = np.asarray(box, dtype=float).reshape(4)
    return b if np.isfinite(b).all() and b[2] >= b[0] and b[3] >= b[1] else None


def _union(a: np.ndarray | None, b: np.ndarray | None) -> np.ndarray | None:
    if a is None or b is None:
        return b if a is None else a
    return np.array([min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])])


# m: how far a view's box may stick out of a footprint and still be the same floor (depth
# noise at box_range, and the points being samples of a surface rather than its outline)
_NOISE_PAD = 0.1


def _inside(box: np.ndarray, outer: np.ndarray, pad: float) -> bool:
    return bool(box[0] >= outer[0] - pad and box[1] >= outer[1] - pad
                and box[2] <= outer[2] + pad and box[3] <= outer[3] + pad)


def _box_gap(a: np.ndarray, b: np.ndarray) -> float:
    """Distance between two boxes (0 when they overlap)."""
    dx = max(0.0, a[0] - b[2], b[0] - a[2])
    dy = max(0.0, a[1] - b[3], b[1] - a[3])
    return math.hypot(dx, dy)


def _half_diagonal(box: np.ndarray) -> float:
    return 0.5 * math.hypot(box[2] - box[0], box[3] - box[1])


def _overlapping(boxes: np.ndarray, box: np.ndarray, fraction: float) -> np.ndarray:
    """Which of ``boxes`` (K, 4) share at least ``fraction`` of the smaller box's area with
    ``box`` ((4,) or (K, 4)); NaN boxes never do. Degenerate (zero-area) boxes count by
    their larger side, so a thin sliver still overlaps what it lies on."""
    b = np.broadcast_to(box, boxes.shape)
    w = np.minimum(boxes[:, 2], b[:, 2]) - np.maximum(boxes[:, 0], b[:, 0])
    h = np.minimum(boxes[:, 3], b[:, 3]) - np.maximum(boxes[:, 1], b[:, 1])
    pad = 0.05  # m: points are samples of a surface, not its outline
    with np.errstate(invalid="ignore"):
        inter = np.clip(w + pad, 0.0, None) * np.clip(h + pad, 0.0, None)
        area_a = (boxes[:, 2] - boxes[:, 0] + pad) * (boxes[:, 3] - boxes[:, 1] + pad)
        area_b = (b[:, 2] - b[:, 0] + pad) * (b[:, 3] - b[:, 1] + pad)
        return (w > -pad) & (h > -pad) & (inter >= fraction * np.minimum(area_a, area_b))


def _dist2(points: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Squared distances, written out so the linear-scan reference computes bit-identical values."""
    d = points - p
    return d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]


def _dist2_scalar(a: np.ndarray, b: np.ndarray) -> float:
    dx, dy, dz = float(a[0] - b[0]), float(a[1] - b[1]), float(a[2] - b[2])
    return dx * dx + dy * dy + dz * dz


def associate_linear_scan(
    graph: ObjectGraph, observations: list[Observation], expected: list[int], session: int, stamp: float
) -> list[Event]:
    """Algorithm 2 (paper mode) by plain linear scans over every node: the reference.

    No index is consulted: each expected node scans all observations and each unmatched
    observation scans all present nodes, as in the paper. The graph is mutated through the
    same primitives as :meth:`ObjectGraph.associate`, so both leave identical graphs.
    """
    graph._begin(session)
    exp = [i for i in dict.fromkeys(expected) if i in graph.nodes]
    events: list[Event] = []
    unmatched = [True] * len(observations)
    for vid in exp:
        v = graph.nodes[vid]
        delta = graph.threshold(v.category)
        delta2 = delta * delta
        hits = [
            j for j, o in enumerate(observations)
            if o.category == v.category and _dist2_scalar(o.position, v.position) <= delta2
        ]
        if not hits:
            events.append(graph._remove(v, session, stamp))
            continue
        for j in hits:
            unmatched[j] = False
        graph._touch(v, session, stamp)
    for j, o in enumerate(observations):
        if not unmatched[j]:
            continue
        d_min2 = math.inf
        for v in graph.nodes.values():
            if v.category == o.category:
                d_min2 = min(d_min2, _dist2_scalar(o.position, v.position))
        delta = graph.threshold(o.category)
        if d_min2 > delta * delta:
            events.append(graph._add(o, session, stamp))
    return events


def nodes_in_polygon_linear(
    graph: ObjectGraph, polygon: np.ndarray, z_range: tuple[float, float] | None = None
) -> list[Node]:
    """The FoV query by a scan over every node (reference for tests and the benchmark)."""
    poly = _check_polygon(polygon)
    nodes = sorted(graph.nodes.values(), key=lambda n: n.id)
    if not nodes:
        return []
    pos = np.array([n.position for n in nodes])
    mask = points_in_polygon(pos[:, :2], poly)
    if z_range is not None:
        mask &= (pos[:, 2] >= z_range[0]) & (pos[:, 2] <= z_range[1])
    return [n for n, m in zip(nodes, mask, strict=True) if m]
