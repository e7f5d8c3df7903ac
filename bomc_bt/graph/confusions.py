"""One object, one label: a new sighting on a node of another category is a confusion.

A detector now and then names a chair "table". Such a sighting lies on the chair's node,
in a frame that did not see the chair; a real table with a chair under it is seen together
with the chair. So robust association counts a new object's sighting within
``association.relabel_radius`` (planar) of a node of another category only in a frame that
also matched that node.

"On the node" is also anywhere on its floor footprint: a long object called by another
name is seen at one end as often as at its middle. A sofa's end named "television" in two
frames a second apart lay 0.63 and 1.0 m from the sofa's centre, and a table's end named
"sofa" 0.7 m from the table's (36 x 28 m office, seed 7717): each became a node that no
later frame could remove, since the object under it holds its place
(:func:`~bomc_bt.perception.expected.place_held`).
"""

from __future__ import annotations

import math
from collections.abc import Collection
from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.records import Observation

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph

# m: how far from its node's centre a footprint may reach (half the longest furniture, a
# 2.4 m table, and the centre off its middle), so the footprints a point lies on are found
_FOOTPRINT_REACH = 1.5


def confusing_node(graph: ObjectGraph, o: Observation, matched: Collection[int], radius: float) -> int | None:
    """The node of another category that this frame did not match (``matched``: the frame's
    matched node ids) ``o`` lies within ``radius`` of, or on the floor footprint of; None if
    there is none, or ``radius`` is 0. :mod:`.replacements` counts them."""
    if radius <= 0.0:
        return None
    x, y = float(o.position[0]), float(o.position[1])
    r = max(radius, _FOOTPRINT_REACH)
    square = np.array([[x - r, y - r], [x + r, y - r], [x + r, y + r], [x - r, y + r]])
    for vid in graph.index.ids_in_polygon(square).tolist():
        v = graph.nodes.get(int(vid))
        if v is None or v.category == o.category or int(vid) in matched:
            continue
        fp = v.footprint
        if math.hypot(v.position[0] - x, v.position[1] - y) <= radius or (
                fp is not None and fp[0] <= x <= fp[2] and fp[1] <= y <= fp[3]):
            return int(vid)
    return None
