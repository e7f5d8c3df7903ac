"""The read adapter: a floor of the central store seen through the interface ``bomc evaluate`` and ``bomc view`` read.

:class:`CentralGraph` answers ``sessions()``, ``events()`` and ``graph_after()`` as
:class:`~bomc_bt.store.SiteStore` does (the graph is replayed by the same
:func:`~bomc_bt.graph.history.replay_graph`, from the same rows, so the numbers are the same);
:meth:`CentralGraph.file` gives the generation's map, trajectory, build record and plan
for the viewer. Everything is read in one REPEATABLE READ, READ ONLY transaction at open
(one consistent picture while robots sync), then the connection is closed; nothing is
written, not even a schema upgrade.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from bomc_bt.central import schema
from bomc_bt.central.connection import CentralSite, central_errors, connect, parse_central_site
from bomc_bt.central.rows import read_central
from bomc_bt.errors import BomcError
from bomc_bt.graph import Event, Node
from bomc_bt.graph.history import replay_graph
from bomc_bt.store import SessionRecord


class CentralGraph:
    """One floor's map generation in the central store, read once.

    ``site``: a ``postgresql://...?building=B&floor=F`` URL or its parsed form.
    """

    def __init__(self, site: str | CentralSite, timeout: float = 10.0):
        self.site = site if isinstance(site, CentralSite) else parse_central_site(site)
        self.path = self.site.shown  # what error messages name, as a local store's path
        conn = connect(self.site.conninfo, timeout)
        try:
            with central_errors(self.site.conninfo, "read"), conn.transaction():
                conn.execute("SET TRANSACTION ISOLATION LEVEL REPEATABLE READ, READ ONLY")
                schema.check(conn, self.path)
                self.generation = self._generation(conn)
                key = (self.site.building, self.site.floor, self.generation)
                self._rows = read_central(conn, key)
                self._files = {name: bytes(content) for name, content in conn.execute(
                    "SELECT path, content FROM bomc.files WHERE building = %s AND floor = %s AND generation = %s",
                    key).fetchall()}
        finally:
            conn.close()
        self._events = [_event(row) for row in self._rows.node_history]

    def _generation(self, conn: Any) -> int:
        if self.site.generation is not None:
            return self.site.generation
        row = conn.execute("SELECT current_generation FROM bomc.floors WHERE building = %s AND floor = %s",
                           (self.site.building, self.site.floor)).fetchone()
        if row is None or row[0] is None:
            raise BomcError("no such floor in the central store", self.path, "floor")
        return int(row[0])

    def sessions(self) -> list[SessionRecord]:
        return [SessionRecord(n, s0, w0, s1, w1, out, _loads(c), _loads(r), _loads(i))
                for n, s0, w0, s1, w1, out, c, r, i in self._rows.sessions]

    def events(self, session: int | None = None, until: int | None = None, operator: bool = False) -> list[Event]:
        """As :meth:`bomc_bt.store.SiteStore.events`: the robot's events unless ``operator``."""
        events = self._events if operator else [e for e in self._events if not e.by_operator]
        if session is not None:
            return [e for e in events if e.session == session]
        if until is not None:
            return [e for e in events if e.session <= until]
        return list(events)

    def graph_after(self, session: int) -> list[Node]:
        return replay_graph(self.events(until=session, operator=True))

    def file(self, name: str) -> bytes | None:
        """A travelled file by its central name (``map/map.yaml``, ``graph/plan.json``; bomc_bt.central.site_files)."""
        return self._files.get(name)

    @property
    def name(self) -> str:
        return f"{self.site.building} / {self.site.floor}"

    def close(self) -> None:
        pass

    def __enter__(self) -> CentralGraph:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _event(row: tuple) -> Event:
    _seq, nid, session, stamp, kind, cat, x, y, z, conf, px, py, pz, detail = row
    return Event(kind, nid, cat, np.array([x, y, z]), session, stamp,
                 None if px is None else np.array([px, py, pz]), conf, json.loads(detail) if detail else None)


def _loads(text: str | None) -> dict[str, Any]:
    return json.loads(text) if text else {}


def write_map_files(graph: CentralGraph, folder: Path) -> Path | None:
    """Write the generation's ``map.yaml`` and its image into ``folder`` (for load_map); None without a map."""
    yaml_text = graph.file("map/map.yaml")
    if yaml_text is None:
        return None
    (folder / "map.yaml").write_bytes(yaml_text)
    image = graph.file("map/map.pgm")
    if image is not None:
        (folder / "map.pgm").write_bytes(image)
    return folder / "map.yaml"
