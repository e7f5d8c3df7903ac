"""Read-only questions to a finished site: which objects, where, since when, what changed.

:func:`open_site` opens the site's store read-only (:mod:`bomc_bt.store_schema`): it takes
no lock, writes no byte and works on a site nobody may write, beside a running pass.

* :meth:`SiteReader.objects` -- the objects as they stand now (the node table, the
  operator's edits included) or at the end of session N (the history replayed), filtered
  by category and distance from a point. ``sessions_seen`` are the sessions with an
  added / updated / moved event of the node (robust mode reports every session that
  matched it; paper mode never updates, so there it is the session that added it).
* :meth:`SiteReader.changes` -- the net change of each node over each pass, as ``bomc
  evaluate`` computes it (:func:`bomc_bt.change_evaluation.net_changes`: a node removed
  and found again within one pass is no change), with the evidence: for a removal the
  frames that saw it missing (counted misses, at most one per
  ``association.confirm_interval``; paper mode removes on the first; None on a site
  recorded before store schema 3), for every change when the node was last seen (its
  latest *recorded* sighting: the history keeps a node's first sighting in each pass and
  every drift over ``association.report_distance``, not every match), for a move how far
  it went (planar, m); and the operator's edits that took effect in the pass.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.graph import AssociationParams, Event, Node
from bomc_bt.net_changes import net_changes
from bomc_bt.site.layout import Site
from bomc_bt.store import SessionRecord, SiteStore

SEEN_KINDS = ("added", "updated", "moved")


@dataclass(frozen=True)
class SiteObject:
    """One object of the map. Positions in the map frame (m); sessions by number."""

    id: int
    category: str
    position: tuple[float, float, float]
    confidence: float  # [-] the best detector score seen
    first_seen: int
    last_seen: int
    sessions_seen: tuple[int, ...]
    notes: tuple[str, ...] = ()  # the operator's notes, oldest first
    distance: float | None = None  # [m] from the --near point, when one was given

    def to_json(self) -> dict[str, Any]:
        out = {"id": self.id, "category": self.category, "position": [round(v, 3) for v in self.position],
               "confidence": round(self.confidence, 3), "first_seen": self.first_seen,
               "last_seen": self.last_seen, "sessions_seen": list(self.sessions_seen), "notes": list(self.notes)}
        if self.distance is not None:
            out["distance"] = round(self.distance, 3)
        return out


@dataclass(frozen=True)
class NodeChange:
    """A node's net change over one pass, with the evidence for it."""

    session: int
    kind: str  # "added" | "removed" | "moved" | "first_seen" (new where no pass looked) | "retracted"
    node_id: int
    category: str
    old: tuple[float, float, float] | None  # where it was (None: added)
    new: tuple[float, float, float] | None  # where it is (None: removed)
    last_seen_session: int | None  # the node's latest sighting up to the end of the pass
    last_seen_stamp: float | None  # [s] robot time of that sighting
    missing_frames: int | None = None  # removals: frames that saw it missing (None: not recorded)
    merged: bool = False  # removals: folded into a neighbouring node of its category (a duplicate)
    moved_m: float | None = None  # [m] moves: planar distance between the two ends
    back_of: int | None = None  # additions: the node an earlier pass saw go from this place (brought back)
    first_seen_why: str | None = None  # first seen: "unseen", "edge_on" or "sighted" (net_changes.NetChange)

    def to_json(self) -> dict[str, Any]:
        def xyz(p):
            return None if p is None else [round(v, 3) for v in p]

        return {"session": self.session, "kind": self.kind, "id": self.node_id, "category": self.category,
                "old": xyz(self.old), "new": xyz(self.new), "last_seen_session": self.last_seen_session,
                "last_seen_stamp": None if self.last_seen_stamp is None else round(self.last_seen_stamp, 3),
                "missing_frames": self.missing_frames, "merged": self.merged,
                "moved_m": None if self.moved_m is None else round(self.moved_m, 3), "back_of": self.back_of,
                "first_seen_why": self.first_seen_why}


@dataclass(frozen=True)
class OperatorEdit:
    """One correction by the operator (``bomc edit``), filed under the pass it took effect in."""

    session: int
    kind: str  # "relabelled" | "deleted" | "restored" | "noted"
    node_id: int
    category: str
    detail: dict[str, Any]

    def to_json(self) -> dict[str, Any]:
        return {"session": self.session, "kind": self.kind, "id": self.node_id, "category": self.category,
                **self.detail}


@dataclass
class SessionChanges:
    """What pass ``session`` changed since pass ``previous`` (None: the empty map)."""

    session: int
    previous: int | None
    changes: list[NodeChange] = field(default_factory=list)
    edits: list[OperatorEdit] = field(default_factory=list)
    pending: bool = False  # the pass has not run yet: only the operator's edits waiting for it

    def to_json(self) -> dict[str, Any]:
        return {"session": self.session, "previous_session": self.previous, "pending": self.pending,
                "changes": [c.to_json() for c in self.changes], "edits": [e.to_json() for e in self.edits]}


def open_site(root: str | Path, association: AssociationParams | None = None) -> SiteReader:
    """A read-only view of the site in ``root`` (a :class:`BomcError` when there is none)."""
    return SiteReader(root, association)


class SiteReader:
    """Queries on one site's object graph; use as a context manager, or :meth:`close` it."""

    def __init__(self, root: str | Path, association: AssociationParams | None = None):
        root = Path(root)
        if not root.is_dir():
            raise BomcError("not a site directory", root)
        self.site = Site(root)
        if not self.site.store_path.is_file():
            raise BomcError("no object graph here: run `bomc monitor` first", self.site.store_path)
        self.association = association or AssociationParams()
        self.store = SiteStore(self.site.store_path, readonly=True)
        self._sessions = {s.number: s for s in self.store.sessions()}
        self._graphs: dict[int, list[Node]] = {}  # graph_after, replayed once per session

    def close(self) -> None:
        self.store.close()

    def __enter__(self) -> SiteReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ sessions
    def sessions(self) -> list[SessionRecord]:
        """The recorded passes, by number."""
        return [self._sessions[n] for n in sorted(self._sessions)]

    def categories(self) -> list[str]:
        """Every category a node of this site ever had."""
        return self.store.categories()

    def require_session(self, number: int, option: str = "--session") -> None:
        if number not in self._sessions:
            known = ", ".join(map(str, sorted(self._sessions))) or "none"
            raise BomcError(f"session {number} was not recorded (recorded: {known})", self.site.store_path, option)

    # ------------------------------------------------------------------- objects
    def objects(self, session: int | None = None, category: str | None = None,
                near: tuple[float, float] | None = None, radius: float = 2.0) -> list[SiteObject]:
        """The present objects now, or at the end of ``session``; of ``category``; within
        ``radius`` m of ``near`` (x, y) in the map frame, then nearest first, else by id."""
        check_near(near, radius)
        if session is not None:
            self.require_session(session)
        if category is not None and category not in self.categories():
            raise BomcError(f"no object of category {category!r} on this site (categories: "
                            f"{', '.join(self.categories()) or 'none'})", self.site.root, "--category")
        nodes = self.store.nodes() if session is None else self.store.graph_after(session)
        history = self.store.events(until=session, operator=True)
        seen: dict[int, set[int]] = defaultdict(set)
        notes: dict[int, list[str]] = defaultdict(list)
        for e in history:
            if e.kind in SEEN_KINDS:
                seen[e.node_id].add(e.session)
            elif e.kind == "noted" and e.detail:
                notes[e.node_id].append(str(e.detail.get("text", "")))
        out = []
        for n in nodes:
            if category is not None and n.category != category:
                continue
            distance = None if near is None else math.hypot(n.position[0] - near[0], n.position[1] - near[1])
            if distance is not None and distance > radius:
                continue
            out.append(_site_object(n, seen[n.id], notes[n.id], distance))
        return sorted(out, key=lambda o: (o.distance, o.id)) if near is not None else out

    # ------------------------------------------------------------------- changes
    def changes(self, since: int | None = None, until: int | None = None) -> list[SessionChanges]:
        """Per recorded pass after ``since`` up to ``until`` (both session numbers, both
        optional): each node's net change over the pass and the operator's edits; last,
        unless ``until`` is given, the edits waiting for the next pass (``pending``)."""
        last = max(self._sessions, default=None)
        if last is None:
            return []
        for value, option in ((since, "--since"), (until, "--until")):
            if value is not None and not 0 <= value <= last:
                raise BomcError(f"must be a session number from 0 to {last} (the last recorded)",
                                self.site.store_path, option)
        if since is not None and until is not None and since >= until:
            raise BomcError(f"--since {since} must be before --until {until}", self.site.store_path, "--since")
        chosen = [n for n in sorted(self._sessions)
                  if (since is None or n > since) and (until is None or n <= until)]
        history = self.store.events(operator=True)
        out = [self._session_changes(n, history) for n in chosen]
        waiting = [OperatorEdit(e.session, e.kind, e.node_id, e.category, dict(e.detail or {}))
                   for e in history if e.by_operator and e.session > last]
        if waiting and until is None:  # edits filed for the next pass, which has not run
            out.append(SessionChanges(waiting[0].session, last, [], waiting, pending=True))
        return out

    def _session_changes(self, session: int, history: list[Event]) -> SessionChanges:
        previous = max((n for n in self._sessions if n < session), default=None)
        robot = [e for e in history if e.session <= session and not e.by_operator]
        out = SessionChanges(session, previous)
        sightings = _last_sightings(robot)
        for c in net_changes(robot, previous, self.association.distance):
            seen = sightings.get(c.node_id)
            merged = c.kind == "removed" and bool(c.merged)
            moved = c.distance if c.kind == "moved" else None
            out.changes.append(NodeChange(
                session, c.kind, c.node_id, c.category, _tuple(c.old), _tuple(c.new),
                None if seen is None else seen.session, None if seen is None else seen.stamp,
                c.missing_frames, merged, moved, c.back_of, c.first_seen_why))
        out.edits = [OperatorEdit(e.session, e.kind, e.node_id, e.category, dict(e.detail or {}))
                     for e in history if e.session == session and e.by_operator]
        return out

    def _graph_after(self, session: int) -> list[Node]:
        if session not in self._graphs:
            self._graphs[session] = self.store.graph_after(session)
        return self._graphs[session]


def check_near(near: tuple[float, float] | None, radius: float) -> None:
    """A finite point and a positive, finite radius (m), or a one-line error."""
    if near is not None and (len(near) != 2 or not all(math.isfinite(float(v)) for v in near)):
        raise BomcError(f"must be two finite numbers X,Y (m), got {near!r}", None, "--near")
    if not (math.isfinite(radius) and radius > 0):
        raise BomcError(f"must be a positive number of metres, got {radius!r}", None, "--radius")


def _site_object(n: Node, seen: set[int], notes: list[str], distance: float | None) -> SiteObject:
    sessions = tuple(sorted(seen | {n.first_session, n.last_session}))
    return SiteObject(int(n.id), n.category, _tuple(n.position), float(n.confidence), int(n.first_session),
                      int(n.last_session), sessions, tuple(notes), distance)


def _last_sightings(events: list[Event]) -> dict[int, Event]:
    """Per node, its latest added / updated / moved event among ``events``, leaving out the
    rows an ended session writes to reconcile positions (stamped with the pass's end)."""
    out: dict[int, Event] = {}
    for e in events:
        if e.kind in SEEN_KINDS and not (e.detail or {}).get("reconciled"):
            out[e.node_id] = e
    return out


def _tuple(p: np.ndarray | None) -> tuple[float, float, float] | None:
    return None if p is None else tuple(float(v) for v in np.asarray(p, dtype=float).reshape(3))
