"""The query results as text: an aligned table, JSON, CSV and GeoJSON.

GeoJSON (RFC 7946 structure) is written in the **map frame**, not WGS 84: coordinates are
``[x, y, z]`` metres of the site's map (the frame of ``map.yaml``, the robot's ``map``
frame), which the collection says in its foreign members ``"frame": "map"`` and
``"units": "m"``. GIS tools place it on the map PNG through the PNG's world file
(:mod:`bomc_bt.site.export`), which is in the same coordinates.

CSV has a header row; ``sessions_seen`` is space separated, notes are joined by `` | ``.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from typing import Any

from bomc_bt.net_changes import NEW_BECAUSE
from bomc_bt.site.query import SessionChanges, SiteObject

OBJECT_FORMATS = ("table", "json", "csv", "geojson")
CHANGE_FORMATS = ("table", "json", "csv")
OBJECT_COLUMNS = ("id", "category", "x", "y", "z", "confidence", "first_seen", "last_seen", "sessions_seen",
                  "notes", "distance")
CHANGE_COLUMNS = ("session", "kind", "id", "category", "old_x", "old_y", "new_x", "new_y", "moved_m",
                  "missing_frames", "merged", "last_seen_session", "last_seen_stamp", "back_of", "first_seen_why")


def format_objects(objects: Sequence[SiteObject], fmt: str, header: dict[str, Any] | None = None) -> str:
    """``objects`` in ``fmt`` (one of :data:`OBJECT_FORMATS`); ``header`` adds top-level JSON keys."""
    if fmt == "json":
        return json.dumps({**(header or {}), "objects": [o.to_json() for o in objects]}, indent=1) + "\n"
    if fmt == "geojson":
        return json.dumps(objects_geojson(objects, header), indent=1) + "\n"
    rows = [_object_row(o) for o in objects]
    if fmt == "csv":
        return _csv(OBJECT_COLUMNS, rows)
    if not rows:
        return "no objects\n"
    near = objects[0].distance is not None
    table = [[*r[:9], *(r[10:] if near else []), _short(r[9], 40)] for r in rows]
    columns = ("id", "category", "x", "y", "z", "conf", "first", "last", "sessions", *(("dist",) if near else ()))
    return _table((*columns, "note"), table)


def objects_geojson(objects: Sequence[SiteObject], header: dict[str, Any] | None = None) -> dict[str, Any]:
    """A FeatureCollection of Points in the map frame (see the module docstring)."""
    features = []
    for o in objects:
        props = o.to_json()
        coords = props.pop("position")
        features.append({"type": "Feature", "id": o.id, "geometry": {"type": "Point", "coordinates": coords},
                         "properties": props})
    return {"type": "FeatureCollection", "frame": "map", "units": "m", **(header or {}), "features": features}


def format_changes(result: Sequence[SessionChanges], fmt: str) -> str:
    """Per pass: its net changes with their evidence, then the operator's edits."""
    if fmt == "json":
        return json.dumps({"sessions": [s.to_json() for s in result]}, indent=1) + "\n"
    rows = [_change_row(c.to_json()) for s in result for c in s.changes]
    if fmt == "csv":
        return _csv(CHANGE_COLUMNS, rows)
    lines = []
    for s in result:
        since = "the empty map" if s.previous is None else f"session {s.previous}"
        if s.pending:
            lines.append(f"session {s.session} (not run yet): {len(s.edits)} operator edit(s) waiting for it")
        else:
            first = sum(c.kind == "first_seen" for c in s.changes)  # new to the map: listed, not changes
            withdrawn = sum(c.kind == "retracted" for c in s.changes)  # seen too seldom: listed, not changes
            lines.append(f"session {s.session} (since {since}): {len(s.changes) - first - withdrawn} change(s)"
                         + (f", {first} first seen" if first else "")
                         + (f", {withdrawn} retracted" if withdrawn else ""))
        lines.extend("  " + _describe(c.to_json()) for c in s.changes)
        lines.extend(f"  operator {e.kind} node {e.node_id} ({e.category}){_edit_words(e.detail)}" for e in s.edits)
    return "\n".join(lines or ["no recorded session in that range"]) + "\n"


def _object_row(o: SiteObject) -> list[Any]:
    x, y, z = (round(v, 3) for v in o.position)
    return [o.id, o.category, x, y, z, round(o.confidence, 3), o.first_seen, o.last_seen,
            " ".join(map(str, o.sessions_seen)), " | ".join(o.notes),
            None if o.distance is None else round(o.distance, 3)]


def _change_row(c: dict[str, Any]) -> list[Any]:
    old, new = c["old"] or [None, None], c["new"] or [None, None]
    return [c["session"], c["kind"], c["id"], c["category"], old[0], old[1], new[0], new[1], c["moved_m"],
            c["missing_frames"], c["merged"], c["last_seen_session"], c["last_seen_stamp"], c.get("back_of"),
            c.get("first_seen_why")]


def _describe(c: dict[str, Any]) -> str:
    def at(p):
        return f"({p[0]:.2f}, {p[1]:.2f})"

    words = f"{c['kind']} node {c['id']} ({c['category']})"
    if c["kind"] == "retracted":
        words += f" at {at(c['old'])}: seen in too few frames to trust, or missed moments after a sighting"
    elif c["kind"] == "removed":
        words += f" at {at(c['old'])}: " + ("merged into a neighbour" if c["merged"] else
                                           f"missing in {_or_unknown(c['missing_frames'])} frame(s)")
    elif c["kind"] in ("added", "first_seen"):  # first seen: new to the map where no earlier pass looked
        words += f" at {at(c['new'])}" + ("" if c.get("back_of") is None else f", back where node {c['back_of']} went")
        if c["kind"] == "first_seen" and c.get("first_seen_why") in NEW_BECAUSE:
            words += f" ({NEW_BECAUSE[c['first_seen_why']]})"
    else:
        words += f" {at(c['old'])} -> {at(c['new'])}, {c['moved_m']:.2f} m"
    if c["last_seen_session"] is not None:
        words += f"; last seen in session {c['last_seen_session']} at {c['last_seen_stamp']:.1f} s"
    return words


def _edit_words(detail: dict[str, Any]) -> str:
    if "from" in detail:
        return f" from {detail['from']!r}"
    if "text" in detail:
        return f": {_short(str(detail['text']), 60)}"
    return ""


def _or_unknown(value: Any) -> str:
    return "?" if value is None else str(value)


def _short(text: str, width: int) -> str:
    return text if len(text) <= width else text[:width - 3] + "..."


def _csv(columns: Sequence[str], rows: list[list[Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    writer.writerows([["" if v is None else v for v in row] for row in rows])
    return buffer.getvalue()


def _table(columns: Sequence[str], rows: list[list[Any]]) -> str:
    cells = [list(map(str, columns))] + [[str(v) for v in row] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(columns))]
    return "\n".join("  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip() for r in cells) + "\n"
