"""Algorithm 2 of the paper, as written, so its behaviour can be reproduced and compared.

Every expected node with no same-category observation within delta_c is removed at once;
every observation within delta_c of an expected same-category node leaves the unmatched
set; an unmatched observation becomes a new node only when no same-category node (the
graph as it stands, including nodes added earlier in the same frame) lies within
delta_c. Matched nodes keep their position and confidence (the algorithm never updates
them); only the bookkeeping fields ``last_session`` and ``observations`` change.

The spatial index answers the delta-queries; :mod:`bomc_bt.graph.reference` computes the
same by linear scans over every node, as the paper does.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.association import near_any
from bomc_bt.graph.records import AssociationParams, Event, Node, Observation

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph


class PaperPolicy:
    """Algorithm 2: delta_c gates, every observation within reach confirms, one miss removes."""

    vertical_weight = 1.0

    def __init__(self, params: AssociationParams):
        self.params = params

    def gate(self, o: Observation) -> float:
        """delta_c of the observation's category."""
        return self.params.distance(o.category)

    def associate(
        self, graph: ObjectGraph, observations: Sequence[Observation], expected: Sequence[int], session: int,
        stamp: float, in_view: Sequence[int] | None = None, miss_weights: Sequence[float] | None = None,
        place: np.ndarray | None = None,
    ) -> list[Event]:
        """Algorithm 2 on one frame (``in_view``, ``miss_weights`` and ``place`` play no part)."""
        obs, exp = observations, graph.begin(session, expected)
        events: list[Event] = []
        unmatched = np.ones(len(obs), dtype=bool)
        hits = self._expected_hits(graph, obs, exp)
        for row, vid in enumerate(exp):
            v = graph.nodes[vid]
            if not hits[row].any():
                events.append(graph.remove(v, session, stamp))
                continue
            unmatched &= ~hits[row]
            graph.touch(v, session, stamp, reset_misses=False)
        candidates = [obs[j] for j in np.nonzero(unmatched)[0]]
        gates = [self.gate(o) for o in candidates]
        near = graph.index.within_many([o.category for o in candidates], [o.position for o in candidates],
                                       gates, gates)
        added: list[Node] = []  # V' grows inside the loop: later observations see earlier additions
        for o, (ids, _) in zip(candidates, near, strict=True):
            if len(ids) == 0 and not near_any(o, added, self.gate(o), graph.index.scale):
                events.append(graph.add(o, session, stamp))
                added.append(graph.nodes[events[-1].node_id])
        return events

    def _expected_hits(self, graph: ObjectGraph, obs: Sequence[Observation], expected: list[int]) -> np.ndarray:
        """(E, M) bool: observation j has expected node i's category and lies within its delta."""
        if not expected or not obs:
            return np.zeros((len(expected), len(obs)), dtype=bool)
        codes: dict[str, int] = {}
        ocode = np.array([codes.setdefault(o.category, len(codes)) for o in obs])
        vcode = np.array([codes.get(graph.nodes[i].category, -1) for i in expected])
        delta = np.array([self.params.distance(graph.nodes[i].category) for i in expected])
        obs_pos = np.array([o.position for o in obs]) * graph.index.scale
        d = graph.index.positions(expected)[:, None, :] - obs_pos
        d2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
        return (vcode[:, None] == ocode[None, :]) & (d2 <= (delta * delta)[:, None])
