"""Replay of a finished pass in ``bomc view`` (issue 19, item 3): the timeline API.

``GET /api/timeline?session=N`` answers with the pass's timeline
(:mod:`bomc_bt.timeline`: tree statuses, poses, frames' detections, graph events) and the
map the pass started from (``start``: the graph after the previous pass with the
operator's edits filed for this one), so the page rebuilds any moment by itself: the pose
and the frame are the last ones at or before it, the tree the status changes applied up to
it, the objects ``start`` with the events up to it. The page scrubs and plays back
without asking the server again (``static/replay.js``).

Each session's timeline is read once and kept; the site is read-only here.
"""

from __future__ import annotations

import threading
from typing import Any

from bomc_bt.errors import BomcError
from bomc_bt.viewer.sections import category_hex, node_json

Query = dict[str, list[str]]
MAX_SESSION = 1_000_000


class ReplayApi:
    """The ``/api/timeline`` route of one :class:`~bomc_bt.viewer.site.SiteView`."""

    def __init__(self, view: Any):
        self.view = view
        self._cache: dict[int, dict[str, Any]] = {}
        self._lock = threading.Lock()

    def routes(self) -> dict[str, Any]:
        return {"/api/timeline": self.timeline}

    def timeline(self, query: Query) -> dict[str, Any]:
        number = _session(query)
        if self.view.central is not None:
            raise BomcError("replay reads a site directory's timelines; the central store keeps none", None,
                            "session")
        if number not in {r.number for r in self.view.records}:
            known = [r.number for r in self.view.records]
            raise BomcError(f"no session {number} (sessions: {known})", None, "session")
        with self._lock:
            if number not in self._cache:
                self._cache[number] = self._load(number)
            return self._cache[number]

    def _load(self, number: int) -> dict[str, Any]:
        from bomc_bt.timeline import read_timeline, timeline_path

        timeline = read_timeline(timeline_path(self.view.site.session_dir(number)), number)
        start = [node_json(n) for n in self._start_graph(number)]
        categories = {n["category"] for n in start}
        categories |= {row[2] for ev in timeline.events for row in ev["e"] if isinstance(row, list) and len(row) > 2}
        categories |= {d[0] for f in timeline.frames for d in f["d"] if isinstance(d, list) and d}
        return {**timeline.to_json(), "start_objects": start,
                "colours": {str(c): category_hex(str(c)) for c in categories}}

    def _start_graph(self, number: int) -> list:
        """The map the pass started from: history before it, and the operator's edits filed for it."""
        from bomc_bt.store import SiteStore, replay_graph

        path = self.view.site.store_path
        if not path.exists():
            return []
        with SiteStore(path, readonly=True) as store:
            before = store.events(until=number - 1, operator=True)
            edits = [e for e in store.events(session=number, operator=True) if e.by_operator]
        return replay_graph([*before, *edits])


def _session(query: Query) -> int:
    text = (query.get("session") or [""])[0]
    if not text.isdigit() or len(text) > 7 or not 1 <= int(text) <= MAX_SESSION:
        raise BomcError(f"give a session number 1 to {MAX_SESSION}: /api/timeline?session=N (got {text[:20]!r})",
                        None, "session")
    return int(text)
