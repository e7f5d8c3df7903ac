"""The things a world is made of: labelled objects, unlabelled obstacles and changes.

Plain frozen records, shared by the loader that builds them from a world file, the
timeline that replays changes, the simulator that renders them and the evaluator that
scores a graph against them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np


def box_corners(x: float, y: float, sx: float, sy: float, yaw: float) -> np.ndarray:
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
    # how it looks: RGB 0-255 of its surface; None draws the category's colour (every
    # object of a kind alike, as in worlds written before objects had colours)
    colour: tuple[int, int, int] | None = None

    def footprint(self) -> np.ndarray:
        """(4, 2) map-frame corners of the rotated box, counter-clockwise."""
        return box_corners(self.position[0], self.position[1], self.size[0], self.size[1], self.yaw)

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
        out = {"name": self.name, "category": self.category, "position": list(self.position),
               "size": list(self.size), "yaw": self.yaw}
        if self.colour is not None:
            out["colour"] = list(self.colour)
        return out


@dataclass(frozen=True)
class Obstacle:
    """An unlabelled blocker: the robot must drive around it, the detector should ignore it."""

    position: tuple[float, float]
    size: tuple[float, float]
    height: float = 1.0
    yaw: float = 0.0

    def footprint(self) -> np.ndarray:
        """(4, 2) map-frame corners of the rotated box, counter-clockwise."""
        return box_corners(self.position[0], self.position[1], self.size[0], self.size[1], self.yaw)

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


