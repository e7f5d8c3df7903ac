"""What the web viewer shows, as versioned JSON sections, for a running mission or a finished site.

The page is a pure function of a handful of *sections* (``tree``, ``blackboard``,
``progress``, ``scene``, ``events``, ``map``, ``site``). :class:`StateStore` keeps the
latest value of each with the version at which it last changed, so the server pushes only
the sections that changed since what a client has seen, and a client that reconnects with
an unknown or stale version (a restarted server: another ``epoch``) gets everything.

The occupancy grid is the one big thing: it never goes into JSON. The store keeps a copy
of the cells and the ``map`` section carries only its version and geometry; the server
encodes the PNG lazily, on its own thread, once per version.

:class:`ViewerHook` is the ``on_tick`` hook of a live mission. Ticks are the mission's hot
loop, so a tick costs a pose read (the path is tracked every tick, or a fast simulation
would draw a coarse path) and, at most ``interval_wall_s`` of *wall* time apart, one
sample of the mission. Wall time only paces the display; nothing the robot does depends on
it. The map is copied at most every ``map_interval_sim_s`` robot seconds and only when the
robot port handed out a new grid object (the simulated mapper caches its grid between scans).
"""

from __future__ import annotations

import math
import os
import reprlib
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import py_trees
from py_trees.common import Status

from bomc_bt.errors import BomcError
from bomc_bt.graph import Event, Node
from bomc_bt.grid import OccupancyGrid
from bomc_bt.tree.view import snapshot

Sections = dict[str, Any]


@dataclass
class ViewerParams:
    """Tunables of the viewer (display only: none of them changes what the robot does)."""

    interval_wall_s: float = 0.2  # at most 5 samples per wall second
    map_interval_sim_s: float = 2.0  # the live map is copied at most this often (robot s)
    path_step: float = 0.05  # m the robot must move before the path gets a new point
    max_path_points: int = 4000  # older path points are thinned beyond this
    max_events: int = 200  # newest events kept in the log
    highlight_s: float = 30.0  # robot s an added / moved object stays highlighted
    max_frontier_cells: int = 4000  # frontier cells sent, subsampled evenly beyond this
    blackboard_keys: int = 200  # keys shown
    value_chars: int = 80  # characters of a blackboard value's repr
    moved_distance: float = 0.5  # m: site diff calls a node moved beyond this (or on a moved event)


# ---------------------------------------------------------------------------- the store
class StateStore:
    """Thread-safe latest value of every section, each with the version it last changed at."""

    def __init__(self) -> None:
        self.epoch = f"{os.getpid():x}{time.time_ns():x}"  # tells a restarted server from this one
        self._cond = threading.Condition()
        self._version = 0
        self._sections: Sections = {}
        self._changed_at: dict[str, int] = {}
        self._map_cells: np.ndarray | None = None
        self._png: tuple[int, bytes] | None = None
        self._closed = False

    @property
    def version(self) -> int:
        with self._cond:
            return self._version

    def update(self, sections: Sections) -> int:
        """Store the sections whose value differs from the stored one; returns the version."""
        with self._cond:
            changed = [k for k, v in sections.items() if k not in self._sections or self._sections[k] != v]
            if changed:
                self._version += 1
                for key in changed:
                    self._sections[key] = sections[key]
                    self._changed_at[key] = self._version
                self._cond.notify_all()
            return self._version

    def set_map(self, grid: OccupancyGrid) -> None:
        """A new occupancy grid: copy its cells and bump the ``map`` section."""
        cells = np.array(grid.data, dtype=np.int8, copy=True)
        with self._cond:
            if self._map_cells is not None and np.array_equal(self._map_cells, cells):
                return
            self._map_cells = cells
            number = self._sections.get("map", {}).get("number", 0) + 1
        self.update({"map": {
            "number": number, "width": int(grid.width), "height": int(grid.height),
            "resolution": float(grid.resolution), "origin": [float(grid.origin[0]), float(grid.origin[1])],
        }})

    def changes(self, since: int | None) -> tuple[int, Sections, bool]:
        """(version, sections changed after ``since``, full); ``since`` None or ahead of us: all."""
        with self._cond:
            full = since is None or since > self._version
            picked = {k: v for k, v in self._sections.items() if full or self._changed_at[k] > since}
            return self._version, picked, full

    def wait(self, since: int, timeout: float) -> bool:
        """Block until the version passes ``since`` (True) or ``timeout`` wall seconds pass."""
        with self._cond:
            return self._cond.wait_for(lambda: self._closed or self._version > since, timeout)

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        return self._closed

    def map_png(self) -> bytes | None:
        """The current map as a north-up grey PNG (encoded once per map version)."""
        import cv2

        with self._cond:
            cells = self._map_cells
            number = self._sections.get("map", {}).get("number", 0)
            if cells is None:
                return None
            if self._png is not None and self._png[0] == number:
                return self._png[1]
        ok, data = cv2.imencode(".png", map_pixels(cells))
        if not ok:
            raise OSError("cannot encode the map as PNG")
        png = data.tobytes()
        with self._cond:
            self._png = (number, png)
        return png


def map_pixels(cells: np.ndarray) -> np.ndarray:
    """Grey levels as ``render.map_image`` draws them (unknown 205, free 254, occupied 40), north up."""
    img = np.full(cells.shape, 205, dtype=np.uint8)
    img[cells == 0] = 254
    img[cells >= 50] = 40
    return np.ascontiguousarray(np.flipud(img))


# --------------------------------------------------------------------- section builders
_COLOURS: dict[str, str] = {}


def category_hex(category: str) -> str:
    """``render.category_colour`` as CSS ``#rrggbb`` (the PNG reports and the page agree)."""
    colour = _COLOURS.get(category)
    if colour is None:
        from bomc_bt.render import category_colour

        b, g, r = category_colour(category)
        colour = _COLOURS[category] = f"#{r:02x}{g:02x}{b:02x}"
    return colour


def _r(value: float, digits: int = 3) -> float:
    return round(float(value), digits)


def tree_section(root: py_trees.behaviour.Behaviour) -> dict[str, Any]:
    return snapshot(root)


def blackboard_section(storage: dict[str, Any], params: ViewerParams) -> list[list[str]]:
    """``[[key, short repr], ...]`` sorted by key: what the tree branches on, readable at a glance."""
    short = reprlib.Repr()
    short.maxstring = short.maxother = params.value_chars
    short.maxlist = short.maxtuple = short.maxdict = short.maxset = 6
    rows = []
    for key in sorted(storage)[: params.blackboard_keys]:
        try:
            text = short.repr(storage[key])
        except Exception as exc:  # a user's object with a broken __repr__ must not stop the mission
            text = f"<unprintable {type(storage[key]).__name__}: {exc}>"
        if len(text) > params.value_chars:
            text = text[: params.value_chars - 1] + "…"
        rows.append([str(key), text])
    return rows


def node_json(node: Node) -> dict[str, Any]:
    p = node.position
    return {"id": int(node.id), "category": node.category, "x": _r(p[0]), "y": _r(p[1]), "z": _r(p[2]),
            "confidence": _r(node.confidence, 2), "colour": category_hex(node.category)}


def event_json(event: Event) -> dict[str, Any]:
    p = event.position
    out = {"kind": event.kind, "id": int(event.node_id), "category": event.category, "x": _r(p[0]),
           "y": _r(p[1]), "session": int(event.session), "stamp": _r(event.stamp, 2),
           "colour": category_hex(event.category)}
    if event.previous is not None:
        out["from"] = [_r(event.previous[0]), _r(event.previous[1])]
    return out


def events_section(events: Sequence[Event], params: ViewerParams) -> dict[str, Any]:
    """The newest structural events (added / removed / moved): ``updated`` refreshes are noise here."""
    picked: list[Event] = []
    for e in reversed(events):
        if e.kind != "updated":
            picked.append(e)
            if len(picked) >= params.max_events:
                break
    return {"total": len(events), "items": [event_json(e) for e in reversed(picked)]}


def frontiers_json(frontiers: Iterable[Any], grid: OccupancyGrid | None, limit: int) -> list[dict[str, Any]]:
    """Centroids and (evenly thinned) cells in world metres; cells need the grid's geometry."""
    frontiers = list(frontiers or [])
    total = sum(int(getattr(f, "size", len(getattr(f, "cells", ())))) for f in frontiers) or 1
    out = []
    for f in frontiers:
        item: dict[str, Any] = {"centroid": [_r(f.centroid[0]), _r(f.centroid[1])],
                                "size": int(getattr(f, "size", 0))}
        cells = getattr(f, "cells", None)
        if grid is not None and cells is not None and len(cells):
            cells = np.asarray(cells)
            keep = max(1, int(limit * len(cells) / total))
            cells = cells[:: max(1, math.ceil(len(cells) / keep))]
            xs = grid.origin[0] + (cells[:, 1] + 0.5) * grid.resolution
            ys = grid.origin[1] + (cells[:, 0] + 0.5) * grid.resolution
            item["cells"] = np.round(np.stack([xs, ys], axis=1), 3).ravel().tolist()
        out.append(item)
    return out


def waypoints_json(plan: Any, traverse: Any) -> list[dict[str, Any]]:
    if plan is None:
        return []
    states = list(getattr(traverse, "states", []) or [])
    current = getattr(traverse, "current", None)
    out = []
    for i, wp in enumerate(plan.waypoints):
        out.append({"x": _r(wp.x), "y": _r(wp.y), "state": states[i] if i < len(states) else "pending",
                    "current": i == current})
    return out


def progress_section(ctx: Any, runner: Any) -> dict[str, Any]:
    p = ctx.progress
    out = {"mission": ctx.mission, "session": int(ctx.session), "sim_time": _r(ctx.now(), 2),
           "elapsed": _r(runner.elapsed, 2), "ticks": int(runner.ticks),
           "status": runner.root.status.value.lower(),
           "explored_area": _r(p.explored_area, 2), "path_length": _r(p.path_length, 2),
           "waypoint": int(p.waypoint), "waypoints": int(p.waypoints), "frames": int(p.frames),
           "nodes": int(p.nodes), "message": p.message}
    if ctx.explorer is not None:
        out["goals"] = int(getattr(ctx.explorer, "goals", 0))
    return out


# ------------------------------------------------------------------------ live mission
class PathTracker:
    """The robot's path, one point per ``step`` metres, thinned by half when it grows too long."""

    def __init__(self, step: float, limit: int):
        self.step = step
        self.limit = max(limit, 2)
        self.points: list[tuple[float, float]] = []

    def add(self, x: float, y: float) -> None:
        if self.points:
            lx, ly = self.points[-1]
            if math.hypot(x - lx, y - ly) < self.step:
                return
        self.points.append((x, y))
        if len(self.points) > self.limit:
            self.points = self.points[::2] + ([self.points[-1]] if len(self.points) % 2 == 0 else [])

    def flat(self) -> list[float]:
        return [_r(v) for xy in self.points for v in xy]


class ViewerHook:
    """``on_tick`` hook that samples a running mission into a :class:`StateStore`.

    ``sink`` is the store or anything with a ``state`` store (the :class:`~.server.Server`).
    ``wall_clock`` is injectable for tests; it paces the display only.
    """

    def __init__(self, sink: Any, ctx: Any, params: ViewerParams | None = None,
                 wall_clock: Callable[[], float] = time.monotonic):
        self.store: StateStore = sink if isinstance(sink, StateStore) else sink.state
        self.ctx = ctx
        self.params = params or ViewerParams()
        self.wall_clock = wall_clock
        self.path = PathTracker(self.params.path_step, self.params.max_path_points)
        self.samples = 0
        self._last_wall: float | None = None
        self._grid: OccupancyGrid | None = None
        self._map_sim: float | None = None

    def __call__(self, runner: Any) -> None:
        pose = self.ctx.robot.pose()
        if pose is not None:
            self.path.add(float(pose.x), float(pose.y))
        done = runner.root.status in (Status.SUCCESS, Status.FAILURE)
        now = self.wall_clock()
        if not done and self._last_wall is not None and now - self._last_wall < self.params.interval_wall_s:
            return
        self._last_wall = now
        self.sample(runner, force_map=done)

    def sample(self, runner: Any, force_map: bool = False) -> None:
        """Read the mission once and hand the sections to the store (the server thread sends them)."""
        ctx = self.ctx
        grid = self._maybe_map(force_map)
        self.store.update({
            "mode": "live",
            "tree": tree_section(runner.root),
            "blackboard": blackboard_section(py_trees.blackboard.Blackboard.storage, self.params),
            "progress": progress_section(ctx, runner),
            "scene": self._scene(grid),
            "events": self._events(),
        })
        self.samples += 1

    def _maybe_map(self, force: bool) -> OccupancyGrid | None:
        """The live grid; copied into the store when it is a new grid and the interval passed."""
        try:
            grid = self.ctx.robot.live_map()
        except Exception:  # a robot without a map yet (ROS before the first /map message)
            return self._grid
        sim_now = self.ctx.now()
        due = self._map_sim is None or sim_now - self._map_sim >= self.params.map_interval_sim_s
        if grid is not None and grid is not self._grid and (due or force):
            self.store.set_map(grid)
            self._grid, self._map_sim = grid, sim_now
        return self._grid

    def _scene(self, grid: OccupancyGrid | None) -> dict[str, Any]:
        ctx = self.ctx
        pose = ctx.robot.pose()
        graph = ctx.graph
        explorer = ctx.explorer
        scene: dict[str, Any] = {
            "robot": None if pose is None else [_r(pose.x), _r(pose.y), _r(pose.yaw)],
            "path": self.path.flat(),
            "objects": [node_json(n) for n in (graph.nodes.values() if graph is not None else [])],
            "waypoints": waypoints_json(ctx.plan, ctx.traverse),
            "frontiers": [], "blacklist": [],
        }
        if explorer is not None:
            scene["frontiers"] = frontiers_json(getattr(explorer, "frontiers", None), grid,
                                                self.params.max_frontier_cells)
            points = getattr(getattr(explorer, "blacklist", None), "points", []) or []
            scene["blacklist"] = [[_r(x), _r(y)] for x, y in points]
        scene["highlight"] = self._highlight()
        return scene

    def _highlight(self) -> dict[str, str]:
        """Object id -> the kind of its latest recent change, for the map's halo."""
        events = getattr(self.ctx.perception, "events", None) or []
        horizon = self.ctx.now() - self.params.highlight_s
        marks: dict[str, str] = {}
        for e in reversed(events):
            if e.stamp < horizon:
                break
            if e.kind != "updated":
                marks.setdefault(str(e.node_id), e.kind)
        return marks

    def _events(self) -> dict[str, Any]:
        events = getattr(self.ctx.perception, "events", None) or []
        return events_section(events, self.params)


# ------------------------------------------------------------------------ finished site
def diff_nodes(before: Iterable[Node], after: Iterable[Node], moved_distance: float,
               moved_ids: Iterable[int] = ()) -> dict[str, list[dict[str, Any]]]:
    """Added / removed / moved between two graphs (ids are never reused, so ids decide).

    A node is moved when a ``moved`` event touched it in between (``moved_ids``) or it is
    more than ``moved_distance`` from where it was: small drift from refreshes is not a move.
    """
    old = {n.id: n for n in before}
    new = {n.id: n for n in after}
    marked = set(moved_ids)
    moved = []
    for nid in sorted(old.keys() & new.keys()):
        a, b = old[nid].position, new[nid].position
        dist = float(np.hypot(*(b[:2] - a[:2])))
        if (nid in marked and dist > 1e-6) or dist > moved_distance:
            moved.append({**node_json(new[nid]), "from": [_r(a[0]), _r(a[1])], "distance": _r(dist, 2)})
    return {
        "added": [node_json(new[i]) for i in sorted(new.keys() - old.keys())],
        "removed": [node_json(old[i]) for i in sorted(old.keys() - new.keys())],
        "moved": moved,
    }


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
            store = SiteStore(self.site.store_path)
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
        try:
            data = read_json(self.site.build_json)
        except BomcError:
            return {}
        return data if isinstance(data, dict) else {}

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
                out.append({"x": _r(xy[0]), "y": _r(xy[1]), "state": "pending", "current": False})
        return out


def load_site(store: StateStore, view: SiteView) -> None:
    """Fill ``store`` with a finished site (it never changes afterwards)."""
    if view.grid is not None:
        store.set_map(view.grid)
    store.update(view.sections())
