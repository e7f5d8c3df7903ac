"""The objects standing on the floor at one point of the timeline, and how they come and go.

:class:`Layout` is the generator's replay of the world's timeline: session 1 is furnished
through it, and every later change (remove, move, bring back, add) is drawn against the
layout as it stands at that moment, so a change never names an object that is not there
and a new position never overlaps what already stands. Every placement goes through the
room's :class:`~bomc_bt.officegen.rooms.RoomSpace` checks.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.officegen.floor import FloorPlan
from bomc_bt.officegen.params import ELEVATION, HOT_PLACE, SIZES, OfficeParams
from bomc_bt.officegen.rooms import RoomSpace
from bomc_bt.world.looks import model_colour

TRIES = 25  # candidate poses tried before a placement gives up


@dataclass(frozen=True)
class Item:
    """An object of the generated world: where it stands and in which room."""

    name: str
    category: str
    x: float
    y: float
    yaw: float
    size: tuple[float, float, float]
    room: int
    colour: tuple[int, int, int] | None = None  # RGB 0-255 (bomc_bt.world.looks), set when first put

    @property
    def z(self) -> float:
        return round(ELEVATION.get(self.category, 0.0) + self.size[2] / 2.0, 3)

    def record(self) -> dict[str, Any]:
        """The world-file form (CONTRACTS section 1)."""
        out = {"name": self.name, "category": self.category, "position": [self.x, self.y, self.z],
               "size": list(self.size), "yaw": self.yaw}
        if self.colour is not None:
            out["colour"] = list(self.colour)
        return out


def _r(v: float) -> float:
    return round(float(v), 3)


class Layout:
    """What stands where; placements are checked, names are unique over the whole timeline."""

    def __init__(self, plan: FloorPlan, params: OfficeParams, rng: np.random.Generator):
        self.plan, self.params, self.rng = plan, params, rng
        self.spaces = [RoomSpace(room, plan.doorways, params) for room in plan.rooms]
        self.present: dict[str, Item] = {}
        self.removed: dict[str, Item] = {}  # removed earlier, may be brought back
        self.corridor: dict[str, Item] = {}  # chairs left in a corridor: they stay (officegen.corridor_chairs)
        self._counters: dict[str, int] = {}
        self.hot: set[int] = set()  # rooms where changes concentrate (OfficeParams.hot_rooms)

    def new_name(self, category: str) -> str:
        slug = re.sub(r"[^a-z0-9]+", "-", category.lower()).strip("-")
        self._counters[slug] = self._counters.get(slug, 0) + 1
        return f"{slug}-{self._counters[slug]}"

    # -- placing -------------------------------------------------------------------------------
    def put(self, item: Item, margin: float = 0.1, keepout: bool = True) -> Item | None:
        """Stand ``item`` (rounded as the file will hold it) if its room accepts it, else None."""
        colour = item.colour or model_colour(self.params.seed, item.name, item.category)
        item = replace(item, x=_r(item.x), y=_r(item.y), yaw=_r(item.yaw), colour=colour)
        space = self.spaces[item.room]
        if not space.fits(item.x, item.y, item.yaw, item.size, margin, keepout):
            return None
        space.add(item.name, item.x, item.y, item.yaw, item.size)
        self.present[item.name] = item
        self.removed.pop(item.name, None)
        return item

    def place(self, name: str, category: str, room: int, size: tuple[float, float, float] | None = None,
              yaw: float | None = None, wall: bool = True, margin: float = 0.1) -> Item | None:
        """Put a new box somewhere in ``room``: against a wall, or anywhere at a given/random yaw."""
        size = size or SIZES[category]
        space = self.spaces[room]
        for _ in range(TRIES):
            if wall and yaw is None:
                x, y, a = space.along_wall(self.rng, size)
            else:
                a = yaw if yaw is not None else float(self.rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2]))
                x, y = space.anywhere(self.rng, size, a)
            got = self.put(Item(name, category, x, y, a, size, room), margin)
            if got is not None:
                return got
        return None

    def room_for(self, size: tuple[float, float, float], min_area: float = 0.0) -> list[int]:
        """Rooms in random order, big enough for a box of ``size`` (and ``min_area``)."""
        order = [int(i) for i in self.rng.permutation(len(self.plan.rooms))]
        rooms = self.plan.rooms
        if self.hot and self.rng.random() < HOT_PLACE:  # changes happen in the hot rooms
            order = [i for i in order if i in self.hot] + [i for i in order if i not in self.hot]
        return [i for i in order if rooms[i].rect.area >= min_area
                and min(rooms[i].rect.width, rooms[i].rect.height) >= max(size[0], size[1]) + 0.2]

    # -- changes -------------------------------------------------------------------------------
    def remove(self, name: str) -> None:
        item = self.present.pop(name)
        self.spaces[item.room].remove(name)
        self.removed[name] = item

    def relocate(self, name: str, same_room: float = 0.5) -> Item | None:
        """Move ``name`` (its yaw and height kept, as a world-file ``move`` does) to a free spot."""
        item = self.present[name]
        self.spaces[item.room].remove(name)
        del self.present[name]
        same_room = 1.0 if item.room in self.hot else same_room
        rooms = [item.room] if self.rng.random() < same_room else []
        rooms += self.room_for(item.size)[:4]
        for room in rooms:
            for _ in range(TRIES // 2):
                x, y = self.spaces[room].anywhere(self.rng, item.size, item.yaw)
                if math.hypot(x - item.x, y - item.y) < 1.0:  # a move the robot could not tell apart
                    continue
                got = self.put(replace(item, x=x, y=y, room=room))
                if got is not None:
                    return got
        if self.put(item, margin=0.0, keepout=False) is None:  # nowhere to go: it stays put
            raise BomcError(f"generator bug: {name} no longer fits where it stood")
        return None

    def bring_back(self, name: str) -> Item | None:
        """Re-add an object removed earlier: at its old place when that is free, else elsewhere."""
        item = self.removed[name]
        if self.rng.random() < 0.5:
            got = self.put(item)
            if got is not None:
                return got
        for room in self.room_for(item.size)[:4]:
            got = self.place(name, item.category, room, item.size, wall=item.category != "chair")
            if got is not None:
                return got
        return None

    def add_new(self, category: str) -> Item | None:
        """A brand-new object of ``category`` in some room (chairs anywhere, the rest at walls)."""
        size = SIZES[category]
        name = self.new_name(category)
        for room in self.room_for(size)[:6]:
            got = self.place(name, category, room, size, wall=category != "chair")
            if got is not None:
                return got
        return None
