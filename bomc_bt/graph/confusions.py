"""One object, one label: a new sighting on a node of another category is a confusion.

A detector now and then names a chair "table". Such a sighting lies on the chair's node,
in a frame that did not see the chair; a real table with a chair under it is seen together
with the chair. So robust association counts a new object's sighting within
``association.relabel_radius`` (planar) of a node of another category only in a frame that
also matched that node.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.records import Observation

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph


def confused(graph: ObjectGraph, o: Observation, matched: Collection[int], radius: float) -> bool:
    """Whether ``o`` lies within ``radius`` of a node of another category that this frame
    did not match (``matched``: the frame's matched node ids); ``radius`` 0: never."""
    if radius <= 0.0:
        return False
    x, y = float(o.position[0]), float(o.position[1])
    square = np.array([[x - radius, y - radius], [x + radius, y - radius], [x + radius, y + radius],
                       [x - radius, y + radius]])
    for vid in graph.index.ids_in_polygon(square).tolist():
        v = graph.nodes.get(int(vid))
        if v is not None and v.category != o.category and int(vid) not in matched \
                and math.hypot(v.position[0] - x, v.position[1] - y) <= radius:
            return True
    return False
