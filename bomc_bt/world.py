"""Simulation worlds: the ground truth a simulated mission runs in and is scored against.

A world file (format version 1, ``CONTRACTS.md`` section 1) names a real occupancy map,
a start pose, the labelled objects of session 1, the changes applied before each later
session and the changes that happen *during* a session. This module loads and validates
it completely up front -- every malformed entry is a one-line :class:`BomcError` naming
the file and the entry -- so the simulator and the evaluator can trust what they get.

Timeline semantics (one rule, used by the loader's checks and by every query):

* Session 1 starts with ``objects``.
* During session *k*, the ``during`` entries of session *k* fire in order of ``at``
  (ties keep file order); their effects persist into later sessions.
* Before session *k* >= 2 starts, ``sessions[k]`` is applied (after the during changes of
  session *k* - 1). Sessions are cumulative.
* Within one change, ``remove`` is applied first, then ``move``, then ``add``; so a change
  may remove a name and add a new object under it, but cannot move what it removed.
* Unlabelled ``obstacles`` of ``sessions[k]`` are present for session *k* only; those of a
  during change appear at its ``at`` and last until the end of that session.

"Inside a wall" is defined robustly for real SLAM maps: an object (or obstacle) is
rejected only when its centre cell is a wall *and* not a single free cell lies within its
footprint grown by one cell. A door standing in a doorway, a cabinet pushed against a
wall or a chair whose centre hits a stray occupied pixel all load; a box typed into the
middle of a wall, an unknown pocket or outside the image does not.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid, load_map
from bomc_bt.yaml_io import read_yaml

FORMAT_VERSION = 1
DEFAULT_WALL_HEIGHT = 2.5

_TOP_KEYS = {"version", "name", "map", "start", "wall_height", "objects", "sessions", "during"}
_OBJECT_KEYS = {"name", "category", "position", "size", "yaw"}
_OBSTACLE_KEYS = {"position", "size", "height", "yaw"}
_CHANGE_KEYS = {"remove", "move", "add", "obstacles"}
_DURING_KEYS = {"session", "at"} | _CHANGE_KEYS
_PLAIN_KEY = re.compile(r"[\w\-. ]+")


# -- records ---------------------------------------------------------------------------------
def _box_corners(x: float, y: float, sx: float, sy: float, yaw: float) -> np.ndarray:
    """Map-frame corners (counter-clockwise) of a ``sx`` x ``sy`` box rotated by ``yaw``."""
    local = np.array([[-sx, -sy], [sx, -sy], [sx, sy], [-sx, sy]], dtype=float) / 2.0
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + np.array([x, y])


@dataclass(frozen=True)
class WorldObject:
    """A labelled ground-truth object: a box standing in the map frame."""

    name: str
    category: str
    position: tuple[float, float, float]  # centre, map frame, m
    size: tuple[float, float, float]  # box extents x, y, z in its own frame, m
    yaw: float = 0.0

    def footprint(self) -> np.ndarray:
        """(4, 2) map-frame corners of the rotated box, counter-clockwise."""
        return _box_corners(self.position[0], self.position[1], self.size[0], self.size[1], self.yaw)

    def moved_to(self, position) -> WorldObject:
        """A copy at ``position``: ``[x, y]`` keeps the height, ``[x, y, z]`` replaces it."""
        p = tuple(float(v) for v in position)
        if len(p) == 2:
            p = (p[0], p[1], self.position[2])
        if len(p) != 3:
            raise ValueError(f"position needs 2 or 3 values, got {len(p)}")
        return replace(self, position=p)

    def to_dict(self) -> dict[str, Any]:
        """The world-file form of this object (for writers such as :mod:`bomc_bt.worldgen`)."""
        return {"name": self.name, "category": self.category, "position": list(self.position),
                "size": list(self.size), "yaw": self.yaw}


@dataclass(frozen=True)
class Obstacle:
    """An unlabelled blocker: the robot must drive around it, the detector should ignore it."""

    position: tuple[float, float]
    size: tuple[float, float]
    height: float = 1.0
    yaw: float = 0.0

    def footprint(self) -> np.ndarray:
        """(4, 2) map-frame corners of the rotated box, counter-clockwise."""
        return _box_corners(self.position[0], self.position[1], self.size[0], self.size[1], self.yaw)

    def to_dict(self) -> dict[str, Any]:
        return {"position": list(self.position), "size": list(self.size), "height": self.height,
                "yaw": self.yaw}


@dataclass
class Change:
    """One batch of changes (applied remove -> move -> add)."""

    remove: list[str] = field(default_factory=list)
    move: dict[str, tuple[float, ...]] = field(default_factory=dict)
    add: list[WorldObject] = field(default_factory=list)
    obstacles: list[Obstacle] = field(default_factory=list)


@dataclass
class DuringChange:
    """A change applied when session ``session``'s sim time reaches ``at`` seconds."""

    session: int
    at: float
    change: Change
    index: int = 0  # position in the file's ``during`` list (names the entry in errors)


@dataclass
class World:
    """A loaded, validated world. Queries replay the timeline (cheap: a few dict copies)."""

    name: str
    path: Path
    map_path: Path
    grid: OccupancyGrid  # the true map as loaded
    start: Pose2D
    wall_height: float
    objects: dict[str, WorldObject]  # session 1 ground truth
    sessions: dict[int, Change]  # applied before session N (N >= 2), cumulative
    during: list[DuringChange]  # sorted by (session, at), ties in file order

    @property
    def last_session(self) -> int:
        """The highest session the file mentions (1 if it has no changes)."""
        return max([1, *self.sessions, *(d.session for d in self.during)])

    def walls(self) -> np.ndarray:
        """Bool mask like ``grid.data``: occupied or unknown (outside the image is wall too)."""
        return wall_mask(self.grid)

    def is_wall(self, x: float, y: float) -> bool:
        """Whether a map-frame point is in a wall cell (outside the image counts as wall)."""
        r, c = self.grid.world_to_cell(x, y)
        return not bool(self.grid.in_bounds(r, c)) or bool(self.walls()[r, c])

    def during_changes(self, n: int) -> list[DuringChange]:
        """Session ``n``'s intra-session changes, sorted by ``at``."""
        return [d for d in self.during if d.session == n]

    def objects_in_session(self, n: int) -> dict[str, WorldObject]:
        """Objects present when session ``n`` starts (earlier during changes persist)."""
        self._check_session(n)
        state = dict(self.objects)
        for k in range(2, n + 1):
            for d in self.during_changes(k - 1):
                state = apply_change(state, d.change, self.path, f"during[{d.index}]")
            if k in self.sessions:
                state = apply_change(state, self.sessions[k], self.path, f"sessions[{k}]")
        return state

    def ground_truth(self, n: int, at: float | None = None) -> dict[str, WorldObject]:
        """Objects present at sim time ``at`` of session ``n`` (None: at its end)."""
        state = self.objects_in_session(n)
        for d in self.during_changes(n):
            if at is None or d.at <= at:
                state = apply_change(state, d.change, self.path, f"during[{d.index}]")
        return state

    def obstacles_in_session(self, n: int) -> list[Obstacle]:
        """Unlabelled obstacles present from the start of session ``n`` (for that session only)."""
        self._check_session(n)
        change = self.sessions.get(n)
        return list(change.obstacles) if change else []

    def obstacles_at(self, n: int, at: float | None = None) -> list[Obstacle]:
        """All obstacles present at sim time ``at`` of session ``n`` (None: at its end)."""
        out = self.obstacles_in_session(n)
        for d in self.during_changes(n):
            if at is None or d.at <= at:
                out.extend(d.change.obstacles)
        return out

    def _check_session(self, n: int) -> None:
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise BomcError(f"session must be an integer >= 1, got {n!r}", self.path, "session")


def wall_mask(grid: OccupancyGrid) -> np.ndarray:
    """Occupied-or-unknown cells: what a simulator built on this map treats as solid.

    The image's outermost cells count as wall too: everything outside the image is wall,
    and real SLAM maps often run free space out to the edge, where a robot would see
    nothing (its lidar starts inside the wall) and a planner would route along a strip
    that does not exist.
    """
    cached = grid._cache.get("world_walls")
    if cached is None or cached.shape != grid.data.shape:
        cached = grid.occupied_mask() | grid.unknown_mask()
        cached[[0, -1], :] = True
        cached[:, [0, -1]] = True
        grid._cache["world_walls"] = cached
    return cached


def embedded_in_wall(grid: OccupancyGrid, walls: np.ndarray, position, size, yaw: float) -> bool:
    """True when the centre cell is wall and no free cell lies in the footprint grown by a cell.

    Real SLAM maps have thin, noisy walls: a door in a doorway or a cabinet against a wall
    may have its centre on a wall pixel, so only a box with no free space at all under it
    (one cell of slack for rasterisation) counts as inside a wall.
    """
    x, y = float(position[0]), float(position[1])
    r, c = grid.world_to_cell(x, y)
    if bool(grid.in_bounds(r, c)) and not walls[r, c]:
        return False
    res = grid.resolution
    hx, hy = size[0] / 2.0 + res, size[1] / 2.0 + res
    reach = math.hypot(hx, hy)
    r0, c0 = grid.world_to_cell(x - reach, y - reach)
    r1, c1 = grid.world_to_cell(x + reach, y + reach)
    r0, c0 = max(int(r0), 0), max(int(c0), 0)
    r1, c1 = min(int(r1), grid.height - 1), min(int(c1), grid.width - 1)
    if r0 > r1 or c0 > c1:
        return True  # entirely outside the image
    rows, cols = np.mgrid[r0:r1 + 1, c0:c1 + 1]
    cx, cy = grid.cell_to_world(rows, cols)
    cos, sin = math.cos(yaw), math.sin(yaw)
    lx = (cx - x) * cos + (cy - y) * sin
    ly = -(cx - x) * sin + (cy - y) * cos
    inside = (np.abs(lx) <= hx) & (np.abs(ly) <= hy)
    return not bool(np.any(inside & ~walls[r0:r1 + 1, c0:c1 + 1]))


# -- applying changes ------------------------------------------------------------------------
def apply_change(objects: dict[str, WorldObject], change: Change, file: str | Path | None = None,
                 where: str = "change") -> dict[str, WorldObject]:
    """A new dict with ``change`` applied (remove, then move, then add); ``objects`` is untouched.

    Raises :class:`BomcError` naming ``file`` and the entry for a name that is not present
    (remove, move) or already present (add).
    """
    state = dict(objects)
    for i, name in enumerate(change.remove):
        if name not in state:
            raise BomcError(f"cannot remove {name!r}: no such object at this point", file,
                            f"{where}.remove[{i}]")
        del state[name]
    for name, position in change.move.items():
        if name not in state:
            raise BomcError(f"cannot move {name!r}: no such object at this point", file,
                            f"{where}.move.{_key(name)}")
        try:
            state[name] = state[name].moved_to(position)
        except (ValueError, TypeError):
            raise BomcError("expected [x, y] or [x, y, z] numbers", file,
                            f"{where}.move.{_key(name)}") from None
    for i, obj in enumerate(change.add):
        if obj.name in state:
            raise BomcError(f"cannot add {obj.name!r}: an object of that name already exists", file,
                            f"{where}.add[{i}].name")
        state[obj.name] = obj
    return state


# -- loading ---------------------------------------------------------------------------------
def load_world(path: str | Path) -> World:
    """Load and fully validate a world file (format version 1)."""
    path = Path(path)
    data = read_yaml(path, "world file")
    return _Parser(path).world(data)


def _key(key: Any) -> str:
    """A mapping key as it may appear in a one-line field path (odd text is quoted)."""
    text = str(key)
    return text if _PLAIN_KEY.fullmatch(text) else repr(text)


def _join(where: str, key: Any) -> str:
    return f"{where}.{_key(key)}" if where else _key(key)


def _describe(value: Any) -> str:
    return "null" if value is None else f"{type(value).__name__} {value!r}"[:50]


@dataclass
class _Parser:
    """Turns the parsed YAML into records, raising BomcError(file, field) on the first problem."""

    file: Path

    def fail(self, message: str, where: str) -> BomcError:
        return BomcError(message, self.file, where or None)

    # -- primitives --------------------------------------------------------------------------
    def mapping(self, value: Any, where: str, allowed: set[str], required: tuple[str, ...] = ()) -> dict:
        if not isinstance(value, dict):
            raise self.fail(f"expected a mapping, got {_describe(value)}", where)
        for key in value:
            if not isinstance(key, str):
                raise self.fail(f"keys must be text, got {_describe(key)}", where)
            if key not in allowed and not key.startswith("x-"):
                expected = ", ".join(sorted(allowed))
                raise self.fail(f"unknown key (expected one of: {expected}; 'x-' keys are extensions)",
                                _join(where, key))
        for key in required:
            if key not in value:
                raise self.fail("missing", _join(where, key))
        return value

    def number(self, value: Any, where: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(f"expected a number, got {_describe(value)}", where)
        if not math.isfinite(value):
            raise self.fail("must be a finite number", where)
        return float(value)

    def text(self, value: Any, where: str) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.fail(f"expected non-empty text, got {_describe(value)}", where)
        return value

    def vector(self, value: Any, where: str, shape: str, lengths: tuple[int, ...]) -> tuple[float, ...]:
        ok = isinstance(value, list) and len(value) in lengths and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        if not ok:
            raise self.fail(f"expected {shape} numbers", where)
        if not all(math.isfinite(v) for v in value):
            raise self.fail(f"expected {shape} finite numbers (no NaN or inf)", where)
        return tuple(float(v) for v in value)

    def size(self, value: Any, where: str, shape: str, n: int) -> tuple[float, ...]:
        size = self.vector(value, where, shape, (n,))
        if min(size) <= 0.0:
            raise self.fail("sizes must be positive", where)
        return size

    def items(self, value: Any, where: str) -> list:
        if not isinstance(value, list):
            raise self.fail(f"expected a list, got {_describe(value)}", where)
        return value

    # -- records -----------------------------------------------------------------------------
    def world_object(self, value: Any, where: str) -> WorldObject:
        m = self.mapping(value, where, _OBJECT_KEYS, ("name", "category", "position", "size"))
        yaw = self.number(m.get("yaw", 0.0), _join(where, "yaw"))
        return WorldObject(
            name=self.text(m["name"], _join(where, "name")),
            category=self.text(m["category"], _join(where, "category")),
            position=self.vector(m["position"], _join(where, "position"), "[x, y, z]", (3,)),  # type: ignore[arg-type]
            size=self.size(m["size"], _join(where, "size"), "[x, y, z]", 3),  # type: ignore[arg-type]
            yaw=yaw,
        )

    def obstacle(self, value: Any, where: str) -> Obstacle:
        m = self.mapping(value, where, _OBSTACLE_KEYS, ("position", "size"))
        height = self.number(m.get("height", 1.0), _join(where, "height"))
        if height <= 0.0:
            raise self.fail("must be positive", _join(where, "height"))
        return Obstacle(
            position=self.vector(m["position"], _join(where, "position"), "[x, y]", (2,)),  # type: ignore[arg-type]
            size=self.size(m["size"], _join(where, "size"), "[x, y]", 2),  # type: ignore[arg-type]
            height=height,
            yaw=self.number(m.get("yaw", 0.0), _join(where, "yaw")),
        )

    def change(self, m: dict, where: str) -> Change:
        remove = self.items(m.get("remove", []), _join(where, "remove"))
        names = [self.text(n, f"{where}.remove[{i}]") for i, n in enumerate(remove)]
        move_raw = m.get("move", {})
        if not isinstance(move_raw, dict):
            raise self.fail(f"expected a mapping of name: [x, y(, z)], got {_describe(move_raw)}",
                            _join(where, "move"))
        move = {}
        for name, pos in move_raw.items():
            key = self.text(name, _join(where, "move"))
            move[key] = self.vector(pos, f"{where}.move.{_key(key)}", "[x, y] or [x, y, z]", (2, 3))
        add = [self.world_object(o, f"{where}.add[{i}]")
               for i, o in enumerate(self.items(m.get("add", []), _join(where, "add")))]
        obstacles = [self.obstacle(o, f"{where}.obstacles[{i}]")
                     for i, o in enumerate(self.items(m.get("obstacles", []), _join(where, "obstacles")))]
        return Change(remove=names, move=move, add=add, obstacles=obstacles)

    def sessions(self, value: Any) -> dict[int, Change]:
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.fail(f"expected a mapping of session number: changes, got {_describe(value)}",
                            "sessions")
        out: dict[int, Change] = {}
        for key, body in value.items():
            if isinstance(key, bool) or not isinstance(key, int) or key < 2:
                raise self.fail(f"session numbers are integers >= 2, got {_describe(key)}", "sessions")
            where = f"sessions[{key}]"
            out[key] = self.change(self.mapping({} if body is None else body, where, _CHANGE_KEYS), where)
        return dict(sorted(out.items()))

    def during(self, value: Any) -> list[DuringChange]:
        out = []
        for i, entry in enumerate(self.items([] if value is None else value, "during")):
            where = f"during[{i}]"
            m = self.mapping(entry, where, _DURING_KEYS, ("session", "at"))
            session = m["session"]
            if isinstance(session, bool) or not isinstance(session, int) or session < 1:
                raise self.fail(f"expected a session number >= 1, got {_describe(session)}",
                                _join(where, "session"))
            at = self.number(m["at"], _join(where, "at"))
            if at < 0.0:
                raise self.fail("must be >= 0 (seconds of session sim time)", _join(where, "at"))
            out.append(DuringChange(session, at, self.change(m, where), index=i))
        return sorted(out, key=lambda d: (d.session, d.at, d.index))

    def world(self, data: Any) -> World:
        top = self.mapping(data, "", _TOP_KEYS, ("version", "map", "start"))
        version = top["version"]
        if isinstance(version, bool) or version != FORMAT_VERSION:
            raise self.fail(f"unsupported version {version!r} (this bomc-bt reads version {FORMAT_VERSION})",
                            "version")
        name = self.text(top.get("name", self.file.stem), "name")
        map_path = self.file.parent / self.text(top["map"], "map")
        wall_height = self.number(top.get("wall_height", DEFAULT_WALL_HEIGHT), "wall_height")
        if wall_height <= 0.0:
            raise self.fail("must be positive", "wall_height")
        start = self.vector(top["start"], "start", "[x, y, yaw]", (2, 3))
        objects: dict[str, WorldObject] = {}
        for i, raw in enumerate(self.items([] if top.get("objects") is None else top["objects"], "objects")):
            obj = self.world_object(raw, f"objects[{i}]")
            if obj.name in objects:
                raise self.fail(f"duplicate object name {obj.name!r}", f"objects[{i}].name")
            objects[obj.name] = obj
        sessions = self.sessions(top.get("sessions"))
        during = self.during(top.get("during"))
        for where, change in [*((f"sessions[{k}]", c) for k, c in sessions.items()),
                              *((f"during[{d.index}]", d.change) for d in during)]:
            seen: set[str] = set()
            for i, obj in enumerate(change.add):
                if obj.name in seen:
                    raise self.fail(f"duplicate object name {obj.name!r}", f"{where}.add[{i}].name")
                seen.add(obj.name)
        try:
            grid = load_map(map_path)
        except BomcError as exc:
            raise self.fail(str(exc).replace("\n", "\\n"), "map") from None
        except (OSError, ValueError) as exc:  # e.g. a NUL byte in the path
            raise self.fail(f"cannot read map ({type(exc).__name__})", "map") from None
        world = World(name, self.file, map_path, grid, Pose2D(*start), wall_height, objects, sessions, during)
        self.check_placement(world, start)
        return world

    # -- checks against the map and the timeline ---------------------------------------------
    def check_placement(self, world: World, start: tuple[float, ...]) -> None:
        grid, walls = world.grid, world.walls()
        r, c = grid.world_to_cell(start[0], start[1])
        if not bool(grid.in_bounds(r, c)) or walls[r, c]:
            raise self.fail(f"start ({start[0]:g}, {start[1]:g}) is not in free space of the map", "start")

        def check_obj(obj: WorldObject, where: str) -> None:
            if embedded_in_wall(grid, walls, obj.position, obj.size, obj.yaw):
                raise self.fail(f"{obj.name!r} at ({obj.position[0]:g}, {obj.position[1]:g}) "
                                "lies inside a wall (no free cell under it)", where)

        for i, obj in enumerate(world.objects.values()):
            check_obj(obj, f"objects[{i}].position")
        self.replay(world, check_obj)

    def replay(self, world: World, check_obj: Callable[[WorldObject, str], None]) -> None:
        """Run the whole timeline once, so every change is checked against the state it meets."""
        grid, walls = world.grid, world.walls()
        state = dict(world.objects)

        def step(change: Change, where: str) -> None:
            nonlocal state
            state = apply_change(state, change, self.file, where)
            for name in change.move:
                check_obj(state[name], f"{where}.move.{_key(name)}")
            for i, obj in enumerate(change.add):
                check_obj(obj, f"{where}.add[{i}].position")
            for i, ob in enumerate(change.obstacles):
                if embedded_in_wall(grid, walls, ob.position, ob.size, ob.yaw):
                    raise self.fail("obstacle lies inside a wall (no free cell under it)",
                                    f"{where}.obstacles[{i}].position")

        for k in range(1, world.last_session + 1):
            if k in world.sessions:
                step(world.sessions[k], f"sessions[{k}]")
            for d in world.during_changes(k):
                step(d.change, f"during[{d.index}]")
