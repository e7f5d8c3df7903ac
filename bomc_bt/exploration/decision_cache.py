"""What the gain explorer measured at the last decisions and the map has not changed since.

Every decision of the ``gain`` explorer finds a safe standoff goal for each reachable
frontier (:class:`.gain.Standoffs`) and the unknown area visible from each goal
(:func:`.gain.visible_unknown`). On an Environment-A-size office (93 x 90 m, 3.3 million
cells, 700 frontiers late in the build) both ran over the whole map at every decision and
were most of the build's wall time, while between two decisions the lidar changes the map
only around the robot. So both are kept per frontier (per goal) and recomputed only where
the map changed since:

* :class:`ChangeStamps` remembers, per tile of the map, the last decision at which a cell
  of the tile (or of the planner's reachable area over it) changed;
* a kept value depends only on a window of the map around its frontier or goal (shown in
  :mod:`.standoff_window` for the standoff, by the ray length for the gain), and is used
  again while no tile of that window changed, so the results are those of a computation
  from scratch, bit for bit (tests/test_decision_cache.py).
"""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.exploration.frontiers import Frontier
from bomc_bt.exploration.gain import visible_unknown
from bomc_bt.exploration.reachability import Reachability
from bomc_bt.exploration.standoff_window import StandoffResult, standoff_margin, window_standoff
from bomc_bt.grid import OccupancyGrid, any_per_block

_TILE = 16  # [count] map cells per tile side (a multiple of the planner's factor, see ChangeStamps)


class ChangeStamps:
    """Per tile of the map, the number of the last update at which it changed."""

    def __init__(self) -> None:
        self.count = 0
        self.tile = _TILE
        self._grid: np.ndarray | None = None
        self._component: np.ndarray | None = None
        self._factor = 0
        self.stamps = np.zeros((0, 0), dtype=np.int64)

    def update(self, grid: OccupancyGrid, reach: Reachability) -> None:
        """Compare the map and the reachable area with the previous update's; a new shape,
        resolution or planning factor marks every tile changed."""
        self.count += 1
        data, comp, f = grid.data, reach.component, reach.factor
        tile = _TILE * f if _TILE % f else _TILE
        same = (self._grid is not None and self._grid.shape == data.shape and self._factor == f
                and self.tile == tile and self._component.shape == comp.shape)
        if not same:
            self.tile = tile
            rows, cols = -(-data.shape[0] // tile), -(-data.shape[1] // tile)
            self.stamps = np.full((rows, cols), self.count, dtype=np.int64)
        else:
            changed = any_per_block(self._grid != data, tile) | any_per_block(self._component != comp, tile // f)
            self.stamps[changed[:self.stamps.shape[0], :self.stamps.shape[1]]] = self.count
        self._grid, self._component, self._factor = data.copy(), comp.copy(), f

    def clean_since(self, stamp: int, r0: int, r1: int, c0: int, c1: int) -> bool:
        """Whether no tile holding a cell of rows ``r0:r1``, cols ``c0:c1`` changed after
        update ``stamp``."""
        t = self.tile
        window = self.stamps[max(r0, 0) // t:(max(r1, 1) - 1) // t + 1, max(c0, 0) // t:(max(c1, 1) - 1) // t + 1]
        return window.size == 0 or int(window.max()) <= stamp


class DecisionCache:
    """Standoff goals and gains kept across decisions of one exploration (module docstring).

    Call :meth:`update` with each decision's map and reachable area first; a different
    reachable-area computation (the squeeze radius) needs its own cache."""

    def __init__(self, clearance: float, max_standoff: float, gain_radius: float):
        self.clearance = clearance
        self.max_standoff = max_standoff
        self.gain_radius = gain_radius
        self.changes = ChangeStamps()
        self._grid: OccupancyGrid | None = None
        self._reach: Reachability | None = None
        self._standoffs: dict[bytes, tuple[int, tuple[int, int, int, int], StandoffResult]] = {}
        self._gains: dict[tuple[float, float], tuple[int, float]] = {}
        self._asked_standoffs: set[bytes] = set()
        self._asked_gains: set[tuple[float, float]] = set()
        self.reused = {"standoff": 0, "gain": 0}  # [count] values used again instead of recomputed

    def update(self, grid: OccupancyGrid, reach: Reachability) -> None:
        """A new decision's map and reachable area; what the previous decision did not ask
        for is dropped (frontiers that are gone), so memory follows the live frontiers."""
        self.changes.update(grid, reach)
        self._grid, self._reach = grid, reach
        self._standoffs = {k: self._standoffs[k] for k in self._asked_standoffs if k in self._standoffs}
        self._gains = {k: self._gains[k] for k in self._asked_gains if k in self._gains}
        self._asked_standoffs, self._asked_gains = set(), set()

    def standoff(self, frontier: Frontier) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """:meth:`.gain.Standoffs.goal` of ``frontier`` on the map of the last update."""
        key = frontier.cells.tobytes()
        self._asked_standoffs.add(key)
        kept = self._standoffs.get(key)
        if kept is not None and self.changes.clean_since(kept[0], *kept[1]):
            self.reused["standoff"] += 1
            return kept[2]
        grid, reach = self._grid, self._reach
        window = _window(frontier.cells, standoff_margin(grid.resolution, self.clearance, self.max_standoff),
                         grid.data.shape)
        result = window_standoff(grid, reach.component, reach.factor, self.clearance, self.max_standoff,
                                 frontier, window)
        self._standoffs[key] = (self.changes.count, window, result)
        return result

    def gains(self, points: list[tuple[float, float]]) -> np.ndarray:
        """:func:`.gain.visible_unknown` of ``points`` (radius ``gain_radius``) on the last
        update's map: kept values where no tile within the rays' reach changed, the rest
        computed together."""
        grid = self._grid
        reach_cells = int(math.ceil(self.gain_radius / grid.resolution)) + 4
        out = np.zeros(len(points))
        missing = []
        self._asked_gains.update(points)
        for i, xy in enumerate(points):
            kept = self._gains.get(xy)
            row, col = (int(v) for v in grid.world_to_cell(*xy))
            if kept is not None and self.changes.clean_since(kept[0], row - reach_cells, row + reach_cells + 1,
                                                             col - reach_cells, col + reach_cells + 1):
                out[i] = kept[1]
                self.reused["gain"] += 1
            else:
                missing.append(i)
        if missing:
            fresh = visible_unknown(grid, [points[i] for i in missing], self.gain_radius)
            for i, g in zip(missing, fresh, strict=True):
                out[i] = g
                self._gains[points[i]] = (self.changes.count, float(g))
        return out


def _window(cells: np.ndarray, margin: int, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """Rows ``r0:r1`` and cols ``c0:c1`` around ``cells`` widened by ``margin``, within the map."""
    r0, c0 = cells.min(axis=0)
    r1, c1 = cells.max(axis=0)
    return (max(int(r0) - margin, 0), min(int(r1) + margin + 1, shape[0]),
            max(int(c0) - margin, 0), min(int(c1) + margin + 1, shape[1]))
