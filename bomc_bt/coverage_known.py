"""Known objects as coverage targets: each seen once from where a miss counts fully.

The coverage plan (:mod:`bomc_bt.coverage_plan`) covers floor, and a far look covers floor
as well as a near one. A removal is confirmed by misses, though, and a miss weighs fully
only within ``projection.miss_full_range`` of the camera, falling to nothing at
``expect_range`` (:func:`bomc_bt.perception.expected.miss_weights`): an object the plan
only sees from 4 m is practically never dropped when it is taken away.

So each node of the graph (known when the pass is planned) becomes ``weight`` extra targets
(``weight`` is the plan's ``min_count``: a node alone is worth a stop, as a chair's floor
is), seen from a place within ``close_range`` of the node that sees some floor target within
``radius`` of it; on the legs, from a sample within ``close_range - radius`` that sees such a
target facing ahead. Nodes no candidate sees from that near are left to the far looks
(reported as ``unreachable``). The greedy cover, the tour and the pruning then treat these
targets like floor, so a node already seen from near on the way costs nothing.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bomc_bt.grid import OccupancyGrid
from bomc_bt.node_sight import camera_clear, sees_target
from bomc_bt.sight import Sight, along_paths


def index_ranges(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """np.concatenate([np.arange(a, b) for a, b in zip(lo, hi)]), vectorised."""
    lens = hi - lo
    total = int(lens.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(lens)[:-1]])
    return np.repeat(lo - starts, lens) + np.arange(total)


@dataclass
class KnownTargets:
    """Node targets after the floor's: node n is targets ``n_floor + n * weight + [0, weight)``."""

    n_floor: int
    weight: int
    positions: np.ndarray  # (N, 2) node positions in the map frame
    close_range: float
    pair_node: np.ndarray  # (P,) node of each (floor target, node) pair, sorted by target
    t_ptr: np.ndarray  # (n_floor + 1,) pairs of target t: pair_node[t_ptr[t]:t_ptr[t + 1]]
    leg_sight: Sight | None  # floor within close_range - radius, for the legs; None: legs credit no node

    @classmethod
    def build(cls, grid: OccupancyGrid, sight: Sight, positions: np.ndarray, radius: float, close_range: float,
              weight: int, min_range: float, footprints: Sequence | None = None) -> KnownTargets:
        """``footprints`` (one per node, each None or x0, y0, x1, y1): a floor target shows a node
        only where it sees a face of its footprint (:func:`~bomc_bt.node_sight.sees_target`),
        not across the wall it stands against (a door on a wall's far face)."""
        positions = np.asarray(positions, dtype=float).reshape(-1, 2)
        h, w = sight.floor.shape
        step = grid.resolution * sight.lattice
        n = int(math.ceil(radius / step))
        di, dj = np.mgrid[-n:n + 1, -n:n + 1]
        keep = np.hypot(di, dj).ravel() * step <= radius
        di, dj = di.ravel()[keep], dj.ravel()[keep]
        rows, cols = grid.world_to_cell(positions[:, 0], positions[:, 1])
        ci = np.round(np.asarray(rows, float) / sight.lattice).astype(np.int64)[:, None] + di[None, :]
        cj = np.round(np.asarray(cols, float) / sight.lattice).astype(np.int64)[:, None] + dj[None, :]
        inside = (ci >= 0) & (ci < h) & (cj >= 0) & (cj < w)
        inside[inside] &= sight.floor[ci[inside], cj[inside]]
        node = np.broadcast_to(np.arange(len(positions))[:, None], ci.shape)[inside]
        target = (ci * w + cj)[inside]
        if footprints is not None and len(node):
            node, target = _facing(grid, sight.lattice, w, positions, footprints, node, target)
        order = np.argsort(target, kind="stable")
        t_ptr = np.concatenate([[0], np.cumsum(np.bincount(target, minlength=h * w))])
        leg_range = close_range - radius
        leg_sight = (Sight(grid, sight.floor, sight.lattice, leg_range, min_range, sight.shadow)
                     if leg_range > min_range and len(positions) else None)
        return cls(h * w, weight, positions, close_range, node[order], t_ptr, leg_sight)

    @property
    def n_targets(self) -> int:
        return self.n_floor + self.weight * len(self.positions)

    def _slots(self, nodes: np.ndarray) -> np.ndarray:
        return (self.n_floor + nodes[:, None] * self.weight + np.arange(self.weight)[None, :]).ravel()

    def extend_views(self, views: list[np.ndarray], places_xy: np.ndarray) -> list[np.ndarray]:
        """Each place's floor view plus the slots of the nodes it sees from within close_range."""
        if len(self.positions) == 0 or not views:
            return views
        lens = np.array([len(v) for v in views], dtype=np.int64)
        seen = np.concatenate(views).astype(np.int64)
        owner = np.repeat(np.arange(len(views)), lens)
        near = self.t_ptr[seen + 1] > self.t_ptr[seen]
        seen, owner = seen[near], owner[near]
        counts = self.t_ptr[seen + 1] - self.t_ptr[seen]
        node = self.pair_node[index_ranges(self.t_ptr[seen], self.t_ptr[seen + 1])]
        owner = np.repeat(owner, counts)
        d = np.hypot(*(places_xy[owner] - self.positions[node]).T)
        pairs = np.unique(owner[d <= self.close_range] * len(self.positions) + node[d <= self.close_range])
        by_place = np.split(pairs % len(self.positions), np.searchsorted(pairs // len(self.positions),
                                                                        np.arange(1, len(views))))
        return [np.concatenate([v, self._slots(p)]) if len(p) else v for v, p in zip(views, by_place, strict=True)]

    def seeable(self, views: list[np.ndarray]) -> np.ndarray:
        """(N,) bool: the nodes some place sees from near (views as :meth:`extend_views` returns)."""
        out = np.zeros(len(self.positions), dtype=bool)
        for v in views:
            out[(v[v >= self.n_floor] - self.n_floor) // self.weight] = True
        return out

    def along(self, sight: Sight, paths: list, step: float, hfov: float) -> np.ndarray:
        """Targets seen driving ``paths`` facing ahead: floor as far as ``sight`` reaches, and
        the slots of nodes with some floor target near them seen within close_range - radius."""
        floor = along_paths(sight, paths, step, hfov)
        if self.leg_sight is None:
            return floor
        near = along_paths(self.leg_sight, paths, step, hfov)
        nodes = np.unique(self.pair_node[index_ranges(self.t_ptr[near], self.t_ptr[near + 1])])
        return np.concatenate([floor, self._slots(nodes)]) if len(nodes) else floor

    def target_xy(self, targets: np.ndarray, floor_xy) -> np.ndarray:
        """(M, 2) map points of targets: floor ones through ``floor_xy(flat)``, node slots their node."""
        targets = np.asarray(targets, dtype=np.int64)
        out = np.zeros((len(targets), 2))
        is_floor = targets < self.n_floor
        out[is_floor] = floor_xy(targets[is_floor])
        out[~is_floor] = self.positions[(targets[~is_floor] - self.n_floor) // self.weight]
        return out


def _facing(grid: OccupancyGrid, lattice: int, width: int, positions: np.ndarray, footprints: Sequence,
            node: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (node, floor target) pairs whose target sees a face of the node's footprint."""
    clear = camera_clear(grid)
    rows, cols = np.divmod(target, width)
    x, y = grid.cell_to_world(rows * lattice, cols * lattice)
    keep = np.array([sees_target(grid, clear, (float(x[i]), float(y[i])), positions[n], footprints[n])
                     for i, n in enumerate(node)], dtype=bool)
    return node[keep], target[keep]
