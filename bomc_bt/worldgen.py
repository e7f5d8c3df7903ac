"""Random worlds over any occupancy map, so the project is tested on maps nobody tuned for.

:func:`generate_world` scatters labelled boxes over the free space of a map_server map
(only over the largest connected free region, so every object is reachable from the
start), keeps each one clear of walls, of the others and of the start pose, and writes a
version-1 world file. Two recipes for what changes between passes:

- the default (``churn`` None), three sessions as the tests know them: a session 2 with
  removals, moves and additions, a session 3 with removals, additions and an unlabelled
  obstacle, an intra-session change in each (longer worlds repeat session 3's recipe);
- ``churn`` (a share of the objects per session, ``bomc world map``): before every session
  k >= 2 about a third of that share is removed, a third moved and the rest added, half of
  those objects removed earlier coming back (at their old place when it is free); every
  third session an obstacle for that session only; one change during every pass. 0 is a
  static world.

The same seed always gives the same file. The result is loaded back through
:func:`bomc_bt.world.load_world`, so a generator bug surfaces as a validation error.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid, load_map
from bomc_bt.world import FORMAT_VERSION, World, load_world
from bomc_bt.world.looks import model_colour
from bomc_bt.worldgen_placer import PlacementRules, Placer, clearance_map, reachable_free

# Typical box (x, y, z extents, m) per category; the centre stands at half the height
# unless the category hangs higher (a television on a wall mount or stand).
DEFAULT_SIZES: dict[str, tuple[float, float, float]] = {
    "chair": (0.5, 0.5, 0.9),
    "table": (1.2, 0.8, 0.75),
    "trash bin": (0.4, 0.4, 0.6),
    "door": (0.9, 0.06, 2.0),
    "person": (0.5, 0.4, 1.7),
    "cabinet": (0.9, 0.5, 1.2),
    "television": (1.0, 0.15, 0.6),
    "umbrella": (0.3, 0.3, 1.0),
    "sofa": (1.8, 0.9, 0.8),
    "potted plant": (0.4, 0.4, 0.9),
}
DEFAULT_ELEVATION: dict[str, float] = {"television": 0.8}  # bottom of the box above the floor
FALLBACK_SIZE = (0.5, 0.5, 0.8)


@dataclass
class WorldGenParams:
    """Tunables of the generator (all lengths in metres, times in simulated seconds)."""

    # what a placement leaves free: clearance, a way for the robot, a view of each object
    placement: PlacementRules = field(default_factory=PlacementRules)
    start_keepout: float = 1.0  # free radius kept around the start pose
    remove_fraction: float = 0.15  # share of objects removed before session 2 (at least one)
    move_fraction: float = 0.15  # share of objects moved before session 2 (at least one)
    added: int = 2  # new objects before session 2 (and half as many before session 3)
    obstacle_size: tuple[float, float] = (1.0, 0.6)
    obstacle_height: float = 1.0
    during_window: tuple[float, float] = (20.0, 120.0)  # when intra-session changes fire
    # [m^2/s] floor a monitor pass covers per simulated second, roughly: the churn recipe times
    # its change during a pass at 10-50 % of the pass this gives for the map's reachable floor
    pass_rate: float = 1.0
    wall_height: float = 2.5
    sizes: dict[str, tuple[float, float, float]] = field(default_factory=lambda: dict(DEFAULT_SIZES))


def largest_clearance_pose(grid: OccupancyGrid) -> Pose2D:
    """The reachable free cell farthest from any wall: a safe dock / start pose."""
    clear = clearance_map(reachable_free(grid), grid.resolution)
    if not clear.any():
        raise BomcError("the map has no free space")
    r, c = np.unravel_index(int(np.argmax(clear)), clear.shape)
    x, y = grid.cell_to_world(r, c)
    return Pose2D(float(x), float(y), 0.0)


def _slug(category: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", category.lower()).strip("-") or "object"


@dataclass
class _Builder:
    """Keeps the evolving object set so every generated change refers to what exists then."""

    placer: Placer
    params: WorldGenParams
    rng: np.random.Generator
    categories: list[str]
    grid_file: Path
    present: dict[str, dict[str, Any]] = field(default_factory=dict)  # copies, as they stand now
    removed: dict[str, dict[str, Any]] = field(default_factory=dict)  # taken away (churn recipe)
    counters: dict[str, int] = field(default_factory=dict)
    made: int = 0
    seed: int = 0  # the world's seed: with an object's name, its model's colour (bomc_bt.world.looks)

    def new_object(self) -> dict[str, Any]:
        category = self.categories[self.made % len(self.categories)]
        self.made += 1
        size = tuple(float(v) for v in self.params.sizes.get(category, FALLBACK_SIZE))
        xy = self.placer.place(0.5 * math.hypot(size[0], size[1]))
        if xy is None:
            raise BomcError(f"no free space left for a {category!r} (map too small or too cluttered "
                            "for this many objects)", self.grid_file)
        slug = _slug(category)
        self.counters[slug] = self.counters.get(slug, 0) + 1
        z = DEFAULT_ELEVATION.get(category, 0.0) + size[2] / 2.0
        obj = {"name": f"{slug}-{self.counters[slug]}", "category": category,
               "position": [xy[0], xy[1], round(z, 3)], "size": list(size),
               "yaw": round(float(self.rng.uniform(-math.pi, math.pi)), 3)}
        colour = model_colour(self.seed, obj["name"], category)
        if colour is not None:
            obj["colour"] = list(colour)
        self.present[obj["name"]] = copy.deepcopy(obj)
        return obj

    def pick(self, count: int) -> list[str]:
        names = sorted(self.present)
        count = min(count, len(names))
        return [names[i] for i in sorted(self.rng.choice(len(names), size=count, replace=False))]

    def remove(self, count: int) -> list[str]:
        gone = self.pick(count)
        for name in gone:
            del self.present[name]
        return gone

    def move(self, count: int) -> dict[str, list[float]]:
        out = {}
        for name in self.pick(count):
            size = self.present[name]["size"]
            xy = self.placer.place(0.5 * math.hypot(size[0], size[1]))
            if xy is not None:  # a crowded map may leave nowhere to go: then it stays put
                out[name] = [xy[0], xy[1]]
        return out

    def obstacle(self) -> dict[str, Any] | None:
        sx, sy = self.params.obstacle_size
        xy = self.placer.place(0.5 * math.hypot(sx, sy))
        if xy is None:
            return None
        return {"position": list(xy), "size": [sx, sy], "height": self.params.obstacle_height,
                "yaw": round(float(self.rng.uniform(-math.pi, math.pi)), 3)}

    def at(self) -> float:
        lo, hi = self.params.during_window
        return round(float(self.rng.uniform(lo, hi)), 1)

    # -- the churn recipe: objects leave, move and come back, their space freed and taken again --
    def _radius(self, obj: dict[str, Any]) -> float:
        return 0.5 * math.hypot(obj["size"][0], obj["size"][1])

    def _discs(self, skip: str = "") -> list[tuple[float, float, float]]:
        return [(o["position"][0], o["position"][1], self._radius(o)) for n, o in self.present.items() if n != skip]

    def take_away(self, name: str) -> None:
        obj = self.present.pop(name)
        self.removed[name] = obj
        self.placer.release(obj["position"][0], obj["position"][1], self._radius(obj), self._discs())

    def relocate(self, name: str) -> list[float] | None:
        """Move a present object to a free place elsewhere; None (it stays) when there is none."""
        obj = self.present[name]
        x, y, r = obj["position"][0], obj["position"][1], self._radius(obj)
        self.placer.release(x, y, r, self._discs(skip=name))
        xy = self.placer.place(r)
        if xy is None:
            self.placer.reserve(x, y, r)
            return None
        obj["position"] = [xy[0], xy[1], obj["position"][2]]
        return [xy[0], xy[1]]

    def bring_back(self, name: str) -> dict[str, Any] | None:
        """An object removed earlier, at its old place when that is free, else elsewhere."""
        obj = self.removed[name]
        x, y, r = obj["position"][0], obj["position"][1], self._radius(obj)
        if self.placer.fits(x, y, r):
            self.placer.reserve(x, y, r)
        else:
            xy = self.placer.place(r)
            if xy is None:
                return None
            obj["position"] = [xy[0], xy[1], obj["position"][2]]
        self.present[name] = self.removed.pop(name)
        return copy.deepcopy(obj)


def generate_world(grid_yaml_path: str | Path, seed: int, n_objects: int,
                   categories: Sequence[str] | Mapping[str, Sequence[float]], out_path: str | Path,
                   params: WorldGenParams | None = None, name: str | None = None, sessions: int = 3,
                   churn: float | None = None) -> World:
    """Write a random world of ``sessions`` sessions over ``grid_yaml_path`` to ``out_path`` and load it.

    ``categories`` are used round-robin (balanced classes); a mapping gives each its box
    size ``[x, y, z]``, otherwise :data:`DEFAULT_SIZES` (or a generic box) is used.
    ``churn``: None for the fixed recipe, else the share of the objects changed before each
    session (0: nothing ever changes); see the module's docstring.
    """
    params = dataclasses.replace(params) if params else WorldGenParams()
    grid_file, out_path = Path(grid_yaml_path), Path(out_path)
    if n_objects < 1 or not categories:
        raise BomcError("need at least one object and one category", out_path)
    if sessions < 1 or (churn is not None and not 0.0 <= churn <= 0.5):
        raise BomcError("need at least one session and a churn of 0 to 0.5", out_path)
    if isinstance(categories, Mapping):
        params.sizes = {**params.sizes, **{k: tuple(float(v) for v in s) for k, s in categories.items()}}
    grid = load_map(grid_file)
    rng = np.random.default_rng(seed)
    start = largest_clearance_pose(grid)
    placer = Placer(grid, rng, params.placement, (start.x, start.y), params.start_keepout)
    b = _Builder(placer, params, rng, list(categories), grid_file, seed=seed)

    objects = [b.new_object() for _ in range(n_objects)]
    timeline = _fixed_recipe(b, n_objects, sessions) if churn is None else _churn_recipe(b, sessions, churn)
    doc = {
        "version": FORMAT_VERSION,
        "name": name or f"{grid_file.stem}-gen{seed}",
        "map": os.path.relpath(grid_file.resolve(), out_path.resolve().parent),
        "start": [round(start.x, 3), round(start.y, 3), 0.0],
        "wall_height": params.wall_height,
        "objects": objects,
        "sessions": {k: _drop_empty(c) for k, c in timeline[0].items()},
        "during": [_drop_empty(d) for d in timeline[1] if any(d.get(k) for k in ("remove", "move", "add"))],
    }
    out_path.parent.mkdir(parents=True, exist_ok=True)
    header = (f"# generated by bomc_bt.worldgen.generate_world(seed={seed}, n_objects={n_objects}, "
              f"sessions={sessions}, churn={churn})\n")
    out_path.write_text(header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=110))
    return load_world(out_path)


Timeline = tuple[dict[int, dict[str, Any]], list[dict[str, Any]]]


def _fixed_recipe(b: _Builder, n_objects: int, sessions: int) -> Timeline:
    """Session 2: removals, moves, additions; session 3 (and later): removals, additions, an obstacle."""
    p = b.params
    changes: dict[int, dict[str, Any]] = {}
    during: list[dict[str, Any]] = []
    for k in range(2, sessions + 1):
        if k == 2:
            change: dict[str, Any] = {"remove": b.remove(max(1, round(n_objects * p.remove_fraction)))}
            change["move"] = b.move(max(1, round(n_objects * p.move_fraction)))
            change["add"] = [b.new_object() for _ in range(p.added)]
            during.append({"session": 2, "at": b.at(), "move": b.move(1)})
        else:
            change = {"remove": b.remove(max(1, round(n_objects * p.remove_fraction / 2)))}
            change["add"] = [b.new_object() for _ in range(max(1, p.added // 2))]
            obstacle = b.obstacle()
            change["obstacles"] = [obstacle] if obstacle else []
            during.append({"session": k, "at": b.at(), "remove": b.remove(1), "add": [b.new_object()]})
        changes[k] = change
    return changes, during


def _churn_recipe(b: _Builder, sessions: int, churn: float) -> Timeline:
    """Before each session a ``churn`` share changes (a third removed, a third moved, the rest
    added, half of those coming back); an obstacle every third session; one change per pass."""
    changes: dict[int, dict[str, Any]] = {}
    during: list[dict[str, Any]] = []
    for k in range(2, sessions + 1):
        if churn == 0:
            changes[k] = {}
            continue
        n = int(round(churn * len(b.present)))
        n_remove, n_move = max(1, round(0.3 * n)), max(1, round(0.3 * n))
        n_add = max(1, n - n_remove - n_move)
        removed = b.pick(n_remove)
        for name in removed:
            b.take_away(name)
        moved = {name: xy for name in b.pick(n_move) if (xy := b.relocate(name)) is not None}
        pool = sorted(set(b.removed) - set(removed))
        n_back = min(len(pool), max(1, n_add // 2))
        back = [pool[int(i)] for i in sorted(b.rng.choice(len(pool), size=n_back, replace=False))] if n_back else []
        added = [got for name in back if (got := b.bring_back(name)) is not None]
        added += [b.new_object() for _ in range(n_add - len(back))]
        change: dict[str, Any] = {"remove": removed, "move": moved, "add": added}
        if k % 3 == 0:
            obstacle = b.obstacle()
            change["obstacles"] = [obstacle] if obstacle else []
        changes[k] = change
        during.append(_during_change(b, k))
    return changes, during


def _during_change(b: _Builder, k: int) -> dict[str, Any]:
    """One object removed, moved or added while pass ``k`` runs."""
    floor = float(b.placer.reachable.sum()) * b.placer.grid.resolution ** 2
    at = round(float(b.rng.uniform(0.1, 0.5)) * max(60.0, floor / b.params.pass_rate), 1)
    entry: dict[str, Any] = {"session": k, "at": at}
    kind = ("remove", "move", "add")[int(b.rng.integers(3))]
    if kind == "add" or not b.present:
        entry["add"] = [b.new_object()]
    elif kind == "remove":
        entry["remove"] = b.pick(1)
        b.take_away(entry["remove"][0])
    else:
        name = b.pick(1)[0]
        xy = b.relocate(name)
        entry["move"] = {name: xy} if xy is not None else {}
    return entry


def _drop_empty(change: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in change.items() if v not in ([], {}, None)}
