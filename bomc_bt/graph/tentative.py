"""Confirm before adding: first sightings wait off the graph until they are seen again.

A false positive (a shadow taken for a door, a box for a bin) rarely repeats at the same
place in the next frames, a real object does. Robust association therefore adds a new
object only once ``confirm_detections`` frames, at least ``confirm_interval`` seconds
apart, have seen it; a first sighting waits here for ``tentative_ttl`` seconds, and the
observation that confirms it becomes the node, at the mean of the sightings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bomc_bt.graph.records import AssociationParams, Observation


@dataclass
class Sighting:
    """A first sighting awaiting confirmation."""

    category: str
    position: np.ndarray  # mean of the sightings so far
    count: int  # sightings so far
    last: float  # robot time of the latest sighting
    first: float  # robot time of the first sighting


class TentativeSightings:
    """The first sightings of the current session that wait for their confirmation."""

    def __init__(self, params: AssociationParams, scale: np.ndarray):
        self.params = params
        self.scale = scale  # (3,) distance weights, as the graph's index uses them
        self.waiting: list[Sighting] = []
        self._session: int | None = None

    def begin(self, session: int) -> None:
        """Sightings of an earlier session never confirm one of this session."""
        if session != self._session:
            self.waiting = []
            self._session = session

    def to_json(self) -> dict:
        """The sightings waiting, JSON-able (a resumed pass picks them up again)."""
        return {"session": self._session,
                "waiting": [{"category": t.category, "position": t.position.tolist(), "count": t.count,
                             "last": t.last, "first": t.first} for t in self.waiting]}

    def restore(self, data: dict) -> None:
        self._session = data.get("session")
        self.waiting = [Sighting(w["category"], np.asarray(w["position"], dtype=float), int(w["count"]),
                                 float(w["last"]), float(w["first"])) for w in data.get("waiting", [])]

    def confirmed(self, o: Observation, stamp: float, gate: float) -> bool:
        """Whether ``o`` is now seen often enough to be added (then ``o.position`` becomes the
        mean of its sightings); otherwise it is remembered or counted as a sighting."""
        need = self.params.confirm_detections
        if need <= 1:
            return True
        ttl = self.params.tentative_ttl
        self.waiting = [t for t in self.waiting if stamp - t.last <= ttl]
        for k, t in enumerate(self.waiting):
            if t.category != o.category or np.linalg.norm((t.position - o.position) * self.scale) > gate:
                continue
            if stamp - t.last < self.params.confirm_interval:
                return False  # the same burst of frames: not independent evidence
            count = t.count + 1
            mean = (t.position * (count - 1) + o.position) / count
            if count >= need:
                del self.waiting[k]
                o.position = mean
                return True
            self.waiting[k] = Sighting(t.category, mean, count, stamp, t.first)
            return False
        self.waiting.append(Sighting(o.category, o.position.copy(), 1, stamp, stamp))
        return False
