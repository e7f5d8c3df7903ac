"""A graph rebuilt from its history: what any store (the site's SQLite, the central
PostgreSQL) replays to answer "which objects stood there after session N"."""

from __future__ import annotations

from collections.abc import Iterable

from bomc_bt.graph.records import PRESENT, REMOVED, Event, Node


def replay_graph(events: Iterable[Event]) -> list[Node]:
    """The present nodes after ``events`` (history in write order): how a graph is rebuilt
    from any store. Operator edits (:mod:`bomc_bt.site.edits`) relabel, delete and restore."""
    nodes: dict[int, Node] = {}
    for e in events:
        node = nodes.get(e.node_id)
        if e.kind == "added" or node is None:
            nodes[e.node_id] = Node(e.node_id, e.category, e.position, e.confidence, e.session, e.session)
            if e.kind in ("removed", "deleted"):
                nodes[e.node_id].state = REMOVED
            continue
        node.position = e.position
        node.confidence = e.confidence
        node.category = e.category  # an operator's relabelling
        if e.kind in ("removed", "deleted"):
            node.state = REMOVED
        elif e.kind == "restored":
            node.state = PRESENT
        elif not e.by_operator:
            node.state = PRESENT
            node.last_session = e.session
            node.observations += 1
    return [n for _, n in sorted(nodes.items()) if n.state == PRESENT]


def withdrawn_nodes(events: Iterable[Event]) -> set[int]:
    """The nodes whose last removal among ``events`` (a pass's, in write order) retracted them as
    missed moments after a sighting (``contradicted`` in its detail; ``association.retract_within``):
    the map withdrew them, no object went."""
    last = {e.node_id: e for e in events if e.kind == "removed"}
    return {nid for nid, e in last.items() if e.retracted and "contradicted" in (e.detail or {})}
