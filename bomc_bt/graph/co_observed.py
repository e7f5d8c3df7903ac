"""Nodes seen as two objects in one frame are two objects, however close.

Robust association folds a node into a neighbour of its category when one observation
covers both (:meth:`RobustPolicy._merge_hidden_duplicates
<bomc_bt.graph.robust.RobustPolicy._merge_hidden_duplicates>`): two views of one table from
opposite ends leave two nodes that must become one. But chairs stand 0.8 m apart round a
table, and a view of one whose mask bled onto the next covers both: on an
Environment-A-size floor 10 of the 11 chairs a first pass removed while they stood there
were folded into a neighbour this way (issue 17). A frame in which *both* nodes were
matched, each by its own detection, already showed two objects; no later view that covers
both undoes that. So every frame notes the pairs of same-category nodes it matched that
stand within ``reach`` of each other, and the fold leaves such a pair alone. A node the
frame placed (a sighting confirmed, a node moved to a detection) counts with the nodes it
matched: one frame confirmed a chair's sighting while its neighbour's node, 0.8 m away, took
its own detection, and a view bled over both folded the new chair into the neighbour's node
(Environment-A-size floor, seed 9922, pass 1).

What one pass saw holds for the next: a fold is for duplicates, and two nodes an earlier
pass matched in one frame were never one object. If one of them has gone since, its misses
take it off (a removal the operator is told of); folded into its neighbour it vanished as
no change. With the pairs kept per pass only, on an Environment-A-size floor with 5 % churn
(seed 7171) passes 2 and 3 folded 6 and 9 chairs that pass 1 or 2 had seen beside their
neighbour in one frame. Most came back seconds later under a new id; one left a gap its removed
neighbour's id was moved into. So a pass starts from the pairs of the pass before it
(:meth:`CoObserved.carry`, :func:`bomc_bt.pass_resume.earlier_co_observed`), and the pairs
it saves in its resume point hold both.

In memory for the pass (saved in the graph's pass state, so a resumed pass keeps it and
the next pass starts from it).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


class CoObserved:
    """Pairs of same-category nodes matched in one frame (ids, smaller first)."""

    def __init__(self) -> None:
        self.pairs: set[tuple[int, int]] = set()
        self._session: int | None = None

    def begin(self, session: int) -> None:
        """A new session not started by :meth:`carry` starts from nothing (no earlier pass known)."""
        if session != self._session:
            self._session, self.pairs = session, set()

    def carry(self, session: int, pairs: Iterable[tuple[int, int]]) -> None:
        """Start ``session`` from ``pairs`` an earlier pass saw (ids of nodes still present)."""
        self._session, self.pairs = session, {(min(a, b), max(a, b)) for a, b in pairs}

    def note(self, nodes: Iterable, reach: float) -> None:
        """Record the same-category pairs among ``nodes`` (this frame's matched) within ``reach`` m."""
        nodes = sorted(nodes, key=lambda n: n.id)
        if len(nodes) < 2:
            return
        xy = np.array([n.position[:2] for n in nodes], dtype=float)
        near = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1]) <= reach
        for i, j in zip(*np.nonzero(np.triu(near, 1)), strict=True):
            if nodes[i].category == nodes[j].category:
                self.pairs.add((nodes[i].id, nodes[j].id))

    def add(self, a: int, b: int | None) -> None:
        """Record that nodes ``a`` and ``b`` (None: nothing to record) are two objects: the
        first sighting of ``a`` stood clear of ``b``'s own view in one frame
        (:meth:`TentativeSightings.claims <bomc_bt.graph.tentative.TentativeSightings.claims>`)."""
        if b is not None and b != a:
            self.pairs.add((min(a, b), max(a, b)))

    def seen_apart(self, a: int, b: int) -> bool:
        return (min(a, b), max(a, b)) in self.pairs

    def to_json(self) -> dict:
        return {"session": self._session, "pairs": sorted([a, b] for a, b in self.pairs)}

    def restore(self, state: dict) -> None:
        self._session = state.get("session")
        self.pairs = {(int(a), int(b)) for a, b in state.get("pairs", [])}
