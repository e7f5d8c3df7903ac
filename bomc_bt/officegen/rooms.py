"""Placing boxes inside one room without ever shutting the robot out of it.

Every placement in a room, in session 1 and in every later change, goes through
:meth:`RoomSpace.fits`, which checks three things on a small raster of the room (its
interior, a pad of wall around it and the doorway gaps through that pad):

* the box lies inside the room and does not overlap another box (grown by a margin);
* it keeps off the approach in front of every doorway (unless it is that doorway's leaf);
* with every box in the room solid, a robot of ``robot_radius`` (plus one cell) can still
  pass between every pair of the room's doorways, and reach a pose within ``view_reach``
  of every box's centre -- so doorways stay passable and every object can be looked at.

Boxes are rasterised exactly as the simulator's scene does (:mod:`bomc_bt.sim.scene`):
cells under the polygon plus the cell under its centre, all solid for the robot's base.
A room raster is a few ten thousand cells, so a check costs a fraction of a millisecond.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from bomc_bt.officegen.connectivity import rasterise
from bomc_bt.officegen.floor import Doorway, Rect, Room
from bomc_bt.officegen.params import OfficeParams
from bomc_bt.world.records import box_corners

OPPOSITE = {"S": "N", "N": "S", "W": "E", "E": "W"}
APPROACH_DEPTH = 1.0  # m of floor kept clear in front of a doorway, inside the room


class RoomSpace:
    """The boxes standing in one room, and the checks every new one must pass."""

    def __init__(self, room: Room, doorways: Sequence[Doorway], params: OfficeParams):
        self.room, self.params = room, params
        self.res = params.resolution
        r = room.rect
        pad = math.ceil((params.robot_radius + 0.4) / self.res - 1e-9) * self.res  # whole cells: aligned with the map
        self.origin = (r.x0 - pad, r.y0 - pad)
        self.shape = (self._n(r.height + 2 * pad), self._n(r.width + 2 * pad))
        solid = np.ones(self.shape, dtype=bool)
        solid[self._slices(r)] = False
        self.keepout = np.zeros(self.shape, dtype=bool)
        self.seeds: list[tuple[int, int]] = []
        for index in room.doorways:
            d = doorways[index]
            side = d.side if d.room == room.index else OPPOSITE[d.side]
            gap, approach, seed = self._doorway_regions(d.opening, side, pad)
            solid[self._slices(gap)] = False
            self.keepout[self._slices(approach)] = True
            self.seeds.append(seed)
        self.walls = solid
        self.boxes: dict[str, tuple[np.ndarray, tuple[float, float]]] = {}  # name -> (corners, centre)
        self._taken: np.ndarray | None = None

    # -- geometry helpers -----------------------------------------------------------------------
    def _n(self, length: float) -> int:
        return int(round(length / self.res))

    def _slices(self, rect: Rect) -> tuple[slice, slice]:
        c0, c1 = self._n(rect.x0 - self.origin[0]), self._n(rect.x1 - self.origin[0])
        r0, r1 = self._n(rect.y0 - self.origin[1]), self._n(rect.y1 - self.origin[1])
        return slice(max(r0, 0), max(r1, 0)), slice(max(c0, 0), max(c1, 0))

    def _doorway_regions(self, o: Rect, side: str, pad: float):
        """The gap through the pad, the approach inside the room, and the seed cell at the gap's end."""
        r = self.room.rect
        if side == "S":
            gap, approach = Rect(o.x0, r.y0 - pad, o.x1, r.y0), Rect(o.x0, r.y0, o.x1, r.y0 + APPROACH_DEPTH)
        elif side == "N":
            gap, approach = Rect(o.x0, r.y1, o.x1, r.y1 + pad), Rect(o.x0, r.y1 - APPROACH_DEPTH, o.x1, r.y1)
        elif side == "W":
            gap, approach = Rect(r.x0 - pad, o.y0, r.x0, o.y1), Rect(r.x0, o.y0, r.x0 + APPROACH_DEPTH, o.y1)
        else:
            gap, approach = Rect(r.x1, o.y0, r.x1 + pad, o.y1), Rect(r.x1 - APPROACH_DEPTH, o.y0, r.x1, o.y1)
        cx, cy = gap.centre
        far = {"S": (cx, r.y0 - pad + self.res / 2), "N": (cx, r.y1 + pad - self.res / 2),
               "W": (r.x0 - pad + self.res / 2, cy), "E": (r.x1 + pad - self.res / 2, cy)}[side]
        return gap, approach, self._cell(*far)

    def _cell(self, x: float, y: float) -> tuple[int, int]:
        row = int(np.clip(math.floor((y - self.origin[1]) / self.res), 0, self.shape[0] - 1))
        col = int(np.clip(math.floor((x - self.origin[0]) / self.res), 0, self.shape[1] - 1))
        return row, col

    def rasterise(self, polygons: Sequence[np.ndarray]) -> np.ndarray:
        return rasterise(self.shape, self.origin, self.res, polygons)

    def taken(self) -> np.ndarray:
        if self._taken is None:
            self._taken = self.rasterise([c for c, _ in self.boxes.values()]).astype(bool)
        return self._taken

    # -- the checks ------------------------------------------------------------------------------
    def inside(self, corners: np.ndarray, slack: float = 0.01) -> bool:
        r = self.room.rect
        xs, ys = corners[:, 0], corners[:, 1]
        return bool(xs.min() >= r.x0 + slack and xs.max() <= r.x1 - slack
                    and ys.min() >= r.y0 + slack and ys.max() <= r.y1 - slack)

    def fits(self, x: float, y: float, yaw: float, size: Sequence[float], margin: float = 0.1,
             keepout: bool = True) -> bool:
        """Whether a box may stand here (see the module docstring for what is checked)."""
        corners = box_corners(x, y, size[0], size[1], yaw)
        if not self.inside(corners):
            return False
        grown = box_corners(x, y, size[0] + 2 * margin, size[1] + 2 * margin, yaw)
        footprint = self.rasterise([grown]).astype(bool)
        blocked = self.taken() | self.keepout if keepout else self.taken()
        if np.any(footprint & blocked):
            return False
        solid = self.walls | self.taken() | self.rasterise([corners]).astype(bool)
        centres = [centre for _, centre in self.boxes.values()] + [(x, y)]
        return self.reachable(solid, centres)

    def reachable(self, solid: np.ndarray, centres: Sequence[tuple[float, float]]) -> bool:
        """All doorway seeds in one robot-passable region that comes within view of every centre."""
        p = self.params
        dist = cv2.distanceTransform((~solid).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * self.res
        passable = (dist >= p.robot_radius + self.res).astype(np.uint8)
        _, labels = cv2.connectedComponents(passable, connectivity=4)
        seed_labels = {int(labels[s]) for s in self.seeds}
        if not self.seeds or 0 in seed_labels or len(seed_labels) != 1:
            return False
        region = labels == seed_labels.pop()
        to_region = cv2.distanceTransform((~region).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * self.res
        return all(float(to_region[self._cell(cx, cy)]) <= p.view_reach for cx, cy in centres)

    # -- changes ---------------------------------------------------------------------------------
    def add(self, name: str, x: float, y: float, yaw: float, size: Sequence[float]) -> None:
        corners = box_corners(x, y, size[0], size[1], yaw)
        self.boxes[name] = (corners, (x, y))
        if self._taken is not None:
            self._taken |= self.rasterise([corners]).astype(bool)

    def remove(self, name: str) -> None:
        del self.boxes[name]
        self._taken = None

    def passable(self) -> bool:
        """The room as it stands passes the reachability check (used to verify a finished layout)."""
        return self.reachable(self.walls | self.taken(), [c for _, c in self.boxes.values()])

    # -- candidate poses ---------------------------------------------------------------------------
    def along_wall(self, rng: np.random.Generator, size: Sequence[float]) -> tuple[float, float, float]:
        """A pose with the box's back against a random wall (its x extent along the wall)."""
        r, gap = self.room.rect, 0.03
        side = ("S", "N", "W", "E")[int(rng.integers(4))]
        sx, sy = size[0], size[1]
        if side in ("S", "N"):
            x = rng.uniform(r.x0 + sx / 2, max(r.x1 - sx / 2, r.x0 + sx / 2))
            y = r.y0 + sy / 2 + gap if side == "S" else r.y1 - sy / 2 - gap
            return x, y, 0.0 if side == "S" else math.pi
        y = rng.uniform(r.y0 + sx / 2, max(r.y1 - sx / 2, r.y0 + sx / 2))
        x = r.x0 + sy / 2 + gap if side == "W" else r.x1 - sy / 2 - gap
        return x, y, -math.pi / 2 if side == "W" else math.pi / 2

    def anywhere(self, rng: np.random.Generator, size: Sequence[float], yaw: float) -> tuple[float, float]:
        """A centre drawn uniformly where the box (at ``yaw``) would lie inside the room."""
        r = self.room.rect
        hx = 0.5 * (abs(size[0] * math.cos(yaw)) + abs(size[1] * math.sin(yaw)))
        hy = 0.5 * (abs(size[0] * math.sin(yaw)) + abs(size[1] * math.cos(yaw)))
        x = rng.uniform(r.x0 + hx, max(r.x1 - hx, r.x0 + hx))
        y = rng.uniform(r.y0 + hy, max(r.y1 - hy, r.y0 + hy))
        return x, y
