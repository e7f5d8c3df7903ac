"""Robust association: our extension of Algorithm 2 where the paper names its limitations (occlusion, misses, moves).

* *One-to-one matching.* Observations and nodes of a category are paired greedily by distance (shortest pair
  first, ties by node id then observation order) among pairs within delta_c. In the paper one detection can
  keep two nearby nodes alive; here a duplicate node that never gets its own detection is eventually removed.
* *Refresh.* A matched node moves towards the observation by a running average with weight
  ``position_smoothing`` (centroids from single frames are noisy, a moving average converges on the object),
  keeps the maximum confidence seen (the paper's attribute is the detection score; the best view is the most
  informative), and records ``last_session``, ``observations`` and resets ``misses``.
* *Confirm before deleting.* An unmatched expected node gains a miss, at most one per ``confirm_interval``
  of robot time, and goes at ``confirm_misses`` consecutive misses seen from robot places ``miss_spacing``
  apart (misses from one spot are one look). Misses are weighed by how often the frames that expected the node
  saw it (:meth:`RobustPolicy.misses_needed`): an object often missed from where the robot passes needs more.
* *Confirm before adding* (:mod:`bomc_bt.graph.tentative`): a new object must be seen in ``confirm_detections`` frames.
* *One object, one label* (:mod:`bomc_bt.graph.confusions`): a new sighting within ``relabel_radius`` of a
  node of another category counts only in a frame that matched that node.
* *No duplicates.* An unmatched observation within delta_c of a same-category node (which then has been
  matched by a closer observation) is absorbed, as in the paper, unless its floor box lies clear of that
  closer view's: a frame names each object once. Big objects earn wider gates and footprints
  (:mod:`bomc_bt.graph.extents`).
* *Neighbours stay apart* (``separate_neighbours``). A view whose floor box lies clear of a small node's
  footprint is another object, however near (chairs 0.8 m apart round a table, delta_c 0.7 m), once that
  footprint holds a whole view (not only cut-off ones). A view nearer a sighting begun beside a node's own view
  of one frame goes to that sighting, not to the node (``TentativeSightings.claims``). Nor does a view match
  a node whose colour lies beyond ``colour_match_tolerance`` of its own: a red chair put where a blue one
  stood is another chair, and the blue one's node is left to its misses.
* *Moves keep their id.* An unmatched observation farther than delta_c from every same-category node but
  within ``move_radius`` of a same-category node that was removed earlier in this session is taken to be that
  object moved: it keeps its id and the event is ``moved`` with the previous position: identity across a
  relocation lets a user ask "where did chair 12 go?". The other order too: when an older node's absence is
  confirmed and a node of its category new in this session stands within ``move_radius``, that node is folded
  into the old one, which moves there (the robot saw the chair's new place before its old one). Neither way
  beyond delta_c to a place no earlier pass looked at: that object was always there; nor between two whose
  colours tell them apart (:func:`~bomc_bt.graph.looks.looks_apart`): a yellow bin put near where a blue one
  went is another bin; nor to where an earlier pass saw a look-alike go (that one is back): :mod:`~bomc_bt.graph.moves`.
  A shift while its footprint grew over the old one is no move
  (:mod:`bomc_bt.graph.refinement`).
* *Retract, not remove, what was barely seen.* A node matched in at most ``retract_observations`` frames in all
  (by default: never matched again after the two sightings of a look-alike that confirmed it) that misses take
  off is marked retracted: the map drops it either way, but the change report does not tell the operator an
  object went (:mod:`bomc_bt.net_changes`). So is one taken off within ``retract_within`` of a frame of the
  same pass that matched it: the visit that saw it missed it from elsewhere moments later, a view-dependent
  sighting (a look-alike, a door edge-on), not an object carried off -- that one the pass never sees.
* *Sparse updated events*: at a node's first match in a session, after a ``report_distance`` drift (reconciled at end).

Distances are measured on (x, y, w * z), w = ``vertical_weight``: a tall object cut off by the image edge sits low
(such a view only bounds a node's height: :func:`~bomc_bt.graph.records.bounded_height`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph import looks, moves, pass_end
from bomc_bt.graph.association import near_any
from bomc_bt.graph.co_observed import CoObserved
from bomc_bt.graph.confusions import confusing_node
from bomc_bt.graph.evidence import misses_needed
from bomc_bt.graph.extents import BIG_MARGIN, NodeExtents
from bomc_bt.graph.geometry import dist2_scalar
from bomc_bt.graph.identity import keeper, twin_of
from bomc_bt.graph.parts import longer_than_one, reference_lengths
from bomc_bt.graph.records import REMOVED, AssociationParams, Event, Node, Observation, bounded_height
from bomc_bt.graph.replacements import Replacements
from bomc_bt.graph.tentative import TentativeSightings
from bomc_bt.graph.view_sides import side_of

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph
    from bomc_bt.graph.walls import Walls

Pair = tuple[float, int, int]  # (squared distance, node id, observation index)


class RobustPolicy:
    """One-to-one matching, confirmation before adding and deleting, moves that keep ids."""

    def __init__(self, params: AssociationParams):
        self.params = params
        self.vertical_weight = params.vertical_weight
        self.extents = NodeExtents(params)
        self.walls: Walls | None = None  # the saved map, when the pass gives it (:mod:`~bomc_bt.graph.walls`)
        self.tentative = TentativeSightings(params, np.array([1.0, 1.0, params.vertical_weight]))
        self.co_observed = CoObserved()  # nodes one frame matched as two objects (never folded)
        self.replacements = Replacements(params.replace_sightings, params.confirm_interval)
        self.gone: Sequence[Node] = ()  # nodes earlier passes saw go (first_seen.gone_before), given by the pass
        # nodes whose latest removal retracted them as seen moments before (no object went, nor
        # moved from there); a resumed pass reads them back from its events (pass_resume.restore_pass)
        self.withdrawn: set[int] = set()

    def gate(self, o: Observation) -> float:
        """delta_c, widened by a large object's own spread (capped at ``extent_gate`` * delta_c).

        Seen from another side, a table's visible-surface centroid moves by up to half its
        length, and without this the same table becomes two nodes. Small objects keep delta_c.
        """
        delta = self.params.distance(o.category)
        return max(delta, min(1.5 * o.extent, self.params.extent_gate * delta))

    def associate(
        self, graph: ObjectGraph, observations: Sequence[Observation], expected: Sequence[int], session: int,
        stamp: float, in_view: Sequence[int] | None = None, miss_weights: Sequence[float] | None = None,
        place: np.ndarray | None = None) -> list[Event]:
        """Match, refresh, count misses, place the unmatched, fold hidden duplicates."""
        self.tentative.begin(session)
        self.co_observed.begin(session)
        self.replacements.begin(session)
        weights = dict(zip(expected, miss_weights, strict=True)) if miss_weights is not None else {}
        obs, exp = observations, graph.begin(session, expected)
        events: list[Event] = []
        near = self._near(graph, obs, stamp)  # one vectorised pass, graph as it stood at the frame's start
        pairs: list[Pair] = []
        for j, (ids, d2) in enumerate(near):
            pairs.extend(zip(d2.tolist(), ids.tolist(), [j] * len(ids), strict=True))
        pairs.sort()
        matched_nodes: set[int] = set()
        matched_obs: dict[int, int] = {}  # observation index -> the node it matched
        before: dict[int, tuple[np.ndarray | None, np.ndarray]] = {}  # footprints, positions before the frame
        for _, vid, j in pairs:
            if vid in matched_nodes or j in matched_obs:
                continue
            matched_nodes.add(vid)
            matched_obs[j] = vid
            before[vid] = (graph.nodes[vid].footprint, graph.nodes[vid].position.copy())
            events.extend(self._refresh(graph, graph.nodes[vid], obs[j], session, stamp))
        self.co_observed.note((graph.nodes[v] for v in matched_nodes if v in graph.nodes),
                              self.params.extent_gate * self.params.largest_distance())
        for vid in exp:
            if vid not in graph.nodes:  # an arrival an earlier miss in this loop folded into its moved node
                continue
            if vid in matched_nodes:
                graph.evidence.seen(vid, stamp, self.params.confirm_interval, self._side(graph.nodes[vid], place))
            elif weights.get(vid, 1.0) > 0.0:
                events.extend(self._miss(graph, graph.nodes[vid], session, stamp, weights.get(vid, 1.0), place))
        taker = {vid: obs[j] for j, vid in matched_obs.items()}  # the view each matched node took
        fresh: list[int] = []  # observations of objects the graph does not hold
        beside: list[int | None] = []  # per fresh one, a node whose view of this frame stood clear of it
        for j, o in enumerate(obs):
            if j in matched_obs or self._absorbed(o, near[j][0], taker):
                continue
            if o.truncated and (v := self.extents.touched_node(graph, o)) is not None \
                    and not (self.walls is not None and self.walls.between(v.footprint, o.box)):
                # a part of a known object, cut off by an occluder (see NodeExtents.touched_node), not
                # one across a wall (walls.Walls), unless it would make that object longer than its kind
                if self.extents.fits(graph, v, o):
                    events.extend(self._refresh(graph, v, o, session, stamp, restart=False, extend=True))
                continue
            vid = confusing_node(graph, o, matched_nodes, self.params.relabel_radius)
            if vid is not None:  # the detector's other name for a node, or another object in its place
                events.extend(self.replacements.note(graph, vid, o, session, stamp,
                                                     self.params.retracts(graph.nodes[vid])))
                if vid in graph.nodes:
                    continue
            fresh.append(j)
            beside.append(next((int(v) for v in near[j][0] if int(v) in taker), None))
        confirmed = self.tentative.confirm_frame([obs[j] for j in fresh], [self.gate(obs[j]) for j in fresh], stamp,
                                                 beside)
        placed: list[Node] = []  # nodes added or moved in this frame
        for k, j in enumerate(fresh):
            o = obs[j]
            if not confirmed[k] or near_any(o, placed, self.gate(o), graph.index.scale):
                continue
            moved = moves.removed_here(graph, o, self.gate(o), self.params, self.gone, self.withdrawn)
            events.append(self._move(graph, moved, o, session, stamp) if moved else graph.add(o, session, stamp))
            placed.append(graph.nodes[events[-1].node_id])
            if not moved:
                self.extents.grow(graph, placed[-1], o, self.gate(o))
                self.co_observed.add(placed[-1].id, self.tentative.beside_of[k])  # its first frame showed both
        # seen as two at once: the nodes placed and those matched, each by its own detection
        both = {v.id: v for v in placed} | {v: graph.nodes[v] for v in matched_nodes if v in graph.nodes}
        self.co_observed.note(both.values(), self.params.extent_gate * self.params.largest_distance())
        hidden = set(in_view or ()) - set(exp)
        events.extend(self._merge_hidden_duplicates(graph, pairs, matched_nodes, hidden, obs, session, stamp,
                                                    before))
        return events

    def _absorbed(self, o: Observation, near_ids: np.ndarray, taker: dict[int, Observation]) -> bool:
        """Whether the unmatched ``o`` is the object of a node near it that a closer view of
        this frame took (as in the paper); not when it lies beside each such view."""
        return len(near_ids) > 0 and not self.extents.beside(o, [taker[int(v)] for v in near_ids if int(v) in taker])

    def _near(self, graph: ObjectGraph, obs: Sequence[Observation], stamp: float
              ) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per observation: ids and squared distances of the nodes it may match (not those
        whose small object's footprint its view lies clear of: a neighbour, not the same;
        nor one whose colour tells it apart from the view's: another object in its place;
        nor one beside which a nearer sighting waits: :meth:`TentativeSightings.claims`)."""
        tolerance = self.params.colour_match_tolerance if self.params.colour_tolerance > 0.0 else 0.0
        gates = [self.gate(o) for o in obs]
        reaches = [max(self.extents.reach(o), g) for o, g in zip(obs, gates, strict=True)]
        boxes = [o.box for o in obs] if self.extents.boxes else None
        near = graph.index.within_many([o.category for o in obs], [o.position for o in obs], reaches, gates,
                                       boxes, self.params.footprint_overlap)
        out = []
        for o, g, (ids, d2) in zip(obs, gates, near, strict=True):
            keep = [not self.extents.separate(graph, graph.nodes[int(i)], o)
                    and not looks.looks_apart(graph.nodes[int(i)], o, tolerance)
                    and not self.tentative.claims(o, int(i), float(np.sqrt(d)), g, stamp)
                    for i, d in zip(ids, d2, strict=True)]
            out.append((ids, d2) if all(keep) else (ids[keep], d2[keep]))
        return out

    def _merge_hidden_duplicates(self, graph: ObjectGraph, pairs: list[Pair], matched: set[int], hidden: set[int],
                                 obs: Sequence[Observation], session: int, stamp: float,
                                 before: dict[int, tuple[np.ndarray | None, np.ndarray]]) -> list[Event]:
        """Fold into the matched node any same-category node that the same observation also
        covers: unmatched and either hidden (in view, not expected) or lying on the floor
        area the observation's own points cover.

        Two views of a big object from opposite sides can leave two nodes a little over
        delta_c apart; as their running averages converge, the second ends up *inside* the
        object, where the depth image hides it, so it is never expected and never missed.
        Likewise a sliver of a table seen past an obstacle can start a node at one end of
        a table whose node sits at the other. An observation that covers both settles it:
        the node an earlier pass had, else the one seen more often, keeps its id
        (:func:`~bomc_bt.graph.identity.keeper`; position averaged by observations), the
        other is removed. A node that was expected but unmatched and lies elsewhere is not
        touched: it may be a second object, and the miss count decides. Nor are two small
        nodes whose whole footprints lie apart (:meth:`NodeExtents.apart`): two chairs side by
        side, which a view bleeding over both covers; nor two nodes a frame of this pass or an
        earlier one matched at once (:mod:`bomc_bt.graph.co_observed`); nor two nodes an
        earlier pass kept apart that lie farther apart than one object reaches
        (:meth:`_reach_each_other`), whichever way the view covers them; nor, with
        ``separate_neighbours``, two whose footprints together are longer than one object of
        their category this pass (:func:`~bomc_bt.graph.parts.longer_than_one`): a table's
        view bled over the end of the table beside it.
        """
        events: list[Event] = []
        best: dict[int, int] = {}
        reference: dict[str, float] | None = None  # worked out at the first fold it may refuse
        for _, vid, j in pairs:  # sorted by distance: the observation each matched node got
            if vid in matched and j not in best.values() and vid not in best:
                best[vid] = j
        for vid, j in best.items():
            o, matched_node = obs[j], graph.nodes.get(vid)
            if matched_node is None:  # folded into another node earlier in this loop
                continue
            stood = before[vid][1]  # where the matched node stood before this view moved it
            covered = {w for w in self.extents.overlapped(graph, o)
                       if self._reach_each_other(graph, matched_node, stood, graph.nodes[w], o, session)}
            covered |= self._hidden_beside(graph, matched_node, stood, o, hidden, session)
            for oid in sorted(covered):
                v, other = graph.nodes.get(vid), graph.nodes.get(oid)
                if v is None or other is None or oid == vid or oid in matched or self.co_observed.seen_apart(vid, oid) \
                        or self.extents.separate(graph, other, o) or self.extents.apart(v, other, before[vid][0]):
                    continue
                if self.params.separate_neighbours:
                    reference = self.reference(graph, session) if reference is None else reference
                    if longer_than_one(v, other, reference, self.params.distance, BIG_MARGIN,
                                       self.params.footprint_touch):
                        continue
                keep, drop = keeper(v, other, session)
                total = max(keep.observations + drop.observations, 1)
                graph.relocate(keep, (keep.position * keep.observations + drop.position * drop.observations) / total)
                graph.add_observations(keep, drop.observations)
                graph.set_confidence(keep, max(keep.confidence, drop.confidence))
                self.extents.fold(graph, keep, drop)
                events.append(graph.remove(drop, session, stamp, merged_into=keep.id))  # never "moved" back
                events.append(graph.report("updated", keep, session, stamp))
                matched.add(keep.id)
        return events

    def reference(self, graph: ObjectGraph, session: int) -> dict[str, float]:
        """How long one object of each category is, by this pass's views (as when the pass ends)."""
        seen = [v for v in graph.nodes.values() if v.last_session == session]
        return reference_lengths(seen, self.extents.longest_whole(graph), self.params.distance, BIG_MARGIN)

    def _hidden_beside(self, graph: ObjectGraph, v: Node, stood: np.ndarray, o: Observation, hidden: set[int],
                       session: int) -> set[int]:
        """Hidden nodes within ``o``'s gate that ``o`` (matched by ``v``) may show to be ``v``'s
        object (:meth:`_reach_each_other`)."""
        return {w.id for w, _ in graph.within(o.category, o.position, self.gate(o))
                if w.id in hidden and self._reach_each_other(graph, v, stood, w, o, session)}

    def _reach_each_other(self, graph: ObjectGraph, v: Node, stood: np.ndarray, w: Node, o: Observation,
                          session: int) -> bool:
        """Whether ``v`` (at ``stood`` before ``o`` moved it) and ``w``, both covered by ``o``,
        may be one object by where they stand: two nodes that both an earlier pass kept apart
        must lie within ``o``'s gate of each other. A view covering two nodes farther apart
        than one object reaches is no evidence they are one: lab-b's two cabinets, 1.0 m
        apart, were folded by a far view whose centre fell between them; chairs 0.8 m apart at
        a table, by a view that covered both (Environment-A-size floor, seed 7272, pass 2). A
        node this pass started is judged by this pass's frames alone (a door's sliver seen
        once 0.8 m from the door's node still folds into it)."""
        if v.first_session >= session or w.first_session >= session:
            return True
        return dist2_scalar(w.position * graph.index.scale, stood * graph.index.scale) <= self.gate(o) ** 2

    def _refresh(self, graph: ObjectGraph, v: Node, o: Observation, session: int, stamp: float,
                 restart: bool | None = None, extend: bool = False) -> list[Event]:
        """Move ``v`` towards ``o`` and count it seen; the "updated" event if one is due."""
        w = self.params.position_smoothing
        first_in_session = v.last_session != session
        self.extents.grow(graph, v, o, self.gate(o), restart=first_in_session if restart is None else restart,
                          extend=extend)
        target = (1.0 - w) * v.position + w * o.position
        target[2] = bounded_height(o, v.position[2], target[2])
        if self.extents.is_big(v):  # the middle of the floor it covers, not of its visible faces
            target[:2] = (v.footprint[:2] + v.footprint[2:]) / 2.0
        graph.relocate(v, target)
        graph.set_confidence(v, max(v.confidence, float(o.confidence)))
        graph.touch(v, session, stamp)
        looks.blend(v, o.colour)
        if first_in_session or graph.drift_since_report(v) > self.params.report_distance:
            return [graph.report("updated", v, session, stamp)]
        return []

    def _miss(self, graph: ObjectGraph, v: Node, session: int, stamp: float, weight: float,
              place: np.ndarray | None) -> list[Event]:
        """Count a miss of the expected, unmatched ``v`` (weighing ``weight``, the robot at ``place``);
        its removal once the run weighs ``misses_needed`` and was seen from places ``miss_spacing`` apart
        (or an earlier pass ended with a look of its own: :meth:`~.evidence.MissEvidence.apart`)."""
        if not graph.miss(v, session, stamp, self.params.confirm_interval):
            return []
        run = graph.evidence.missed(v.id, weight, place, self._side(v, place))
        needed = self.misses_needed(graph, v)
        if run >= needed - 1e-9 and graph.evidence.apart(v.id, self.params.miss_spacing):
            since = self.params.contradicted(v, session, stamp)  # seen moments ago: it went nowhere, unless
            if since is not None and graph.evidence.sides_prove_absence(v.id):  # no views, or ones that never missed it
                since = None
            arrival = None if since is not None else moves.arrival_of(graph, v, session, self.params, self.gone)
            if arrival is not None:
                return self.moved_to(graph, v, arrival, session, stamp)
            twin = twin_of(graph, v, self.params.distance(v.category), self.co_observed.seen_apart)
            into = None if twin is None else twin.id  # a duplicate of the node there: no change
            retracted = into is None and (since is not None or self.params.retracts(v))
            event = graph.remove(v, session, stamp, merged_into=into, retracted=retracted)
            (self.withdrawn.add if retracted and since is not None else self.withdrawn.discard)(v.id)
            if v.id in self.withdrawn:
                event.detail["contradicted"] = round(since, 1)
            return [event]
        return []

    def moved_to(self, graph: ObjectGraph, v: Node, arrival: Node, session: int, stamp: float) -> list[Event]:
        """``v`` moved to where ``arrival`` stands: ``v`` keeps its id and takes the arrival's
        place, size and sightings; the arrival is folded into it (no change of its own)."""
        previous = v.position.copy()
        if v.state == REMOVED:  # paired when the pass ended (pair_relocations)
            graph.restore(v, arrival.position.copy())
        else:
            graph.relocate(v, arrival.position.copy())
        if self.extents.boxes:
            self.extents.adopt(graph, v, arrival)
        graph.add_observations(v, arrival.observations)
        graph.set_confidence(v, max(v.confidence, arrival.confidence))
        graph.touch(v, session, arrival.last_seen if arrival.last_seen is not None else stamp)
        if arrival.colour is not None:  # how it looks now
            v.colour = arrival.colour.copy()
        merged = graph.remove(arrival, session, stamp, merged_into=v.id)
        self._new_place(graph, v, previous)
        return [merged, graph.report("moved", v, session, stamp, previous)]

    def take_back_moves(self, graph: ObjectGraph, session: int, stamp: float,
                        history: Sequence[Event]) -> list[Event]:
        """When the pass ends: moves a neighbour found late undoes, taken back (:mod:`~bomc_bt.graph.pass_end`)."""
        return pass_end.take_back_moves(self, graph, session, stamp, history)

    def pair_relocations(self, graph: ObjectGraph, session: int, stamp: float,
                         candidate: Callable[[Node], bool], gone: Sequence[Node] = ()) -> list[Event]:
        """When the pass ends: parts joined, removals paired with additions (:mod:`~bomc_bt.graph.pass_end`)."""
        return pass_end.pair_relocations(self, graph, session, stamp, candidate, gone, self.withdrawn)

    def misses_needed(self, graph: ObjectGraph, v: Node) -> int:
        """Consecutive counted misses that remove ``v`` (:func:`~bomc_bt.graph.evidence.misses_needed`
        at ``v``'s own detection rate, or its run's sides' when lower: :mod:`~bomc_bt.graph.view_sides`)."""
        p = self.params
        rate = graph.evidence.run_rate(v.id, p.detection_prior, p.detection_prior_weight)
        return misses_needed(rate, p.detection_prior, p.confirm_misses, p.max_misses)

    def _side(self, v: Node, place: np.ndarray | None) -> int | None:
        """The viewing side of ``v`` the robot at ``place`` sees it from (None: unknown or not kept)."""
        return None if place is None or not self.params.miss_sides else side_of(v.position, place,
                                                                                self.params.miss_sides)

    def _move(self, graph: ObjectGraph, v: Node, o: Observation, session: int, stamp: float) -> Event:
        """``v`` moved to where ``o`` saw it: same id, a "moved" event with where it was."""
        previous = v.position.copy()
        if v.state == REMOVED:
            graph.restore(v, o.position.copy())
        else:
            graph.relocate(v, o.position.copy())
        if self.extents.boxes:  # where it stood before says nothing about its size here
            self.extents.restart(graph, v, o)
        graph.set_confidence(v, float(o.confidence))
        graph.touch(v, session, stamp)
        looks.blend(v, o.colour)
        self._new_place(graph, v, previous)
        return graph.report("moved", v, session, stamp, previous)

    def _new_place(self, graph: ObjectGraph, v: Node, previous: np.ndarray) -> None:
        """Where ``v`` was missed from at its old place says nothing about its new one, unless
        it is the same place (a node removed and found again where it stood)."""
        moved = float(np.hypot(*(v.position[:2] - previous[:2])))
        if graph.evidence.sides is not None and moved > self.params.distance(v.category):
            graph.evidence.sides.forget(v.id)
