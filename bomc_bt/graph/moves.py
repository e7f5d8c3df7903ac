"""Where a node's object went: the new node or the view that is the same object, moved.

The robust policy (:mod:`~bomc_bt.graph.robust`) tells a move in two orders. A view of an
object new to the map near a node this pass already removed is that object seen at its new
place (:func:`removed_here`); a node whose absence is now confirmed near a node new in this
pass is folded into it, the robot having seen the new place first (:func:`arrival_of`).
Both pick the nearest candidate of the category within ``association.move_radius`` [m],
and both refuse the same candidates:

* beyond the node's own gate, one at a place no earlier pass looked at, or where the
  previous pass detected another object of its category: that object was most likely always
  there (:func:`~bomc_bt.graph.association.never_looked`,
  :func:`~bomc_bt.graph.association.sighted_before`);
* one whose colour tells it apart (:func:`~bomc_bt.graph.looks.looks_apart`): a yellow
  bin put near where a blue one went is another bin;
* one standing where an earlier pass saw an object of its kind and look go
  (:func:`~bomc_bt.graph.brought_back.stands_where_gone`, within ``association.return_radius``):
  that object is back, and the pass end says so (unless the place is one the node itself
  left, :func:`~bomc_bt.first_seen.gone_before`: it may have gone back). Traced on a
  36 x 28 m office (seed 9105, pass 11): chair-11 carried 1.6 m while chair-5, of the same
  navy model, came back to its place 1.4 m the other side; the node of chair-11 took the
  nearer new node, chair-5's, for its move, and chair-11 at its new place was reported added.

A node with only some misses is no move candidate: one missed frame let a neighbouring
chair, seen for the first time, take its id. Its absence confirmed, :func:`arrival_of` still
makes it a move.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.association import never_looked, sighted_before
from bomc_bt.graph.brought_back import stands_where_gone
from bomc_bt.graph.looks import looks_apart
from bomc_bt.graph.records import AssociationParams, Node, Observation

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph


def removed_here(graph: ObjectGraph, o: Observation, gate: float, params: AssociationParams,
                 gone: Sequence[Node] = (), withdrawn: Collection[int] = ()) -> Node | None:
    """The node of ``o``'s category removed this session that ``o`` sees moved (nearest, then
    lowest id; ``gate``: ``o``'s own, m; ``gone``: nodes earlier passes saw go). A ``withdrawn``
    node (retracted: no object went from its place) may come back at its place, never move."""
    fresh = never_looked(graph, o)
    best: tuple[float, int, Node] | None = None
    for v in graph.removed_this_session():
        if v.category != o.category:
            continue
        d = float(np.linalg.norm((v.position - o.position) * graph.index.scale))
        if d > params.move_radius or (best is not None and (d, v.id) >= best[:2]):
            continue
        if d > gate and (fresh or v.id in withdrawn or sighted_before(graph, o, v, params.sighting_radius)):
            continue
        if not looks_apart(v, o, params.colour_tolerance):
            best = (d, v.id, v)
    if best is None or stands_where_gone(o, others(gone, best[2]), params.return_radius, params.colour_tolerance):
        return None
    return best[2]


def arrival_of(graph: ObjectGraph, v: Node, session: int, params: AssociationParams,
               gone: Sequence[Node] = ()) -> Node | None:
    """The node new in ``session`` that the older ``v``, its absence just confirmed, moved to
    (nearest, then lowest id; ``gone``: nodes earlier passes saw go); None for a node of
    this session."""
    if v.first_session >= session:
        return None
    gate, radius, tolerance = params.distance(v.category), params.sighting_radius, params.colour_tolerance
    near = [(d, n.id, n) for n, d in graph.within(v.category, v.position, params.move_radius)
            if n.id != v.id and n.first_session == session and not looks_apart(v, n, tolerance)
            and (d <= gate or not (never_looked(graph, n) or sighted_before(graph, n, v, radius)))
            and not stands_where_gone(n, others(gone, v), params.return_radius, tolerance)]
    return min(near, key=lambda t: t[:2])[2] if near else None


def others(gone: Sequence[Node], v: Node) -> list[Node]:
    """``gone`` but the place ``v`` itself left (:func:`~bomc_bt.first_seen.gone_before`): it may go back there."""
    return [g for g in gone if g.id != v.id]
