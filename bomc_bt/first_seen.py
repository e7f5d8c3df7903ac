"""First seen or added: was an object new to the map, or did it appear where a pass had looked?

An object appearing where no earlier pass looked is not a change: the map simply had not
seen that place (a room pass 1 did not enter, a corner its budget skipped, a door beyond
the camera's reach). Only an object appearing where an earlier pass looked and saw
nothing is *added*. On an Environment-A-size floor 20 of session 2's 23 net additions
were of the first kind; reported as "added" they are work an operator cannot act on.

What each pass looked at is its camera's floor coverage within reach
(``Perception.looked`` in :mod:`bomc_bt.monitoring`: each frame's depth-limited view fan,
cut back to ``projection.expect_range``, the range within which a detector is expected to
see an object, so that not seeing one there is evidence; farther, the graph does not count
a miss either). It is saved per session in the store's ``progress`` table under
``looked/<n>`` (:func:`bomc_bt.pass_resume.looked_key`) beside the whole fans
(``coverage/<n>``): each waypoint's commit writes a snapshot for resuming, and the
session's end writes the final masks in the same transaction that closes it
(:meth:`SiteStore.end_session <bomc_bt.store.SiteStore.end_session>`). A pass recorded
before ``looked/<n>`` existed left its ``coverage/<n>`` snapshot (the whole fans, up to its
last waypoint): that is used instead, which sees more and so claims fewer first sightings.
A site's ``site.db`` belongs to one map generation (a re-build with ``--new-map`` archives
it), so the masks in it are all on the current map; the central store syncs the
``progress`` rows with the rest.

At the start of a pass :func:`load_seen_before` takes the union of the masks of every
earlier recorded pass, widened into walls by ``association.first_seen_margin`` ([m]: a
door's centre lies in its wall, beyond the floor the view fan reached; the floor itself is
not widened, see :func:`widen_into_walls`), and :meth:`SeenBefore.mark` marks each ``added``
event at a place outside it with ``{"first_seen": true}`` in the event's ``detail``
(which travels to the central store with the event).
:func:`bomc_bt.net_changes.net_changes` then reports the node as ``first_seen``, not
``added``.

A flat object (a door leaf) is seen only from its faces: for a node of flat footprint the
pass end asks whether an earlier pass looked at its place from a viewing side facing it
(``association.face_on_deg``; the per-side looks are saved as ``looked_sides/<n>``,
:mod:`bomc_bt.looked_sides`). Looked at only edge-on, it is first seen.

The claim is only made on evidence. A pass with no earlier pass (the first of a map:
scored against the empty map, everything is an addition) marks nothing. Neither does a
pass when any earlier pass left no mask at all (a site recorded before the masks were saved, a
pass killed before its first waypoint, a site pulled from a store without them): what
that pass saw is unknown, and unknown counts as seen, so its additions stay ``added`` as
before (the old behaviour, never a true change hidden as "new to the map").
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.graph import PRESENT, REMOVED, AssociationParams, Event, Node
from bomc_bt.grid import OccupancyGrid, inflate_mask
from bomc_bt.looked_sides import MAX_SIDES, earlier_side_looks, face_sides, side_bits, side_count
from bomc_bt.pass_resume import coverage_key, looked_key, saved_mask, sightings_key
from bomc_bt.sightings import other_looks, unpack_sightings

FIRST_SEEN = "first_seen"  # the key in an ``added`` event's detail (and a pass end's ``updated`` verdict)
UNSEEN_SIDES = "unseen_sides"  # beside it: a flat object's face-on sides, none of which an earlier pass looked from
SIGHTED_IN = "sighted_in"  # beside it: the pass that had detected the object there (bomc_bt.sightings)


def is_first_seen(event: Event) -> bool:
    """Whether ``event`` added its node at a place no earlier pass had seen."""
    return event.kind == "added" and bool((event.detail or {}).get(FIRST_SEEN, False))


def first_seen_verdicts(events: Iterable[Event]) -> dict[int, bool]:
    """Per node added among ``events`` (write order), whether it is new to the map (:func:`verdicts`)."""
    return {nid: bool(detail.get(FIRST_SEEN, False)) for nid, detail in verdicts(events).items()}


def verdicts(events: Iterable[Event]) -> dict[int, dict]:
    """Per node added among ``events`` (write order), the detail of its verdict: its first
    ``added`` event's mark, or the last verdict after it that a pass end wrote (an ``updated``
    event whose detail carries ``first_seen``: :meth:`SeenBefore.final_verdicts`)."""
    out: dict[int, dict] = {}
    for e in events:
        nid = int(e.node_id)
        if (e.kind == "added" and nid not in out) or (e.kind == "updated" and nid in out
                                                      and FIRST_SEEN in (e.detail or {})):
            out[nid] = dict(e.detail or {})
    return out


@dataclass
class SeenBefore:
    """The floor earlier passes saw (widened by the margin) on ``grid``'s cells."""

    grid: OccupancyGrid
    seen: np.ndarray  # bool (H, W): True where an earlier pass saw the floor (margin included)
    # per category, where the previous pass detected objects (widened by the sighting radius)
    sighted: dict[str, np.ndarray] = field(default_factory=dict)
    sighted_in: int | None = None  # that pass
    # (x, y) of the nodes that pass removed on evidence of absence, and the radius round them
    # in which its sightings claim nothing (see :meth:`mark`)
    removed_there: dict[str, np.ndarray] = field(default_factory=dict)
    removed_radius: float = 0.0
    # per category, the previous pass's sightings not widened, and the (x, y) and colours of
    # the nodes it left on the map: whose views those were (bomc_bt.sightings.other_looks)
    sighting_cells: dict[str, np.ndarray] = field(default_factory=dict)
    looks: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    colour_tolerance: float = 0.0  # [-] association.colour_tolerance (0: colours off)
    # per square, a bit per viewing side earlier passes looked from (bomc_bt.looked_sides; None: any look counts)
    side_seen: np.ndarray | None = None
    side_grid: OccupancyGrid | None = None  # the squares those bits are on (None: ``grid``'s cells)
    side_count: int = 0  # [count] of viewing sides those bits are of (association.miss_sides)
    face_deg: float = 90.0  # [deg] association.face_on_deg: a flat node's sides within this of its normal

    def saw(self, xy: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
        """Bool per (x, y) point: an earlier pass saw that place (off the map: never); with
        ``mask``, whether that mask holds the place."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        rows, cols = self.grid.world_to_cell(xy[:, 0], xy[:, 1])
        inside = self.grid.in_bounds(rows, cols)
        out = np.zeros(len(xy), dtype=bool)
        out[inside] = (self.seen if mask is None else mask)[rows[inside], cols[inside]]
        return out

    def never_looked(self, position: np.ndarray) -> bool:
        """Whether no earlier pass saw the place at ``position`` (x, y[, z])."""
        return not bool(self.saw(np.asarray(position, dtype=float)[:2])[0])

    def sighted_here(self, category: str, position: np.ndarray) -> bool:
        """Whether the previous pass detected an object of ``category`` within the sighting
        radius of ``position`` (x, y[, z])."""
        mask = self.sighted.get(category)
        return mask is not None and bool(self.saw(np.asarray(position, dtype=float)[:2], mask)[0])

    def mark(self, events: list[Event]) -> int:
        """Mark as first seen the ``added`` events at places no earlier pass saw, and those
        where the previous pass detected an object of their category; how many."""
        marked = 0
        for event in (e for e in events if e.kind == "added"):
            verdict = self.verdict(event.category, event.position)
            if verdict[FIRST_SEEN]:
                event.detail = {**(event.detail or {}), **verdict}
                marked += 1
        return marked

    def verdict(self, category: str, position: np.ndarray, colour: np.ndarray | None = None,
                sides: Sequence[int] = ()) -> dict:
        """What an addition of ``category`` at ``position`` (x, y[, z]) is: ``{"first_seen":
        True}`` where no earlier pass saw the place (from one of ``sides``, where given: a
        flat object's face-on viewing sides, :mod:`bomc_bt.looked_sides`), with
        ``"sighted_in"`` where the previous pass detected an object of its kind there (and did
        not see such an object go from there, nor were those detections all of a node whose
        look differs from ``colour``, the addition's, where known); ``{"first_seen": False}``:
        an addition."""
        xy = np.asarray(position, dtype=float)[:2]
        if not self.saw(xy)[0]:
            return {FIRST_SEEN: True}
        if not self._saw_from(xy, sides):
            return {FIRST_SEEN: True, UNSEEN_SIDES: sorted(set(sides))}
        if self.sighted_here(category, xy) and not self._removed_near(category, xy) \
                and not self._other_looks(category, xy, colour):
            return {FIRST_SEEN: True, SIGHTED_IN: self.sighted_in}
        return {FIRST_SEEN: False}

    def final_verdicts(self, arrivals: Iterable[Node], history: Iterable[Event]) -> list[tuple[Node, dict]]:
        """When a pass ends: each of its ``arrivals`` (nodes it added, as they stand now) whose
        verdict at its final place differs from the one its ``history`` holds (:meth:`mark`'s,
        made where the node stood when added), with the new verdict.

        Why: a node is added where its first confirmed views put it, and a view of one end of
        an object puts it off the object's middle. A door seen first edge-on from the corridor
        stood 0.41 m along its wall from where the previous pass had detected it, beyond the
        sighting radius, and was reported added; the pass's later views brought the node
        within 0.12 m of that sighting (93 x 90 m office, seed 8231, pass 2). The other way
        too: a chair's first place fell within the radius of a sighting of the chair beside it,
        its final place did not, and a true addition was called first seen (36 x 28 m office,
        seed 8223, pass 5). Where the object stands is the node's final place, and the pass's
        views of it have shown whether it is flat (whose faces an earlier pass must have looked
        at: :func:`~bomc_bt.looked_sides.face_sides`)."""
        known = first_seen_verdicts(history)
        out = []
        for v in arrivals:
            if v.id not in known:
                continue
            sides = face_sides(v, self.side_count, self.face_deg) if self.side_seen is not None else []
            verdict = self.verdict(v.category, v.position, v.colour, sides)
            if verdict[FIRST_SEEN] != known[v.id]:
                out.append((v, verdict))
        return out

    def _saw_from(self, xy: np.ndarray, sides: Sequence[int]) -> bool:
        """Whether an earlier pass looked at ``xy`` from one of ``sides`` (True where either is unknown)."""
        if self.side_seen is None or not sides:
            return True
        grid = self.grid if self.side_grid is None else self.side_grid
        rows, cols = grid.world_to_cell(xy[None, 0], xy[None, 1])
        return not grid.in_bounds(rows, cols)[0] or bool(int(self.side_seen[rows[0], cols[0]]) & side_bits(sides))

    def _other_looks(self, category: str, xy: np.ndarray, colour: np.ndarray | None) -> bool:
        """Whether the previous pass's sightings near ``xy`` (within the sighting radius, which
        ``removed_radius`` holds) were all of a node that looks unlike ``colour``
        (:func:`~bomc_bt.sightings.other_looks`)."""
        mask = self.sighting_cells.get(category)
        return mask is not None and other_looks(mask, self.grid, xy, self.removed_radius, colour,
                                                self.looks.get(category), self.colour_tolerance)

    def _removed_near(self, category: str, xy: np.ndarray) -> bool:
        """Whether the previous pass removed a node of ``category`` on evidence of absence
        within the sighting radius of ``xy``: its sightings there were of an object it then
        saw gone, so one there now was brought back (an addition), not there all along. The
        previous pass reported the removal; calling the return first seen left the map's
        story at "removed" (36 x 28 m office, seed 7503, pass 3: a bin taken away during
        pass 2 after the robot saw it, brought back to its place before pass 3)."""
        near = self.removed_there.get(category)
        if near is None or len(near) == 0:
            return False
        return bool((np.hypot(near[:, 0] - xy[0], near[:, 1] - xy[1]) <= self.removed_radius).any())


def load_seen_before(store, session: int, grid: OccupancyGrid, margin: float,
                     sighting_radius: float = 0.0, colour_tolerance: float = 0.0, sides: int = 0,
                     face_deg: float = 90.0) -> SeenBefore | None:
    """What the recorded passes before ``session`` saw, or None where it is not known (see the
    module docstring: no earlier pass, or one without a saved mask); with ``sighting_radius``
    (m, > 0) also where the previous one detected objects (:mod:`bomc_bt.sightings`), with
    ``colour_tolerance`` (> 0) the looks of the nodes it left there, and with ``sides`` (> 0)
    and ``face_deg`` (< 90) from which of that many viewing sides each place was looked at, for
    flat objects' faces (:mod:`bomc_bt.looked_sides`)."""
    earlier = [s.number for s in store.sessions() if s.number < session]
    if not earlier:
        return None
    looked: dict[int, np.ndarray] = {}
    for number in earlier:
        mask = saved_coverage(store, number, grid.data.shape, looked_key(number))
        if mask is None:  # a pass that saved only its whole view fans: those (more seen, fewer claims)
            mask = saved_coverage(store, number, grid.data.shape)
        if mask is None:
            return None
        looked[number] = mask
    union = np.zeros(grid.data.shape, dtype=bool)
    for mask in looked.values():
        union |= mask
    seen = SeenBefore(grid, widen_into_walls(union, grid, margin))
    if 1 <= sides <= MAX_SIDES and face_deg < 90.0:
        seen.side_seen, seen.side_grid = earlier_side_looks(store, looked, grid, margin, sides)
        seen.side_count, seen.face_deg = sides, face_deg
    if sighting_radius > 0.0:
        seen.sighted_in = max(earlier)
        seen.sighting_cells = previous_sightings(store, seen.sighted_in, grid)
        seen.sighted = {c: inflate_mask(m, sighting_radius / grid.resolution) for c, m in seen.sighting_cells.items()}
        if colour_tolerance > 0.0:
            seen.looks, seen.colour_tolerance = looks_after(store, seen.sighted_in), colour_tolerance
        seen.removed_there = removed_on_evidence(store, seen.sighted_in, sighting_radius)
        seen.removed_radius = sighting_radius
    return seen


def removed_on_evidence(store, session: int, away: float = math.inf) -> dict[str, np.ndarray]:
    """Per category, the (x, y) of the nodes pass ``session`` removed on evidence of absence
    (missed frames, not a merge, not a retraction) and did not bring back in that pass; and
    the places of those it removed so and then found moved, as moves are paired when a pass
    ends, to farther than ``away`` (m): that place, too, was seen empty. Traced: a bin the
    robot saw early in a pass was taken away during it, its node removed on misses and then
    paired with a bin that had come in 3 m away; brought back before the next pass, it was
    called first seen there (36 x 28 m office, seed 7915, pass 9)."""
    events = store.events(session=session)
    last = _last_changes(events)
    out: dict[str, list] = {}
    for e in events:
        if not _gone_on_evidence(e):
            continue
        final = last[e.node_id]
        moved_off = final.kind == "moved" and float(np.hypot(*(np.asarray(final.position, dtype=float)[:2]
                                                               - np.asarray(e.position, dtype=float)[:2]))) > away
        if final is e or moved_off:
            out.setdefault(e.category, []).append(np.asarray(e.position, dtype=float)[:2])
    return {c: np.array(v) for c, v in out.items()}


def gone_before(store, session: int) -> list[Node]:
    """The nodes that passes before ``session`` removed on evidence of absence and that none
    has seen since, as they last stood, with their looks: where an object of their kind new in
    ``session`` is one of them brought back (:mod:`bomc_bt.graph.brought_back`). A node an
    operator deleted after (``bomc edit``: it was never there) is not among them.

    So are the places a node present now left when a pass removed it there on evidence and
    then, as the pass ended, paired the removal with an arrival of its look (a copy of the
    node standing where it was removed): that place was seen empty, and the node stands
    elsewhere. An object of its look new there is another one, back, unless the node is
    missing where it stands now (the pass end and the move rules leave such a place to the
    node itself: it may have gone back). Traced on a 36 x 28 m office (seed 9201): pass 3
    paired the removal of chair-11 with chair-13's arrival 6.3 m off (one look); chair-11,
    brought back in pass 4, was then paired with the removal of another chair of that look
    12 m off, and so on in passes 6 and 9."""
    history = [e for e in store.events(until=session, operator=True)
               if e.session < session or e.kind in ("deleted", "restored")]  # edits filed under this pass too
    last = _last_changes(history)
    ids = {nid for nid, e in last.items() if _gone_on_evidence(e)}
    nodes = store.nodes(include_removed=True)
    gone = [n for n in nodes if n.state == REMOVED and n.id in ids]
    return gone + _places_left(history, [n for n in nodes if n.state == PRESENT])


def _places_left(history: list[Event], present: list[Node], apart: float = 1.0) -> list[Node]:
    """For each ``present`` node whose last removal on evidence in ``history`` its own pass
    undid by a move, a copy standing where it was removed (none within ``apart`` m of where
    the node stands now)."""
    removal: dict[int, Event] = {}
    for e in history:
        if _gone_on_evidence(e):
            removal[e.node_id] = e
    undone = {e.node_id for e in history if e.kind == "moved" and (r := removal.get(e.node_id)) is not None
              and e.session == r.session and e.stamp >= r.stamp}
    left = []
    for n in present:
        if n.id in undone:
            at = np.asarray(removal[n.id].position, dtype=float)
            if float(np.hypot(*(n.position[:2] - at[:2]))) > apart:
                left.append(dataclasses.replace(n, position=at.copy(), state=REMOVED))
    return left


def _last_changes(events: list[Event]) -> dict[int, Event]:
    """Each node's last added, removed or moved event of ``events`` (or an operator's deletion
    or restoration, where ``events`` hold them)."""
    return {e.node_id: e for e in events if e.kind in ("added", "removed", "moved", "deleted", "restored")}


def _gone_on_evidence(e: Event) -> bool:
    """Whether ``e`` removed its node on missed frames (not a merge, not a retraction)."""
    merged = bool((e.detail or {}).get("merged")) or e.merged_into is not None
    return e.kind == "removed" and (e.misses or 0) > 0 and not merged and not e.retracted


def widen_into_walls(looked: np.ndarray, grid: OccupancyGrid, margin: float) -> np.ndarray:
    """``looked`` and the cells the map holds as occupied within ``margin`` (m) of it.

    The floor an object newly stands on was seen only if the view fan covered it: an object
    that stood there all along, undetected, cut the fan at its near face (the fan stops at
    anything standing, :mod:`bomc_bt.perception.looked`), so its centre lies a little beyond
    the looked floor. Widening the floor itself by the margin called such objects "added"
    when a later pass found them: all six false additions of four Environment-A-size floors
    and a 36 x 28 m office lay 0.07-0.25 m beyond it, every true one inside it. Only a wall
    is widened into: an object whose centre lies inside one (a door in its wall) was in
    view where the fan reached the wall's face.
    """
    widened = inflate_mask(looked, margin / grid.resolution) & grid.occupied_mask()
    return looked.astype(bool) | widened


def seen_before_for(store, session: int, grid: OccupancyGrid, params: AssociationParams) -> SeenBefore | None:
    """:func:`load_seen_before` with the association's ``first_seen_margin``, ``sighting_radius``
    and ``colour_tolerance`` (what a monitor pass and a replayed one load)."""
    return load_seen_before(store, session, grid, params.first_seen_margin, params.sighting_radius,
                            params.colour_tolerance, side_count(params), params.face_on_deg)


def looks_after(store, session: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per category, the (x, y) where the nodes of known colour stood at the end of pass
    ``session`` and their colours (as the store holds them now: the start of the next pass)."""
    colours = {n.id: n.colour for n in store.nodes(include_removed=True) if n.colour is not None}
    out: dict[str, tuple[list, list]] = {}
    for n in store.graph_after(session):
        if n.id in colours:
            xy, looks = out.setdefault(n.category, ([], []))
            xy.append(np.asarray(n.position, dtype=float)[:2])
            looks.append(colours[n.id])
    return {c: (np.array(xy).reshape(-1, 2), np.array(looks).reshape(-1, 2)) for c, (xy, looks) in out.items()}


def previous_sightings(store, session: int, grid: OccupancyGrid, radius: float = 0.0) -> dict[str, np.ndarray]:
    """Pass ``session``'s sightings (the cells observations' centres fell in), each widened by
    ``radius`` (m); none where it saved none (a pass recorded before they were); a mask not
    of this map is a corrupt store."""
    try:
        masks = unpack_sightings(store.get_progress(sightings_key(session)), grid.data.shape)
    except (ValueError, TypeError, zlib.error) as exc:
        raise BomcError(f"corrupt site store: the saved sightings of session {session} are not masks of this map "
                        f"({exc})", store.path, f"progress.{sightings_key(session)}") from None
    return {c: inflate_mask(m, radius / grid.resolution) if radius > 0.0 else m for c, m in (masks or {}).items()}


def saved_coverage(store, session: int, shape: tuple[int, int], key: str | None = None) -> np.ndarray | None:
    """The floor pass ``session`` saw (bool, ``shape``) as saved under ``key`` (default: its
    whole view fans), None when it saved none; a mask that is not one of this map is a corrupt
    store (one line naming the progress key)."""
    mask = saved_mask(store, session, key or coverage_key(session), shape)
    return None if mask is None else mask.astype(bool)
