"""The spatial index of the object graph: a uniform hash grid over a contiguous array.

The paper scans all nodes for every unmatched observation and every field-of-view query.
This index keeps the (scaled) positions of the present nodes in one numpy array, slot by
slot, and a uniform hash grid over the floor plane (cell size = the largest association
distance), one grid per category plus one over all categories. A delta-query then reads
at most 3 x 3 cells and a field-of-view query the cells under the polygon's bounding box,
and the distances of all candidates are measured in one numpy pass.

Distances are measured on (x, y, w * z) with ``scale`` = (1, 1, w): robust association
down-weights height (see :mod:`bomc_bt.graph.robust`). Besides its position, each slot
carries the node's own gate (the reach its object's size earned; 0: none) and its
footprint box (NaN: unknown), which queries may honour.

The index knows node ids, categories and arrays, not :class:`~bomc_bt.graph.records.Node`;
only :class:`~bomc_bt.graph.object_graph.ObjectGraph` changes it, in step with its nodes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bomc_bt.graph.footprints import overlapping
from bomc_bt.graph.geometry import dist2, points_in_polygon

_EDGE = 1e-9  # m: slack of a polygon query's bounding box (points on the edge are inside)
_EMPTY_IDS = np.zeros(0, np.int64)


class SpatialIndex:
    """Node ids by position, per category and over all categories."""

    def __init__(self, cell: float, scale: np.ndarray, capacity: int = 1024):
        self.cell = cell  # [m] grid cell side
        self.scale = scale  # (3,) factors applied to positions before measuring distances
        self._pos = np.zeros((capacity, 3))
        self._slot_id = np.full(capacity, -1, dtype=np.int64)
        self._gate = np.zeros(capacity)
        self._box = np.full((capacity, 4), np.nan)
        self._slot_of: dict[int, int] = {}
        self._free: list[int] = []
        self._used = 0  # high-water mark of slots
        self._cat_cells: dict[tuple[str, int, int], list[int]] = {}
        self._cells: dict[tuple[int, int], list[int]] = {}
        self._cat_slots: dict[str, set[int]] = {}

    # ------------------------------------------------------------ changes
    def insert(self, node_id: int, category: str, position: np.ndarray, box: np.ndarray | None) -> None:
        """Index a node at ``position`` (map frame) with its footprint ``box`` (None: unknown)."""
        if self._free:
            slot = self._free.pop()
        else:
            if self._used == len(self._pos):
                self._grow()
            slot = self._used
            self._used += 1
        self._pos[slot] = position * self.scale
        self._slot_id[slot] = node_id
        self._gate[slot] = 0.0
        self._box[slot] = np.nan if box is None else box
        self._slot_of[node_id] = slot
        kx, ky = self._key(position[0], position[1])
        self._cells.setdefault((kx, ky), []).append(slot)
        self._cat_cells.setdefault((category, kx, ky), []).append(slot)
        self._cat_slots.setdefault(category, set()).add(slot)

    def delete(self, node_id: int, category: str, position: np.ndarray) -> None:
        """Forget a node indexed at ``position``."""
        slot = self._slot_of.pop(node_id)
        self._unlink(category, slot, self._key(position[0], position[1]))
        self._cat_slots[category].discard(slot)
        self._slot_id[slot] = -1
        self._free.append(slot)

    def move(self, node_id: int, category: str, old: np.ndarray, new: np.ndarray) -> None:
        """Move a node indexed at ``old`` to ``new``."""
        slot = self._slot_of[node_id]
        old_key = self._key(old[0], old[1])
        new_key = self._key(new[0], new[1])
        if old_key != new_key:
            self._unlink(category, slot, old_key)
            self._cells.setdefault(new_key, []).append(slot)
            self._cat_cells.setdefault((category, *new_key), []).append(slot)
        self._pos[slot] = new * self.scale

    def widen_gate(self, node_id: int, gate: float) -> None:
        """Let the node's own gate grow to ``gate`` (it never shrinks)."""
        slot = self._slot_of.get(node_id)
        if slot is not None:
            self._gate[slot] = max(self._gate[slot], gate)

    def gate_of(self, node_id: int) -> float:
        """The node's own gate (0: none, or not indexed)."""
        slot = self._slot_of.get(node_id)
        return 0.0 if slot is None else float(self._gate[slot])

    def set_box(self, node_id: int, box: np.ndarray | None) -> None:
        """Replace the node's footprint box (None: unknown)."""
        slot = self._slot_of.get(node_id)
        if slot is not None:
            self._box[slot] = np.nan if box is None else box

    # ------------------------------------------------------------ queries
    def positions(self, ids: Sequence[int]) -> np.ndarray:
        """(N, 3) scaled positions of the nodes ``ids``."""
        return self._pos[[self._slot_of[i] for i in ids]]

    def ids_in_polygon(self, polygon: np.ndarray) -> np.ndarray:
        """Ids (unordered) of nodes whose xy lies inside ``polygon`` (K, 2)."""
        # the polygon's own box, padded: a point on its edge counts as inside (points_in_polygon)
        # and rounding must not put it just outside the box first (hypothesis found x = -1e-254)
        slots = self._slots_in_box(polygon.min(axis=0) - _EDGE, polygon.max(axis=0) + _EDGE)
        if len(slots) == 0:
            return _EMPTY_IDS
        return self._slot_id[slots[points_in_polygon(self._pos[slots][:, :2], polygon)]]

    def within(self, category: str, position: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Ids and squared scaled distances of ``category`` nodes within ``radius``, nearest first
        (ties by id)."""
        p = np.asarray(position, dtype=float).reshape(3) * self.scale
        slots = self._cat_candidates(category, p, radius)
        if len(slots) == 0:
            return _EMPTY_IDS, np.zeros(0)
        d2 = dist2(self._pos[slots], p)
        keep = d2 <= radius * radius
        ids, d2 = self._slot_id[slots[keep]], d2[keep]
        order = np.lexsort((ids, d2))
        return ids[order], d2[order]

    def nearest(self, category: str, position: np.ndarray, max_distance: float | None = None) -> tuple[int, float]:
        """Id and scaled distance of the closest ``category`` node (ties by id), or (-1, inf)."""
        p = np.asarray(position, dtype=float).reshape(3) * self.scale
        members = self._cat_slots.get(category)
        if not members:
            return -1, math.inf
        if max_distance is not None:
            slots = self._cat_candidates(category, p, max_distance)
        else:
            slots = self._ring_search(category, p, len(members))
        if len(slots) == 0:
            return -1, math.inf
        d2 = dist2(self._pos[slots], p)
        k = int(np.lexsort((self._slot_id[slots], d2))[0])
        dist = math.sqrt(float(d2[k]))
        if max_distance is not None and dist > max_distance:
            return -1, math.inf
        return int(self._slot_id[slots[k]]), dist

    def within_many(
        self, categories: Sequence[str], positions: Sequence[np.ndarray], reaches: Sequence[float],
        radii: Sequence[float], boxes: Sequence[np.ndarray | None] | None = None, overlap: float = 0.0,
    ) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per query j: ids and squared distances of same-category nodes that match it.

        A node matches when its distance is within ``radii[j]`` or the node's own gate, if
        wider, or (``boxes`` given) its footprint shares ``overlap`` of the smaller box with
        ``boxes[j]``. ``reaches[j]`` bounds how far candidates are gathered from the grid.
        Candidates of all queries are measured in one numpy pass, which is what keeps a
        20-observation frame well under a millisecond.
        """
        counts: list[int] = []
        gathered: list[np.ndarray] = []
        for category, position, reach in zip(categories, positions, reaches, strict=True):
            slots = self._cat_candidates(category, position * self.scale, reach)
            counts.append(len(slots))
            gathered.append(slots)
        if not counts or sum(counts) == 0:
            return [(_EMPTY_IDS, np.zeros(0))] * len(counts)
        slots = np.concatenate(gathered)
        owner = np.repeat(np.arange(len(counts)), counts)
        qpos = np.array(positions) * self.scale
        radius = np.maximum(np.array(radii)[owner], self._gate[slots])
        d = self._pos[slots] - qpos[owner]
        d2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
        keep = d2 <= radius * radius
        if boxes is not None:
            query_boxes = np.array([np.full(4, np.nan) if b is None else b for b in boxes])[owner]
            keep |= overlapping(self._box[slots], query_boxes, overlap)
        bounds = np.concatenate([[0], np.cumsum(counts)])
        out = []
        for j in range(len(counts)):
            k = keep[bounds[j]:bounds[j + 1]]
            out.append((self._slot_id[slots[bounds[j]:bounds[j + 1]][k]], d2[bounds[j]:bounds[j + 1]][k]))
        return out

    def boxes_near(self, category: str, position: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """Ids and footprint boxes (K, 4; NaN rows: unknown) of ``category`` nodes that may lie
        within ``reach`` of ``position`` (a superset: the grid cells around it)."""
        slots = self._cat_candidates(category, position * self.scale, reach)
        return self._slot_id[slots], self._box[slots]

    # ------------------------------------------------------------ the grid
    def _key(self, x: float, y: float) -> tuple[int, int]:
        return math.floor(x / self.cell), math.floor(y / self.cell)

    def _grow(self) -> None:
        self._pos = np.concatenate([self._pos, np.zeros_like(self._pos)])
        self._slot_id = np.concatenate([self._slot_id, np.full(len(self._slot_id), -1, np.int64)])
        self._gate = np.concatenate([self._gate, np.zeros(len(self._gate))])
        self._box = np.concatenate([self._box, np.full_like(self._box, np.nan)])

    def _unlink(self, category: str, slot: int, key: tuple[int, int]) -> None:
        for table, k in ((self._cells, key), (self._cat_cells, (category, *key))):
            members = table[k]
            members.remove(slot)
            if not members:
                del table[k]

    def _cat_candidates(self, category: str, p: np.ndarray, radius: float) -> np.ndarray:
        r = max(1, math.ceil(radius / self.cell))
        kx, ky = self._key(p[0], p[1])
        if (2 * r + 1) ** 2 > len(self._cat_slots.get(category, ())):
            return np.fromiter(self._cat_slots.get(category, ()), dtype=np.int64)
        out: list[int] = []
        cells = self._cat_cells
        for ix in range(kx - r, kx + r + 1):
            for iy in range(ky - r, ky + r + 1):
                members = cells.get((category, ix, iy))
                if members:
                    out.extend(members)
        return np.array(out, dtype=np.int64)

    def _ring_search(self, category: str, p: np.ndarray, n_members: int) -> np.ndarray:
        """Candidate slots that surely contain the nearest ``category`` node to ``p``."""
        kx, ky = self._key(p[0], p[1])
        found: list[int] = []
        r = 0
        while (2 * r + 1) ** 2 <= 4 * n_members:
            for ix in range(kx - r, kx + r + 1):
                for iy in range(ky - r, ky + r + 1):
                    if max(abs(ix - kx), abs(iy - ky)) == r:
                        found.extend(self._cat_cells.get((category, ix, iy), ()))
            if found:
                # a node in ring r is within (r + 1) * sqrt(2) cells; one more sweep to that radius is exact
                reach = math.ceil((r + 1) * math.sqrt(2))
                return self._cat_candidates(category, p, reach * self.cell)
            r += 1
        return np.fromiter(self._cat_slots[category], dtype=np.int64)

    def _slots_in_box(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        x0, y0 = self._key(lo[0], lo[1])
        x1, y1 = self._key(hi[0], hi[1])
        out: list[int] = []
        if (x1 - x0 + 1) * (y1 - y0 + 1) > len(self._cells):
            for (ix, iy), members in self._cells.items():
                if x0 <= ix <= x1 and y0 <= iy <= y1:
                    out.extend(members)
        else:
            for ix in range(x0, x1 + 1):
                for iy in range(y0, y1 + 1):
                    members = self._cells.get((ix, iy))
                    if members:
                        out.extend(members)
        return np.array(out, dtype=np.int64)
