"""Loading a world file (format version 1, ``CONTRACTS.md`` section 1) into a :class:`World`.

A world file names a real occupancy map, a start pose, the labelled objects of session
1, the changes applied before each later session and the changes that happen *during* a
session. It is validated completely up front -- every malformed entry is a one-line
:class:`BomcError` naming the file and the entry, and the whole timeline is replayed once
against the map -- so the simulator and the evaluator can trust what they get.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import load_map
from bomc_bt.world.fields import FieldReader, describe, join
from bomc_bt.world.records import Change, DuringChange, Obstacle, WorldObject
from bomc_bt.world.timeline import MAX_SESSION, World, apply_change, entry_key
from bomc_bt.world.walls import embedded_in_wall
from bomc_bt.yaml_io import read_yaml

FORMAT_VERSION = 1
DEFAULT_WALL_HEIGHT = 2.5

_TOP_KEYS = {"version", "name", "map", "start", "wall_height", "objects", "sessions", "during"}
_OBJECT_KEYS = {"name", "category", "position", "size", "yaw", "colour"}
_OBSTACLE_KEYS = {"position", "size", "height", "yaw"}
_CHANGE_KEYS = {"remove", "move", "add", "obstacles"}
_DURING_KEYS = {"session", "at"} | _CHANGE_KEYS


def load_world(path: str | Path) -> World:
    """Load and fully validate a world file (format version 1)."""
    path = Path(path)
    data = read_yaml(path, "world file")
    return _Parser(path).world(data)


class _Parser(FieldReader):
    """Turns the parsed YAML into records, raising BomcError(file, field) on the first problem."""

    # -- records -----------------------------------------------------------------------------
    def world_object(self, value: Any, where: str) -> WorldObject:
        m = self.mapping(value, where, _OBJECT_KEYS, ("name", "category", "position", "size"))
        yaw = self.number(m.get("yaw", 0.0), join(where, "yaw"))
        return WorldObject(
            name=self.text(m["name"], join(where, "name")),
            category=self.text(m["category"], join(where, "category")),
            position=self.vector(m["position"], join(where, "position"), "[x, y, z]", (3,)),  # type: ignore[arg-type]
            size=self.size(m["size"], join(where, "size"), "[x, y, z]", 3),  # type: ignore[arg-type]
            yaw=yaw,
            colour=self.colour(m["colour"], join(where, "colour")) if "colour" in m else None,
        )

    def colour(self, value: Any, where: str) -> tuple[int, int, int]:
        rgb = self.vector(value, where, "[r, g, b]", (3,))
        if not all(0.0 <= v <= 255.0 and v == int(v) for v in rgb):
            raise self.fail("expected whole numbers from 0 to 255", where)
        return int(rgb[0]), int(rgb[1]), int(rgb[2])

    def obstacle(self, value: Any, where: str) -> Obstacle:
        m = self.mapping(value, where, _OBSTACLE_KEYS, ("position", "size"))
        height = self.number(m.get("height", 1.0), join(where, "height"))
        if height <= 0.0:
            raise self.fail("must be positive", join(where, "height"))
        return Obstacle(
            position=self.vector(m["position"], join(where, "position"), "[x, y]", (2,)),  # type: ignore[arg-type]
            size=self.size(m["size"], join(where, "size"), "[x, y]", 2),  # type: ignore[arg-type]
            height=height,
            yaw=self.number(m.get("yaw", 0.0), join(where, "yaw")),
        )

    def change(self, m: dict, where: str) -> Change:
        remove = self.items(m.get("remove", []), join(where, "remove"))
        names = [self.text(n, f"{where}.remove[{i}]") for i, n in enumerate(remove)]
        move_raw = m.get("move", {})
        if not isinstance(move_raw, dict):
            raise self.fail(f"expected a mapping of name: [x, y(, z)], got {describe(move_raw)}",
                            join(where, "move"))
        move = {}
        for name, pos in move_raw.items():
            key = self.text(name, join(where, "move"))
            move[key] = self.vector(pos, f"{where}.move.{entry_key(key)}", "[x, y] or [x, y, z]", (2, 3))
        add = [self.world_object(o, f"{where}.add[{i}]")
               for i, o in enumerate(self.items(m.get("add", []), join(where, "add")))]
        obstacles = [self.obstacle(o, f"{where}.obstacles[{i}]")
                     for i, o in enumerate(self.items(m.get("obstacles", []), join(where, "obstacles")))]
        return Change(remove=names, move=move, add=add, obstacles=obstacles)

    def sessions(self, value: Any) -> dict[int, Change]:
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.fail(f"expected a mapping of session number: changes, got {describe(value)}",
                            "sessions")
        out: dict[int, Change] = {}
        for key, body in value.items():
            if isinstance(key, bool) or not isinstance(key, int) or not 2 <= key <= MAX_SESSION:
                raise self.fail(f"session numbers are integers >= 2, got {describe(key)} (at most {MAX_SESSION})",
                                "sessions")
            where = f"sessions[{key}]"
            out[key] = self.change(self.mapping({} if body is None else body, where, _CHANGE_KEYS), where)
        return dict(sorted(out.items()))

    def during(self, value: Any) -> list[DuringChange]:
        out = []
        for i, entry in enumerate(self.items([] if value is None else value, "during")):
            where = f"during[{i}]"
            m = self.mapping(entry, where, _DURING_KEYS, ("session", "at"))
            session = m["session"]
            if isinstance(session, bool) or not isinstance(session, int) or not 1 <= session <= MAX_SESSION:
                raise self.fail(f"expected a session number >= 1, got {describe(session)} (at most {MAX_SESSION})",
                                join(where, "session"))
            at = self.number(m["at"], join(where, "at"))
            if at < 0.0:
                raise self.fail("must be >= 0 (seconds of session sim time)", join(where, "at"))
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
                check_obj(state[name], f"{where}.move.{entry_key(name)}")
            for i, obj in enumerate(change.add):
                check_obj(obj, f"{where}.add[{i}].position")
            for i, ob in enumerate(change.obstacles):
                if embedded_in_wall(grid, walls, ob.position, ob.size, ob.yaw):
                    raise self.fail("obstacle lies inside a wall (no free cell under it)",
                                    f"{where}.obstacles[{i}].position")

        for k in world.mentioned_sessions():  # in order; never every number up to the last
            if k in world.sessions:
                step(world.sessions[k], f"sessions[{k}]")
            for d in world.during_changes(k):
                step(d.change, f"during[{d.index}]")
