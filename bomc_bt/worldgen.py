"""Random worlds over any occupancy map, so the project is tested on maps nobody tuned for.

:func:`generate_world` scatters labelled boxes over the free space of a map_server map
(only over the largest connected free region, so every object is reachable from the
start), keeps each one clear of walls, of the others and of the start pose, and writes a
version-1 world file with a session 2 (removals, moves, additions), a session 3 (removals,
additions, an unlabelled obstacle) and intra-session changes in sessions 2 and 3. The same
seed always gives the same file. The result is loaded back through
:func:`bomc_bt.world.load_world`, so a generator bug surfaces as a validation error.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid, load_map
from bomc_bt.world import FORMAT_VERSION, World, load_world, wall_mask

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

    clearance: float = 0.15  # free margin kept around each object's bounding circle
    start_keepout: float = 1.0  # free radius kept around the start pose
    remove_fraction: float = 0.15  # share of objects removed before session 2 (at least one)
    move_fraction: float = 0.15  # share of objects moved before session 2 (at least one)
    added: int = 2  # new objects before session 2 (and half as many before session 3)
    obstacle_size: tuple[float, float] = (1.0, 0.6)
    obstacle_height: float = 1.0
    during_window: tuple[float, float] = (20.0, 120.0)  # when intra-session changes fire
    wall_height: float = 2.5
    sizes: dict[str, tuple[float, float, float]] = field(default_factory=lambda: dict(DEFAULT_SIZES))


def reachable_free(grid: OccupancyGrid) -> np.ndarray:
    """The largest 4-connected region of free cells (bool mask like ``grid.data``)."""
    free = (~wall_mask(grid)).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(free, connectivity=4)
    if count <= 1:
        return np.zeros_like(free, dtype=bool)
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return labels == biggest


def clearance_map(mask: np.ndarray, resolution: float) -> np.ndarray:
    """Metres from each cell of ``mask`` to the nearest cell outside it (the image edge counts)."""
    padded = np.pad(mask.astype(np.uint8), 1)
    dist = cv2.distanceTransform(padded, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
    return dist.astype(np.float64) * resolution


def largest_clearance_pose(grid: OccupancyGrid) -> Pose2D:
    """The reachable free cell farthest from any wall: a safe dock / start pose."""
    clear = clearance_map(reachable_free(grid), grid.resolution)
    if not clear.any():
        raise BomcError("the map has no free space")
    r, c = np.unravel_index(int(np.argmax(clear)), clear.shape)
    x, y = grid.cell_to_world(r, c)
    return Pose2D(float(x), float(y), 0.0)


class _Placer:
    """Draws non-overlapping discs over the reachable free space, deterministically for a seed.

    Placed discs are painted into the free mask and the clearance map is recomputed (one
    distance transform, milliseconds), so a candidate centre is valid exactly when its
    clearance covers its own radius plus the margin -- no rejection sampling that could
    miss the last free corner of a cluttered map.
    """

    def __init__(self, grid: OccupancyGrid, rng: np.random.Generator, params: WorldGenParams):
        self.grid, self.rng, self.params = grid, rng, params
        self.free = reachable_free(grid).astype(np.uint8)  # 1 = free and not yet taken
        self._clear: np.ndarray | None = None

    def reserve(self, x: float, y: float, radius: float) -> None:
        r, c = self.grid.world_to_cell(x, y)
        cv2.circle(self.free, (int(c), int(r)), int(math.ceil(radius / self.grid.resolution)), 0, -1)
        self._clear = None

    def place(self, radius: float) -> tuple[float, float] | None:
        """A free centre for a disc of ``radius`` (plus the clearance margin), or None."""
        if self._clear is None:
            self._clear = clearance_map(self.free > 0, self.grid.resolution)
        cells = np.flatnonzero(self._clear >= radius + self.params.clearance)
        if cells.size == 0:
            return None
        r, c = np.unravel_index(int(cells[self.rng.integers(cells.size)]), self._clear.shape)
        x, y = self.grid.cell_to_world(r, c)
        x, y = round(float(x), 3), round(float(y), 3)
        self.reserve(x, y, radius)
        return x, y


def _slug(category: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", category.lower()).strip("-") or "object"


@dataclass
class _Builder:
    """Keeps the evolving object set so every generated change refers to what exists then."""

    placer: _Placer
    params: WorldGenParams
    rng: np.random.Generator
    categories: list[str]
    grid_file: Path
    present: dict[str, dict[str, Any]] = field(default_factory=dict)
    counters: dict[str, int] = field(default_factory=dict)
    made: int = 0

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
        self.present[obj["name"]] = obj
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


def generate_world(grid_yaml_path: str | Path, seed: int, n_objects: int,
                   categories: Sequence[str] | Mapping[str, Sequence[float]], out_path: str | Path,
                   params: WorldGenParams | None = None, name: str | None = None) -> World:
    """Write a random three-session world over ``grid_yaml_path`` to ``out_path`` and load it.

    ``categories`` are used round-robin (balanced classes); a mapping gives each its box
    size ``[x, y, z]``, otherwise :data:`DEFAULT_SIZES` (or a generic box) is used.
    """
    params = dataclasses.replace(params) if params else WorldGenParams()
    grid_file, out_path = Path(grid_yaml_path), Path(out_path)
    if n_objects < 1 or not categories:
        raise BomcError("need at least one object and one category", out_path)
    if isinstance(categories, Mapping):
        params.sizes = {**params.sizes, **{k: tuple(float(v) for v in s) for k, s in categories.items()}}
    grid = load_map(grid_file)
    rng = np.random.default_rng(seed)
    start = largest_clearance_pose(grid)
    placer = _Placer(grid, rng, params)
    placer.reserve(start.x, start.y, params.start_keepout)
    b = _Builder(placer, params, rng, list(categories), grid_file)

    objects = [b.new_object() for _ in range(n_objects)]
    session2: dict[str, Any] = {"remove": b.remove(max(1, round(n_objects * params.remove_fraction)))}
    session2["move"] = b.move(max(1, round(n_objects * params.move_fraction)))
    session2["add"] = [b.new_object() for _ in range(params.added)]
    during = [{"session": 2, "at": b.at(), "move": b.move(1)}]
    session3: dict[str, Any] = {"remove": b.remove(max(1, round(n_objects * params.remove_fraction / 2)))}
    session3["add"] = [b.new_object() for _ in range(max(1, params.added // 2))]
    obstacle = b.obstacle()
    session3["obstacles"] = [obstacle] if obstacle else []
    during.append({"session": 3, "at": b.at(), "remove": b.remove(1), "add": [b.new_object()]})

    doc = {
        "version": FORMAT_VERSION,
        "name": name or f"{grid_file.stem}-gen{seed}",
        "map": os.path.relpath(grid_file.resolve(), out_path.resolve().parent),
        "start": [round(start.x, 3), round(start.y, 3), 0.0],
        "wall_height": params.wall_height,
        "objects": objects,
        "sessions": {2: _drop_empty(session2), 3: _drop_empty(session3)},
        "during": [_drop_empty(d) for d in during if any(d.get(k) for k in ("remove", "move", "add"))],
    }
    out_path.parent.mkdir(parents=True, exist_ok=True)
    header = f"# generated by bomc_bt.worldgen.generate_world(seed={seed}, n_objects={n_objects})\n"
    out_path.write_text(header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=110))
    return load_world(out_path)


def _drop_empty(change: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in change.items() if v not in ([], {}, None)}
