"""Stops the coverage tour can skip: what they see, the tour's own legs or other stops see.

The greedy cover (:mod:`bomc_bt.coverage_plan`) credits the floor seen on the way from the
legs of a first tour, but the stops it then picks are ordered into a different tour whose
legs see other floor. Many stops end up picking slivers that the final legs, or a stop
picked later, see anyway; each still costs a detour, slowing down and turning.

This pass walks the final tour, most costly detour first, and drops a stop when the floor
only it saw, less what the leg that now joins its neighbours sees, is under ``min_count``
targets. Dropping a stop only replaces its two legs by one, so the check is exact for the
plan's model of sight (stops all around, legs facing ahead) and the tour only shortens
(path lengths obey the triangle inequality). The order of the rest is kept: reordering
would change legs, and with them what they see.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

_HOPELESS = 200  # targets only a stop sees beyond which its neighbours' joining leg is not tried
LegSight = Callable[[int, int], np.ndarray]  # (from node, to node) -> targets seen on that leg


@dataclass
class Pruned:
    """The stops kept (indices into the tour, in tour order) and what the legs between them see."""

    kept: list[int]
    en_route: np.ndarray  # (targets,) bool: seen facing ahead on the kept tour's legs


def drop_redundant_stops(views: list[np.ndarray], dist: np.ndarray, n_targets: int, leg_sight: LegSight,
                         min_count: int, closed: bool) -> Pruned:
    """``views[i]``: targets stop i of the tour sees all around (stop i is node i + 1; node 0
    is the dock). ``dist``: (n + 1)-square path lengths over the nodes. ``leg_sight(a, b)``:
    targets seen driving from node a to node b."""
    n = len(views)
    if n == 0:
        return Pruned([], np.zeros(n_targets, dtype=bool))
    prev = list(range(-1, n))  # prev[node], next[node] over nodes 0..n; -1: none
    nxt = list(range(1, n + 1)) + [-1]
    legs: dict[tuple[int, int], np.ndarray] = {}
    count = np.zeros(n_targets, dtype=np.int32)
    for node in range(1, n + 1):
        np.add.at(count, views[node - 1], 1)
        legs[(node - 1, node)] = np.unique(leg_sight(node - 1, node))
        count[legs[(node - 1, node)]] += 1

    def detour(node: int) -> float:
        p, q = prev[node], nxt[node]
        q = q if q >= 0 else (0 if closed else -1)
        return float(dist[p, node] + (dist[node, q] - dist[p, q] if q >= 0 else 0.0))

    alive = np.ones(n + 1, dtype=bool)
    for node in sorted(range(1, n + 1), key=detour, reverse=True):
        p, q = prev[node], nxt[node]
        gone = [views[node - 1], legs[(p, node)]] + ([legs[(node, q)]] if q >= 0 else [])
        touched = np.unique(np.concatenate(gone))
        after = count.copy()
        for part in gone:
            np.subtract.at(after, part, 1)
        lost = int((after[touched] <= 0).sum())
        if lost >= min_count and lost > _HOPELESS:
            continue  # no leg sees that much of what a stop looked round at: spare the leg's search
        joined = np.unique(leg_sight(p, q)) if q >= 0 else np.zeros(0, dtype=np.int64)
        after[joined] += 1
        if int((after[touched] <= 0).sum()) >= min_count:
            continue
        count, alive[node] = after, False
        del legs[(p, node)]
        if q >= 0:
            del legs[(node, q)]
            legs[(p, q)] = joined
            prev[q] = p
        nxt[p] = q
    en_route = np.zeros(n_targets, dtype=bool)
    for seen in legs.values():
        en_route[seen] = True
    return Pruned([node - 1 for node in range(1, n + 1) if alive[node]], en_route)
