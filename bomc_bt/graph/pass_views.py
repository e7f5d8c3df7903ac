"""The floor a node's views covered in this pass, apart from the footprint it carries.

A big object's footprint (:mod:`bomc_bt.graph.extents`) is the union of its views, and a
pass starts it over only when its first view lies clear of the old one: a first view that
lies inside or against the old footprint (a table's end seen past its chairs) keeps it, so
a table seen one end at a time is not cut down to the end in view. Kept, the old floor
stays in the footprint even where the object has left it. When the pass ends, two
questions are asked of the floor the object covers now, and the footprint's old floor
answers them wrongly:

- Did the node shift because more of the object came into view (a refinement), or did
  the object move? Views of this pass that lay on the footprint the pass began with say
  the object still stood there (:meth:`PassViews.on_start`,
  :mod:`bomc_bt.graph.refinement`).
- Are two nodes the two ends of one object (:mod:`bomc_bt.graph.parts`)? A table pushed
  1 m along and across (bookstore map at 0.04 m, generated world seed 9005, pass 5): the
  pass's first view of its west end lay against the old footprint, so the node kept the
  old floor and grew over the new one (1.62 x 1.52 m for a 1.2 x 0.8 m table), the views
  of the east end became a second node, and the two together were longer than one table
  (2.29 m against 2.08): a table added and, a pass later, the old one removed. This pass's
  views of the old node covered 1.29 m of the table where it now stood
  (:meth:`PassViews.moved_off`), the second node's 1.14 m of the same floor: one table,
  moved (:mod:`bomc_bt.graph.pass_end`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from bomc_bt.graph.footprints import NOISE_PAD, inside, union
from bomc_bt.json_text import JSONMemo, keyed

if TYPE_CHECKING:
    from bomc_bt.graph.object_graph import ObjectGraph
    from bomc_bt.graph.records import Node


class PassViews:
    """Per node, the box round its views with a box this pass: all of them, and those on
    the footprint the pass began with (this process's pass; saved with the pass state)."""

    def __init__(self) -> None:
        self._all: dict[int, np.ndarray] = {}
        self._on_start: dict[int, np.ndarray] = {}

    def note(self, graph: ObjectGraph, v: Node, box: np.ndarray) -> None:
        """A view of ``v`` this pass covered ``box`` (after the footprint took it in)."""
        self._all[v.id] = _grow(self._all.get(v.id), box)
        start = graph.started.get(v.id)
        began = start[0] if start is not None else v.footprint  # unchanged yet: as the pass found it
        if began is not None and inside(box, began, NOISE_PAD):  # (a node new in the pass: refinements skip it)
            self._on_start[v.id] = _grow(self._on_start.get(v.id), box)

    def on_start(self) -> dict[int, np.ndarray]:
        """Node id -> the box round its views this pass that lay on the footprint it began with."""
        return dict(self._on_start)

    def moved_off(self, graph: ObjectGraph, v: Node, session: int) -> np.ndarray | None:
        """The box round this pass's views of ``v``, a node of an earlier pass, where they
        reach beyond the footprint the pass began it with: the floor its object covers now,
        without the old floor its footprint kept (None: no such views)."""
        seen, start = self._all.get(v.id), graph.started.get(v.id)
        if v.first_session >= session or seen is None or start is None or start[0] is None:
            return None
        return None if inside(seen, start[0], NOISE_PAD) else seen.copy()

    def to_json(self, memo: JSONMemo | None = None) -> dict:
        """JSON-able (with ``memo``, each map as its text: :class:`~bomc_bt.json_text.JSONMemo`)."""
        return {"on_start": keyed(memo, "views.on_start", self._on_start.items(), np.ndarray.tolist),
                "seen": keyed(memo, "views.seen", self._all.items(), np.ndarray.tolist)}

    def restore(self, data: dict) -> None:
        """Put back what :meth:`to_json` saved (a pass state without it: none)."""
        self._on_start = {int(k): np.array(x, dtype=float) for k, x in data.get("on_start", {}).items()}
        self._all = {int(k): np.array(x, dtype=float) for k, x in data.get("seen", {}).items()}


def _grow(box: np.ndarray | None, more: np.ndarray) -> np.ndarray:
    return more.copy() if box is None else union(box, more)
