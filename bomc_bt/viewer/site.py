"""A finished site for the viewer: the map, the trajectory, each session's graph and events."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.graph import Event, Node
from bomc_bt.viewer.sections import diff_nodes, events_section, node_json, rounded
from bomc_bt.viewer.store import Sections, StateStore, ViewerParams


class SiteView:
    """A finished site read once: the map, the trajectory, each session's graph and events."""

    def __init__(self, site_dir: str | Path, params: ViewerParams | None = None):
        from bomc_bt.grid import load_map
        from bomc_bt.site import Site
        from bomc_bt.store import SiteStore

        self.params = params or ViewerParams()
        self.site = Site(Path(site_dir))
        if not self.site.root.is_dir():
            raise BomcError("not a site directory", self.site.root)
        self.grid = load_map(self.site.map_yaml) if self.site.map_yaml.exists() else None
        self.graphs: dict[int, list[Node]] = {0: []}
        self.events: dict[int, list[Event]] = {}
        self.records = []
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
                "name": self.site.root.resolve().name, "build": self._build(), "sessions": sessions,
                "path": self._trajectory(), "waypoints": self._waypoints(),
                "default_diff": [numbers[-2] if len(numbers) > 1 else 0, numbers[-1]] if numbers else None,
            },
        }

    def diff(self, a: int, b: int) -> dict[str, Any]:
        """What changed from the end of session ``a`` to the end of ``b`` (0: before any session)."""
        for n in (a, b):
            if n not in self.graphs:
                raise BomcError(f"no session {n} (sessions: {sorted(self.graphs)[1:]})", self.site.store_path,
                                "session")
        lo, hi = min(a, b), max(a, b)
        between = [e for n in range(lo + 1, hi + 1) for e in self.events.get(n, [])]
        moved = {e.node_id for e in between if e.kind == "moved"}
        changes = diff_nodes(self.graphs[a], self.graphs[b], self.params.moved_distance, moved)
        return {"a": a, "b": b, **changes}

    def _build(self) -> dict[str, Any]:
        from bomc_bt.site import read_json

        if not self.site.build_json.exists():
            return {}
        data = read_json(self.site.build_json)  # unreadable: refused, not shown as an empty build
        texts = ("termination", "reason", "outcome")  # older builds wrote explored_area, path_length, reason
        numbers = ("explored_area_m2", "path_length_m", "sim_time_s", "explored_area", "path_length")
        known = [k for k in (*texts, *numbers) if isinstance(data, dict) and k in data]
        wrong = [k for k in known if not (isinstance(data[k], str) if k in texts else
                                          isinstance(data[k], (int, float)) and not isinstance(data[k], bool))]
        if not known or wrong:
            what = f"{wrong[0]} has the wrong type" if wrong else "none of " + ", ".join((*texts, *numbers))
            raise BomcError(f"not a build record ({what})", self.site.build_json)
        return data

    def _trajectory(self) -> list[float]:
        path = self.site.trajectory_csv
        if not path.exists():
            return []
        try:
            rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        except ValueError as exc:
            raise BomcError(f"unreadable trajectory ({exc})", path) from None
        if rows.size == 0:
            return []
        xy = rows[:, 1:3]
        xy = xy[:: max(1, math.ceil(len(xy) / self.params.max_path_points))]
        return np.round(xy, 3).ravel().tolist()

    def _waypoints(self) -> list[dict[str, Any]]:
        from bomc_bt.site import read_json

        if not self.site.plan_json.exists():
            return []
        try:
            data = read_json(self.site.plan_json)
        except BomcError:
            return []
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


def load_site(store: StateStore, view: SiteView) -> None:
    """Fill ``store`` with a finished site (it never changes afterwards)."""
    if view.grid is not None:
        store.set_map(view.grid)
    store.update(view.sections())
