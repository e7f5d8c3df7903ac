"""What the robust policy decides when a pass ends, with the whole pass in view.

During a pass each frame is associated as it comes (:mod:`bomc_bt.graph.robust`), so a
decision can only use what the camera has shown so far. When the pass ends (the Pair
Relocations leaf, ``trees/monitor.yaml``) every removal, addition and move of the pass is
known at once, and three stories are told again where the whole pass tells them better,
in this order:

1. a move that a node added later at the old place undoes is taken back
   (:func:`~bomc_bt.graph.returns.moves_taken_back`);
2. two nodes that are the two ends of one object become one
   (:func:`~bomc_bt.graph.parts.part_pairs`);
3. a removal and an addition that were one object moved become one move: by position
   (:func:`~bomc_bt.graph.relocations.relocation_pairs`, unless their colours tell them
   apart), then, of those left, by look (:func:`~bomc_bt.graph.looks.look_pairs`), then, of
   those left, by position with a node of an earlier pass the pass never saw and whose place a
   near, clear view saw empty (its removal short of evidence: a table moved 2 m during a pass
   before the robot came, its old place in no frame's view for most of the pass, was missed
   up close three times of the nine its detection rate asks; 36 x 28 m office, seed 9105,
   pass 3); an
   addition standing where an earlier pass saw one of its kind and look go is that object
   brought back, never an arrival (:func:`~bomc_bt.graph.brought_back.brought_back`). A node
   the pass retracted (taken off having been matched only in the frames that confirmed it)
   is no such removal: the map never trusted an object there (a look-alike's node, retracted
   in pass 2 of a static office under the hard preset, was paired with a real door 8.8 m
   away, a phantom move).

Tried and not kept: a move of the pass given to a node of its kind removed in the pass
whose old place stood nearer the arrival (the story with less motion). On generated
offices, of the true moves with another object of their kind gone (removed or moved) from
within ``move_radius`` of the arrival, the mover had stood the nearer in 5 of 10 (40 floors
of 36 x 28 m with 12 sessions and 6 of 93 x 90 m with 3, 5 % churn): a coin, like the order
the camera comes by, which decides it during the pass.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Collection, Sequence
from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.brought_back import BACK_OF, brought_back
from bomc_bt.graph.extents import BIG_MARGIN
from bomc_bt.graph.footprints import longest_side, overlapping, union
from bomc_bt.graph.identity import keeper
from bomc_bt.graph.looks import look_pairs, looks_apart
from bomc_bt.graph.parts import part_pairs, parts_of_gone
from bomc_bt.graph.records import PRESENT, Event, Node
from bomc_bt.graph.relocations import relocation_pairs
from bomc_bt.graph.returns import moves_taken_back

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph
    from bomc_bt.graph.robust import RobustPolicy


def take_back_moves(policy: RobustPolicy, graph: ObjectGraph, session: int, stamp: float,
                    history: Sequence[Event]) -> list[Event]:
    """Step 1 (``history``: the pass's events so far): the moved node goes back to its old
    place, where the late node stands; the late node (and the sightings of the arrival the
    move had folded in, and the look) takes the moved-to place."""
    events: list[Event] = []
    for m in moves_taken_back(history, graph.nodes, session, policy.params.distance):
        back, late = m.moved, m.late
        went, stood = back.position.copy(), late.position.copy()
        graph.relocate(back, stood)
        graph.relocate(late, went)
        # each look stays with the place it was seen at: the moved node's came from the views of
        # the arrival it followed, the late node's from the object at the old place (kept with the
        # ids, two chairs side by side at a table swapped looks in pass 1 of a 93 x 90 m office,
        # seed 9621, and pass 2's colour test then refused both their views: one removed, a
        # flurry of nodes added)
        back.colour, late.colour = late.colour, back.colour
        if policy.extents.boxes:
            policy.extents.swap(graph, back, late)
        carried = min(m.arrival_observations, back.observations - 1)
        graph.add_observations(back, -carried)
        graph.add_observations(late, carried)
        events.append(graph.report("moved", back, session, stamp, went))
        events.append(graph.report("moved", late, session, stamp, stood))
    return events


def pair_relocations(policy: RobustPolicy, graph: ObjectGraph, session: int, stamp: float,
                     candidate: Callable[[Node], bool], gone: Sequence[Node] = (),
                     withdrawn: Collection[int] = ()) -> list[Event]:
    """Steps 2 and 3: each node the pass removed, paired with a ``candidate`` node it added,
    moved there (``gone``: the nodes earlier passes removed on evidence, as they last stood:
    an addition at one's place is its return, no arrival; ``withdrawn``: the nodes the pass
    retracted, whatever their count of frames)."""
    events = _join_parts(policy, graph, session, stamp)
    # a retracted node was never trusted: no object stood at its place to have moved from there
    removed = [v for v in graph.removed_this_session()
               if v.first_session < session and not policy.params.retracts(v) and v.id not in withdrawn]
    arrivals = [n for n in graph.nodes.values() if n.first_session == session and candidate(n)]
    tolerance = policy.params.colour_tolerance
    gone = [g for g in gone if g.id not in {v.id for v in removed}]  # a place it left: it may be back
    back = brought_back(arrivals, gone, policy.params.return_radius, tolerance)
    for arrival, went in back:
        events.append(graph.report("updated", arrival, session, stamp))
        events[-1].detail = {BACK_OF: went.id}
        if graph.evidence.sides is not None:  # where the views that removed it missed it from
            graph.evidence.sides.bring_back(arrival.id, went.id)
    arrivals = [n for n in arrivals if n.id not in {a.id for a, _ in back}]
    near = relocation_pairs(removed, arrivals, policy.params.relocation_radius,
                            lambda v, a: looks_apart(v, a, tolerance))
    paired = {n.id for pair in near for n in pair}
    unseen = [v for v in graph.nodes.values()
              if v.state == PRESENT and v.first_session < session and v.last_session != session]
    earlier = [v for v in graph.nodes.values() if v.state == PRESENT and v.first_session < session]
    first_seen = [n for n in graph.nodes.values()
                  if n.state == PRESENT and n.first_session == session and not candidate(n)]
    far = look_pairs([v for v in removed if v.id not in paired], [a for a in arrivals if a.id not in paired],
                     tolerance, list(graph.nodes.values()), unseen, policy.params.move_radius, earlier, first_seen,
                     policy.params.look_odds)
    paired |= {n.id for pair in far for n in pair}
    late = relocation_pairs([v for v in unseen if graph.missed_up_close(v.id) and not policy.params.retracts(v)],
                            [a for a in arrivals if a.id not in paired], policy.params.relocation_radius,
                            lambda v, a: looks_apart(v, a, tolerance))
    for v, arrival in sorted(near + far + late, key=lambda p: p[0].id):
        events.extend(policy.moved_to(graph, v, arrival, session, stamp))
    return events


def _join_parts(policy: RobustPolicy, graph: ObjectGraph, session: int, stamp: float) -> list[Event]:
    """Two nodes the pass saw that are the two ends of one object become one, in the middle:
    by the size the category shows this pass (a node of an earlier pass whose views reached
    beyond the footprint it began with, by the floor they covered:
    :meth:`~bomc_bt.graph.pass_views.PassViews.moved_off`), then by the size of an object the pass removed
    whose parts they are (:func:`~bomc_bt.graph.parts.parts_of_gone`: carried off and seen in
    two parts at its new place, it then pairs with its old node as a move)."""
    if not policy.extents.boxes or not policy.params.separate_neighbours:
        return []
    seen = [v for v in graph.nodes.values() if v.last_session == session]
    extents, events = policy.extents, []
    reference = policy.reference(graph, session)
    big = {c for c, length in reference.items() if length > policy.params.distance(c) + BIG_MARGIN}
    touch, seen_apart = policy.params.footprint_touch, policy.co_observed.seen_apart
    now = {v.id: box for v in seen if (box := extents.views.moved_off(graph, v, session)) is not None}
    shown = [dataclasses.replace(v, footprint=now[v.id]) if v.id in now else v for v in seen]
    joined: set[int] = set()
    for a, b in part_pairs(shown, reference, BIG_MARGIN, seen_apart, big, touch):
        a, b = graph.nodes[a.id], graph.nodes[b.id]
        joined |= {a.id, b.id}
        for v in (a, b):  # an older node's object stands where this pass saw it, not on its old floor
            if v.id in now:
                graph.set_footprint(v, now[v.id])
        events += _join(policy, graph, a, b, session, stamp)
    for a, b in _second_nodes(policy, graph, {i: box for i, box in now.items() if i not in joined}, reference,
                              session, joined, big):
        graph.set_footprint(a, now[a.id])
        events += _join(policy, graph, a, b, session, stamp)
    gone = [v for v in graph.removed_this_session() if v.first_session < session]
    arrivals = [v for v in graph.nodes.values() if v.first_session == session]
    tolerance = policy.params.colour_tolerance
    for a, b in parts_of_gone(gone, arrivals, BIG_MARGIN, seen_apart, lambda v, a: looks_apart(v, a, tolerance),
                              lambda c: policy.params.distance(c) + BIG_MARGIN):
        events += _join(policy, graph, a, b, session, stamp)
    return events


def _second_nodes(policy: RobustPolicy, graph: ObjectGraph, now: dict[int, np.ndarray],
                  reference: dict[str, float], session: int, joined: set[int],
                  big: set[str]) -> list[tuple[Node, Node]]:
    """(older node, node added this pass) pairs of one ``big`` object: the floor this pass's views of
    the older node covered beyond its old footprint (``now``) and the added node's footprint
    overlap as one object's views do (``footprint_overlap``), together no longer than one
    object of the kind (``reference`` plus the margin and what an occluder hides), and no
    frame showed the two apart. The object moved a little: the old node followed the part
    of it that lay against its old floor, and the rest became a node of its own
    (:mod:`bomc_bt.graph.pass_views`). Nearest first, each node in one pair at most, none
    of the ``joined`` (parts already)."""
    params, seen_apart = policy.params, policy.co_observed.seen_apart
    candidates = []
    for a in (graph.nodes[i] for i in sorted(now) if i in graph.nodes):
        length = reference.get(a.category) if a.category in big else None
        for b in graph.nodes.values():
            if b.first_session != session or b.category != a.category or b.footprint is None or length is None \
                    or b.id in joined or seen_apart(a.id, b.id):
                continue
            joint = longest_side(union(now[a.id], b.footprint))
            if joint <= length + BIG_MARGIN + params.footprint_touch \
                    and overlapping(now[a.id][None], b.footprint, params.footprint_overlap)[0]:
                candidates.append((float(np.hypot(*(a.position[:2] - b.position[:2]))), a.id, b.id, a, b))
    pairs, used = [], set()
    for _, _, _, a, b in sorted(candidates, key=lambda c: c[:3]):
        if a.id not in used and b.id not in used:
            pairs.append((a, b))
            used |= {a.id, b.id}
    return pairs


def _join(policy: RobustPolicy, graph: ObjectGraph, a: Node, b: Node, session: int, stamp: float) -> list[Event]:
    """``a`` and ``b`` become one node in the middle of their joint footprint."""
    keep, drop = keeper(a, b, session)
    policy.extents.join(graph, keep, drop)
    graph.relocate(keep, np.array([*((keep.footprint[:2] + keep.footprint[2:]) / 2.0), keep.position[2]]))
    graph.add_observations(keep, drop.observations)
    graph.set_confidence(keep, max(keep.confidence, drop.confidence))
    return [graph.remove(drop, session, stamp, merged_into=keep.id), graph.report("updated", keep, session, stamp)]
