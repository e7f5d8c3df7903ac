"""Net changes: what changed per node between two points of the history, with the evidence.

A monitor pass writes raw events frame by frame (a node may be removed when its misses are
counted and found again a few seconds later); an operator wants to know what is different
now from before. :func:`net_changes` replays the history to both ends of a period and
compares each node that had an event in it:

* absent -> present: ``added``; present -> absent: ``removed``, at the position the node
  had when the period began: that is the object the map showed and that is gone. A removed
  node the pass revived once elsewhere (a neighbour's detection taken for it moved) and
  removed again reports the place the operator knew, not the neighbour's;
  present -> present farther than ``threshold(category)`` along the floor, not counting
  shifts the pass marked as its footprint growing (:mod:`bomc_bt.graph.refinement`): ``moved``;
* anything else (removed and found again, moved away and back, a nudge) is no change;
* a node folded into another as a duplicate (a removal with ``merged_into``) is no change
  either: the object is still there, under the other node's id;
* absent -> present where the node's addition in the period was marked first seen (no
  earlier pass had seen that place, :mod:`bomc_bt.first_seen`; the mark of the event that
  added it, or the verdict the pass end wrote for its final place): ``first_seen``,
  new to the map and not a change. It is listed apart and is no change an evaluation
  scores. From the empty map (``since=None``) every new node is ``added``;
* present -> absent where the removal was marked retracted (the node had been matched in
  only a few frames in all, ``association.retract_observations``, or missed moments after the
  same pass saw it, ``association.retract_within``): ``retracted``, the map
  withdrawing sightings it no longer trusts, not an object that went. Listed apart like
  first-seen nodes, and no change an evaluation scores.

Each :class:`NetChange` carries its evidence: for a removal the frames that counted the
object missing before it was taken off and when it was last seen; for a move how far it
went; for every change how many raw events were behind it. The session report, the
viewer's difference of two sessions, the ROS summary at the end of a pass and ``bomc
evaluate``'s change scores all use this one function.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bomc_bt.first_seen import SIGHTED_IN, UNSEEN_SIDES, verdicts
from bomc_bt.graph import Event
from bomc_bt.graph.brought_back import back_of
from bomc_bt.graph.refinement import refined_shifts

NET_KINDS = ("removed", "added", "moved")  # the changes
FIRST_SEEN = "first_seen"  # a node new to the map where no earlier pass looked: not a change
RETRACTED = "retracted"  # a node seen too seldom to trust, dropped: not a change
REPORTED_KINDS = (*NET_KINDS, FIRST_SEEN, RETRACTED)  # what net_changes returns, in its order


@dataclass
class NetChange:
    """One node's change over a period. ``old`` is None for an addition, ``new`` for a removal."""

    kind: str  # "removed" | "added" | "moved" | "first_seen" | "retracted"
    node_id: int
    category: str
    old: np.ndarray | None  # where it stood when the period began
    new: np.ndarray | None  # where it stands at the end
    distance: float  # m, old to new (0 unless moved)
    missing_frames: int | None  # a removal: frames that counted it missing (None: not recorded)
    last_seen: float | None  # a removal: robot time the pass last saw it (None: not in that pass)
    session: int  # the session of the node's last event in the period (where last_seen is measured)
    stamp: float  # robot time of that event
    events: int  # raw events of the node in the period
    merged: bool = False  # a removal: folded into a neighbour of its category whose id is not recorded
    back_of: int | None = None  # an addition: the node an earlier pass saw go from here (graph.brought_back)
    # first seen: why it is new to the map -- "unseen" (no earlier pass saw the place), "edge_on"
    # (earlier passes looked at it only edge-on: bomc_bt.looked_sides), "sighted" (the previous
    # pass had detected it there: bomc_bt.sightings); None for the other kinds
    first_seen_why: str | None = None

    def to_json(self) -> dict[str, Any]:
        """A JSON-able dict (positions and times rounded to cm and 0.1 s)."""
        def xyz(p):
            return None if p is None else [round(float(v), 2) for v in p]

        return {"kind": self.kind, "node": self.node_id, "category": self.category, "old": xyz(self.old),
                "new": xyz(self.new), "distance_m": round(self.distance, 2), "missing_frames": self.missing_frames,
                "last_seen_s": None if self.last_seen is None else round(self.last_seen, 1),
                "session": self.session, "stamp_s": round(self.stamp, 1), "events": self.events,
                "merged": self.merged, "back_of": self.back_of, "first_seen_why": self.first_seen_why}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> NetChange:
        """Back from :meth:`to_json` (a report read again, the viewer)."""
        def xyz(p):
            return None if p is None else np.array(p, dtype=float)

        return cls(d["kind"], int(d["node"]), d["category"], xyz(d["old"]), xyz(d["new"]), float(d["distance_m"]),
                   d["missing_frames"], d["last_seen_s"], int(d["session"]), float(d["stamp_s"]), int(d["events"]),
                   bool(d.get("merged", False)), d.get("back_of"), d.get("first_seen_why"))

    def describe(self) -> str:
        """One line an operator reads: what, where, and why we think so."""
        def at(p):
            return f"({p[0]:.2f}, {p[1]:.2f})"

        what = f"{self.category} #{self.node_id}"
        if self.kind == "added":
            back = "" if self.back_of is None else f", back where #{self.back_of} went"
            text = f"added {what} at {at(self.new)}{back}"
        elif self.kind == FIRST_SEEN:
            because = NEW_BECAUSE.get(self.first_seen_why or "unseen", NEW_BECAUSE["unseen"])
            text = f"first seen {what} at {at(self.new)} ({because})"
        elif self.kind == "moved":
            text = f"moved {what} {at(self.old)} -> {at(self.new)}, {self.distance:.2f} m"
        elif self.kind == RETRACTED:
            then = "" if self.last_seen is None else (
                f", or seen t={self.last_seen:.1f} s and missing {self.stamp - self.last_seen:.1f} s later: "
                "a sighting that depends on the view")
            text = f"retracted {what} at {at(self.old)} (seen in too few frames to trust{then}; no object seen since)"
        else:
            seen = "not seen this pass" if self.last_seen is None else f"last seen t={self.last_seen:.1f} s"
            frames = "" if self.missing_frames is None else f"missing in {self.missing_frames} frames, "
            text = f"removed {what} at {at(self.old)} ({frames}{seen})"
        return text + ("" if self.events <= 1 else f" [{self.events} raw events]")


# what a first-seen node's report line says for each ``first_seen_why``
NEW_BECAUSE = {"unseen": "no earlier pass saw this place",
                "edge_on": "earlier passes looked at this place only edge-on to it",
                "sighted": "the previous pass had detected it here"}


def first_seen_why(detail: dict) -> str:
    """Why a verdict's ``detail`` calls its node first seen (:attr:`NetChange.first_seen_why`)."""
    return "edge_on" if UNSEEN_SIDES in detail else "sighted" if SIGHTED_IN in detail else "unseen"


def _replay(events: Sequence[Event]) -> dict[int, Event]:
    """The last event of each node: its state (removed or present) and position."""
    last: dict[int, Event] = {}
    for e in events:
        last[int(e.node_id)] = e
    return last


def net_changes(events: Sequence[Event], since: int | None,
                threshold: Callable[[str], float]) -> list[NetChange]:
    """The net change of every node over the sessions after ``since``, by kind then node id.

    ``events``: the history in write order up to the end of the period (the store's
    ``events(until=N)``); events of sessions up to ``since`` give the state the period
    starts from (``since=None``: the empty map). ``threshold(category)``: how far a node
    must have gone to have moved (the association distance: less is the same place).
    """
    before = _replay([e for e in events if since is not None and e.session <= since])
    period = [e for e in events if since is None or e.session > since]
    after = _replay(period)
    refined, back = refined_shifts(period), back_of(period)
    counts: dict[int, int] = {}
    for e in period:
        counts[int(e.node_id)] = counts.get(int(e.node_id), 0) + 1
    new_to_map = {nid: d for nid, d in verdicts(period).items() if d.get(FIRST_SEEN)} if since is not None else {}
    out = []
    for nid in sorted(after):
        b, a = before.get(nid), after[nid]
        was, now = b is not None and b.kind != "removed", a.kind != "removed"
        pos = np.asarray(a.position, dtype=float)
        if was and now:
            old = np.asarray(b.position, dtype=float)
            # along the floor: a centroid's height follows how much of the object the camera
            # saw (a door's top cut off by the image edge), not where the object stands
            distance = float(np.hypot(*(pos[:2] - old[:2])))
            went = pos[:2] - old[:2] - refined.get(nid, np.zeros(2))  # a refinement is no move
            if float(np.hypot(*went)) > threshold(a.category):
                out.append(NetChange("moved", nid, a.category, old, pos, distance, None, None, a.session,
                                     a.stamp, counts[nid]))
        elif was and a.merged_into is None:
            kind = RETRACTED if a.retracted else "removed"
            out.append(NetChange(kind, nid, a.category, np.asarray(b.position, dtype=float), None, 0.0, a.misses,
                                 a.last_seen, a.session, a.stamp, counts[nid],
                                 bool((a.detail or {}).get("merged", False))))
        elif now and not was:
            why = first_seen_why(new_to_map[nid]) if nid in new_to_map else None
            out.append(NetChange("added" if why is None else FIRST_SEEN, nid, a.category, None, pos, 0.0, None, None,
                                 a.session, a.stamp, counts[nid], back_of=back.get(nid), first_seen_why=why))
    return sorted(out, key=lambda c: (REPORTED_KINDS.index(c.kind), c.node_id))


def summarize(changes: Sequence[NetChange]) -> dict[str, int]:
    """How many net changes of each kind (every kind listed; first-seen nodes are no change:
    :func:`first_seen_count`)."""
    return {k: sum(c.kind == k for c in changes) for k in NET_KINDS}


def first_seen_count(changes: Sequence[NetChange]) -> int:
    """How many of ``changes`` are nodes new to the map (``first_seen``)."""
    return sum(c.kind == FIRST_SEEN for c in changes)


def retracted_count(changes: Sequence[NetChange]) -> int:
    """How many of ``changes`` are nodes the map withdrew (``retracted``): no object went."""
    return sum(c.kind == RETRACTED for c in changes)


def only_changes(changes: Sequence[NetChange]) -> list[NetChange]:
    """The changes among ``changes``: first-seen and retracted nodes left out (not changes)."""
    return [c for c in changes if c.kind in NET_KINDS]
