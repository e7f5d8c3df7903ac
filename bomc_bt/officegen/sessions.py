"""Sessions 2..N: what changes between monitor passes and during them.

Before each session k >= 2 a share (``churn``) of the movable objects changes, drawn by
:data:`~bomc_bt.officegen.params.CHURN_WEIGHT` (chairs and bins often, tables rarely,
doors never): about a third are removed, a third relocated, and the rest are objects
removed earlier coming back (at their old place when it is free, else elsewhere) or new
ones -- at least one of each, however small the floor. Every ``obstacle_every``-th
session a corridor segment between two crossings is closed wall to wall by an
unlabelled obstacle, away from any doorway, and the generator verifies that the robot
can still reach everything it could reach before by going round. Where no segment can be
closed so (corridors that form no loop, or loops whose segments are all lined with
doorways: narrow and small floors, 25 x 12 or 18 x 18 m), the session closes none. Every session
k >= 2 also has one change *during* the pass, timed inside it.

All changes are drawn against :class:`~bomc_bt.officegen.layout.Layout` as it stands at
that point of the timeline, in the order the world file applies them (CONTRACTS 1).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bomc_bt.officegen.connectivity import rasterise, reachable
from bomc_bt.officegen.corridor_chairs import (
    add_corridor_move,
    corridor_chair_sessions,
    footprints,
    leave_chair_in_corridor,
)
from bomc_bt.officegen.floor import Corridor, FloorPlan
from bomc_bt.officegen.layout import Item, Layout
from bomc_bt.officegen.params import ADDED_MIX, CHURN_WEIGHT, HOT_WEIGHT
from bomc_bt.world.records import box_corners

OBSTACLE_DEPTH = 0.6  # m along the corridor
OBSTACLE_HEIGHT = 1.0  # m: the lidar sees it, the robot cannot pass it
DOOR_CLEARANCE = 1.0  # m kept between a closing obstacle and any doorway
SPEED = 0.4  # m/s: a rough monitor-pass speed, to time the during changes inside the pass


@dataclass
class Timeline:
    """The world file's ``sessions`` and ``during`` entries, plus what a report may count."""

    sessions: dict[int, dict[str, Any]] = field(default_factory=dict)
    during: list[dict[str, Any]] = field(default_factory=list)
    blocked: dict[int, Corridor] = field(default_factory=dict)  # session -> the corridor closed
    corridor_chairs: dict[int, str] = field(default_factory=dict)  # session -> the chair left in a corridor


def plan_timeline(layout: Layout) -> Timeline:
    """Changes for sessions 2..N (none at all for a static world)."""
    p = layout.params
    out = Timeline()
    if p.hot_rooms > 0 and not p.static:
        n = max(1, int(round(p.hot_rooms * len(layout.plan.rooms))))
        layout.hot = {int(i) for i in layout.rng.permutation(len(layout.plan.rooms))[:n]}
    for k in range(2, p.sessions + 1):
        if p.static:
            out.sessions[k] = {}
            continue
        change = _between(layout, k)
        if k % p.obstacle_every == 0:
            got = _block_corridor(layout)
            if got is not None:
                change["obstacles"] = [got[0]]
                out.blocked[k] = got[1]
        if k in corridor_chair_sessions(p.corridor_chair_every, p.sessions):
            added = {a["name"] for a in change.get("add", [])}
            moved = leave_chair_in_corridor(layout, _free_spans, _segments(layout.plan), out.blocked.get(k), added)
            add_corridor_move(change, moved)
            if moved:
                out.corridor_chairs[k] = next(iter(moved))
        out.sessions[k] = {key: v for key, v in change.items() if v}
        during = _during(layout, k)
        if during is not None:
            out.during.append(during)
    return out


def _pick(layout: Layout, count: int, exclude: set[str] = frozenset()) -> list[str]:  # type: ignore[assignment]
    """Up to ``count`` present objects, drawn without replacement by churn weight."""
    names = [n for n in sorted(layout.present) if n not in exclude
             and CHURN_WEIGHT.get(layout.present[n].category, 0.5) > 0.0]
    if count <= 0 or not names:
        return []
    w = np.array([CHURN_WEIGHT.get(layout.present[n].category, 0.5)
                  * (HOT_WEIGHT if layout.present[n].room in layout.hot else 1.0) for n in names])
    count = min(count, len(names))
    picked = layout.rng.choice(len(names), size=count, replace=False, p=w / w.sum())
    return [names[int(i)] for i in sorted(picked)]


def _new_category(layout: Layout) -> str:
    cats, shares = zip(*ADDED_MIX, strict=True)
    return str(cats[int(layout.rng.choice(len(cats), p=np.array(shares) / sum(shares)))])


def _between(layout: Layout, k: int) -> dict[str, Any]:
    """The object changes before session ``k`` (remove, then move, then add)."""
    p = layout.params
    movable = [n for n, it in layout.present.items() if CHURN_WEIGHT.get(it.category, 0.5) > 0.0]
    n = int(round(p.churn * len(movable)))
    back_pool = sorted(layout.removed)
    if p.churn > 0:  # at least one of each kind of change, however small the floor
        n_remove, n_move = max(1, round(0.3 * n)), max(1, round(0.3 * n))
        n_add = max(1, n - n_remove - n_move)
    else:
        n_remove = n_move = n_add = 0
    n_back = min(len(back_pool), max(1, n_add // 2)) if n_add else 0
    n_new = n_add - n_back
    removed = _pick(layout, n_remove)
    for name in removed:
        layout.remove(name)
    moved: dict[str, list[float]] = {}
    for name in _pick(layout, n_move):
        got = layout.relocate(name)
        if got is not None:
            moved[name] = [got.x, got.y]
    added: list[Item] = []
    if n_back:
        for i in sorted(layout.rng.choice(len(back_pool), size=n_back, replace=False)):
            got = layout.bring_back(back_pool[int(i)])
            if got is not None:
                added.append(got)
    for _ in range(n_new):
        got = layout.add_new(_new_category(layout))
        if got is not None:
            added.append(got)
    return {"remove": removed, "move": moved, "add": [it.record() for it in added]}


def _during(layout: Layout, k: int) -> dict[str, Any] | None:
    """One change while session ``k`` runs: an object removed, moved or added."""
    plan = layout.plan
    est = (plan.corridor_length() + 4.0 * len(plan.rooms)) / SPEED
    at = round(float(layout.rng.uniform(0.1, 0.5) * est), 1)
    kind = ("remove", "move", "add")[int(layout.rng.integers(3))]
    entry: dict[str, Any] = {"session": k, "at": at}
    if kind == "add":
        got = layout.add_new(_new_category(layout))
        if got is not None:
            entry["add"] = [got.record()]
    else:
        names = _pick(layout, 1)
        if names and kind == "remove":
            layout.remove(names[0])
            entry["remove"] = names
        elif names:
            moved = layout.relocate(names[0])
            if moved is not None:
                entry["move"] = {names[0]: [moved.x, moved.y]}
    return entry if len(entry) > 2 else None


def _segments(plan: FloorPlan) -> list[tuple[Corridor, float, float]]:
    """Corridor stretches between two consecutive crossings: (corridor, lo, hi) along its axis."""
    out = []
    for c in plan.corridors:
        across = sorted((o.rect.y0, o.rect.y1) if c.axis == "y" else (o.rect.x0, o.rect.x1)
                        for o in plan.corridors if o.axis != c.axis)
        out.extend((c, a[1], b[0]) for a, b in zip(across[:-1], across[1:], strict=True))
    return out


def _free_spans(plan: FloorPlan, c: Corridor, lo: float, hi: float) -> list[float]:
    """Positions along a segment (0.1 m steps) a closing obstacle may take: away from doorways."""
    vertical = c.axis == "y"
    half = OBSTACLE_DEPTH / 2
    pos = np.arange(lo + 1.5 + half, hi - 1.5 - half, 0.1)
    ok = np.ones(pos.shape, dtype=bool)
    r = c.rect
    for d in plan.doorways:
        o = d.opening
        near = (o.x1 >= r.x0 - 0.5 and o.x0 <= r.x1 + 0.5) if vertical else (o.y1 >= r.y0 - 0.5 and o.y0 <= r.y1 + 0.5)
        if not near:
            continue
        a, b = (o.y0, o.y1) if vertical else (o.x0, o.x1)
        ok &= (pos + half < a - DOOR_CLEARANCE) | (pos - half > b + DOOR_CLEARANCE)
    return [round(float(v), 3) for v in pos[ok]]


def _block_corridor(layout: Layout) -> tuple[dict[str, Any], Corridor] | None:
    """An obstacle closing one corridor segment wall to wall, with the floor still connected round it."""
    plan, p = layout.plan, layout.params
    grid = plan.grid()
    start = plan.start[:2]
    boxes = footprints(layout)
    before = reachable(grid, boxes, p.robot_radius, start)
    segments = _segments(plan)
    for i in layout.rng.permutation(len(segments)):
        c, lo, hi = segments[int(i)]
        spans = _free_spans(plan, c, lo, hi)
        if not spans:
            continue
        along = spans[int(layout.rng.integers(len(spans)))]
        r = c.rect
        across = (r.x1 - r.x0) if c.axis == "y" else (r.y1 - r.y0)
        span = round(across + p.corridor_wall, 3)  # reaches into both walls: no gap to squeeze through
        if c.axis == "y":
            ob = {"position": [round((r.x0 + r.x1) / 2, 3), along], "size": [span, OBSTACLE_DEPTH]}
        else:
            ob = {"position": [along, round((r.y0 + r.y1) / 2, 3)], "size": [OBSTACLE_DEPTH, span]}
        ob.update(height=OBSTACLE_HEIGHT, yaw=0.0)
        corners = box_corners(*ob["position"], *ob["size"], 0.0)
        after = reachable(grid, [*boxes, corners], p.robot_radius, start)
        near = rasterise(grid.data.shape, grid.origin, grid.resolution,
                         [box_corners(*ob["position"], ob["size"][0] + 2 * p.robot_radius + 0.3,
                                      ob["size"][1] + 2 * p.robot_radius + 0.3, 0.0)]).astype(bool)
        if not np.any(before & ~after & ~near):
            return ob, c
    return None  # no loop to go round, or no stretch of one clear of doorways
