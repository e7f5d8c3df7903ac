"""Corrections from the site viewer (issue 19, item 4): relabel, delete, restore, note a node.

``POST /api/edit`` with ``{"action": "relabel", "id": 7, "value": "cabinet"}`` goes through
the very code ``bomc edit`` runs (:func:`bomc_bt.site.edits.edit_site`): the same checks,
the same operator event in the site's history, the same writer lock. So the viewer cannot
do what the command line may not: an edit beside a running build or pass (or a ``bomc
edit`` in another terminal) is refused with the holder named, and bad input writes
nothing. The request itself is checked first: a JSON object of at most
:data:`MAX_BODY` bytes, sent as ``application/json`` from this server's own page (a
browser sends a cross-site page's POST with a foreign ``Origin``, and cannot send one as
JSON without asking first, which this server never allows).

The ``corrections`` section (pushed to the page after every edit) holds the map as it
stands now, the operator's edits included, and the operator's events, newest last.
"""

from __future__ import annotations

import json
import threading
from typing import Any

from bomc_bt.errors import BomcError
from bomc_bt.viewer.sections import category_hex, node_json, rounded

MAX_BODY = 4096  # [count] bytes of one edit request
FIELDS = ("action", "id", "value")


class CorrectionsApi:
    """The ``/api/edit`` route and the ``corrections`` section of one finished site."""

    def __init__(self, view: Any, state: Any):
        self.view = view
        self.state = state
        self._lock = threading.Lock()  # one edit at a time from this viewer (the site lock covers others)

    def routes(self) -> dict[str, Any]:
        return {"/api/edit": self.edit}

    def publish(self) -> None:
        """Put the current map and the operator's history in the page's state."""
        self.state.update({"corrections": self.section()})

    def section(self) -> dict[str, Any]:
        if self.view.central is not None:
            return {"available": False, "why": "corrections are made on a site directory (bomc pull it first)"}
        from bomc_bt.store import SiteStore

        path = self.view.site.store_path
        if not path.exists():
            return {"available": False, "why": "no object graph yet: run `bomc monitor` first"}
        with SiteStore(path, readonly=True) as store:
            nodes = store.nodes(include_removed=True)
            edits = [e for e in store.events(operator=True) if e.by_operator]
        return {
            "available": True,
            "objects": [{**node_json(n), "state": n.state} for n in sorted(nodes, key=lambda n: n.id)],
            "edits": [{"kind": e.kind, "id": int(e.node_id), "category": e.category, "session": int(e.session),
                       "x": rounded(e.position[0]), "y": rounded(e.position[1]), "detail": e.detail or {},
                       "colour": category_hex(e.category)} for e in edits],
        }

    def edit(self, payload: Any) -> dict[str, Any]:
        from bomc_bt.site.edits import edit_site

        action, node_id, value = _request(payload)
        if self.view.central is not None:
            raise BomcError("corrections are made on a site directory (bomc pull it first)", None, "site")
        with self._lock:
            result = edit_site(self.view.site.root, action, node_id, value)
            self.publish()
        return {"message": result.message, "changed": result.changed}


def _request(payload: Any) -> tuple[str, int | str, str | None]:
    """``action``, ``id`` and ``value`` of an edit request, type-checked (edit_site checks the rest)."""
    if not isinstance(payload, dict):
        raise BomcError("an edit is a JSON object {action, id, value}", None, "body")
    unknown = sorted(set(payload) - set(FIELDS))
    if unknown:
        raise BomcError(f"unknown field {unknown[0][:40]!r} (expected {', '.join(FIELDS)})", None, "body")
    action, node_id, value = payload.get("action"), payload.get("id"), payload.get("value")
    if not isinstance(action, str):
        raise BomcError("give the edit's action: relabel, delete, restore or note", None, "action")
    if isinstance(node_id, bool) or not isinstance(node_id, (int, str)):
        raise BomcError("give the node's id (a whole number)", None, "id")
    if value is not None and not isinstance(value, str):
        raise BomcError("the value is text (a category or a note)", None, "value")
    if value == "" and action not in ("relabel", "note"):
        value = None  # a form's empty field: no value
    return action, node_id, value


def read_request(headers: Any, body: Any, port: int) -> Any:
    """The JSON of a POST from this server's own page; BomcError for anything else."""
    kind = (headers.get("Content-Type") or "").split(";")[0].strip().lower()
    if kind != "application/json":
        raise BomcError("send the edit as application/json", None, "Content-Type")
    origin = headers.get("Origin")
    if origin is not None and origin.rstrip("/") not in (f"http://127.0.0.1:{port}", f"http://localhost:{port}"):
        raise BomcError(f"edits are taken from this viewer's own page only, not from {origin[:60]!r}", None,
                        "Origin")
    try:
        length = int(headers.get("Content-Length") or "")
    except ValueError:
        raise BomcError("a request without its length", None, "Content-Length") from None
    if not 0 < length <= MAX_BODY:
        raise BomcError(f"an edit request is 1 to {MAX_BODY} bytes, not {length}", None, "Content-Length")
    try:
        return json.loads(body.read(length).decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise BomcError("not JSON", None, "body") from None
