"""What an office floor is made of: sizes, the object mix and the ranges every tunable must lie in.

The object mix is the paper's Environment A (93 x 90 m, about 8,400 m2 of floor: 18
corridors, 45 tables, 109 chairs, 170 doors, about 420 objects in all) expressed as
densities per 1,000 m2 of floor, so a floor of any size gets the same mix. Doors are not
a density: there is one per doorway of the generated plan, and the plan's room sizes are
what make their count come out near the paper's.

:meth:`OfficeParams.check` validates every field with its range (not only its type), so a
bad value from the command line or a test is one :class:`BomcError` naming the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from bomc_bt.errors import BomcError
from bomc_bt.worldgen import DEFAULT_SIZES

# Box extents (x along the object's front, y depth, z height), metres: the generic ones of
# bomc_bt.worldgen, with an office's own doors, tables, desks, sofas and screens.
SIZES: dict[str, tuple[float, float, float]] = {
    **DEFAULT_SIZES,
    "door": (0.9, 0.05, 2.0),
    "table": (1.6, 0.8, 0.75),  # meeting / open-plan table
    "desk": (1.2, 0.6, 0.75),  # a desk is scored as a "table" (the category the paper maps)
    "sofa": (1.8, 0.85, 0.8),
    "television": (1.0, 0.12, 0.6),
}
ELEVATION: dict[str, float] = {"television": 0.9}  # bottom of the box above the floor (wall mounted)

# Objects per 1,000 m2 of floor at the paper's Environment A mix (doors come from the plan).
DENSITY: dict[str, float] = {
    "table": 45 / 8.37,
    "chair": 109 / 8.37,
    "trash bin": 4.5,
    "cabinet": 3.0,
    "potted plant": 2.5,
    "sofa": 0.8,
    "television": 0.6,
}

# How likely a category is to take part in the churn between sessions (doors never do).
CHURN_WEIGHT: dict[str, float] = {
    "chair": 1.0,
    "trash bin": 1.0,
    "potted plant": 0.6,
    "table": 0.15,
    "cabinet": 0.1,
    "sofa": 0.1,
    "television": 0.0,
    "door": 0.0,
}
HOT_WEIGHT = 25.0  # how much likelier an object in a hot room is to change (OfficeParams.hot_rooms)
HOT_PLACE = 0.85  # share of new and returning objects placed in a hot room, when there are hot rooms
# What appears when a session adds new objects (category, share).
ADDED_MIX: tuple[tuple[str, float], ...] = (("chair", 0.6), ("trash bin", 0.25), ("potted plant", 0.15))

# [m] wall thicknesses drawn at the default 0.05 m cells; at coarser cells see walls_at()
NOMINAL_WALLS = {"outer_wall": 0.2, "corridor_wall": 0.15, "partition_wall": 0.1}
MAX_CELLS = 30_000_000  # a 270 x 270 m floor at 0.05 m/cell: memory stays under about 1 GB


def walls_at(resolution: float) -> dict[str, float]:
    """The nominal wall thicknesses, each made at least two map cells thick at ``resolution``
    (the least :meth:`OfficeParams.check` allows). A floor asked for at 0.1 m cells gets
    0.2 m walls, not an error about a wall its user never set."""
    two_cells = 2 * resolution if isinstance(resolution, (int, float)) and math.isfinite(resolution) else 0.0
    return {name: round(max(nominal, two_cells), 6) for name, nominal in NOMINAL_WALLS.items()}


@dataclass
class OfficeParams:
    """Tunables of :func:`bomc_bt.officegen.generate_office` (metres, seconds, shares in [0, 1]).

    The walls' defaults are two cells thick at 0.05 m cells or finer; at a coarser
    ``resolution`` pass ``**walls_at(resolution)`` too, as ``bomc world office`` does."""

    width: float = 93.0  # outer size of the floor, x
    height: float = 90.0  # outer size of the floor, y
    resolution: float = 0.05  # metres per map cell
    seed: int = 0
    sessions: int = 3  # sessions the world describes (changes before 2..N)
    churn: float = 0.05  # share of the movable objects changed before each session >= 2
    static: bool = False  # nothing ever changes (all sessions identical)
    hot_rooms: float = 0.0  # share of rooms where changes concentrate (HOT_WEIGHT times as likely); 0: none
    name: str = ""  # world name; empty: the output file's stem
    corridor_pitch: float = 10.0  # centre-to-centre spacing of parallel corridors
    corridor_width: tuple[float, float] = (2.0, 2.5)
    outer_wall: float = NOMINAL_WALLS["outer_wall"]
    corridor_wall: float = NOMINAL_WALLS["corridor_wall"]
    partition_wall: float = NOMINAL_WALLS["partition_wall"]
    door_width: float = 1.2  # clear opening of a doorway
    room_width: tuple[float, float] = (3.5, 8.0)  # rooms along a corridor, their frontage
    double_row_share: float = 0.75  # deep blocks split into two rows of rooms back to back
    open_plan_share: float = 0.15  # blocks that become one open-plan area (when big enough)
    internal_door_share: float = 0.12  # neighbouring rooms that also get a door between them
    robot_radius: float = 0.3  # doorways and objects keep a way this wide (plus a cell) open
    view_reach: float = 1.6  # every object has a reachable robot pose within this distance
    obstacle_every: int = 3  # sessions 3, 6, 9, ... block a corridor segment
    corridor_chair_every: int = 0  # sessions N, 2N, ... (>= 2) leave a chair mid-corridor; 0: never
    margin: float = 0.5  # unknown border around the floor in the map image

    def check(self) -> OfficeParams:
        """Raise BomcError(field) for the first value out of its range; return self."""
        def need(ok: bool, name: str, what: str) -> None:
            if not ok:
                raise BomcError(f"{what}, got {getattr(self, name)!r}", None, name)

        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("name", "seed", "sessions", "obstacle_every", "corridor_chair_every", "static"):
                continue
            values = value if isinstance(value, tuple) else (value,)
            need(all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values),
                 f.name, "must be finite numbers" if isinstance(value, tuple) else "must be a finite number")
        need(isinstance(self.static, bool), "static", "must be true or false")
        need(isinstance(self.name, str), "name", "must be text")
        need(12.0 <= self.width <= 400.0, "width", "must be 12 to 400 m")
        need(12.0 <= self.height <= 400.0, "height", "must be 12 to 400 m")
        need(0.02 <= self.resolution <= 0.1, "resolution", "must be 0.02 to 0.1 m per cell")
        cells = (self.width + 2 * self.margin) * (self.height + 2 * self.margin) / self.resolution**2
        need(cells <= MAX_CELLS, "resolution", f"gives {cells / 1e6:.0f} M cells for this size (at most "
             f"{MAX_CELLS // 1_000_000} M: use a coarser resolution or a smaller floor)")
        need(isinstance(self.seed, int) and not isinstance(self.seed, bool) and 0 <= self.seed < 2**63,
             "seed", "must be an integer 0 to 2**63-1")
        need(isinstance(self.sessions, int) and not isinstance(self.sessions, bool) and 1 <= self.sessions <= 100,
             "sessions", "must be an integer 1 to 100")
        need(0.0 <= self.churn <= 0.5, "churn", "must be 0 to 0.5")
        need(0.0 <= self.hot_rooms <= 1.0, "hot_rooms", "must be 0 to 1")
        need(6.0 <= self.corridor_pitch <= 40.0, "corridor_pitch", "must be 6 to 40 m")
        lo, hi = self.corridor_width
        need(1.5 <= lo <= hi <= 4.0, "corridor_width", "must be (lo, hi) with 1.5 <= lo <= hi <= 4 m")
        for name in ("outer_wall", "corridor_wall", "partition_wall"):
            need(2 * self.resolution - 1e-9 <= getattr(self, name) <= 0.5, name,
                 "must be 0.5 m at most and at least two map cells thick")
        need(2 * self.robot_radius + 0.3 <= self.door_width <= 2.0, "door_width",
             "must be 2 robot radii + 0.3 m to 2 m (a robot must pass with room to spare)")
        lo, hi = self.room_width
        need(self.door_width + SIZES["door"][0] + 0.4 <= lo <= hi <= 20.0, "room_width",
             "must be (lo, hi) with space for a doorway and its open leaf <= lo <= hi <= 20 m")
        need(0.0 <= self.open_plan_share <= 1.0, "open_plan_share", "must be 0 to 1")
        need(0.0 <= self.double_row_share <= 1.0, "double_row_share", "must be 0 to 1")
        need(0.0 <= self.internal_door_share <= 1.0, "internal_door_share", "must be 0 to 1")
        need(0.1 <= self.robot_radius <= 0.6, "robot_radius", "must be 0.1 to 0.6 m")
        need(0.5 <= self.view_reach <= 5.0, "view_reach", "must be 0.5 to 5 m")
        need(isinstance(self.obstacle_every, int) and self.obstacle_every >= 2, "obstacle_every",
             "must be an integer >= 2")
        need(isinstance(self.corridor_chair_every, int) and not isinstance(self.corridor_chair_every, bool)
             and 0 <= self.corridor_chair_every <= 100, "corridor_chair_every", "must be an integer 0 to 100")
        need(0.0 <= self.margin <= 5.0, "margin", "must be 0 to 5 m")
        return self
