"""Moves taken back when the pass ends: a neighbour found late is not the object gone.

During a pass the robust policy keeps an object's id across a move as the camera comes by
(:mod:`bomc_bt.graph.robust`): a node whose absence is confirmed moves to a node of its
category new in the pass nearby, or to the next unmatched view of its category nearby.
Two chairs side by side, one of which no earlier pass gave a node of its own, make that go
wrong: the camera finds the missing neighbour, and the old chair, hidden behind it for a
few frames (its misses counted, a detector misses half-hidden objects), is confirmed gone;
its node moves the 0.75 m to the neighbour. A few seconds later the camera sees the old
chair again, where it always stood, and gives it a new node. On an Environment-A-size
floor where nothing changed (seed 343, pass 2) two of five phantom events were such
"moves".

When the pass ends the whole story is known. A node moved in this pass, and a node of its
category added *after* that move, standing where the moved node stood before it (within
the association distance delta_c): either the object moved and another one was then put
exactly where it had stood (two changes), or the object never moved and the node it moved
to was its neighbour, found late (one change, or none when the neighbour is new to the
map). The pass takes the second, smaller story: the moved node goes back and takes the
late node's place and footprint, and the late node takes the place the moved one went to
(:meth:`~bomc_bt.graph.robust.RobustPolicy.take_back_moves`). The late node keeps how it
was added (``added`` or first seen), so the neighbour is reported as new or as new to the
map, never as a move of the chair beside it.

What this costs: a real move whose old place a new object of the same kind takes in the
same pass, after the robot saw the move, is reported as one addition where the move was.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bomc_bt.graph.records import Event, Node


@dataclass(frozen=True)
class MoveTakenBack:
    """``moved`` went from ``origin`` in this pass; ``late`` was added afterwards, at ``origin``."""

    moved: Node
    late: Node
    origin: np.ndarray  # (3,) where ``moved`` stood before its move
    arrival_observations: int  # frames that had matched the arrival folded into ``moved`` by the move (0: none)


def moves_taken_back(history: Sequence[Event], nodes: Mapping[int, Node], session: int,
                     distance: Callable[[str], float]) -> list[MoveTakenBack]:
    """The moves of ``session`` (its events in ``history``) that a node added later at the
    moved node's old place undoes, each late node used once (nearest first, then by id).

    ``nodes``: the present nodes; ``distance(category)``: delta_c, how near the old place
    a late node must stand (and nearer it than the moved node stands now).
    """
    events = [e for e in history if e.session == session]
    last_move: dict[int, int] = {}  # node id: index of its last "moved" event in the pass
    added_at: dict[int, float] = {}  # node id: stamp of its "added" event in the pass
    for i, e in enumerate(events):
        if e.kind == "moved" and e.previous is not None:
            last_move[int(e.node_id)] = i
        elif e.kind == "added":
            added_at.setdefault(int(e.node_id), float(e.stamp))
    candidates: list[tuple[float, int, int, int]] = []  # (distance, moved id, late id, move index)
    for nid, i in last_move.items():
        move, moved = events[i], nodes.get(nid)
        if moved is None:
            continue
        origin = np.asarray(move.previous, dtype=float)
        reach, away = distance(moved.category), _floor_distance(moved.position, origin)
        for lid, stamp in added_at.items():
            late = nodes.get(lid)
            if late is None or lid == nid or late.category != moved.category or stamp < move.stamp:
                continue
            d = _floor_distance(late.position, origin)
            if d <= reach and d < away:  # the late node stands where the moved one stood, nearer than it
                candidates.append((d, nid, lid, i))
    out: list[MoveTakenBack] = []
    used: set[int] = set()
    for _, nid, lid, i in sorted(candidates):
        if nid in used or lid in used:
            continue
        used.update((nid, lid))
        out.append(MoveTakenBack(nodes[nid], nodes[lid], np.asarray(events[i].previous, dtype=float),
                                 _arrival_observations(events, nid, events[i].stamp)))
    return sorted(out, key=lambda m: m.moved.id)


def _arrival_observations(events: Sequence[Event], into: int, stamp: float) -> int:
    """Observations of the node folded into ``into`` as the arrival of its move at ``stamp`` (0: none)."""
    for e in events:
        if e.kind == "removed" and e.merged_into == into and e.stamp == stamp:
            return int((e.detail or {}).get("observations", 0))
    return 0


def _floor_distance(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.hypot(a[0] - b[0], a[1] - b[1]))
