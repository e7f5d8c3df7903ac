"""How big a node's object has shown itself, and which views that makes the same object.

Robust association remembers two things about each node's size: its own gate (the widest
spread of its points, see :meth:`NodeExtents.grow`) and its footprint, the union of the
floor-plane boxes its views covered. Both let a partial view of a big object (a table
seen end-on, or past the chairs in front of it) join the node instead of starting a
duplicate. The box arithmetic lives in :mod:`bomc_bt.graph.footprints`; this module
applies it to the graph, through its public API.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.footprints import NOISE_PAD, box_gap, half_diagonal, inside, overlapping, union
from bomc_bt.graph.records import AssociationParams, Node, Observation

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph


class NodeExtents:
    """The size-aware parts of robust association: node gates and footprints."""

    def __init__(self, params: AssociationParams):
        self.params = params
        self.boxes = params.footprint_overlap > 0.0  # footprints take part in association

    def reach(self, o: Observation) -> float:
        """How far from ``o`` a node whose size makes it the same object may lie."""
        reach = self.params.extent_gate * self.params.distance(o.category)
        if self.boxes and o.box is not None:
            reach = max(reach, half_diagonal(o.box))
        return reach

    def is_big(self, v: Node) -> bool:
        """Whether the node's footprint is longer than delta_c on a side: a table, not a cup."""
        fp = v.footprint
        return self.boxes and fp is not None and max(fp[2] - fp[0], fp[3] - fp[1]) > self.params.distance(v.category)

    def grow(self, graph: ObjectGraph, v: Node, o: Observation, gate: float, restart: bool = False) -> None:
        """Remember how big this node's object has shown itself: its widest spread (the
        ``gate`` that ``o`` earns) and the floor area its points covered (the footprint,
        union of boxes).

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
        graph.widen_gate(v, gate)
        if self.boxes and o.box is not None:
            if restart and v.footprint is not None and inside(o.box, v.footprint, NOISE_PAD):
                restart = False
            graph.set_footprint(v, o.box.copy() if restart else union(v.footprint, o.box))

    def touched_node(self, graph: ObjectGraph, o: Observation) -> Node | None:
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
        if not self.boxes or o.box is None:
            return None
        touch = self.params.footprint_touch
        grown = o.box + np.array([-touch, -touch, touch, touch])
        reach = max(self.params.extent_gate * self.params.distance(o.category), half_diagonal(grown))
        ids, boxes = graph.index.boxes_near(o.category, o.position, reach)
        if len(ids) == 0:
            return None
        with np.errstate(invalid="ignore"):
            big = np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]) > self.params.distance(o.category)
        hits = np.nonzero(big & overlapping(boxes, grown, 1e-9))[0]
        if len(hits) == 0:
            return None
        gaps = [box_gap(boxes[k], o.box) for k in hits]
        best = min(range(len(hits)), key=lambda i: (gaps[i], int(ids[hits[i]])))
        return graph.nodes[int(ids[hits[best]])]

    def overlapped(self, graph: ObjectGraph, o: Observation) -> list[int]:
        """Ids of same-category nodes whose footprint shares ``footprint_overlap`` of the
        smaller of the two boxes with the observation's box."""
        if not self.boxes or o.box is None:
            return []
        reach = max(self.params.extent_gate * self.params.distance(o.category), half_diagonal(o.box))
        ids, boxes = graph.index.boxes_near(o.category, o.position, reach)
        if len(ids) == 0:
            return []
        hit = overlapping(boxes, o.box, self.params.footprint_overlap)
        return sorted(int(i) for i in ids[hit])
