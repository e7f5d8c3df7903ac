"""The operator's corrections, as the association of later passes respects them.

An operator corrects the map between passes (``bomc edit``, :mod:`bomc_bt.site.edits`):
the corrections are events in the site's history, and the store hands them to the graph
of the next pass as an :class:`OperatorEdits` (:meth:`OperatorEdits.from_history`). Two
rules follow, applied by :class:`~bomc_bt.graph.object_graph.ObjectGraph` for both
association modes:

* **A relabelled node keeps its label.** The detector goes on calling the object what it
  called it before (a cabinet it takes for a door stays a "door" to it), so a detection of
  the node's *detected* category within the node's association gate is read as the
  operator's category (:meth:`OperatorEdits.relabel`) and confirms the node; without
  this, the node would go unmatched, be removed after its misses, and the detector's label
  come back as a new node.
* **A deleted node is not re-added at the same place** unless a later pass sees it again
  with high confidence. A detection of its category (detected or operator's) that lies
  within the detection's association gate (delta_c, ``association.default_distance`` /
  ``per_category``, widened for big objects as in matching) of where the node was
  deleted, and nearer to that place than to any node of its category, is a sighting of
  the deleted object: it is ignored -- it neither starts a node nor confirms a neighbour
  (a cabinet beside a deleted look-alike would otherwise be dragged onto it) -- unless
  its confidence is at least ``association.readd_confidence`` ([-], detector score; 0.95
  by default). A confident one goes through association as usual (robust mode: it needs
  ``confirm_detections`` such sightings) and, once a node of the category added since
  the deletion stands within delta_c of the place, the place is an ordinary part of the map
  (:meth:`OperatorEdits.ignore_deleted`). Edits take effect from the pass after them, so
  every pass that sees them is a later session.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.records import Event, Node, Observation

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph

Gate = Callable[[Observation], float]


@dataclass(frozen=True)
class DeletedSpot:
    """Where the operator deleted node ``node_id``, and the categories it was known by."""

    node_id: int
    categories: frozenset[str]
    position: np.ndarray
    session: int  # the first pass the deletion holds in


@dataclass
class OperatorEdits:
    """What the association of a pass must respect (empty: nothing was ever edited)."""

    deleted: list[DeletedSpot] = field(default_factory=list)
    detected_as: dict[int, str] = field(default_factory=dict)  # relabelled node id -> the detector's category

    def __bool__(self) -> bool:
        return bool(self.deleted or self.detected_as)

    @classmethod
    def from_history(cls, events: Iterable[Event]) -> OperatorEdits:
        """Replay the history (write order) of the nodes an operator edited.

        A node's detected category is the one it was added with; its deletion holds until
        an operator restores it.
        """
        first: dict[int, str] = {}
        last: dict[int, Event] = {}
        deleted: dict[int, Event] = {}
        for e in events:
            first.setdefault(e.node_id, e.category)
            last[e.node_id] = e
            if e.kind == "deleted":
                deleted[e.node_id] = e
            elif e.kind == "restored":
                deleted.pop(e.node_id, None)
        spots = [DeletedSpot(nid, frozenset({first[nid], e.category}), np.asarray(e.position, dtype=float),
                             e.session) for nid, e in sorted(deleted.items())]
        relabelled = {nid: first[nid] for nid, e in last.items()
                      if nid not in deleted and e.category != first[nid]}
        return cls(spots, relabelled)

    def relabel(self, observations: Sequence[Observation], nodes: dict[int, Node], scale: np.ndarray,
                gate: Gate) -> list[Observation]:
        """``observations`` with the detector's category of a relabelled node read as the
        operator's, for detections within that node's gate (the nearest such node wins)."""
        out = list(observations)
        if not self.detected_as:
            return out
        for j, o in enumerate(out):
            best: tuple[float, int] | None = None
            for nid, detected in self.detected_as.items():
                node = nodes.get(nid)
                if node is None or o.category != detected:
                    continue
                d = float(np.linalg.norm((node.position - o.position) * scale))
                if d <= gate(o) and (best is None or (d, nid) < best):
                    best = (d, nid)
            if best is not None:
                out[j] = dataclasses.replace(o, category=nodes[best[1]].category)
        return out

    def ignore_deleted(self, observations: Sequence[Observation], graph: ObjectGraph,
                       readd_confidence: float) -> list[Observation]:
        """``observations`` less the sightings of deleted objects (the module's rule)."""
        spots = [s for s in self.deleted if not self._back_on_map(s, graph)]
        if not spots:
            return list(observations)
        return [o for o in observations
                if float(o.confidence) >= readd_confidence or not self._sighting_of(o, spots, graph)]

    @staticmethod
    def _back_on_map(spot: DeletedSpot, graph: ObjectGraph) -> bool:
        """A node of the spot's categories added since the deletion stands within delta_c of
        it: the object came back (a neighbour that was there all along does not count)."""
        return any(node.first_session >= spot.session for c in spot.categories
                   for node, _ in graph.within(c, spot.position, graph.threshold(c)))

    @staticmethod
    def _sighting_of(o: Observation, spots: list[DeletedSpot], graph: ObjectGraph) -> bool:
        """``o`` lies within its gate of a deleted spot of its category, nearer to it than
        to any node of its category."""
        scale = graph.index.scale
        gate = graph.gate(o)
        d_spot = min((float(np.linalg.norm((s.position - o.position) * scale)) for s in spots
                      if o.category in s.categories), default=np.inf)
        return d_spot <= gate and d_spot < graph.nearest(o.category, o.position)[1]
