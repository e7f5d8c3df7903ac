"""The naive paper: Algorithm 2 and the field-of-view query by linear scans over every node.

No spatial index is consulted: each expected node scans all observations and each
unmatched observation scans all present nodes, as the paper describes. These are the
oracle the tests check the indexed :class:`~bomc_bt.graph.paper.PaperPolicy` against, and
the baseline of ``benchmarks/bench_association.py``. They change the graph through its
public mutation API, as the policies do, so both leave identical graphs.
"""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.graph.geometry import check_polygon, dist2_scalar, points_in_polygon
from bomc_bt.graph.object_graph import ObjectGraph
from bomc_bt.graph.records import Event, Node, Observation


def associate_linear_scan(
    graph: ObjectGraph, observations: list[Observation], expected: list[int], session: int, stamp: float
) -> list[Event]:
    """Algorithm 2 (paper mode) by plain linear scans over every node: the reference."""
    exp = graph.begin(session, expected)
    events: list[Event] = []
    unmatched = [True] * len(observations)
    for vid in exp:
        v = graph.nodes[vid]
        delta = graph.threshold(v.category)
        delta2 = delta * delta
        hits = [
            j for j, o in enumerate(observations)
            if o.category == v.category and dist2_scalar(o.position, v.position) <= delta2
        ]
        if not hits:
            events.append(graph.remove(v, session, stamp))
            continue
        for j in hits:
            unmatched[j] = False
        graph.touch(v, session, stamp, reset_misses=False)
    for j, o in enumerate(observations):
        if not unmatched[j]:
            continue
        d_min2 = math.inf
        for v in graph.nodes.values():
            if v.category == o.category:
                d_min2 = min(d_min2, dist2_scalar(o.position, v.position))
        delta = graph.threshold(o.category)
        if d_min2 > delta * delta:
            events.append(graph.add(o, session, stamp))
    return events


def nodes_in_polygon_linear(
    graph: ObjectGraph, polygon: np.ndarray, z_range: tuple[float, float] | None = None
) -> list[Node]:
    """The FoV query by a scan over every node (reference for tests and the benchmark)."""
    poly = check_polygon(polygon)
    nodes = sorted(graph.nodes.values(), key=lambda n: n.id)
    if not nodes:
        return []
    pos = np.array([n.position for n in nodes])
    mask = points_in_polygon(pos[:, :2], poly)
    if z_range is not None:
        mask &= (pos[:, 2] >= z_range[0]) & (pos[:, 2] <= z_range[1])
    return [n for n, m in zip(nodes, mask, strict=True) if m]
