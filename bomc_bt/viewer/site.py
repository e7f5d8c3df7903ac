"""A finished site for the viewer: the map, the trajectory, each session's graph and events."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from bomc_bt.central.connection import is_central
from bomc_bt.errors import BomcError
from bomc_bt.graph import AssociationParams, Event, Node
from bomc_bt.net_changes import REPORTED_KINDS, net_changes
from bomc_bt.viewer.sections import change_json, events_section, node_json, rounded
from bomc_bt.viewer.store import Sections, StateStore, ViewerParams


class SiteView:
    """A finished site read once: the map, the trajectory, each session's graph and events."""

    def __init__(self, site_dir: str | Path, params: ViewerParams | None = None,
                 association: AssociationParams | None = None):
        from bomc_bt.grid import load_map
        from bomc_bt.site import Site
        from bomc_bt.store import SiteStore

        self.params = params or ViewerParams()
        # how far a node must go to have moved: the association distance, as the report says
        self.threshold = (association or AssociationParams()).distance
        self.graphs: dict[int, list[Node]] = {0: []}
        self.events: dict[int, list[Event]] = {}
        self.records = []
        self.central = None
        if is_central(site_dir):  # a floor of the central store: the same view, read through the adapter
            self._read_central(str(site_dir))
            return
        self.site = Site(Path(site_dir))
        if not self.site.root.is_dir():
            raise BomcError("not a site directory", self.site.root)
        self.grid = load_map(self.site.map_yaml) if self.site.map_yaml.exists() else None
        if self.site.store_path.exists():
            store = SiteStore(self.site.store_path, readonly=True)
            try:
                self.records = store.sessions()
                for rec in self.records:
                    self.graphs[rec.number] = store.graph_after(rec.number)
                    self.events[rec.number] = store.events(session=rec.number)
            finally:
                store.close()
        if self.grid is None and not self.records:
            raise BomcError("neither a map (map.yaml) nor a site store (site.db): run `bomc build` first",
                            self.site.root)

    def _read_central(self, url: str) -> None:
        import tempfile

        from bomc_bt.central.reader import CentralGraph, write_map_files
        from bomc_bt.grid import load_map

        self.central = CentralGraph(url)
        with tempfile.TemporaryDirectory(prefix="bomc-view-") as folder:
            path = write_map_files(self.central, Path(folder))
            self.grid = load_map(path) if path is not None else None
        self.records = self.central.sessions()
        for rec in self.records:
            self.graphs[rec.number] = self.central.graph_after(rec.number)
            self.events[rec.number] = self.central.events(session=rec.number)

    def _file(self, local: Path, central_name: str) -> bytes | None:
        """A site file's bytes, from the directory or the central store (None when it is not there)."""
        if self.central is not None:
            return self.central.file(central_name)
        try:
            return local.read_bytes() if local.exists() else None
        except OSError:
            return None

    def _store_name(self) -> object:
        return self.central.path if self.central is not None else self.site.store_path

    @property
    def name(self) -> str:
        return self.central.name if self.central is not None else self.site.root.resolve().name

    def sections(self) -> Sections:
        numbers = [r.number for r in self.records]
        sessions = []
        for rec in self.records:
            n = rec.number
            sessions.append({
                "number": n, "outcome": rec.outcome, "ended": rec.ended, "counts": rec.counts,
                "started": rec.started_stamp, "ended_stamp": rec.ended_stamp,
                "objects": [node_json(node) for node in self.graphs[n]],
                "events": events_section(self.events.get(n, []), self.params)["items"],
            })
        return {
            "mode": "site",
            "site": {
                "name": self.name, "build": self._build(), "sessions": sessions,
                "path": self._trajectory(), "waypoints": self._waypoints(),
                "default_diff": [numbers[-2] if len(numbers) > 1 else 0, numbers[-1]] if numbers else None,
            },
        }

    def diff(self, a: int, b: int) -> dict[str, Any]:
        """What changed from the end of session ``a`` to the end of ``b`` (0: before any session):
        the net change per node (:mod:`bomc_bt.net_changes`) with its evidence; ``a`` > ``b``
        reads it backwards."""
        for n in (a, b):
            if n not in self.graphs:
                raise BomcError(f"no session {n} (sessions: {sorted(self.graphs)[1:]})", self._store_name(),
                                "session")
        lo, hi = min(a, b), max(a, b)
        history = [e for n in sorted(self.events) if n <= hi for e in self.events[n]]
        changes = net_changes(history, lo if lo > 0 else None, self.threshold)
        items = [change_json(c, backwards=a > b) for c in changes]
        return {"a": a, "b": b, **{k: [i for i in items if i["kind"] == k] for k in REPORTED_KINDS}}

    def _build(self) -> dict[str, Any]:
        payload = self._file(None if self.central else self.site.build_json, "map/build.json")
        if payload is None:
            return {}
        data = _json(payload)
        where = self._store_name() if self.central else self.site.build_json
        if data is None:
            raise BomcError("not a build record (not JSON)", where)
        texts = ("termination", "reason", "outcome")  # older builds wrote explored_area, path_length, reason
        numbers = ("explored_area_m2", "path_length_m", "sim_time_s", "explored_area", "path_length")
        known = [k for k in (*texts, *numbers) if isinstance(data, dict) and k in data]
        wrong = [k for k in known if not (isinstance(data[k], str) if k in texts else
                                          isinstance(data[k], (int, float)) and not isinstance(data[k], bool))]
        if not known or wrong:
            what = f"{wrong[0]} has the wrong type" if wrong else "none of " + ", ".join((*texts, *numbers))
            raise BomcError(f"not a build record ({what})", where)
        return data

    def _trajectory(self) -> list[float]:
        import io

        payload = self._file(None if self.central else self.site.trajectory_csv, "map/trajectory.csv")
        if payload is None:
            return []
        try:
            rows = np.loadtxt(io.BytesIO(payload), delimiter=",", skiprows=1, ndmin=2)
        except ValueError as exc:
            raise BomcError(f"unreadable trajectory ({exc})", "trajectory.csv") from None
        if rows.size == 0:
            return []
        xy = rows[:, 1:3]
        xy = xy[:: max(1, math.ceil(len(xy) / self.params.max_path_points))]
        return np.round(xy, 3).ravel().tolist()

    def _waypoints(self) -> list[dict[str, Any]]:
        data = _json(self._file(None if self.central else self.site.plan_json, "graph/plan.json"))
        raw = data.get("waypoints", []) if isinstance(data, dict) else []
        out = []
        for wp in raw if isinstance(raw, list) else []:
            if isinstance(wp, dict):
                xy: tuple = (wp.get("x"), wp.get("y"))
            else:
                xy = tuple(wp[:2]) if isinstance(wp, list) else ()
            if len(xy) == 2 and all(isinstance(v, (int, float)) for v in xy):
                out.append({"x": rounded(xy[0]), "y": rounded(xy[1]), "state": "pending", "current": False})
        return out


def _json(payload: bytes | None) -> Any:
    """Parsed JSON, or None for a missing or unreadable file (the viewer shows what it can)."""
    import json

    try:
        return None if payload is None else json.loads(payload)
    except ValueError:
        return None


def load_site(store: StateStore, view: SiteView) -> None:
    """Fill ``store`` with a finished site (it never changes afterwards)."""
    if view.grid is not None:
        store.set_map(view.grid)
    store.update(view.sections())
