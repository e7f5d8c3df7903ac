"""The interface every association policy offers the object graph, and what policies share.

A policy decides how one frame's observations change the graph: which node each
observation confirms, which expected nodes are gone, which observations are new objects.
It changes the graph only through :class:`~bomc_bt.graph.object_graph.ObjectGraph`'s
public mutation API, so the spatial index and the change log stay in step whatever the
policy does. The graph picks its policy once, from :attr:`AssociationParams.mode`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from bomc_bt.graph.footprints import box_gap
from bomc_bt.graph.geometry import dist2_scalar
from bomc_bt.graph.records import Event, Node, Observation

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph


class AssociationPolicy(Protocol):
    """How a frame's observations update the graph."""

    # weight of height differences in every distance the graph measures (1: plain 3D distance)
    vertical_weight: float

    def gate(self, o: Observation) -> float:
        """How far a node may be from ``o`` and still be the same object."""
        ...

    def associate(
        self, graph: ObjectGraph, observations: Sequence[Observation], expected: Sequence[int], session: int,
        stamp: float, in_view: Sequence[int] | None = None, miss_weights: Sequence[float] | None = None,
        place: np.ndarray | None = None,
    ) -> list[Event]:
        """Update ``graph`` with one frame of ``session`` at robot time ``stamp``; the events in order.

        ``expected``: ids of nodes the frame can confirm or deny; ``in_view``: ids of all
        nodes inside the field of view, hidden ones included; ``miss_weights``: per expected
        node, how much its absence from this frame weighs; ``place``: the robot's (x, y) when
        the frame was taken (a policy may ignore the last three).
        """
        ...


def near_any(o: Observation, nodes: Sequence[Node], gate: float, scale: np.ndarray) -> bool:
    """Whether a node of ``o``'s category among ``nodes`` lies within ``gate`` of it (scaled distance)."""
    return any(
        v.category == o.category and dist2_scalar(v.position * scale, o.position * scale) <= gate * gate
        for v in nodes
    )


def never_looked(graph: ObjectGraph, at: Node | Observation) -> bool:
    """Whether no earlier pass looked where ``at`` stands (``ObjectGraph.never_looked``)."""
    return graph.never_looked is not None and graph.never_looked(at.position)


def sighted_before(graph: ObjectGraph, at: Node | Observation, other: Node, radius: float) -> bool:
    """Whether the previous pass detected an object of ``at``'s category where ``at`` stands
    (``ObjectGraph.sighted_before``) that was not ``other``: a place beyond ``radius`` (m) of
    ``other``'s footprint (its position where it has none), where none of its views fell."""
    if graph.sighted_before is None or not graph.sighted_before(at.category, at.position):
        return False
    point = np.tile(np.asarray(at.position[:2], dtype=float), 2)  # a box of no size: (x, y, x, y)
    box = other.footprint if other.footprint is not None else np.tile(other.position[:2], 2)
    return box_gap(box, point) > radius
