"""``bomc edit``: an operator's corrections of the map, kept in its history.

``relabel ID CATEGORY``, ``delete ID``, ``restore ID`` and ``note ID TEXT`` each append one
operator event (:data:`~bomc_bt.graph.OPERATOR_KINDS`: relabelled, deleted, restored,
noted) to the node's history and update its row, in one transaction, while holding the
site's writer lock (:mod:`bomc_bt.site_lock`: never beside a build or a pass). Every input
is checked first, against the store read under that lock; bad input is one line, exit 2,
and nothing is written.

An edit is filed under the pass it takes effect in: the next one after the last ended
session (or the open session a killed pass left, which ``--resume`` continues), with
``detail.after_session`` the session the operator looked at. So ``bomc evaluate`` of a
pass scores what the robot did, and the map a pass starts from (``graph_after``) has
every edit made before it. How later passes respect the edits (a relabelled node keeps
its label; a deleted node comes back at the same place only from a detection of at least
``association.readd_confidence``) is in :mod:`bomc_bt.graph.operator_edits`.

``restore`` brings back a node that is not present, deleted by an operator or removed by
a pass, at its last position: the operator says it is there (a later pass that does not
see it removes it again).
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from pathlib import Path

from bomc_bt.errors import BomcError
from bomc_bt.graph import PRESENT, REMOVED, Event, Node
from bomc_bt.site.layout import Site
from bomc_bt.site_lock import SiteLock
from bomc_bt.store import SiteStore

ACTIONS = ("relabel", "delete", "restore", "note")
MAX_CATEGORY = 64  # [count] characters of a category name
MAX_NOTE = 500  # [count] characters of a note


@dataclass(frozen=True)
class EditResult:
    """What an edit did: ``changed`` is False when the node already was as asked."""

    message: str
    changed: bool = True


def edit_site(root: str | Path, action: str, node_id: str | int, value: str | None = None) -> EditResult:
    """Apply one operator edit to the site in ``root`` (see the module docstring)."""
    root = Path(root)
    site = _site(root)
    if action not in ACTIONS:
        raise BomcError(f"unknown edit {action!r} (one of {', '.join(ACTIONS)})", None, "action")
    nid = _node_id(node_id)
    value = _value(action, value)
    with SiteLock.acquire(root, "edit"):
        with SiteStore(site.store_path, readonly=True) as store:
            node, session, after, stamp = _target(store, nid)
        if action == "relabel" and node.category == value:
            return EditResult(f"node {nid} is already labelled {value!r}: nothing changed", changed=False)
        event, changed = _apply(action, node, value, session, stamp, after)
        with SiteStore(site.store_path) as store:
            store.record([event], [changed] if changed is not None else [])
    return EditResult(f"node {nid} {event.kind}{_words(event)} (takes effect from session {session})")


def _site(root: Path) -> Site:
    if not root.is_dir():
        raise BomcError("not a site directory", root)
    site = Site(root)
    if not site.store_path.is_file():
        raise BomcError("no object graph here: run `bomc monitor` first", site.store_path)
    return site


def _node_id(text: str | int) -> int:
    try:
        nid = int(str(text).strip())
    except ValueError:
        raise BomcError(f"not a node id: {str(text)[:40]!r} (a whole number, as `bomc objects` lists)",
                        None, "ID") from None
    if not 0 <= nid < 2**62:
        raise BomcError(f"node id out of range: {nid}", None, "ID")
    return nid


def _value(action: str, value: str | None) -> str | None:
    """The category (relabel) or text (note), checked; None for the others."""
    if action not in ("relabel", "note"):
        if value is not None:
            raise BomcError(f"`{action}` takes only a node id, not {value[:40]!r}", None, action)
        return None
    what, limit = ("CATEGORY", MAX_CATEGORY) if action == "relabel" else ("TEXT", MAX_NOTE)
    if value is None or not value.strip():
        raise BomcError(f"`{action}` needs a non-empty {what}", None, what)
    if len(value) > limit or not value.isprintable() or value != value.strip():
        raise BomcError(f"must be 1 to {limit} printable characters on one line, without leading or "
                        f"trailing spaces: {value[:40]!r}", None, what)
    return value


def _target(store: SiteStore, nid: int) -> tuple[Node, int, int | None, float]:
    """The node, the session the edit is filed under, the last ended session, the stamp."""
    sessions = store.sessions()
    if not sessions:
        raise BomcError("no monitor pass has run on this site: nothing to edit", store.path)
    nodes = {n.id: n for n in store.nodes(include_removed=True)}
    if nid not in nodes:
        span = f"ids {min(nodes)} to {max(nodes)}" if nodes else "no nodes"
        raise BomcError(f"no node {nid} on this site ({span}; `bomc objects` lists them)", store.path, "ID")
    last = sessions[-1]
    ended = [s for s in sessions if s.ended]
    session = last.number + 1 if last.ended else last.number
    stamp = last.ended_stamp if last.ended_stamp is not None else 0.0
    return nodes[nid], session, (ended[-1].number if ended else None), float(stamp)


def _apply(action: str, node: Node, value: str | None, session: int, stamp: float,
           after: int | None) -> tuple[Event, Node | None]:
    """The operator event and the node's new row (None: the row does not change)."""
    detail: dict = {"by": "operator", "after_session": after,
                    "wall": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}
    present = node.state == PRESENT
    if action in ("relabel", "delete") and not present:
        raise BomcError(f"node {node.id} ({node.category}) is not on the map (removed, last seen in session "
                        f"{node.last_session}); `bomc edit ... restore {node.id}` first", None, "ID")
    if action == "restore" and present:
        raise BomcError(f"node {node.id} ({node.category}) is on the map: nothing to restore", None, "ID")
    changed: Node | None = node
    if action == "relabel":
        detail["from"] = node.category
        node.category = str(value)
        kind = "relabelled"
    elif action == "delete":
        node.state, node.misses, kind = REMOVED, 0, "deleted"
    elif action == "restore":
        node.state, node.misses, kind = PRESENT, 0, "restored"
    else:
        detail["text"], changed, kind = value, None, "noted"
    event = Event(kind, node.id, node.category, node.position.copy(), session, stamp, None, node.confidence, detail)
    return event, changed


def _words(event: Event) -> str:
    detail = event.detail or {}
    if event.kind == "relabelled":
        return f" {detail['from']!r} -> {event.category!r}"
    if event.kind == "noted":
        return f": {detail['text']!r}"
    return f" ({event.category})"
