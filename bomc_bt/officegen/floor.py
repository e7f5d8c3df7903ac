"""The floor plan: a lattice of corridors, rooms in the blocks between them, doorways.

Corridors run the full length of the floor in both directions at about ``corridor_pitch``
spacing (93 x 90 m gives 9 + 9 = 18 corridors, the paper's Environment A). Every block
between corridors is either one open-plan area or one or two rows of rooms, each row
facing a corridor; each room has a doorway to the corridor it faces, so every room is
reachable by construction, and a few neighbours get an internal door as well.

All coordinates are in the map frame: the floor's outer walls span [0, width] x [0,
height]. Every edge is snapped to the map resolution, so walls rasterise to exactly the
intended number of cells and the same plan always gives the same image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from bomc_bt.officegen.params import SIZES, OfficeParams

SIDES = ("S", "N", "W", "E")  # the wall of a room a doorway is in (south: low y, ...)


@dataclass(frozen=True)
class Rect:
    """An axis-aligned rectangle [x0, x1] x [y0, y1] in metres."""

    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def width(self) -> float:
        return self.x1 - self.x0

    @property
    def height(self) -> float:
        return self.y1 - self.y0

    @property
    def area(self) -> float:
        return self.width * self.height

    @property
    def centre(self) -> tuple[float, float]:
        return (self.x0 + self.x1) / 2.0, (self.y0 + self.y1) / 2.0


@dataclass(frozen=True)
class Corridor:
    """A corridor running along ``axis`` ("x": west-east, "y": south-north) over the whole floor."""

    index: int
    axis: str
    rect: Rect


@dataclass(frozen=True)
class Doorway:
    """An opening in the ``side`` wall of room ``room``, leading to a corridor or (``other``) a room.

    ``opening`` is the cut through the wall (from room interior to the far side); ``leaf``
    is the open door leaf: a box (x, y, yaw) lying against the inside of the same wall on
    the ``hinge`` side of the opening, so the lidar sees it and the opening stays clear.
    """

    room: int
    other: int | None
    side: str
    opening: Rect
    leaf: tuple[float, float, float]

    @property
    def centre(self) -> tuple[float, float]:
        return self.opening.centre


@dataclass
class Room:
    """A room's free interior and its doorways (indices into :attr:`FloorPlan.doorways`)."""

    index: int
    kind: str  # "office", "meeting" or "open-plan"
    rect: Rect
    doorways: list[int] = field(default_factory=list)


@dataclass
class FloorPlan:
    params: OfficeParams
    corridors: list[Corridor]
    rooms: list[Room]
    doorways: list[Doorway]
    start: tuple[float, float, float]

    def grid(self) -> OccupancyGrid:
        """The true map: walls occupied, rooms, corridors and openings free, outside unknown."""
        p = self.params
        res, m = p.resolution, p.margin
        shape = (_n(p.height + 2 * m, res), _n(p.width + 2 * m, res))
        data = np.full(shape, UNKNOWN, dtype=np.int8)
        origin = (-m, -m)
        _fill(data, Rect(0.0, 0.0, p.width, p.height), origin, res, OCCUPIED)
        for rect in [*(c.rect for c in self.corridors), *(r.rect for r in self.rooms),
                     *(d.opening for d in self.doorways)]:
            _fill(data, rect, origin, res, FREE)
        return OccupancyGrid(data, res, origin)

    def corridor_length(self) -> float:
        return sum(max(c.rect.width, c.rect.height) for c in self.corridors)


def _n(length: float, res: float) -> int:
    return int(round(length / res))


def _fill(data: np.ndarray, rect: Rect, origin: tuple[float, float], res: float, value: int) -> None:
    c0, c1 = _n(rect.x0 - origin[0], res), _n(rect.x1 - origin[0], res)
    r0, r1 = _n(rect.y0 - origin[1], res), _n(rect.y1 - origin[1], res)
    data[max(r0, 0):max(r1, 0), max(c0, 0):max(c1, 0)] = value


class _Planner:
    """Draws the plan from the seeded generator; every length is snapped to the resolution."""

    def __init__(self, params: OfficeParams, rng: np.random.Generator):
        self.p, self.rng = params, rng
        self.rooms: list[Room] = []
        self.doorways: list[Doorway] = []

    def snap(self, v: float) -> float:
        res = self.p.resolution
        return round(round(v / res) * res, 6)

    def corridors(self, length: float) -> list[tuple[float, float]]:
        """(lo, hi) edges of the corridors spaced along ``length`` (at least one).

        The outermost corridors stay far enough from the outer walls for a row of rooms
        (``room_width[0]`` deep) between them; the rest are spread evenly, jittered a little.
        """
        p = self.p
        n = max(1, int(math.floor(length / p.corridor_pitch + 0.2)))
        edge = p.outer_wall + p.room_width[0] + 0.2 + p.corridor_wall + p.corridor_width[1] / 2
        if n == 1:
            centres = [length / 2]
        else:
            e = max(length / n / 2, edge)
            step = (length - 2 * e) / (n - 1)
            centres = [e + i * step + self.rng.uniform(-0.1, 0.1) * max(0.0, min(step - 7.0, 3.0)) * (0 < i < n - 1)
                       for i in range(n)]
        out = []
        for c in centres:
            width = self.rng.uniform(*p.corridor_width)
            out.append((self.snap(c - width / 2), self.snap(c + width / 2)))
        return out

    def intervals(self, length: float, corridors: list[tuple[float, float]]):
        """Block intervals between corridors: (lo, hi, corridor index below or None, above or None)."""
        p = self.p
        out, lo, below = [], p.outer_wall, None
        for i, (a, b) in enumerate(corridors):
            out.append((lo, self.snap(a - p.corridor_wall), below, i))
            lo, below = self.snap(b + p.corridor_wall), i
        out.append((lo, length - p.outer_wall, below, None))
        return out

    def plan(self) -> FloorPlan:
        p = self.p
        vertical = self.corridors(p.width)  # x centres of corridors running along y
        horizontal = self.corridors(p.height)
        corridors = [Corridor(i, "y", Rect(a, p.outer_wall, b, p.height - p.outer_wall))
                     for i, (a, b) in enumerate(vertical)]
        corridors += [Corridor(len(vertical) + j, "x", Rect(p.outer_wall, a, p.width - p.outer_wall, b))
                      for j, (a, b) in enumerate(horizontal)]
        for x0, x1, west, east in self.intervals(p.width, vertical):
            for y0, y1, south, north in self.intervals(p.height, horizontal):
                faces = {"W": west is not None, "E": east is not None, "S": south is not None,
                         "N": north is not None}
                self.block(Rect(x0, y0, x1, y1), faces)
        # The dock: the corridor crossing nearest the middle of the floor.
        cx = min(((a + b) / 2 for a, b in vertical), key=lambda c: abs(c - p.width / 2))
        cy = min(((a + b) / 2 for a, b in horizontal), key=lambda c: abs(c - p.height / 2))
        return FloorPlan(p, corridors, self.rooms, self.doorways, (self.snap(cx), self.snap(cy), 0.0))

    # -- blocks and rooms ---------------------------------------------------------------------
    def block(self, b: Rect, faces: dict[str, bool]) -> None:
        """Split one block between corridors into rooms, each with a doorway to a corridor."""
        p = self.p
        open_sides = [s for s in SIDES if faces[s]]
        if b.area >= 40.0 and self.rng.random() < p.open_plan_share:
            room = self.room("open-plan", b)
            for side in open_sides[:2]:
                self.doorway(room, side, None)
            return
        long_x = b.width >= b.height
        along, across = (("S", "N"), ("W", "E")) if long_x else (("W", "E"), ("S", "N"))
        if not any(faces[s] for s in along):  # the long sides are outer walls: rows face the ends
            long_x, (along, across) = not long_x, (across, along)
        depth = b.height if long_x else b.width
        facing = [s for s in along if faces[s]]
        min_depth = p.room_width[0]
        if (len(facing) == 2 and depth >= 2 * min_depth + p.partition_wall and depth >= 7.0
                and self.rng.random() < p.double_row_share):
            mid = self.snap((b.y0 + b.y1) / 2 if long_x else (b.x0 + b.x1) / 2)
            half = p.partition_wall / 2
            if long_x:
                rows = [(Rect(b.x0, b.y0, b.x1, self.snap(mid - half)), "S"),
                        (Rect(b.x0, self.snap(mid + half), b.x1, b.y1), "N")]
            else:
                rows = [(Rect(b.x0, b.y0, self.snap(mid - half), b.y1), "W"),
                        (Rect(self.snap(mid + half), b.y0, b.x1, b.y1), "E")]
        else:
            rows = [(b, facing[int(self.rng.integers(len(facing)))])]
        for rect, side in rows:
            self.row(rect, side, long_x)

    def row(self, r: Rect, side: str, long_x: bool) -> None:
        """Rooms side by side along a row, each with a doorway in the ``side`` wall."""
        p = self.p
        lo, hi = p.room_width
        start, end = (r.x0, r.x1) if long_x else (r.y0, r.y1)
        cuts, pos = [], start
        while end - pos > hi:
            w = self.rng.uniform(lo, hi)
            if end - (pos + w + p.partition_wall) < lo:
                w = (end - pos - p.partition_wall) / 2
            cuts.append((pos, self.snap(pos + w)))
            pos = self.snap(pos + w + p.partition_wall)
        cuts.append((pos, end))
        previous = None
        for a, b in cuts:
            rect = Rect(a, r.y0, b, r.y1) if long_x else Rect(r.x0, a, r.x1, b)
            kind = "office" if rect.area < 22.0 else ("meeting" if rect.area < 45.0 else "open-plan")
            room = self.room(kind, rect)
            self.doorway(room, side, None)
            if previous is not None and self.rng.random() < p.internal_door_share:
                self.doorway(previous, ("E" if long_x else "N"), room)
            previous = room

    def room(self, kind: str, rect: Rect) -> Room:
        room = Room(len(self.rooms), kind, rect)
        self.rooms.append(room)
        return room

    def doorway(self, room: Room, side: str, other: Room | None) -> None:
        """Cut a doorway in ``side`` of ``room`` with room for the open leaf on its hinge side.

        An internal doorway (to ``other``) is cut through the partition in its north/east
        half, hinged north/east: its leaf lies along the partition, where the leaf of a
        corridor door (along the corridor wall, ending 0.2 m or more from the corners)
        never reaches.
        """
        p, r = self.p, room.rect
        leaf_len, leaf_t = SIZES["door"][0], SIZES["door"][1]
        wall = p.partition_wall if other is not None else p.corridor_wall
        horizontal_wall = side in ("S", "N")
        u0, u1 = (r.x0, r.x1) if horizontal_wall else (r.y0, r.y1)
        half, need = p.door_width / 2, leaf_len + 0.1
        if other is not None:
            hinge = 1  # towards the far (north/east) end of the partition
            lo, hi = u0 + 0.4 + half, u1 - need - half
            lo = max(lo, (u0 + u1) / 2)
        else:
            hinge = 1 if self.rng.random() < 0.5 else -1
            lo = u0 + 0.15 + half + (need if hinge < 0 else 0.0)
            hi = u1 - 0.15 - half - (need if hinge > 0 else 0.0)
        if hi < lo:
            return
        uc = self.snap(self.rng.uniform(lo, hi))
        a, b = self.snap(uc - half), self.snap(uc + half)
        face = {"S": r.y0, "N": r.y1, "W": r.x0, "E": r.x1}[side]
        outward = -1.0 if side in ("S", "W") else 1.0
        far = self.snap(face + outward * (wall + p.resolution))  # one cell past the far face: no sliver
        w0, w1 = min(face, far), max(face, far)
        opening = Rect(a, w0, b, w1) if horizontal_wall else Rect(w0, a, w1, b)
        leaf_u = (b + 0.05 + leaf_len / 2) if hinge > 0 else (a - 0.05 - leaf_len / 2)
        leaf_v = face - outward * (0.04 + leaf_t / 2)
        leaf = (leaf_u, leaf_v, 0.0) if horizontal_wall else (leaf_v, leaf_u, math.pi / 2)
        door = Doorway(room.index, None if other is None else other.index, side, opening,
                       tuple(round(v, 4) for v in leaf))  # type: ignore[arg-type]
        room.doorways.append(len(self.doorways))
        if other is not None:
            other.doorways.append(len(self.doorways))
        self.doorways.append(door)


def plan_floor(params: OfficeParams, rng: np.random.Generator) -> FloorPlan:
    """A floor plan for ``params`` drawn from ``rng`` (the same generator state, the same plan)."""
    return _Planner(params, rng).plan()
