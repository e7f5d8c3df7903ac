"""Change evaluation: did a monitor pass report what really changed since the previous pass?

The object protocol (:mod:`bomc_bt.evaluation`) scores the map at the end of a pass; an
operator runs passes to learn *what changed*. This module compares the changes a pass
reported with the changes that really happened, between the end of the previous recorded
pass and the end of this one (issue 17, item 1).

**True changes** (from the world's timeline, objects keyed by name): an object present
only after is ``added``, one present only before is ``removed``, one present in both and
displaced by more than its category's association distance is ``moved`` (a nudge smaller
than that is not a change the map can show). An object that disappears and comes back
under the same name in another category counts as removed plus added.

**Net changes** (from the store, nodes keyed by id; :mod:`bomc_bt.net_changes`, the same
the session report shows the operator): only nodes with an event in the pass are looked
at, and only their state at the two ends counts, so a node removed and re-added (or moved
away and back) within the pass is no change at all, nor is a duplicate merged into
another node. present -> absent is ``removed`` (at the node's position when the pass began, the
object the map showed), absent -> present is ``added``, present -> present displaced by more than the
association distance is ``moved``.

**Matching**, per kind and category, one-to-one, the object protocol's maximum matching
within the association distance: a removal on the removed object's old position, an
addition on the added object's position, a move on its new position *and* its old one.
Unmatched net changes are false positives, unmatched true changes false negatives; scores
as in the object protocol (None where undefined). A move the map reported as a removal
plus an addition earns no credit: one fn ``moved``, one fp ``removed``, one fp ``added``
-- the operator was told an object vanished and another appeared, not that it moved.
``overall`` sums the three kinds.

**Phantoms** are the false positives with no real change behind them at all: no true
change of the same category, of any kind, matched or not, has an end (old or new
position) within the association distance of an end of the reported change. A move
reported as removal plus addition, or a real removal reported twice, is wrong but not a
phantom; a removal where nothing changed (a duplicate node cleaned up, an object the
robot failed to see) is.

**Late**: a false positive that reports a true change of the *previous* pass, one that
pass missed (a chair taken away during pass N-1 after the robot had looked there, seen
gone in pass N), has a real change behind it: it is wrong for this pass (a false
positive) but no phantom, and is counted apart (``late``). The miss stays counted in the
previous pass. The first pass has no previous one: what it missed was no change in the
building, so nothing reported after it is late on that account. A change undone within
the previous pass (below) is late too when this pass reports its second half (a bin
brought in and seen, then taken away after the robot had looked: this pass finds it gone).
Changes the previous pass's net result shows are not: they were that pass's to report.

**Transient**: a false positive that reports a change undone before the pass ended (a bin
brought in when the session began and taken away during the pass, after the robot had
looked there) reports what the building really did, only not its net result: wrong
(a false positive), but no phantom, counted apart (``transient``). What the world did
between the end of the previous pass and the end of this one that it no longer shows
(:func:`undone_changes`) explains it.

Session 1 has no previous pass: it is scored against the empty map, so every object
present when it ended is an addition and ``added`` reads like the object protocol.

**Retracted**: a node the map drops after it was matched in only a few frames in all
(:mod:`bomc_bt.net_changes`) reports no object going; like a first-seen node it is counted
apart (``retracted``) and neither a true nor a false positive. A true removal of such a
node stays a miss.

**First seen**: a node added where no earlier pass had looked (:mod:`bomc_bt.first_seen`)
is new to the map, not a change the pass predicts: it is neither a true positive nor a
false one, only counted (``first_seen``). A true addition at such a place stays a miss:
nothing could have told it from an object that was always there. Against the empty map
(session 1) nothing is first seen, so session 1's scores are as before.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from bomc_bt.evaluation import ClassScores, match_pairs, scores
from bomc_bt.graph import EVENT_KINDS, Event
from bomc_bt.net_changes import first_seen_count as count_first_seen
from bomc_bt.net_changes import net_changes, only_changes, retracted_count

CHANGE_KINDS = ("removed", "added", "moved")
Threshold = Callable[[str], float]


@dataclass(eq=False)
class ObjectChange:
    """One object's change between two passes: a true one (``key`` = object name) or one
    the map reported (``key`` = node id). ``old`` is None for an addition, ``new`` for a removal."""

    kind: str
    key: str | int
    category: str
    old: np.ndarray | None
    new: np.ndarray | None

    def ends(self) -> np.ndarray:
        """(k, 3) the positions this change touches (old and/or new)."""
        return np.array([p for p in (self.old, self.new) if p is not None], dtype=float).reshape(-1, 3)


@dataclass
class ChangeMatch:
    """A true positive: node ``node_id``'s reported change explains object ``name``'s."""

    kind: str
    node_id: int
    name: str
    category: str
    distance: float  # for a move: the distances of both ends added


@dataclass
class ChangeResult:
    session: int
    previous: int | None  # the pass compared against (None: the empty map before session 1)
    kinds: dict[str, ClassScores]  # gt = true changes, mapped = net changes of that kind
    overall: ClassScores
    phantom: int
    raw_events: dict[str, int]  # the store's events of the pass, before netting
    matches: list[ChangeMatch] = field(default_factory=list)
    missed: list[ObjectChange] = field(default_factory=list)  # false negatives
    wrong: list[ObjectChange] = field(default_factory=list)  # false positives, phantoms included
    phantoms: list[ObjectChange] = field(default_factory=list)
    late: list[ObjectChange] = field(default_factory=list)  # false positives reporting the previous pass's misses
    transient: list[ObjectChange] = field(default_factory=list)  # false positives reporting changes undone in the pass
    first_seen: int = 0  # nodes new to the map where no earlier pass looked: reported apart, not scored
    retracted: int = 0  # nodes dropped as seen too seldom to trust: reported apart, not scored


def _xyz(p) -> np.ndarray:
    return np.asarray(p, dtype=float).reshape(3)


def _displaced(a: np.ndarray, b: np.ndarray, limit: float) -> bool:
    return bool(np.linalg.norm(a - b) > limit)


def true_changes(before: Mapping[str, tuple[str, np.ndarray]], after: Mapping[str, tuple[str, np.ndarray]],
                 threshold: Threshold) -> list[ObjectChange]:
    """The world's changes from ``before`` to ``after`` ({name: (category, position)})."""
    out: list[ObjectChange] = []
    for name in sorted(set(before) | set(after)):
        b, a = before.get(name), after.get(name)
        if b is not None and a is not None and b[0] == a[0]:
            old, new = _xyz(b[1]), _xyz(a[1])
            if _displaced(old, new, threshold(a[0])):
                out.append(ObjectChange("moved", name, a[0], old, new))
            continue
        if b is not None:
            out.append(ObjectChange("removed", name, b[0], _xyz(b[1]), None))
        if a is not None:
            out.append(ObjectChange("added", name, a[0], None, _xyz(a[1])))
    return out


def undone_changes(states: Sequence[Mapping[str, tuple[str, np.ndarray]]], threshold: Threshold) -> list[ObjectChange]:
    """What the world did between the first and the last of ``states`` that the last one no
    longer shows: each change from one state to the next, kept only at its ends where the
    object (under its name and category) stood neither in the first state nor in the last
    (a bin brought in and taken away again; the middle stop of a chair moved twice)."""
    first, last = states[0], states[-1]

    def undone(name: str, category: str, p: np.ndarray | None) -> np.ndarray | None:
        held = [s[name][1] for s in (first, last) if name in s and s[name][0] == category]
        return None if p is None or any(np.array_equal(p, h) for h in held) else p

    out = []
    for a, b in zip(states[:-1], states[1:], strict=True):
        for c in true_changes(a, b, threshold):
            old, new = undone(str(c.key), c.category, c.old), undone(str(c.key), c.category, c.new)
            if old is not None or new is not None:
                out.append(ObjectChange(c.kind, c.key, c.category, old, new))
    return out


def reported_changes(events: Sequence[Event], since: int | None, threshold: Threshold) -> list[ObjectChange]:
    """The map's net changes over the passes after ``since`` (:func:`bomc_bt.net_changes.net_changes`),
    as :class:`ObjectChange` records keyed by node id; ``events``: the history up to the pass's end.
    First-seen nodes are no predicted change and are left out (:func:`first_seen_count`)."""
    return [ObjectChange(c.kind, c.node_id, c.category, c.old, c.new)
            for c in only_changes(net_changes(events, since, threshold))]


def first_seen_count(events: Sequence[Event], since: int | None, threshold: Threshold) -> int:
    """How many nodes the passes after ``since`` found new to the map (not scored as changes)."""
    return count_first_seen(net_changes(events, since, threshold))


def retracted_nodes(events: Sequence[Event], since: int | None, threshold: Threshold) -> int:
    """How many nodes the passes after ``since`` withdrew as seen too seldom (not scored as changes)."""
    return retracted_count(net_changes(events, since, threshold))


def raw_event_counts(events: Sequence[Event]) -> dict[str, int]:
    """How many events of each kind the pass wrote (every kind listed, zeros included)."""
    counts = dict.fromkeys(EVENT_KINDS, 0)
    for e in events:
        counts[e.kind] = counts.get(e.kind, 0) + 1
    return counts


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2))


def _pairs(kind: str, net: list[ObjectChange], truth: list[ObjectChange], radius: float):
    """The protocol's one-to-one matching of one kind and category, gated as the module says."""
    if not net or not truth:
        return []
    end = "old" if kind == "removed" else "new"
    dist = _distances(np.array([getattr(c, end) for c in net]), np.array([getattr(c, end) for c in truth]))
    edges = dist <= radius
    if kind == "moved":
        before = _distances(np.array([c.old for c in net]), np.array([c.old for c in truth]))
        edges &= before <= radius
        dist = dist + before
    return match_pairs(dist, edges)


def _phantoms(wrong: list[ObjectChange], truth: list[ObjectChange], threshold: Threshold) -> list[ObjectChange]:
    """The false positives no true change of their category comes near (see the module docstring)."""
    out = []
    for cat in sorted({c.category for c in wrong}):
        cat_wrong = [c for c in wrong if c.category == cat]
        ends = [c.ends() for c in truth if c.category == cat]
        if not ends:
            out.extend(cat_wrong)
            continue
        true_ends = np.concatenate(ends)
        owner = np.concatenate([np.full(len(c.ends()), i) for i, c in enumerate(cat_wrong)])
        near = (_distances(np.concatenate([c.ends() for c in cat_wrong]), true_ends) <= threshold(cat)).any(axis=1)
        explained = set(owner[near].tolist())
        out.extend(c for i, c in enumerate(cat_wrong) if i not in explained)
    return out


def score_changes(truth: Sequence[ObjectChange], net: Sequence[ObjectChange], threshold: Threshold,
                  session: int, previous: int | None = None,
                  raw_events: Mapping[str, int] | None = None,
                  missed_before: Sequence[ObjectChange] = (), undone: Sequence[ObjectChange] = ()) -> ChangeResult:
    """Match the map's net changes to the true ones and score them per kind.

    ``missed_before``: the true changes the previous pass missed (and those undone within
    it), which make a false positive near them late rather than a phantom; ``undone``: the
    changes undone within this pass's span (:func:`undone_changes`), which make one
    transient."""
    kinds: dict[str, ClassScores] = {}
    matches: list[ChangeMatch] = []
    missed: list[ObjectChange] = []
    wrong: list[ObjectChange] = []
    for kind in CHANGE_KINDS:
        tp = 0
        kind_truth = [c for c in truth if c.kind == kind]
        kind_net = [c for c in net if c.kind == kind]
        for cat in sorted({c.category for c in kind_truth} | {c.category for c in kind_net}):
            t = [c for c in kind_truth if c.category == cat]
            m = [c for c in kind_net if c.category == cat]
            pairs = _pairs(kind, m, t, float(threshold(cat)))
            matches.extend(ChangeMatch(kind, int(m[a].key), str(t[b].key), cat, d) for a, b, d in pairs)
            wrong.extend(c for i, c in enumerate(m) if i not in {a for a, _, _ in pairs})
            missed.extend(c for i, c in enumerate(t) if i not in {b for _, b, _ in pairs})
            tp += len(pairs)
        kinds[kind] = scores(len(kind_truth), len(kind_net), tp)
    overall = scores(sum(s.gt for s in kinds.values()), sum(s.mapped for s in kinds.values()),
                     sum(s.tp for s in kinds.values()))
    unexplained = _phantoms(wrong, list(truth), threshold)
    lasting = _phantoms(unexplained, list(undone), threshold)
    phantoms = _phantoms(lasting, list(missed_before), threshold)
    return ChangeResult(session, previous, kinds, overall, len(phantoms), dict(raw_events or {}),
                        matches, missed, wrong, phantoms, _others(lasting, phantoms), _others(unexplained, lasting))


def _others(changes: list[ObjectChange], but: list[ObjectChange]) -> list[ObjectChange]:
    return [c for c in changes if all(c is not b for b in but)]
