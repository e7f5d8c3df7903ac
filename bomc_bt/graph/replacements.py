"""Another kind of object where a node's object stood: the node is gone, the newcomer is new.

One object, one label (:mod:`.confusions`): a sighting on a node of another category in a
frame that did not match that node is dropped, since a detector names a chair "table" now
and then. But when a table is carried off and a cabinet set down where it stood, every
frame that sees the place names a cabinet on the table's node and none matches the table,
and the table's place is held (a view blocked there counts no miss): the map kept the
table and never added the cabinet (small house, 25 objects, seed 8632, pass 5: 52 frames
in a row named the cabinet on the table's node).

So a node this pass has not matched, whose place ``replace_sightings`` frames (at least
``confirm_interval`` apart, every one naming the same other category) named as another
kind, is taken off: removed, or retracted if the map never trusted it (it may still turn
out to have moved, :meth:`~bomc_bt.graph.ObjectGraph.restore`). The sighting that made the
count then goes the way of any new object's (confirmed by the frames after it). A node
matched once in this pass keeps its label: then the other name was the detector's. The
count is the pass's own, kept in memory like the tentative sightings: a pass resumed after a
kill counts again.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from bomc_bt.graph.records import Event, Observation

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph


class Replacements:
    """Per pass, the frames that named another kind on each node the pass has not matched."""

    def __init__(self, needed: int, interval: float):
        self.needed, self.interval = needed, interval
        self.session: int | None = None
        self.named: dict[int, list[tuple[float, str]]] = {}  # node id -> (stamp, category) per frame

    def begin(self, session: int) -> None:
        if session != self.session:
            self.session = session
            self.named.clear()

    def note(self, graph: ObjectGraph, vid: int, o: Observation, session: int, stamp: float,
             retracted: bool) -> list[Event]:
        """Count ``o``, a sighting of another kind on node ``vid``; the node's removal (or
        retraction) once ``needed`` frames named the same kind there. ``needed`` 0: never."""
        v = graph.nodes.get(vid)
        if v is None or self.needed <= 0 or v.last_session == session:
            return []
        frames = self.named.setdefault(vid, [])
        if frames and frames[-1][1] != o.category:
            frames.clear()  # named otherwise now: count again
        if frames and stamp - frames[-1][0] < self.interval:
            return []
        frames.append((stamp, o.category))
        if len(frames) < self.needed:
            return []
        del self.named[vid]
        return [graph.remove(v, session, stamp, retracted=retracted)]
