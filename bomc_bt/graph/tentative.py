"""Confirm before adding: first sightings wait off the graph until they are seen again.

A false positive (a shadow taken for a door, a box for a bin) rarely repeats at the same
place in the next frames, a real object does. Robust association therefore adds a new
object only once ``confirm_detections`` frames, at least ``confirm_interval`` seconds
apart, have seen it; a first sighting waits here for ``tentative_ttl`` seconds, and the
observation that confirms it becomes the node, at the mean of the sightings.

A sighting whose time runs out unconfirmed is kept as *lapsed* for the rest of the pass: an
object the camera caught once while turning (a bin in a corner, a chair behind a table
seen from a doorway 3.5 m away) is as likely as a false positive, and only a second look
tells which. Look Around turns to it once (:mod:`bomc_bt.look_around`) where a line over
free map cells reaches it, and Refresh Stale plans a stop for what is left at the pass's end
(:mod:`bomc_bt.refresh`). On a 93 x 90 m floor (seed 8231, pass 1) neither reached a chair
caught once behind the chair in front at a table: Look Around's line ran into the lidar
shadow round the furniture, unknown on the map, and the refresh tour found no place within
its look range clear of the other objects' boxes (docs/association.md, "A chair caught once
behind the chair in front").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bomc_bt.graph.records import AssociationParams, Observation
from bomc_bt.json_text import JSONMemo, listed


@dataclass
class Sighting:
    """A first sighting awaiting confirmation."""

    category: str
    position: np.ndarray  # mean of the sightings so far
    count: int  # sightings so far
    last: float  # robot time of the latest sighting
    first: float  # robot time of the first sighting
    # a node whose own view, in the frame of the first sighting, stood clear of this one:
    # two objects side by side, this one not yet in the graph (see ``claims``)
    beside: int | None = None


class TentativeSightings:
    """The first sightings of the current session that wait for their confirmation."""

    def __init__(self, params: AssociationParams, scale: np.ndarray):
        self.params = params
        self.scale = scale  # (3,) distance weights, as the graph's index uses them
        self.waiting: list[Sighting] = []
        self.lapsed: list[Sighting] = []  # sightings of this session whose time ran out unconfirmed
        # (category, place, distance) a head turn faced this session, from that far (m)
        self.looked: list[tuple[str, np.ndarray, float]] = []
        self._session: int | None = None
        # per observation of the last confirm_frame: the ``beside`` of the sighting it confirmed
        self.beside_of: list[int | None] = []

    def begin(self, session: int) -> None:
        """Sightings of an earlier session never confirm one of this session."""
        if session != self._session:
            self.waiting, self.lapsed, self.looked = [], [], []
            self._session = session

    def unconfirmed(self, looked_within: float | None = None) -> list[Sighting]:
        """The sightings of this session not (yet) confirmed, lapsed ones then those waiting,
        but those at a place a head turn has faced already: one look a place, or a false
        positive would turn the head at every waypoint near it.

        With ``looked_within`` (m), a turn from farther does not count for a sighting that
        something backs (:meth:`backed`): a cabinet caught through a doorway at its two ends,
        0.76 m apart, and turned to from 4.6 m outside, where its frames missed it, was never
        looked at again and never mapped (36 x 28 m office, seed 7913, pass 1; a wrong
        addition the next pass). A lone sighting is most often a false positive, and a look
        from afar settles it as before: counting every far turn as none sent the refresh tour
        to 2-8 more of them a pass, 3-4 % more robot time, for no object found."""
        pool = self.lapsed + self.waiting
        if not self.looked:
            return pool
        categories = np.array([c for c, _, _ in self.looked])
        places = np.array([p for _, p, _ in self.looked], dtype=float)
        far = np.array([d for _, _, d in self.looked], dtype=float)
        if looked_within is not None:
            far = far > looked_within

        def faced(t: Sighting) -> bool:  # a head turn faced its place (from near enough)
            same = (categories == t.category) & (
                np.linalg.norm((places - t.position) * self.scale, axis=1) <= self.params.distance(t.category))
            if looked_within is None or not same.any():
                return bool(same.any())
            return bool((same & ~far).any()) or not self.backed(t, pool)

        return [t for t in pool if not faced(t)]

    def backed(self, sighting: Sighting, pool: Sequence[Sighting]) -> bool:
        """Seen in two frames (not yet far enough apart in time to confirm), or another
        sighting of its category in ``pool`` lies within one object's reach of it (``extent_gate``
        times delta_c: the two ends of a long object seen apart)."""
        reach = self.params.extent_gate * self.params.distance(sighting.category)
        return sighting.count >= 2 or any(
            t is not sighting and t.category == sighting.category
            and float(np.linalg.norm((t.position - sighting.position) * self.scale)) <= reach for t in pool)

    def mark_looked(self, sightings: Sequence[Sighting], place: Sequence[float] | None = None) -> None:
        """A head turn faces ``sightings`` now (:mod:`bomc_bt.look_around`), from ``place`` (x, y;
        None: up close)."""
        for t in sightings:
            at = np.asarray(t.position, dtype=float).copy()
            d = 0.0 if place is None else float(np.hypot(at[0] - place[0], at[1] - place[1]))
            self.looked.append((t.category, at, d))

    def _lapse(self, sighting: Sighting) -> None:
        """Keep ``sighting`` as lapsed, unless one lapsed already lies within its category's
        association distance (one place needs one look)."""
        if not any(self._same_place(sighting.category, sighting.position, t.category, t.position)
                   for t in self.lapsed):
            self.lapsed.append(sighting)

    def _same_place(self, category: str, position: np.ndarray, other: str, at: np.ndarray) -> bool:
        """Same category, within its association distance (scaled as the graph's index)."""
        gap = float(np.linalg.norm((position - at) * self.scale))
        return category == other and gap <= self.params.distance(category)

    def to_json(self, memo: JSONMemo | None = None) -> dict:
        """The sightings waiting, JSON-able (a resumed pass picks them up again; with ``memo``,
        each list as its text: :class:`~bomc_bt.json_text.JSONMemo`)."""
        return {"session": self._session, "waiting": listed(memo, "tentative.waiting", self.waiting, _sighting_json),
                "lapsed": listed(memo, "tentative.lapsed", self.lapsed, _sighting_json),
                "looked": _looked_json(self.looked) if memo is None else memo.appended("looked", self.looked, _looked)}

    def restore(self, data: dict) -> None:
        self._session = data.get("session")
        self.waiting = [_sighting(w) for w in data.get("waiting", [])]
        self.lapsed = [_sighting(w) for w in data.get("lapsed", [])]  # absent in a resume point saved before
        self.looked = [(str(e[0]), np.asarray(e[1], dtype=float), float(e[2]) if len(e) > 2 else 0.0)
                       for e in data.get("looked", [])]  # saved before distances were: up close

    def claims(self, o: Observation, node_id: int, node_distance: float, gate: float, stamp: float) -> bool:
        """Whether ``o`` belongs to a waiting sighting begun beside node ``node_id`` rather
        than to that node: the sighting is nearer ``o`` than the node (``node_distance``,
        scaled as the graph's index) and within ``gate``.

        A frame that shows two chairs apart proves two objects, but the second only waits
        here while the first chair's node lies within delta_c of both; without this, the
        next frame that shows the second chair alone drags that node over to it. Chairs
        0.8 m apart at a table, both cut off by it (so the node's footprint is no proof):
        one node swung between the two and the second chair was never mapped (issue 17,
        Environment-A-size floor, seed 9393, chair-79 beside chair-155)."""
        return any(t.beside == node_id and t.category == o.category and stamp - t.last <= self.params.tentative_ttl
                   and (d := float(np.linalg.norm((t.position - o.position) * self.scale))) <= gate
                   and d < node_distance for t in self.waiting)

    def confirm_frame(self, observations: Sequence[Observation], gates: Sequence[float], stamp: float,
                      beside: Sequence[int | None] | None = None) -> list[bool]:
        """Per new sighting of one frame, whether it is now seen often enough to be added (then
        its ``position`` becomes the mean of its sightings); the others are remembered or
        counted as sightings.

        A sighting takes at most one observation of a frame and an observation continues at
        most one sighting, nearest pairs first, as nodes are matched. Taking the first
        sighting in the gate instead, a chair at a table confirmed the sighting its
        neighbour 0.8 m away had started, while the frame's view of that neighbour stood
        beside it: one node at the two chairs' midpoint, and the second chair never mapped
        (issue 17: chair-152 of a static Environment-A-size floor, seed 5353, one of the 7
        "merged" misses of its first pass). ``beside`` (per observation, a node whose view of
        this frame stood clear of it) marks the sightings it begins (:meth:`claims`)."""
        need = self.params.confirm_detections
        self.beside_of = [None] * len(observations)
        if need <= 1:
            return [True] * len(observations)
        for t in self.waiting:
            if stamp - t.last > self.params.tentative_ttl:
                self._lapse(t)
        self.waiting = [t for t in self.waiting if stamp - t.last <= self.params.tentative_ttl]
        pairs = sorted((float(np.linalg.norm((t.position - o.position) * self.scale)), k, j)
                       for j, o in enumerate(observations) for k, t in enumerate(self.waiting)
                       if t.category == o.category)
        taken: dict[int, int] = {}  # sighting index -> observation index
        used: set[int] = set()  # observation indices that continue a sighting
        for d, k, j in pairs:
            if d <= gates[j] and k not in taken and j not in used:
                taken[k] = j
                used.add(j)
        out, done = [False] * len(observations), set()
        for k, j in taken.items():
            t, o = self.waiting[k], observations[j]
            if stamp - t.last < self.params.confirm_interval:
                continue  # the same burst of frames: not independent evidence
            count = t.count + 1
            mean = (t.position * (count - 1) + o.position) / count
            if count >= need:
                o.position, out[j] = mean, True
                self.beside_of[j] = t.beside
                done.add(k)
            else:
                self.waiting[k] = Sighting(t.category, mean, count, stamp, t.first, t.beside)
        self.waiting = [t for k, t in enumerate(self.waiting) if k not in done]
        self.waiting.extend(Sighting(o.category, o.position.copy(), 1, stamp, stamp, beside[j] if beside else None)
                            for j, o in enumerate(observations) if j not in used)
        return out


def _sighting_json(t: Sighting) -> dict:
    return {"category": t.category, "position": t.position.tolist(), "count": t.count, "last": t.last,
            "first": t.first, "beside": t.beside}


def _looked(e: tuple[str, np.ndarray, float]) -> list:
    return [e[0], e[1].tolist(), e[2]]


def _looked_json(looked: list[tuple[str, np.ndarray, float]]) -> list:
    return [_looked(e) for e in looked]  # only appended to (mark_looked): JSONMemo.appended


def _sighting(w: dict) -> Sighting:
    return Sighting(w["category"], np.asarray(w["position"], dtype=float), int(w["count"]), float(w["last"]),
                    float(w["first"]), w.get("beside"))
