"""A node that shifted because more of its object came into view did not move.

A big object's node stands at the middle of the floor its views covered (its footprint,
:mod:`bomc_bt.graph.extents`), and each pass builds that footprint again from its own views.
A pass that saw only one end of a table puts the node at that end; the next pass, seeing
the whole table, puts it at the middle, up to half the table's length away. Reported as
"moved", that is a change nobody made: on Environment-A-size floors the tables behind
chairs were the phantom moves left after everything else (seed 7171 pass 2: table-87's
node went 0.87 m, from a 0.53 m footprint at the table's west end to its whole length;
seed 7272 pass 2: a table first seen once, 0.17 m of it, went 0.84 m).

The test is the floor itself. An object that moved leaves the floor it stood on: the
footprint this pass builds at its new place does not hold the old one. When the footprint
a node ends the pass with holds the one it began the pass with (within the noise pad),
the object still covers all the floor it covered before, and the shift is a better
estimate of where it stood all along. So does a node whose views in this pass lay on the
footprint it began with while the footprint it ends with leaves them out: the object still
stood on that floor, and the footprint was rebuilt from another part of it (seed 6868, pass
2: table-55's node began the pass on its east half, 0.8 m; a whole end-on view of the west
end restarted it there; the east end's views, cut off by chairs, were then too long to join
to that, and the node ended 1.1 m west). Not for a category this pass saw small and whole
(chairs): there a view on the old floor can be the neighbour's.
So, third, does a node whose footprint the pass began with was one end of the footprint it
ends with: the two touch and lie along one line, the first spans at least a margin less of
their joint length than the second, and the joint is no longer than one object of the
category (the longer of the pass's reference length and the end footprint, with the margin
and, for a big object, what an occluder hides, as :func:`~bomc_bt.graph.parts.part_pairs`
joins two parts). A generated 36 x 28 m office, seed 9001, pass 2: a 1.6 m table's node
began on its north 0.68 m (its chairs hid the rest), ended on the south 1.04 m, the two
touching, 1.70 m together: it went 0.84 m and was reported moved. A 50 x 45 m office, seed
9004, pass 2: a table's node began on 0.87 m of its west end (bled over the chair there)
and ended on 1.48 m of it, 0.72 m east. A table seen whole and pushed along its length is
not this: its old footprint is as long as its new one. Pushed less than what an occluder
hides along its length after a pass saw only one end of it, it is; that move cannot be told
from the better view.
A node the pass counted missing and removed is none of this, wherever it ends: its absence
was confirmed on the floor it began with, so a view it matched there earlier in the pass was
something else, or the object before it went (a generated 36 x 28 m office, seed 9001, pass
11: a table's node matched one view on its old floor, was removed 10 s later and paired at
the pass's end with a table new 23 m away; marked refined, the move was no change).
At the end of the pass such a node gets an
``updated`` event whose detail names the position the refinement started from
(:data:`REFINED_FROM`); :func:`bomc_bt.net_changes.net_changes` measures a move from the
refined place, so the shift is no change, and a real move in the same period still is.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.extents import BIG_MARGIN
from bomc_bt.graph.footprints import NOISE_PAD, box_gap, inside, longest_side, union
from bomc_bt.graph.records import Event

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph

REFINED_FROM = "refined_from"  # the key in an ``updated`` event's detail: where the shift began


def refinements(graph: ObjectGraph, started: Mapping[int, tuple[np.ndarray | None, np.ndarray]], session: int,
                stamp: float, threshold: Callable[[str], float],
                shown_on_start: Mapping[int, np.ndarray] | None = None,
                one_object: Callable[[str, np.ndarray, np.ndarray], bool] | None = None) -> list[Event]:
    """At the end of a pass: an ``updated`` event, marked refined, for every node of an
    earlier pass that went farther than ``threshold(category)`` from where this pass
    ``started`` it while its footprint grew over the one it started with, or left out this
    pass's views on it (``started``: node id -> (footprint, position) at the pass's first
    match of it; ``shown_on_start``: node id -> the box round its views this pass that lay
    on that footprint, :meth:`~bomc_bt.graph.extents.NodeExtents.shown_on_start`;
    ``one_object(category, began, ended)``: whether the footprint it began with is one end of
    the one it ended with, :func:`end_of_one`)."""
    shown_on_start = shown_on_start or {}
    events = []
    for node_id, (footprint, position) in sorted(started.items()):
        v = graph.nodes.get(node_id)
        if v is None or v.first_session >= session or footprint is None or v.footprint is None:
            continue  # a node new in this pass is an addition wherever it ends
        if float(np.hypot(*(v.position[:2] - position[:2]))) <= threshold(v.category):
            continue
        shown = shown_on_start.get(node_id)  # views on the floor it began with, that its footprint leaves out
        if inside(footprint, v.footprint, NOISE_PAD) or (shown is not None and not inside(shown, v.footprint,
                                                                                          NOISE_PAD)) \
                or (one_object is not None and one_object(v.category, footprint, v.footprint)):
            event = graph.report("updated", v, session, stamp)
            event.detail = {REFINED_FROM: [round(float(x), 3) for x in position]}
            events.append(event)
    return events


def ends_of_one(graph: ObjectGraph, session: int) -> Callable[[str, np.ndarray, np.ndarray], bool]:
    """:func:`end_of_one` for ``refinements``' ``one_object``, with each category's length by
    this pass's views (as the pass's end joins parts) and what an occluder hides
    (``footprint_touch``); for the robust policy, whose extents keep footprints."""
    reference = graph.policy.reference(graph, session)

    def one_object(category: str, began: np.ndarray, ended: np.ndarray) -> bool:
        return end_of_one(began, ended, reference.get(category), graph.params.distance(category) + BIG_MARGIN,
                          BIG_MARGIN, graph.params.footprint_touch)
    return one_object


def end_of_one(began: np.ndarray, ended: np.ndarray, length: float | None, small: float, margin: float,
               hidden: float) -> bool:
    """Whether footprint ``began`` is one end of the object whose footprint is ``ended``: they
    touch, lie along one line (together no wider across than the wider of the two, within the
    noise pad), ``began`` spans at least ``margin`` less of their joint length than ``ended``,
    and the joint box is no longer than one object: the longer of ``length`` (the category's,
    :func:`~bomc_bt.graph.parts.reference_lengths`; None: unknown) and ``ended``, plus
    ``margin``, and ``hidden`` more where that is longer than ``small`` (a big object)."""
    if box_gap(began, ended) > NOISE_PAD:
        return False
    joint = union(began, ended)
    axis = 0 if joint[2] - joint[0] >= joint[3] - joint[1] else 1
    across = 1 - axis
    if joint[across + 2] - joint[across] > max(began[across + 2] - began[across],
                                                ended[across + 2] - ended[across]) + NOISE_PAD:
        return False
    if began[axis + 2] - began[axis] + margin > ended[axis + 2] - ended[axis]:
        return False
    one = max(length or 0.0, longest_side(ended))
    return longest_side(joint) <= one + margin + (hidden if one > small else 0.0)


def refined_shifts(events: Iterable[Event]) -> dict[int, np.ndarray]:
    """Per node, how far (x, y) its refinements among ``events`` carried it: per session the
    last one counts (a pass resumed after its end step wrote one marks the same shift again)."""
    last: dict[tuple[int, int], Event] = {}
    for e in events:
        if e.kind == "updated" and (e.detail or {}).get(REFINED_FROM) is not None:
            last[(int(e.node_id), int(e.session))] = e
    out: dict[int, np.ndarray] = {}
    for (node_id, _), e in last.items():
        shift = np.asarray(e.position, dtype=float)[:2] - np.asarray(e.detail[REFINED_FROM], dtype=float)[:2]
        out[node_id] = out.get(node_id, np.zeros(2)) + shift
    return out
