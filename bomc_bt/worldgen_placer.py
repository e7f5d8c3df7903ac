"""Where a generated world may put an object on a real map: free, apart, and never in the robot's way.

Random boxes over a SLAM map land anywhere: in a 1 m doorway, across a corridor, in an
alcove the robot cannot enter. A building's furniture does not wall off half the floor,
so a placement is kept only when (1) its disc and a clearance margin are free, (2) every
place the robot could drive to before is still reachable, apart from the ring the disc
itself takes (a robot of ``robot_radius`` plus one cell; pockets under ``pocket_area``
behind it are forgiven), and (3) the robot can come within ``view_reach`` of it over the
floor (not through a wall, nor through a gap no wider than ``sight_gap``). Objects
are bounding discs here, a superset of the boxes the simulator raises, so the test errs
on the safe side. Each test is one distance transform and one labelling of the map
(milliseconds at 0.03-0.05 m cells); a rejected centre is struck off and another drawn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.grid import OccupancyGrid
from bomc_bt.world import wall_mask
from bomc_bt.world.walls import drivable_from


@dataclass
class PlacementRules:
    """What a placement must leave free (metres)."""

    clearance: float = 0.15  # free margin kept around each object's bounding circle
    robot_radius: float = 0.3  # the robot that must still get everywhere (plus one cell)
    view_reach: float = 1.6  # every object has a reachable robot position within this of its disc
    # A gap in a wall no wider than this is no window: the view from the floor to an object
    # goes round walls, not through the gaps of a dotted SLAM wall. Half the smallest default
    # object (a 0.4 m bin), so through such a gap at most half of an object shows (hospital
    # seed 23: four objects over six passes inside outlines drawn with 0.05-0.2 m gaps, never seen).
    sight_gap: float = 0.2
    pocket_area: float = 0.5  # [m^2] floor cut off behind an object that is forgiven (corners)
    tries: int = 40  # centres drawn before a placement gives up


def reachable_free(grid: OccupancyGrid) -> np.ndarray:
    """The largest 4-connected region of free cells (bool mask like ``grid.data``)."""
    free = (~wall_mask(grid)).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(free, connectivity=4)
    if count <= 1:
        return np.zeros_like(free, dtype=bool)
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return labels == biggest


def _without_narrow_gaps(floor: np.ndarray, resolution: float, gap: float) -> np.ndarray:
    """``floor`` less its cells within ``gap / 2`` of a wall (at least one cell): a gap no
    wider than ``gap`` leaves no cell, so what lies behind it is no longer joined to the
    floor in front of it. ``gap`` 0 keeps the floor as it is."""
    if gap <= 0.0:
        return floor
    k = max(1, math.ceil(gap / (2.0 * resolution) - 1e-9))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
    return cv2.erode(floor.astype(np.uint8), disc, borderValue=0) > 0


def clearance_map(mask: np.ndarray, resolution: float) -> np.ndarray:
    """Metres from each cell of ``mask`` to the nearest cell outside it (the image edge counts)."""
    padded = np.pad(mask.astype(np.uint8), 1)
    dist = cv2.distanceTransform(padded, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
    return dist.astype(np.float64) * resolution


class Placer:
    """Draws object discs over the reachable free space, deterministically for a seed.

    ``free`` holds what is neither wall nor taken (object discs and the start's keep-out);
    ``taken`` only the objects, which is what the robot must drive round.
    """

    def __init__(self, grid: OccupancyGrid, rng: np.random.Generator, rules: PlacementRules,
                 start: tuple[float, float], keepout: float):
        self.grid, self.rng, self.rules = grid, rng, rules
        self.reachable = reachable_free(grid)
        self.sight_floor = _without_narrow_gaps(self.reachable, grid.resolution, rules.sight_gap)
        self.free = self.reachable.astype(np.uint8)  # 1 = free and not yet taken
        self.taken = np.zeros_like(self.free)
        self.start, self.keepout = start, keepout
        self._paint(self.free, start[0], start[1], keepout, 0)
        self._clear: np.ndarray | None = None
        self._reach: np.ndarray | None = None

    # -- the masks ------------------------------------------------------------------------
    def _paint(self, mask: np.ndarray, x: float, y: float, radius: float, value: int) -> None:
        r, c = self.grid.world_to_cell(x, y)
        cv2.circle(mask, (int(c), int(r)), int(math.ceil(radius / self.grid.resolution)), value, -1)

    def reserve(self, x: float, y: float, radius: float) -> None:
        self._paint(self.free, x, y, radius, 0)
        self._paint(self.taken, x, y, radius, 1)
        self._clear = self._reach = None

    def release(self, x: float, y: float, radius: float, kept: list[tuple[float, float, float]]) -> None:
        """Give a disc back to the free space (the ``kept`` discs, (x, y, radius), stay taken)."""
        disc = np.zeros_like(self.free)
        self._paint(disc, x, y, radius, 1)
        self.free[(disc > 0) & self.reachable] = 1
        self.taken[disc > 0] = 0
        self._paint(self.free, self.start[0], self.start[1], self.keepout, 0)
        for kx, ky, kr in kept:
            self.reserve(kx, ky, kr)
        self._clear = self._reach = None

    def robot_reach(self, taken: np.ndarray | None = None) -> np.ndarray:
        """Cells a robot at the start can drive to with ``taken`` (default: the objects now) standing."""
        if taken is None and self._reach is not None:
            return self._reach
        solid = ~self.reachable | ((self.taken if taken is None else taken) > 0)
        r, c = self.grid.world_to_cell(*self.start)
        reach = drivable_from(solid, self.grid.resolution, self.rules.robot_radius, (int(r), int(c)))
        if taken is None:
            self._reach = reach
        return reach

    # -- the rules ------------------------------------------------------------------------
    def fits(self, x: float, y: float, radius: float) -> bool:
        """Whether a disc of ``radius`` at (x, y) is free now and keeps the robot's way open."""
        if self._clear is None:
            self._clear = clearance_map(self.free > 0, self.grid.resolution)
        r, c = self.grid.world_to_cell(x, y)
        if not self.grid.in_bounds(r, c) or float(self._clear[r, c]) < radius + self.rules.clearance:
            return False
        return self._keeps_the_way_open(x, y, radius)

    def _keeps_the_way_open(self, x: float, y: float, radius: float) -> bool:
        before = self.robot_reach()
        taken = self.taken.copy()
        self._paint(taken, x, y, radius, 1)
        after = self.robot_reach(taken)
        ring = np.zeros_like(taken)
        self._paint(ring, x, y, radius + self.rules.robot_radius + 2 * self.grid.resolution, 1)
        lost = before & ~after & (ring == 0)
        if lost.sum() * self.grid.resolution ** 2 > self.rules.pocket_area:
            return False
        return self._seen_from(after, x, y, radius)

    def _seen_from(self, reach: np.ndarray, x: float, y: float, radius: float) -> bool:
        """Whether a cell of ``reach`` lies within ``view_reach`` of the disc *through the
        floor*, not through a wall: on a real SLAM map the free space leaks through one-cell
        gaps into pockets behind walls (rays out of a window), and an object placed there,
        1.3-1.7 m from the robot's floor as the crow flies, was never seen by any pass (PAL
        office: 3 of 28 objects). The disc grows one cell a step over the map's floor,
        alternating square and cross steps (an octagon, near a true distance). It grows over
        the floor less its cells within ``sight_gap / 2`` of a wall, so a gap no wider than
        ``sight_gap`` does not conduct at all: an outline drawn with small gaps (hospital)
        is a closed box."""
        res = self.grid.resolution
        steps = int(math.ceil(self.rules.view_reach / res))
        k = steps + int(math.ceil(radius / res)) + 2
        r, c = self.grid.world_to_cell(x, y)
        r0, c0 = max(int(r) - k, 0), max(int(c) - k, 0)
        r1, c1 = min(int(r) + k + 1, self.grid.height), min(int(c) + k + 1, self.grid.width)
        square, cross = (cv2.getStructuringElement(shape, (3, 3)) for shape in (cv2.MORPH_RECT, cv2.MORPH_CROSS))
        disc = np.zeros((r1 - r0, c1 - c0), np.uint8)
        cv2.circle(disc, (int(c) - c0, int(r) - r0), int(math.ceil(radius / res)), 1, -1)
        floor = self.sight_floor[r0:r1, c0:c1].astype(np.uint8)
        window = reach[r0:r1, c0:c1]
        grown = disc
        for step in range(steps):
            if (window & (grown > 0)).any():
                return True
            grown = cv2.dilate(grown, cross if step % 2 else square) & floor
        return bool((window & (grown > 0)).any())

    def place(self, radius: float) -> tuple[float, float] | None:
        """A free centre for a disc of ``radius`` that keeps the robot's way open, or None."""
        if self._clear is None:
            self._clear = clearance_map(self.free > 0, self.grid.resolution)
        cells = np.flatnonzero(self._clear >= radius + self.rules.clearance)
        for _ in range(self.rules.tries):
            if cells.size == 0:
                return None
            i = int(self.rng.integers(cells.size))
            r, c = np.unravel_index(int(cells[i]), self._clear.shape)
            x, y = self.grid.cell_to_world(r, c)
            x, y = round(float(x), 3), round(float(y), 3)
            if self._keeps_the_way_open(x, y, radius):
                self.reserve(x, y, radius)
                return x, y
            cells = np.delete(cells, i)
        return None
