"""The object graph: the present nodes by id, their spatial index, and the change log.

:class:`ObjectGraph` is the only code that changes nodes. Its public mutation API (add,
remove, restore, relocate, touch, miss, set_confidence, add_observations, set_footprint,
widen_gate, report) keeps the spatial index in step with the nodes and records every
changed node for the site store (:meth:`ObjectGraph.drain_changed`). How a frame's
observations change the graph is the business of the association policy chosen once from
:attr:`AssociationParams.mode` (:mod:`bomc_bt.graph.paper`, :mod:`bomc_bt.graph.robust`),
which works through this API only.

Ids continue from ``max id + 1`` as in the paper and are never reused, also not the ids of
removed nodes (the store passes the next id; ids are what the history is keyed on).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from bomc_bt.graph.association import AssociationPolicy
from bomc_bt.graph.evidence import MissEvidence
from bomc_bt.graph.geometry import check_polygon
from bomc_bt.graph.operator_edits import OperatorEdits
from bomc_bt.graph.paper import PaperPolicy
from bomc_bt.graph.records import PRESENT, REMOVED, AssociationParams, Event, Node, Observation
from bomc_bt.graph.refinement import ends_of_one, refinements
from bomc_bt.graph.robust import RobustPolicy
from bomc_bt.graph.spatial import SpatialIndex
from bomc_bt.graph.tentative import Sighting
from bomc_bt.graph.view_sides import SideRates
from bomc_bt.json_text import JSONMemo, keyed


def make_policy(params: AssociationParams) -> AssociationPolicy:
    """The association policy that ``params.mode`` names."""
    return PaperPolicy(params) if params.mode == "paper" else RobustPolicy(params)


class ObjectGraph:
    """The live object graph (present nodes) with a spatial index, a change log and a policy."""

    def __init__(self, params: AssociationParams, nodes: Iterable[Node] = (), next_id: int | None = None,
                 edits: OperatorEdits | None = None):
        self.params = params
        self.edits = edits or OperatorEdits()  # the operator's corrections this graph respects
        self.policy = make_policy(params)
        self.nodes: dict[int, Node] = {}
        self.index = SpatialIndex(params.largest_distance(), np.array([1.0, 1.0, self.policy.vertical_weight]))
        self._pending: set[int] = set()  # present nodes with misses > 0
        self._last_miss: dict[int, tuple[int, float]] = {}  # id -> (session, stamp) of last counted miss
        self._removed_now: dict[int, Node] = {}  # removed in the current session (move candidates)
        # node id: (footprint, position) before the current session first changed it (graph.refinement)
        self.started: dict[int, tuple[np.ndarray | None, np.ndarray]] = {}
        self._session: int | None = None
        self._changed: dict[int, Node] = {}
        self._reported: dict[int, np.ndarray] = {}  # position at the last event of a node
        sides = params.miss_sides if params.mode == "robust" else 0  # robust: per viewing side (graph.view_sides)
        self.evidence = MissEvidence(SideRates(sides, params.side_memory) if sides else None)
        # position -> whether no earlier pass looked there (bomc_bt.first_seen): an object found there beyond
        # a node's gate was most likely always there, so the robust policy takes it for no removed object's
        # new place. None: nothing known.
        self.never_looked: Callable[[np.ndarray], bool] | None = None
        # (category, position) -> whether the previous pass detected an object of that category
        # there (bomc_bt.sightings): an object found there had stood there, missed, and is no
        # removed object's new place either. None: nothing known.
        self.sighted_before: Callable[[str, np.ndarray], bool] | None = None
        max_id = -1
        for node in nodes:
            max_id = max(max_id, node.id)
            if node.state == PRESENT:
                self.insert(node)
        self.next_id = max(max_id + 1, next_id if next_id is not None else 0)

    # ------------------------------------------------------------------ queries
    def threshold(self, category: str) -> float:
        """delta_c: the association distance of ``category``."""
        return self.params.distance(category)

    def gate(self, o: Observation) -> float:
        """How far a node may be from ``o`` and still be the same object (see the policy)."""
        return self.policy.gate(o)

    def __len__(self) -> int:
        return len(self.nodes)

    def nodes_in_polygon(self, polygon: np.ndarray, z_range: tuple[float, float] | None = None) -> list[Node]:
        """Present nodes whose xy lies inside ``polygon`` (K, 2) (and z inside ``z_range``), by id."""
        ids = self.index.ids_in_polygon(check_polygon(polygon))
        if z_range is not None and len(ids):
            z = np.array([self.nodes[int(i)].position[2] for i in ids])
            ids = ids[(z >= z_range[0]) & (z <= z_range[1])]
        return [self.nodes[int(i)] for i in np.sort(ids)]

    def nearest(
        self, category: str, position: np.ndarray, max_distance: float | None = None
    ) -> tuple[Node | None, float]:
        """Closest present node of ``category`` (and its distance), or (None, inf)."""
        node_id, dist = self.index.nearest(category, position, max_distance)
        return (None, dist) if node_id < 0 else (self.nodes[node_id], dist)

    def within(self, category: str, position: np.ndarray, radius: float) -> list[tuple[Node, float]]:
        """Present nodes of ``category`` within ``radius`` of ``position``, nearest first."""
        ids, d2 = self.index.within(category, position, radius)
        return [(self.nodes[int(i)], math.sqrt(float(d))) for i, d in zip(ids, d2, strict=True)]

    def pending(self) -> list[int]:
        """Ids of present nodes awaiting confirmation of their removal (robust mode)."""
        return sorted(self._pending)

    def unresolved(self, session: int) -> list[Node]:
        """Present nodes pass ``session`` has neither confirmed nor removed: not matched in it,
        missed since their last match by a near, clear view (a run of misses weighing 1 or more,
        :mod:`.evidence`), or (robust) added in it and matched in at most ``retract_observations``
        frames: two false detections at one place 4.5 s apart made such a node, never looked at
        again in that pass (issue 17). A clear look decides: confirmed, or removed (retracted)."""
        barely = self.params.retract_observations if isinstance(self.policy, RobustPolicy) else 0
        return [v for v in self.nodes.values() if v.state == PRESENT and (
            v.last_session != session or self.missed_up_close(v.id)
            or (v.first_session == session and v.observations <= barely))]

    def unconfirmed_sightings(self, looked_within: float | None = None) -> list[Sighting]:
        """First sightings of the current session never confirmed (robust mode) with no present
        node of their kind within delta_c: an object caught once, or a false positive. A look
        decides (:mod:`bomc_bt.refresh`); ``looked_within``: see ``TentativeSightings.unconfirmed``."""
        tentative = getattr(self.policy, "tentative", None)
        if tentative is None:
            return []
        return [t for t in tentative.unconfirmed(looked_within)
                if not self.within(t.category, t.position, self.params.distance(t.category))]

    def mark_sightings_looked(self, sightings: Sequence[Sighting], place: Sequence[float] | None = None) -> None:
        """A head turn faces ``sightings`` now, from ``place`` (x, y; None: up close)."""
        tentative = getattr(self.policy, "tentative", None)
        if tentative is not None:
            tentative.mark_looked(sightings, place)

    def missed_up_close(self, node_id: int) -> bool:
        """Its run of misses since the last detection weighs one full miss or more: at least
        one near, clear view saw its place empty (:mod:`.evidence`)."""
        return self.evidence.run(node_id) >= 1.0

    def awaiting_second_look(self) -> list[tuple[Node, tuple[float, float]]]:
        """Present nodes whose run of misses is long enough to remove them but was seen from
        one place only (``miss_spacing``), each with that place: a look from elsewhere decides."""
        needed = getattr(self.policy, "misses_needed", None)
        if needed is None or self.params.miss_spacing <= 0:
            return []
        waiting = []
        for v in self.nodes.values():
            place = self.evidence.run_place(v.id)
            if v.state == PRESENT and place is not None and self.evidence.run(v.id) >= needed(self, v) - 1e-9 \
                    and not self.evidence.apart(v.id, self.params.miss_spacing):
                waiting.append((v, place))
        return waiting

    def removed_this_session(self) -> list[Node]:
        """Nodes removed in the current session that may yet turn out to have moved."""
        return list(self._removed_now.values())

    def drift_since_report(self, v: Node) -> float:
        """How far ``v`` moved since its last event (inf: it never had one in this process)."""
        reported = self._reported.get(v.id)
        return math.inf if reported is None else float(np.linalg.norm(v.position - reported))

    def drain_changed(self) -> list[Node]:
        """Nodes changed (incl. removed ones) since the last call, by id: what the store persists."""
        changed = [self._changed[i] for i in sorted(self._changed)]
        self._changed.clear()
        return changed

    # -------------------------------------------------------------- association
    def associate(
        self, observations: list[Observation], expected: list[int], session: int, stamp: float,
        in_view: list[int] | None = None, miss_weights: Sequence[float] | None = None,
        place: np.ndarray | None = None,
    ) -> list[Event]:
        """Update the graph with one frame (Algorithm 2 or its robust extension); returns the events in order.

        ``expected``: nodes in the field of view that the frame can confirm or deny.
        ``in_view`` (robust mode): all nodes inside the field-of-view polygon, hidden ones
        included; only these may be folded into an observed node as hidden duplicates.
        Nodes in neither list are never touched. ``miss_weights`` (robust mode): per
        expected node, how much a miss of it in this frame weighs (1: a clear, near view).
        ``place`` (robust mode): the robot's (x, y) on the map (base_link), where the frame's
        misses were seen from; turning on the spot swings the camera, not the place.
        """
        if self.edits:  # the operator's corrections (bomc_bt.graph.operator_edits)
            observations = self.edits.relabel(observations, self.nodes, self.index.scale, self.gate)
            observations = self.edits.ignore_deleted(observations, self, self.params.readd_confidence)
        return self.policy.associate(self, observations, expected, session, stamp, in_view, miss_weights, place)

    def take_back_moves(self, session: int, stamp: float, history: Sequence[Event]) -> list[Event]:
        """When ``session`` ends: its moves that a node added later at the old place undoes
        are taken back (:mod:`bomc_bt.graph.returns`; ``history``: the session's events so
        far). The paper's policy moves nothing, so takes nothing back."""
        take_back = getattr(self.policy, "take_back_moves", None)
        return [] if take_back is None else take_back(self, session, stamp, history)

    def pair_relocations(self, session: int, stamp: float, candidate: Callable[[Node], bool] = lambda n: True,
                         gone: Sequence[Node] = ()) -> list[Event]:
        """When ``session`` ends: its removals and additions that were one object moved
        become moves (:mod:`bomc_bt.graph.relocations`; ``candidate`` says which added nodes
        may be such an arrival, ``gone`` where earlier passes saw objects go: one back there is
        none). The paper's policy pairs nothing."""
        pair = getattr(self.policy, "pair_relocations", None)
        return [] if pair is None else pair(self, session, stamp, candidate, gone)

    def mark_refinements(self, session: int, stamp: float) -> list[Event]:
        """When ``session`` ends, after its relocations are paired: an ``updated`` event marked
        refined for each older node whose shift was a better view of the floor it stood on
        (:mod:`bomc_bt.graph.refinement`). The paper's policy keeps no footprints: none."""
        if self.params.mode == "paper":
            return []
        return refinements(self, self.started, session, stamp, self.threshold, self.policy.extents.shown_on_start(self),
                           ends_of_one(self, session))

    def begin(self, session: int, expected: Sequence[int]) -> list[int]:
        """Start a frame of ``session``; returns ``expected`` without repeats and absent ids.

        A new session forgets the previous session's removals (they can no longer be moves).
        """
        if session != self._session:
            self._removed_now.clear()
            self.started.clear()
            self._session = session
        return [i for i in dict.fromkeys(expected) if i in self.nodes]

    # ------------------------------------------------------------ resume state
    def pass_state(self, memo: JSONMemo | None = None) -> dict:
        """What the graph keeps in memory during a pass besides the nodes the store holds:
        when each node was last seen, counted misses, this session's removals (move
        candidates), reported positions, widened gates, which footprints hold only partial
        views (and their longest view), first sightings awaiting confirmation and where each node
        stood before the pass changed it (refinements). JSON-able (``memo``: maps as text, for
        :func:`~bomc_bt.json_text.dumps_raw`); saved with every frame (:mod:`bomc_bt.pass_resume`)."""
        tentative, extents = getattr(self.policy, "tentative", None), getattr(self.policy, "extents", None)
        co_observed = getattr(self.policy, "co_observed", None)
        return {
            "session": self._session,
            "last_seen": keyed(memo, "last_seen", ((i, n.last_seen) for i, n in self.nodes.items()
                                                   if n.last_seen is not None)),
            "last_miss": {str(i): list(v) for i, v in self._last_miss.items()},
            "removed_now": sorted(self._removed_now),
            "reported": keyed(memo, "reported", self._reported.items(), np.ndarray.tolist),
            "gates": keyed(memo, "gates", ((i, g) for i in self.nodes if (g := self.index.gate_of(i)) > 0.0)),
            "tentative": None if tentative is None else tentative.to_json(memo),
            "extents": None if extents is None else extents.to_json(memo),
            "co_observed": None if co_observed is None else co_observed.to_json(),
            "sides": None if self.evidence.sides is None else self.evidence.sides.to_json(memo),
            "second_looks": self.evidence.looks_json(v.id for v, _ in self.awaiting_second_look()),
            "started": keyed(memo, "started", self.started.items(),
                             lambda s: [None if s[0] is None else s[0].tolist(), s[1].tolist()]),
        }

    def keep_apart(self, session: int, pairs: list[tuple[int, int]]) -> None:
        """Start ``session`` knowing the node ``pairs`` earlier passes saw as two objects in one frame (robust
        association never folds them; :mod:`bomc_bt.graph.co_observed`); pairs with a node gone are dropped."""
        co_observed = getattr(self.policy, "co_observed", None)
        if co_observed is not None:
            co_observed.carry(session, [(a, b) for a, b in pairs if a in self.nodes and b in self.nodes])

    def restore_pass_state(self, state: dict, removed: dict[int, Node]) -> None:
        """Put back what :meth:`pass_state` saved; ``removed`` are the store's removed nodes by id."""
        self._session = state.get("session")
        for key, seen in state.get("last_seen", {}).items():
            if int(key) in self.nodes:
                self.nodes[int(key)].last_seen = float(seen)
        self._last_miss = {int(k): (int(v[0]), float(v[1])) for k, v in state.get("last_miss", {}).items()}
        self.evidence.looked_before = set(map(int, (state.get("second_looks") or {}).get("before", [])))
        self._removed_now = {i: removed[i] for i in map(int, state.get("removed_now", [])) if i in removed}
        self._reported = {int(k): np.asarray(v, dtype=float) for k, v in state.get("reported", {}).items()}
        self.started = {int(k): (None if fp is None else np.asarray(fp, dtype=float), np.asarray(p, dtype=float))
                        for k, (fp, p) in state.get("started", {}).items()}
        for key, gate in state.get("gates", {}).items():
            self.index.widen_gate(int(key), float(gate))
        parts = {key: getattr(self.policy, key, None) for key in ("tentative", "extents", "co_observed")}
        for key, part in (parts | {"sides": self.evidence.sides}).items():
            if part is not None and state.get(key) is not None:
                part.restore(state[key])

    # ---------------------------------------------------------------- mutations
    def insert(self, node: Node) -> None:
        """Put an existing present node (loaded from the store) into the graph."""
        if node.id in self.nodes:
            raise ValueError(f"duplicate node id {node.id}")
        self._index(node)
        if node.misses > 0:
            self._pending.add(node.id)

    def add(self, o: Observation, session: int, stamp: float) -> Event:
        """A new node, with the next id, where ``o`` was seen."""
        node = Node(self.next_id, o.category, o.position.copy(), float(o.confidence), session, session,
                    last_seen=stamp, colour=o.colour)
        self.next_id += 1
        self._index(node)
        self._changed[node.id] = node
        return self.report("added", node, session, stamp)

    def remove(self, v: Node, session: int, stamp: float, merged: bool = False,
               merged_into: int | None = None, retracted: bool = False) -> Event:
        """Take ``v`` off the graph. Unless it was ``merged`` into another node (the node
        ``merged_into``, when known), it may come back in this session as a move
        (:meth:`restore`), and a move it is, never a refinement (no start footprint: gone from
        its floor). The event carries the evidence: the misses that confirmed the
        removal (0 for a merge) and when the node was last seen."""
        merged = merged or merged_into is not None
        self.index.delete(v.id, v.category, v.position)
        del self.nodes[v.id]
        v.state = REMOVED
        if not merged:
            self._removed_now[v.id], self.started[v.id] = v, (None, v.position.copy())
        self._pending.discard(v.id)
        self._last_miss.pop(v.id, None)
        self.evidence.forget(v.id)
        self._changed[v.id] = v
        event = self.report("removed", v, session, stamp)
        # a removal is decided on at least the frame that did not see it (Algorithm 2 counts no misses)
        event.removal_evidence(0 if merged else max(int(v.misses), 1), merged, v.last_seen, merged_into,
                               int(v.observations), retracted and not merged)
        return event

    def restore(self, v: Node, position: np.ndarray) -> None:
        """Bring back at ``position`` a node removed in this session: it had moved."""
        self._keep_start(v)
        del self._removed_now[v.id]
        v.state = PRESENT
        v.position = position
        self._index(v)

    def relocate(self, v: Node, position: np.ndarray) -> None:
        """Move ``v`` to ``position``."""
        position = np.asarray(position, dtype=float)
        self._keep_start(v)
        self.index.move(v.id, v.category, v.position, position)
        v.position = position
        self._changed[v.id] = v

    def touch(self, v: Node, session: int, stamp: float, reset_misses: bool = True) -> None:
        """Bookkeeping of a node an observation just confirmed: seen in ``session`` at
        ``stamp`` once more and, with ``reset_misses``, no longer pending removal."""
        v.last_session = session
        v.last_seen = stamp
        v.observations += 1
        if reset_misses:
            if v.misses:
                self.evidence.forget(v.id, refuted=True)
            v.misses = 0
            self._pending.discard(v.id)
            self._last_miss.pop(v.id, None)
        self._changed[v.id] = v

    def miss(self, v: Node, session: int, stamp: float, interval: float) -> bool:
        """Count one miss of an expected node that was not seen, unless one was counted less
        than ``interval`` seconds ago in this session; returns whether it counted."""
        last = self._last_miss.get(v.id)
        if last is not None and last[0] == session and stamp - last[1] < interval:
            return False
        v.misses += 1
        self._last_miss[v.id] = (session, stamp)
        self._pending.add(v.id)
        self._changed[v.id] = v
        return True

    def set_confidence(self, v: Node, confidence: float) -> None:
        """Replace ``v``'s confidence."""
        v.confidence = confidence
        self._changed[v.id] = v

    def add_observations(self, v: Node, count: int) -> None:
        """Credit ``v`` with ``count`` more observations (those of a node merged into it)."""
        v.observations += count
        self._changed[v.id] = v

    def set_footprint(self, v: Node, box: np.ndarray | None) -> None:
        """Replace ``v``'s footprint (None: unknown)."""
        self._keep_start(v)
        v.footprint = box
        self.index.set_box(v.id, box)
        self._changed[v.id] = v

    def _keep_start(self, v: Node) -> None:
        """Remember an older ``v``'s footprint and position as the session found them (before
        its first change); a node this session added is an addition wherever it ends."""
        if v.id not in self.started and v.first_session != self._session:
            self.started[v.id] = (None if v.footprint is None else v.footprint.copy(), v.position.copy())

    def widen_gate(self, v: Node, gate: float) -> None:
        """Let ``v``'s own association gate grow to ``gate``: its object showed itself that big."""
        self.index.widen_gate(v.id, gate)

    def report(self, kind: str, v: Node, session: int, stamp: float, previous: np.ndarray | None = None) -> Event:
        """The event ``kind`` of ``v`` for the store's history; remembers the position reported."""
        self._reported[v.id] = v.position.copy()
        return Event(kind, v.id, v.category, v.position.copy(), session, float(stamp), previous, v.confidence)

    def _index(self, node: Node) -> None:
        self.index.insert(node.id, node.category, node.position, node.footprint)
        self.nodes[node.id] = node
