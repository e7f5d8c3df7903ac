"""Session 1: furnish the floor with the paper's object mix, scaled to the floor's area.

* a **door** in every doorway: the open leaf against the inside of the wall beside the
  opening (the lidar sees it, the opening stays clear for the robot);
* **tables**: a desk against a wall in an office, a table in the middle of a meeting
  room, several in an open-plan area -- until the area's share of tables is used up;
* **chairs**: dealt round-robin to the tables (a desk takes one, a table up to six), the
  rest stand at walls as visitors' chairs;
* **other categories** (trash bins, cabinets, potted plants, sofas, wall-mounted
  televisions) at walls of random rooms.

Counts are densities times the floor area (:data:`~bomc_bt.officegen.params.DENSITY`);
a placement that finds no room left (every candidate overlaps, blocks a doorway or cuts
an object off from the robot) is skipped, so a crowded small floor gets a little less.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from bomc_bt.errors import BomcError
from bomc_bt.officegen.layout import TRIES, Item, Layout
from bomc_bt.officegen.params import DENSITY, SIZES

CHAIR_GAP = 0.05  # m between a chair and its table


@dataclass
class _Table:
    item: Item
    desk: bool
    slots: list[tuple[float, float, float]]  # chair poses (x, y, yaw) in the order they are filled
    chairs: int = 0


@dataclass
class Furnishing:
    """What :func:`furnish` placed, and what it wanted to (the counts a report can compare)."""

    targets: dict[str, int] = field(default_factory=dict)
    placed: dict[str, int] = field(default_factory=dict)


def targets_for_area(area: float) -> dict[str, int]:
    """Objects per category for ``area`` m2 of floor (doors are not in it: one per doorway)."""
    return {category: int(math.floor(per_1000 * area / 1000.0 + 0.5)) for category, per_1000 in DENSITY.items()}


def furnish(layout: Layout) -> Furnishing:
    """Place session 1's objects into ``layout`` (doors, tables, chairs, the rest)."""
    p = layout.params
    report = Furnishing(targets=targets_for_area(p.width * p.height))
    _doors(layout)
    tables = _tables(layout, report.targets["table"])
    _chairs(layout, tables, report.targets["chair"])
    for category in ("trash bin", "cabinet", "potted plant", "sofa", "television"):
        _at_walls(layout, category, report.targets[category], min_area=20.0 if category == "sofa" else 0.0)
    report.targets["door"] = len(layout.plan.doorways)
    for item in layout.present.values():
        report.placed[item.category] = report.placed.get(item.category, 0) + 1
    return report


def _doors(layout: Layout) -> None:
    """One door per doorway; the plan left room for every leaf, so a refusal is a generator bug."""
    size = SIZES["door"]
    for i, d in enumerate(layout.plan.doorways):
        x, y, yaw = d.leaf
        got = layout.put(Item(layout.new_name("door"), "door", x, y, yaw, size, d.room), margin=0.0, keepout=False)
        if got is None:
            raise BomcError(f"generator bug: the door leaf of doorway {i} does not fit in room {d.room}")


def _tables(layout: Layout, budget: int) -> list[_Table]:
    """Desks in offices, tables in meeting rooms and open-plan areas, until ``budget`` is used."""
    out: list[_Table] = []
    rooms = layout.plan.rooms
    progress = True
    while len(out) < budget and progress:
        progress = False
        for room in layout.room_for(SIZES["desk"]):
            if len(out) >= budget:
                break
            kind = rooms[room].kind
            want = 1 if kind != "open-plan" else max(2, int(rooms[room].rect.area // 18))
            have = sum(1 for t in out if t.item.room == room)
            if have >= want:
                continue
            table = _desk(layout, room) if kind == "office" else _table(layout, room)
            if table is not None:
                out.append(table)
                progress = True
    return out


def _desk(layout: Layout, room: int) -> _Table | None:
    size = SIZES["desk"]
    space = layout.spaces[room]
    for _ in range(TRIES):
        x, y, yaw = space.along_wall(layout.rng, size)
        got = layout.put(Item(layout.new_name("table"), "table", x, y, yaw, size, room), margin=0.1)
        if got is not None:
            front = size[1] / 2 + CHAIR_GAP + SIZES["chair"][1] / 2
            slot = (x - math.sin(yaw) * front, y + math.cos(yaw) * front, yaw + math.pi)
            return _Table(got, True, [slot])
    return None


def _table(layout: Layout, room: int) -> _Table | None:
    """A free-standing table, aligned with the room, with a ring of space for chairs around it."""
    size = SIZES["table"]
    space = layout.spaces[room]
    rect = layout.plan.rooms[room].rect
    along = 0.0 if rect.width >= rect.height else math.pi / 2
    for attempt in range(TRIES):
        if attempt == 0 and layout.plan.rooms[room].kind == "meeting":
            x, y = rect.centre
        else:
            x, y = space.anywhere(layout.rng, size, along)
        got = layout.put(Item(layout.new_name("table"), "table", x, y, along, size, room),
                         margin=SIZES["chair"][0] + 0.15)
        if got is not None:
            return _Table(got, False, _ring(got))
    return None


def _ring(table: Item) -> list[tuple[float, float, float]]:
    """Chair poses around a table: both long sides first (alternating), then the ends."""
    sx, sy = table.size[0], table.size[1]
    c, s = math.cos(table.yaw), math.sin(table.yaw)
    side = sy / 2 + CHAIR_GAP + SIZES["chair"][1] / 2
    end = sx / 2 + CHAIR_GAP + SIZES["chair"][0] / 2
    local = [(-sx / 4, -side, math.pi / 2), (sx / 4, side, -math.pi / 2),
             (sx / 4, -side, math.pi / 2), (-sx / 4, side, -math.pi / 2),
             (-end, 0.0, 0.0), (end, 0.0, math.pi)]
    return [(table.x + u * c - v * s, table.y + u * s + v * c, table.yaw + a) for u, v, a in local]


def _chairs(layout: Layout, tables: list[_Table], budget: int) -> None:
    """Deal chairs to tables round-robin (desks take one), then stand the rest at walls."""
    placed, rnd = 0, 0
    while placed < budget:
        dealt = False
        for t in tables:
            if placed >= budget:
                break
            if t.chairs != rnd or rnd >= len(t.slots):
                continue
            x, y, yaw = t.slots[rnd]
            yaw = math.atan2(math.sin(yaw), math.cos(yaw))
            got = layout.put(Item(layout.new_name("chair"), "chair", x, y, yaw, SIZES["chair"], t.item.room),
                             margin=0.02)
            t.chairs += 1  # a slot that does not fit is skipped, not retried
            dealt = True
            placed += got is not None
        rnd += 1
        if not dealt:
            break
    _at_walls(layout, "chair", budget - placed)


def _at_walls(layout: Layout, category: str, count: int, min_area: float = 0.0) -> None:
    size = SIZES[category]
    for _ in range(max(count, 0)):
        name = layout.new_name(category)
        for room in layout.room_for(size, min_area)[:6]:
            if layout.place(name, category, room, size) is not None:
                break
