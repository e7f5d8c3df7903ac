"""Which id lives on when two nodes turn out to be one object.

An id is what the operator follows from pass to pass: the history, the change report and
the viewer are keyed on it. When a view shows two nodes to be one object (a duplicate
folded during the pass, :meth:`~bomc_bt.graph.robust.RobustPolicy._merge_hidden_duplicates`,
or the two ends of one object joined when the pass ends, :mod:`bomc_bt.graph.pass_end`),
the node an earlier pass already had keeps its id and the one this pass started is folded
into it, however often each was matched; between two nodes of the same age the one matched
more often keeps it (then the lower id). Where it stands is the weighted mean either way.

Why the age first: the node this pass started for an object the map already holds is a
second view of it, and folding the old node into it reported the object as new ("added")
and its history as ended (a merge). On a 36 x 28 m office (seed 7605, pass 5) a table
carried 1.7 m kept its id at first (a move); its new place, seen from the far side, started
a second node that collected 313 views in a minute beside the old node's 46 over four
passes, and the fold kept the new one: the move was reported as an addition. A table that
never moved would have been reported the same way.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from bomc_bt.graph.records import Node

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph


def keeper(a: Node, b: Node, session: int) -> tuple[Node, Node]:
    """(keep, drop) of two nodes found to be one object in ``session``: the one from an
    earlier pass, else the one matched more often, else the lower id."""
    def rank(v: Node) -> tuple[bool, int, int]:
        return v.first_session < session, v.observations, -v.id

    return (a, b) if rank(a) >= rank(b) else (b, a)


def twin_of(graph: ObjectGraph, v: Node, reach: float, seen_apart: Callable[[int, int], bool]) -> Node | None:
    """The node ``v`` duplicated, when its misses confirm it gone: one of its category at
    least as old, within ``reach`` (delta_c), that no frame ever showed beside ``v``
    (nearest, then lowest id); None when there is none.

    Why: a node with a neighbour of its kind closer than association tells two objects apart,
    never matched in one frame with it, was a second node for that neighbour's object. Its
    absence is no change: the object is where the other node stands, and that node's own
    misses report it if it went. Generated 50 x 45 m office, seed 9004, pass 2, and 93 x 90
    m, seed 9003, pass 2: one door each, two nodes 0.47-0.49 m apart from pass 1, one removed
    as a phantom (in the first, 11 s into the pass, before a frame matched the other). The 15
    other removals beside a node of their kind within 0.7 m on eleven kept multi-pass sites
    (chairs 0.51-0.67 m apart, a bin) had all been seen side by side
    (:mod:`bomc_bt.graph.co_observed`) and stay removals."""
    near = [(d, w.id, w) for w, d in graph.within(v.category, v.position, reach)
            if w.id != v.id and w.first_session <= v.first_session and not seen_apart(v.id, w.id)]
    return min(near, key=lambda t: t[:2])[2] if near else None
