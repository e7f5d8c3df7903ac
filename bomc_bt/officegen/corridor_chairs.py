"""A chair left in the middle of a corridor: the change that boxes a monitor pass in.

People carry chairs out of rooms and leave them in the corridor. A chair standing in the
middle of a 2.2 m corridor leaves about 0.85 m free on each side: the robot fits past it,
but the saved map does not have it, so a pass that meets it must go round it, possibly
several times, and a robot on the far side of it must find its way back. Issue 15 item 6
("never stuck for long") is reproduced with such worlds.

With ``OfficeParams.corridor_chair_every = N`` (``bomc world office --corridor-chairs N``)
every N-th session k >= 2 moves one chair from a room to the middle of a corridor
segment, away from crossings and doorways, where it stays for the rest of the world's
timeline (no later change picks it again). The floor stays connected for the robot: the
move is checked like a closing obstacle (nothing reachable before becomes unreachable).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from bomc_bt.officegen.connectivity import rasterise, reachable
from bomc_bt.officegen.floor import Corridor
from bomc_bt.officegen.layout import Item, Layout
from bomc_bt.world.records import box_corners

MIN_SIDE_GAP = 0.15  # m: free width each side of the chair beyond the robot's diameter


def footprints(layout: Layout) -> list[np.ndarray]:
    """Corner boxes of everything standing on the floor: the rooms' objects and corridor chairs."""
    items = [*layout.present.values(), *layout.corridor.values()]
    return [box_corners(it.x, it.y, it.size[0], it.size[1], it.yaw) for it in items]


def leave_chair_in_corridor(layout: Layout, spans, segments: list[tuple[Corridor, float, float]],
                            avoid: Corridor | None = None, exclude: set[str] = frozenset()) -> dict[str, list[float]]:
    """Move one chair from a room to the middle of a corridor segment: ``{name: [x, y]}``.

    ``spans(plan, corridor, lo, hi)`` gives the positions along a segment kept clear of
    doorways; ``avoid`` is the corridor closed in the same session; ``exclude`` the chairs
    the session adds (a world applies moves before additions). Empty when no chair stands
    in a room or no segment is wide enough to leave the robot a way past on both sides.
    """
    chairs = sorted(n for n, it in layout.present.items() if it.category == "chair" and n not in exclude)
    if not chairs:
        return {}
    p, plan = layout.params, layout.plan
    grid = plan.grid()
    before = reachable(grid, footprints(layout), p.robot_radius, plan.start[:2])
    name = chairs[int(layout.rng.integers(len(chairs)))]
    item = layout.present[name]
    for i in layout.rng.permutation(len(segments)):
        c, lo, hi = segments[int(i)]
        if avoid is not None and c.index == avoid.index:
            continue
        spot = _spot(layout, item, c, spans(plan, c, lo, hi))
        if spot is None:
            continue
        moved = replace(item, x=spot[0], y=spot[1])
        boxes = [*footprints(layout), box_corners(moved.x, moved.y, moved.size[0], moved.size[1], moved.yaw)]
        after = reachable(grid, boxes, p.robot_radius, plan.start[:2])
        pad = 2 * p.robot_radius + 0.3
        near = rasterise(grid.data.shape, grid.origin, grid.resolution,
                         [box_corners(moved.x, moved.y, moved.size[0] + pad, moved.size[1] + pad, moved.yaw)])
        if np.any(before & ~after & ~near.astype(bool)):  # the chair cut something off
            continue
        layout.remove(name)
        layout.removed.pop(name, None)  # it is not in a room any more, nor gone
        layout.corridor[name] = moved
        return {name: [moved.x, moved.y]}
    return {}


def _spot(layout: Layout, item: Item, c: Corridor, along: list[float]) -> tuple[float, float] | None:
    """A centred position in corridor ``c`` with a way past on both sides, drawn from ``along``."""
    if not along:
        return None
    r = c.rect
    across = (r.x1 - r.x0) if c.axis == "y" else (r.y1 - r.y0)
    corners = box_corners(0.0, 0.0, item.size[0], item.size[1], item.yaw)
    extent = float(np.ptp(corners[:, 0] if c.axis == "y" else corners[:, 1]))
    if (across - extent) / 2 < 2 * layout.params.robot_radius + MIN_SIDE_GAP:
        return None
    a = float(along[int(layout.rng.integers(len(along)))])
    mid = round((r.x0 + r.x1) / 2, 3) if c.axis == "y" else round((r.y0 + r.y1) / 2, 3)
    return (mid, round(a, 3)) if c.axis == "y" else (round(a, 3), mid)


def corridor_chair_sessions(every: int, sessions: int) -> list[int]:
    """The sessions (k >= 2) that leave a chair in a corridor; none when ``every`` is 0."""
    return [k for k in range(2, sessions + 1) if every and k % every == 0]


def add_corridor_move(change: dict[str, Any], moved: dict[str, list[float]]) -> None:
    """Merge the corridor move into session ``change``'s moves (the world applies moves after removals)."""
    if moved:
        change["move"] = {**change.get("move", {}), **moved}
