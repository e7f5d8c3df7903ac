"""Flat objects' faces: a door leaf is seen from in front or behind, not along its wall.

A detector misses a flat object seen edge-on: its leaf is a sliver in the image (the
``hard`` simulated detector does so on purpose; the ``realistic`` one, by too few pixels).
So where it matters what a view could have shown -- whether a miss counts
(:func:`bomc_bt.perception.expected.miss_weights`), whether a pass looked at it
(:mod:`bomc_bt.looked_sides`) -- a flat node is judged by how squarely the view faced it.
A node is flat when its floor footprint is at least :data:`FLAT_ASPECT` times longer than
wide; footprints are axis-aligned boxes, so this knows the faces of walls' doors (the
generator's, and most buildings'), and a flat object standing diagonally, whose box is
square, is judged as any other.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bomc_bt.graph.records import Node

FLAT_ASPECT = 3.0  # [-] a footprint this many times longer than wide is a flat object's (a door leaf's)


def flat_normal(node: Node) -> np.ndarray | None:
    """The unit normal of a flat node's faces (x, y; either way round), or None for a node that
    is not flat or has no footprint."""
    fp = node.footprint
    if fp is None:
        return None
    width, depth = float(fp[2] - fp[0]), float(fp[3] - fp[1])
    if max(width, depth) < FLAT_ASPECT * max(min(width, depth), 1e-3):
        return None
    return np.array([0.0, 1.0]) if width > depth else np.array([1.0, 0.0])


def facing(node: Node, place: Sequence[float]) -> float:
    """The cosine of the angle between the ray from ``place`` (x, y) to the node and its face
    normal (1: face-on, 0: edge-on); 1 for a node that is not flat."""
    normal = flat_normal(node)
    if normal is None:
        return 1.0
    ray = np.asarray(node.position[:2], dtype=float) - np.asarray(place[:2], dtype=float)
    distance = float(np.hypot(*ray))
    return 1.0 if distance <= 1e-6 else abs(float(ray @ normal)) / distance

