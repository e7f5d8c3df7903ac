"""Moves found when a pass ends: a removal and an addition that were one object.

During a pass the robust policy keeps an object's id across a move only within
``move_radius`` and only as the camera happens to come by: the old place checked first,
then the new one, or the other way round (:mod:`bomc_bt.graph.robust`). A chair carried
to the other side of its room is often farther than that, or is seen at its new place
while a neighbour's node is the nearest candidate. When the pass ends, every removal it
confirmed and every object it added are known at once, so they can be paired with all of
them in view: a removed node and a node new in this pass, of one category, each the
other's nearest within ``relocation_radius``, are taken to be one object moved. The older
node keeps its id and moves to where the new one stands; the new one is folded into it
(a merge, no change of its own), so the pass reports one move instead of a removal and an
addition.

Why mutual nearest neighbours within a room's size and no more: identical objects cannot
be told apart by how they look, only by where they are. A chair that vanished from one
room and a chair that appeared in a room at the other end of the floor are as likely a
removal plus an unrelated addition as one chair carried across; pairing them would turn
two right reports into three wrong ones. Within a few metres a move is the likelier
story. Measured on the world files alone (every true removal, addition and move, perfect
perception, moves within ``move_radius`` kept by the pass itself), four 36 x 28 m offices
with 12 sessions and four Environment-A-size floors with 3 sessions: change F1 0.760 and
0.609 without pairing; mutual nearest within 5 m 0.798 and 0.701, within 8 m 0.775 and
0.710, within 12 m 0.750 and 0.689, at any distance 0.662 and 0.525.

Where objects differ in colour, two of them that do not look alike are never paired
here, nor is either the other's nearest: a blue bin taken away 3.0 m from where a green one
arrived does not hide the green one gone 3.3 m from it (a generated 36 x 28 m office, seed
8711, pass 2: two removals and an addition where one bin was taken away and one moved).
The removals and additions left are paired by look at any distance
(:mod:`bomc_bt.graph.looks`, after these pairs; both in :mod:`bomc_bt.graph.pass_end`).

A node new in this pass that is *first seen* (no earlier pass saw its place,
:mod:`bomc_bt.first_seen`) is no candidate: it is most likely an object that was always
there. Algorithm 2 as the paper writes it (``association.mode: paper``) pairs nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from bomc_bt.graph.records import Node


def relocation_pairs(removed: Sequence[Node], arrivals: Sequence[Node], radius: float,
                     apart: Callable[[Node, Node], bool] = lambda v, a: False) -> list[tuple[Node, Node]]:
    """(removed, arrival) pairs of one category, each the other's nearest within ``radius``
    along the floor (ties: the lower id), in the removed nodes' id order. A pair ``apart``
    says are two objects (their colours differ) is no candidate, so it hides no other pair."""
    if radius <= 0:
        return []
    pairs: list[tuple[Node, Node]] = []
    for category in sorted({v.category for v in removed} & {a.category for a in arrivals}):
        olds = sorted((v for v in removed if v.category == category), key=lambda v: v.id)
        news = sorted((a for a in arrivals if a.category == category), key=lambda a: a.id)
        a_xy = np.array([v.position[:2] for v in olds], dtype=float)
        b_xy = np.array([a.position[:2] for a in news], dtype=float)
        d = np.hypot(a_xy[:, None, 0] - b_xy[None, :, 0], a_xy[:, None, 1] - b_xy[None, :, 1])
        for i, j in np.argwhere(d <= radius):
            if apart(olds[i], news[j]):
                d[i, j] = np.inf
        nearest_new, nearest_old = np.argmin(d, axis=1), np.argmin(d, axis=0)  # first index on ties: lower id
        for i, j in enumerate(nearest_new):
            if d[i, j] <= radius and nearest_old[j] == i:
                pairs.append((olds[i], news[int(j)]))
    return sorted(pairs, key=lambda p: p[0].id)
