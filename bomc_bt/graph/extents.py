"""How big a node's object has shown itself, and which views that makes the same object.

Robust association remembers two things about each node's size: its own gate (the widest
spread of its points, see :meth:`NodeExtents.grow`) and its footprint, the union of the
floor-plane boxes its views covered. Both let a partial view of a big object (a table
seen end-on, or past the chairs in front of it) join the node instead of starting a
duplicate. The box arithmetic lives in :mod:`bomc_bt.graph.footprints`; this module
applies it to the graph, through its public API.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.footprints import NOISE_PAD, box_gap, half_diagonal, inside, longest_side, overlapping, sides, union
from bomc_bt.graph.parts import FOOTPRINT_RANK, footprint_length
from bomc_bt.graph.pass_views import PassViews
from bomc_bt.graph.records import AssociationParams, Node, Observation
from bomc_bt.json_text import JSONMemo, keyed

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph


# [-] a whole view's side at least this share of its longer side was seen across the line of
# sight, in full (a table seen end-on: 0.8 m across, a few cm deep, its length hidden)
_ACROSS_SHARE = 0.75
# m: a footprint longer than delta_c by this much on a side is a big object's (a table's),
# not a small one seen with noise (a chair's box is about delta_c long when seen corner-on)
BIG_MARGIN = 2.0 * NOISE_PAD


class NodeExtents:
    """The size-aware parts of robust association: node gates and footprints.

    A footprint is the union of views of *one* object, so it never grows longer than the
    longest single view of that object showed (plus the noise pad): two chairs 0.8 m apart
    at a table, each seen alone with its mask bleeding towards the other, once made one
    "chair" footprint 1.5 m long that then counted as big and swallowed every chair around
    the table (Environment A: 31 of 82 chair nodes, chair recall 0.65). With
    ``separate_neighbours``: a small object's view whose box lies clear of the node's
    footprint is another object, however near, once the footprint holds a whole view
    (:meth:`separate`).
    """

    def __init__(self, params: AssociationParams):
        self.params = params
        self.boxes = params.footprint_overlap > 0.0  # footprints take part in association
        self._longest_view: dict[int, float] = {}  # node id: longest side of one view's box
        self._whole_view: dict[int, np.ndarray] = {}  # node id: widest x, y of its whole views' boxes, this pass
        # nodes whose footprint holds only views cut off by an occluder or the image border
        # (a footprint loaded from the store counts as whole: a pass saw most objects whole)
        self._partial: set[int] = set()
        self.views = PassViews()  # the floor each node's views covered this pass

    def reach(self, o: Observation) -> float:
        """How far from ``o`` a node whose size makes it the same object may lie."""
        reach = self.params.extent_gate * self.params.distance(o.category)
        if self.boxes and o.box is not None:
            reach = max(reach, half_diagonal(o.box))
        return reach

    def is_big(self, v: Node) -> bool:
        """Whether the node's footprint is longer than delta_c on a side: a table, not a cup."""
        fp = v.footprint
        return self.boxes and fp is not None and longest_side(fp) > self.params.distance(v.category) + BIG_MARGIN

    def separate(self, graph: ObjectGraph, v: Node, o: Observation) -> bool:
        """Whether ``o`` is plainly not ``v``'s object: ``v`` is small, its footprint holds a
        whole view of its object, and the floor the view covers lies clear of it (farther
        than the noise pad). Any view of an object, whole or cut off, lies on the floor a
        whole view of it covered; one beside it is a neighbour (chairs 0.8 m apart at a
        table, delta_c 0.7 m). A footprint made of views cut off by an occluder or the
        image border may hold only one end of the object, and a view of its other end lies
        clear of it (lab-b's cabinet, seen end by end, was doubled): no separation then,
        unless the objects of its category are known to be small (:meth:`_small_category`)
        and the two boxes together are longer than any whole view of one showed (plus the
        noise margin). A chair begun from cut-off views of one chair at a table took the
        cut-off views of the chair 0.8 m beside it, and its place followed them there while
        its footprint stayed: the first chair was never mapped, and the next pass doubled
        the second (36 x 28 m office, static, seed 6613)."""
        fp = v.footprint
        if not self.boxes or fp is None or o.box is None or not self.params.separate_neighbours or self.is_big(v):
            return False
        if box_gap(fp, o.box) <= NOISE_PAD:
            return False
        return v.id not in self._partial or self._longer_than_whole(graph, v.category, union(fp, o.box))

    def _longer_than_whole(self, graph: ObjectGraph, category: str, box: np.ndarray) -> bool:
        """Whether ``box`` is longer than the whole views of ``category`` this pass show its
        objects to be (plus the noise margin), the category being small (:meth:`_small_category`)."""
        small = self._small_category(graph, category)
        return small and longest_side(box) > max(self._whole_sides(graph, category)) + BIG_MARGIN

    def beside(self, o: Observation, takers: Sequence[Observation]) -> bool:
        """With ``separate_neighbours``: whether ``o`` is another object than each of
        ``takers``, the same frame's views that took the nodes ``o`` lies near. A detector
        names an object once per frame, so two views of one category whose floor boxes do
        not touch are two objects: chairs 0.8 m apart at a table, both seen cut off by it
        (delta_c 0.7 m). Absorbed into its neighbour's node, the second chair was never
        mapped (issue 17: chair-108 of a static Environment-A-size floor, seed 5353)."""
        if not self.boxes or not self.params.separate_neighbours or o.box is None:
            return False
        return all(t.box is not None and box_gap(t.box, o.box) > 0.0 for t in takers)

    def apart(self, v: Node, w: Node, v_footprint: np.ndarray | None) -> bool:
        """With ``separate_neighbours``: whether ``v`` and ``w`` are plainly two objects: both
        small, both footprints hold a whole view, and ``v_footprint`` (``v``'s before the
        current view changed it) lies clear of ``w``'s (farther than the noise pad). A view
        whose mask bled over both (chairs side by side) does not make them one."""
        if not self.boxes or not self.params.separate_neighbours or v_footprint is None:
            return False
        if v.id in self._partial or w.footprint is None or w.id in self._partial or self.is_big(w):
            return False
        return longest_side(v_footprint) <= self.params.distance(v.category) + BIG_MARGIN \
            and box_gap(v_footprint, w.footprint) > NOISE_PAD

    def fold(self, graph: ObjectGraph, keep: Node, drop: Node) -> None:
        """``drop`` is folded into ``keep``: the union of their footprints, whole if either was,
        unless that union is longer than the longest view of either (plus ``BIG_MARGIN``):
        then they were two small objects, and a "chair" two chairs long would count as big
        and swallow its neighbours (a generated office: one footprint 1.6 m long over two
        chairs after a fold); ``keep`` keeps its own."""
        whole = keep.footprint is not None and keep.id not in self._partial
        whole |= drop.footprint is not None and drop.id not in self._partial
        grown = union(keep.footprint, drop.footprint)
        longest = max(self._longest(keep), self._longest(drop))
        if drop.id in self._whole_view:
            self._saw_whole(keep.id, self._whole_view.pop(drop.id))
        if keep.footprint is None or grown is None or longest_side(grown) <= longest + BIG_MARGIN:
            graph.set_footprint(keep, grown)
            self._mark(keep.id, whole)

    def longest_whole(self, graph: ObjectGraph) -> dict[str, float]:
        """Per category: the longest side of a whole view of any of its nodes this pass."""
        out: dict[str, float] = {}
        for node_id, extent in self._whole_view.items():
            v = graph.nodes.get(node_id)
            if v is not None:
                out[v.category] = max(out.get(v.category, 0.0), float(extent.max()))
        return out

    def join(self, graph: ObjectGraph, keep: Node, drop: Node) -> None:
        """``drop`` is the other part of ``keep``'s object (:mod:`bomc_bt.graph.parts`): the
        footprint covers both."""
        whole = keep.id not in self._partial or drop.id not in self._partial
        graph.set_footprint(keep, union(keep.footprint, drop.footprint))
        self._longest_view[keep.id] = max(self._longest(keep), self._longest(drop))
        if drop.id in self._whole_view:
            self._saw_whole(keep.id, self._whole_view.pop(drop.id))
        self._mark(keep.id, whole)

    def _longest(self, v: Node) -> float:
        """The longest single view of ``v`` (its footprint's side when loaded from the store)."""
        return self._longest_view.get(v.id, longest_side(v.footprint) if v.footprint is not None else 0.0)

    def adopt(self, graph: ObjectGraph, v: Node, arrival: Node) -> None:
        """``v`` moved to where ``arrival`` stands: it takes the arrival's footprint."""
        graph.set_footprint(v, arrival.footprint)
        self._longest_view.pop(v.id, None)
        self._whole_view.pop(v.id, None)
        if arrival.id in self._whole_view:
            self._whole_view[v.id] = self._whole_view[arrival.id].copy()
        self._mark(v.id, arrival.id not in self._partial)

    def swap(self, graph: ObjectGraph, a: Node, b: Node) -> None:
        """``a`` and ``b`` exchange places (a move taken back): each takes the other's footprint."""
        box_a, box_b = a.footprint, b.footprint
        graph.set_footprint(a, box_b)
        graph.set_footprint(b, box_a)
        for table in (self._longest_view, self._whole_view):
            va, vb = table.pop(a.id, None), table.pop(b.id, None)
            if vb is not None:
                table[a.id] = vb
            if va is not None:
                table[b.id] = va
        partial_a, partial_b = a.id in self._partial, b.id in self._partial
        self._mark(a.id, not partial_b)
        self._mark(b.id, not partial_a)

    def restart(self, graph: ObjectGraph, v: Node, o: Observation) -> None:
        """``v`` moved to where ``o`` saw it: its footprint starts over from the view."""
        graph.set_footprint(v, o.box)
        self._longest_view.pop(v.id, None)
        self._whole_view.pop(v.id, None)
        if o.box is not None and not o.truncated:
            self._saw_whole(v.id, sides(o.box))
        self._mark(v.id, not o.truncated)

    def to_json(self, memo: JSONMemo | None = None) -> dict:
        """What a resumed pass needs: longest views, longest whole views, partial footprints,
        the floor views of this pass covered (:class:`~bomc_bt.graph.pass_views.PassViews`; JSON-able)."""
        return {"longest": keyed(memo, "extents.longest", self._longest_view.items()), "partial": sorted(self._partial),
                "whole": keyed(memo, "extents.whole", self._whole_view.items(), np.ndarray.tolist),
                **self.views.to_json(memo)}

    def restore(self, data: dict) -> None:
        """Put back what :meth:`to_json` saved."""
        self._longest_view = {int(k): float(x) for k, x in data.get("longest", {}).items()}
        self._partial = {int(i) for i in data.get("partial", [])}
        self._whole_view = {int(k): np.array(x, dtype=float) for k, x in data.get("whole", {}).items()}
        self.views.restore(data)

    def _saw_whole(self, node_id: int, sides: np.ndarray) -> None:
        seen = self._whole_view.get(node_id)
        self._whole_view[node_id] = sides.copy() if seen is None else np.maximum(seen, sides)

    def _mark(self, node_id: int, whole: bool) -> None:
        if whole:
            self._partial.discard(node_id)
        else:
            self._partial.add(node_id)

    def grow(self, graph: ObjectGraph, v: Node, o: Observation, gate: float, restart: bool = False,
             extend: bool = False) -> None:
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
        duplicate again: office-s perfect session 3, 0.984 -> 0.977.) A union longer than the
        longest single view (plus ``BIG_MARGIN``) is two objects, and is not made, unless
        ``extend``: a truncated view of a big node's hidden end (:meth:`touched_node`). But
        when the footprint holds only views cut off by an occluder or the image border and
        this whole view lies beyond them, the footprint starts over from the view: the node's
        position follows its views, and a footprint left at a neighbour's place made the next
        pass take this object's views for another (a chair first caught at the image edge
        over its neighbour, then seen whole: issue 17, Environment-A-size floor, seed 9911),
        unless the cut-off views lie along the whole view's line of sight and the category
        is not known to be small: a table's far end past an end-on view (:meth:`_along_sight`).
        """
        graph.widen_gate(v, gate)
        if self.boxes and o.box is not None:
            if restart and v.footprint is not None and inside(o.box, v.footprint, NOISE_PAD):
                restart = False
            longest = max(self._longest_view.get(v.id, longest_side(v.footprint) if v.footprint is not None else 0.0),
                          longest_side(o.box))
            self._longest_view[v.id] = longest
            if not o.truncated:
                self._saw_whole(v.id, sides(o.box))
            kept_whole = not restart and v.footprint is not None and v.id not in self._partial
            grown = o.box.copy() if restart else union(v.footprint, o.box)
            if restart or extend or longest_side(grown) <= longest + BIG_MARGIN:
                graph.set_footprint(v, grown)
                self._mark(v.id, kept_whole or not o.truncated)
            elif v.id in self._partial and not o.truncated:
                if self._along_sight(o, grown) and not self._small_category(graph, v.category):
                    graph.set_footprint(v, grown)
                    self._mark(v.id, True)
                else:
                    self.restart(graph, v, o)  # cut-off views only, and a whole one beyond them (docstring)
            self.views.note(graph, v, o.box)

    def shown_on_start(self, graph: ObjectGraph) -> dict[int, np.ndarray]:
        """Per older node not of a category known to be small: the box round its views this
        pass that lay on the footprint the pass began with (:mod:`~bomc_bt.graph.refinement`)."""
        return {i: box for i, box in self.views.on_start().items()
                if i in graph.nodes and not self._small_category(graph, graph.nodes[i].category)}

    @staticmethod
    def _along_sight(o: Observation, grown: np.ndarray) -> bool:
        """Whether ``grown``, a footprint of cut-off views joined with ``o``'s whole view
        beyond them, stays within that view on every side the view shows in full
        (:meth:`_whole_and_shorter`): the cut-off views lie along the line of sight, where
        a whole view does not show how far the object goes. A 1.6 m table seen first cut
        off at one end (past its chairs), then whole end-on at the other (a view 0.6 m long
        and 0.85 m across, the table's width): starting the footprint over from the end-on
        view left the first end outside it, and the next pass took that end for a second
        table (36 x 28 m office, static, seed 6613). Not in a category known to be small
        (:meth:`_small_category`, checked by the caller): a chair seen whole from the front
        is a box 0.5 m wide and 0.3 m deep, and a footprint caught over the chair behind it
        is then also along the line of sight (Environment-A-size floor, seed 9911: one
        chair's footprint grew over the chair 0.8 m behind it)."""
        return not _longer_where_shown(sides(o.box), grown)

    def touched_node(self, graph: ObjectGraph, o: Observation) -> Node | None:
        """The big same-category node whose footprint a truncated view lies against, if any.

        A table behind chairs may only ever show its two ends, from two sides: views whose
        boxes are a chair's width apart. That is also what two tables side by side look
        like, but the second table, seen whole, is a view that is not truncated; a view
        that is cut off by an occluder near a big known object's edge is taken to be more
        of that object, not a new one (at worst a second object is added later, when seen
        whole). Only big objects (a footprint side longer than delta_c) of a category not
        seen small this pass (:meth:`_small_category`) count: small ones are seen whole
        often enough, and chairs around a table are a chair's width apart.
        The view then extends that node's footprint: a table whose far end was hidden by a
        chair until the chair went away grows to its whole length as the end comes into
        view, a sliver at a time, instead of the next sliver becoming a second table. A node
        that has been seen whole is not extended past that view across the line of sight:
        its size there is known, and what lies beyond it is a neighbour.
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
            big = (np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1])
                   > self.params.distance(o.category) + BIG_MARGIN)
        hits = [k for k in np.nonzero(big & overlapping(boxes, grown, 1e-9))[0]
                if not self._whole_and_shorter(graph.nodes[int(ids[k])], o.box)]
        if len(hits) == 0 or self._small_category(graph, o.category):
            return None
        gaps = [box_gap(boxes[k], o.box) for k in hits]
        best = min(range(len(hits)), key=lambda i: (gaps[i], int(ids[hits[i]])))
        return graph.nodes[int(ids[hits[best]])]

    def _small_category(self, graph: ObjectGraph, category: str) -> bool:
        """Whether this pass has seen several objects of ``category`` whole (``FOOTPRINT_RANK``
        of them: one table seen end-on shows only its width), none longer than delta_c plus
        the margin: chairs, whose nodes' footprints pass for big only by mask bleed over a
        neighbour (0.93-1.06 m on an Environment-A-size floor). A cut-off view against such a
        node is its neighbour, not its hidden end (seed 337: 26 chair views in two passes,
        among them the views of a chair just removed by misses, which could not come back)."""
        sides = self._whole_sides(graph, category)
        return len(sides) >= FOOTPRINT_RANK and max(sides) <= self.params.distance(category) + BIG_MARGIN

    def _whole_sides(self, graph: ObjectGraph, category: str) -> list[float]:
        """The longest side of each node of ``category`` seen whole this pass."""
        return [float(x.max()) for i, x in self._whole_view.items()
                if i in graph.nodes and graph.nodes[i].category == category]

    def fits(self, graph: ObjectGraph, v: Node, o: Observation) -> bool:
        """Whether ``o``'s box, taken for ``v``'s hidden end (:meth:`touched_node`), leaves
        ``v``'s footprint no longer than objects of its category show themselves (plus the
        noise margin): the longest whole view of the category this pass, or the length
        that several of its nodes' footprints reach (:func:`~bomc_bt.graph.parts.footprint_length`;
        no limit before the category has that many). A longer union holds more than one
        object: on office-s a door detected on a table beside a door stretched the door's
        footprint to 2.45 m, and a door taken for a table made a 1.2 m table's 3.4 m, each
        node moving 0.6-0.75 m to the middle of it. Such a view is a confusion or a false
        detection on a neighbour, and is dropped: a cap that made such views nodes of their
        own instead added phantoms (depot seed 21 over 12 passes: 6 became 12)."""
        sides = [longest_side(w.footprint) for w in graph.nodes.values()
                 if w.category == v.category and w.footprint is not None]
        reached = footprint_length(sides)
        if reached is None or v.footprint is None or o.box is None:
            return True
        size = max(reached, self.longest_whole(graph).get(v.category, 0.0))
        return longest_side(union(v.footprint, o.box)) <= size + BIG_MARGIN

    def _whole_and_shorter(self, v: Node, box: np.ndarray) -> bool:
        """Whether this pass has seen ``v`` whole and ``box`` would make it longer than those
        views (plus the noise margin) along a side they show in full: then the box is a
        neighbour's, not ``v``'s hidden end (two cabinets half a metre apart on a depot
        floor, the new one seen only cut off, became one node midway).

        A whole view shows an object's full extent across the line of sight, not along it:
        a table seen end-on is a box 0.8 m wide and a few cm deep, and its far end, seen
        cut off later, lengthens the shallow side. So only a side at least
        ``_ACROSS_SHARE`` of the view's longer side counts as shown in full. A node only
        loaded from the store may be one whose end no pass has seen yet, and still grows."""
        whole = self._whole_view.get(v.id)
        grown = union(v.footprint, box)
        return whole is not None and grown is not None and _longer_where_shown(whole, grown)

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




def _longer_where_shown(whole: np.ndarray, box: np.ndarray) -> bool:
    """Whether ``box`` is longer (plus ``BIG_MARGIN``) than a whole view's x, y extents
    ``whole`` along a side that view shows in full: at least ``_ACROSS_SHARE`` of its longer
    side (across the line of sight; along it, the object may go on unseen)."""
    shown = whole >= _ACROSS_SHARE * whole.max()
    return bool((shown & (sides(box) > whole + BIG_MARGIN)).any())
