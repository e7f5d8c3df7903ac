"""Two nodes that are the two ends of one object, found when a pass ends.

A 1.6 m table whose middle the chairs around it hide is seen end by end: each end's views
are half a metre long, the gap between them wider than ``footprint_touch``, and no frame
shows both. Each end becomes a node 0.7 m off the table's middle (Environment A size,
seed 337: ten of the 45 tables, all ten phantoms of a pass over a floor where nothing
changed). Neither end is big, so no view of one is taken for the other's hidden end.
Measured there: the join brings passes 2-3 to 3 / 3 phantoms (from 4 / 7); pass 1's ten
remain, for a reason not yet found (README, "Stable association over many passes").

What tells two ends of one object from two objects is the size its category shows
elsewhere on the floor: tables seen whole at 1.6 m, chairs at 0.5 m. Two nodes of one
category are taken for one object when each is clearly a part (its footprint at most
``PART_SHARE`` of the longest whole view of the category this pass), their joint box is
no longer than that view (plus the noise margin), and no frame of the pass showed both.
Two chairs side by side are each a whole chair, so they stay apart.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

from bomc_bt.graph.footprints import longest_side, union
from bomc_bt.graph.records import Node

# [-] a node whose footprint is at most this share of its category's longest whole view is
# a part of an object, not an object (a table's end: 0.87 m of 1.6 m)
PART_SHARE = 0.6


def part_pairs(nodes: Iterable[Node], longest_whole: dict[str, float], margin: float,
               seen_apart: Callable[[int, int], bool]) -> list[tuple[Node, Node]]:
    """Pairs of nodes that are parts of one object, each node in at most one pair, nearest
    first (ties by ids)."""
    by_category: dict[str, list[Node]] = {}
    for v in nodes:
        whole = longest_whole.get(v.category)
        if v.footprint is not None and whole is not None and longest_side(v.footprint) <= PART_SHARE * whole:
            by_category.setdefault(v.category, []).append(v)
    candidates = []
    for category, parts in by_category.items():
        limit = longest_whole[category] + margin
        for i, a in enumerate(parts):
            for b in parts[i + 1:]:
                if longest_side(union(a.footprint, b.footprint)) <= limit and not seen_apart(a.id, b.id):
                    gap = float(np.hypot(*(a.position[:2] - b.position[:2])))
                    candidates.append((gap, min(a.id, b.id), max(a.id, b.id), a, b))
    candidates.sort(key=lambda c: c[:3])
    used: set[int] = set()
    pairs = []
    for _, _, _, a, b in candidates:
        if a.id not in used and b.id not in used:
            used |= {a.id, b.id}
            pairs.append((a, b))
    return pairs
