"""The JSON sections of the viewer, built from plain values: objects, events, frontiers,
waypoints, progress, the blackboard with the leaves' ports, and the diff of two graphs."""

from __future__ import annotations

import math
import reprlib
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import py_trees

from bomc_bt.exploration.frontiers import Frontier
from bomc_bt.graph import Event, Node
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitoring import TraversalState
from bomc_bt.net_changes import NetChange
from bomc_bt.traversal import TraversalPlan
from bomc_bt.tree.view import snapshot
from bomc_bt.viewer.store import ViewerParams

Ports = Mapping[str, Mapping[str, Sequence[str]]]
"""Blackboard key -> {"reads": leaf names, "writes": leaf names} (see :func:`bomc_bt.tree.view.tree_ports`)."""


_COLOURS: dict[str, str] = {}


def category_hex(category: str) -> str:
    """``render.category_colour`` as CSS ``#rrggbb`` (the PNG reports and the page agree)."""
    colour = _COLOURS.get(category)
    if colour is None:
        from bomc_bt.render import category_colour

        b, g, r = category_colour(category)
        colour = _COLOURS[category] = f"#{r:02x}{g:02x}{b:02x}"
    return colour


def rounded(value: float, digits: int = 3) -> float:
    return round(float(value), digits)


def tree_section(root: py_trees.behaviour.Behaviour) -> dict[str, Any]:
    return snapshot(root)


def blackboard_section(storage: Mapping[str, Any], params: ViewerParams, ports: Ports | None = None) -> list[list[str]]:
    """``[[key, short repr, ports], ...]`` sorted by key: what the tree branches on, readable at a glance.

    Every key a leaf declares is listed, written yet or not (``—``), with the leaves that
    write and read it, so the panel shows the tree's data flow as well as its values.
    """
    ports = ports or {}
    short = reprlib.Repr()
    short.maxstring = short.maxother = params.value_chars
    short.maxlist = short.maxtuple = short.maxdict = short.maxset = 6
    rows = []
    for key in sorted(set(storage) | set(ports))[: params.blackboard_keys]:
        text = "—"
        if key in storage:
            try:
                text = short.repr(storage[key])
            except Exception as exc:  # a user's object with a broken __repr__ must not stop the mission
                text = f"<unprintable {type(storage[key]).__name__}: {exc}>"
        if len(text) > params.value_chars:
            text = text[: params.value_chars - 1] + "…"
        rows.append([str(key), text, port_text(ports.get(key, {}))])
    return rows


def port_text(port: Mapping[str, Sequence[str]]) -> str:
    """``written by A, B · read by C`` (empty for a key no leaf declares)."""
    parts = [f"{verb} by {', '.join(dict.fromkeys(port[kind]))}"
             for kind, verb in (("writes", "written"), ("reads", "read")) if port.get(kind)]
    return " · ".join(parts)


def node_json(node: Node) -> dict[str, Any]:
    p = node.position
    return {"id": int(node.id), "category": node.category, "x": rounded(p[0]), "y": rounded(p[1]), "z": rounded(p[2]),
            "confidence": rounded(node.confidence, 2), "colour": category_hex(node.category)}


def event_json(event: Event) -> dict[str, Any]:
    p = event.position
    out = {"kind": event.kind, "id": int(event.node_id), "category": event.category, "x": rounded(p[0]),
           "y": rounded(p[1]), "session": int(event.session), "stamp": rounded(event.stamp, 2),
           "colour": category_hex(event.category)}
    if event.previous is not None:
        out["from"] = [rounded(event.previous[0]), rounded(event.previous[1])]
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


def frontiers_json(frontiers: Iterable[Frontier], grid: OccupancyGrid | None, limit: int) -> list[dict[str, Any]]:
    """Centroids and (evenly thinned) cells in world metres; cells need the grid's geometry."""
    frontiers = list(frontiers)
    total = sum(int(f.size) for f in frontiers) or 1
    out = []
    for f in frontiers:
        item: dict[str, Any] = {"centroid": [rounded(f.centroid[0]), rounded(f.centroid[1])], "size": int(f.size)}
        cells = f.cells
        if grid is not None and len(cells):
            cells = np.asarray(cells)
            keep = max(1, int(limit * len(cells) / total))
            cells = cells[:: max(1, math.ceil(len(cells) / keep))]
            xs = grid.origin[0] + (cells[:, 1] + 0.5) * grid.resolution
            ys = grid.origin[1] + (cells[:, 0] + 0.5) * grid.resolution
            item["cells"] = np.round(np.stack([xs, ys], axis=1), 3).ravel().tolist()
        out.append(item)
    return out


def waypoints_json(plan: TraversalPlan | None, traverse: TraversalState | None) -> list[dict[str, Any]]:
    if plan is None:
        return []
    states = traverse.states if traverse is not None else []
    current = traverse.current if traverse is not None else None
    out = []
    for i, wp in enumerate(plan.waypoints):
        out.append({"x": rounded(wp.x), "y": rounded(wp.y), "state": states[i] if i < len(states) else "pending",
                    "current": i == current})
    return out


def progress_section(ctx: Any, runner: Any) -> dict[str, Any]:
    p = ctx.progress
    out = {"mission": ctx.mission, "session": int(ctx.session), "sim_time": rounded(ctx.now(), 2),
           "elapsed": rounded(runner.elapsed, 2), "ticks": int(runner.ticks),
           "status": runner.root.status.value.lower(),
           "explored_area": rounded(p.explored_area, 2), "path_length": rounded(p.path_length, 2),
           "waypoint": int(p.waypoint), "waypoints": int(p.waypoints), "frames": int(p.frames),
           "nodes": int(p.nodes), "message": p.message}
    if ctx.explorer is not None:
        out["goals"] = int(ctx.explorer.goals)
    return out


def change_json(change: NetChange, backwards: bool = False) -> dict[str, Any]:
    """A net change for the site diff: where to draw it, what it was, and the operator's line.

    ``backwards`` (the later session chosen first): an addition reads as a removal, a move
    runs from its new place to its old one.
    """
    kind, old, new = change.kind, change.old, change.new
    if backwards:
        kind, old, new = {"added": "removed", "removed": "added"}.get(kind, kind), new, old
    at = new if new is not None else old
    out = {"kind": kind, "id": int(change.node_id), "category": change.category, "x": rounded(at[0]),
           "y": rounded(at[1]), "colour": category_hex(change.category), "text": change.describe(),
           "evidence": change.to_json()}
    if kind == "moved":
        out["from"] = [rounded(old[0]), rounded(old[1])]
        out["distance"] = rounded(change.distance, 2)
    return out
