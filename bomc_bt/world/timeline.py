"""The world's timeline: what is where in session *n*, at time *t*.

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
* The simulator holds back a during change that would put a box where the robot stands
  (:func:`lands_on`) until the robot has moved clear: nobody sets a chair down on a robot,
  and a robot inside a box could never drive out of it.
"""

from __future__ import annotations

import re
import zlib
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.world.records import Change, DuringChange, Obstacle, WorldObject
from bomc_bt.world.walls import wall_mask

_PLAIN_KEY = re.compile(r"[\w\-. ]+")
MAX_SESSION = 1_000_000  # session numbers a world or a site may hold: one pass an hour for over a century


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

    @cached_property
    def key(self) -> int:
        """A number that tells this world from others, the same in every session and process:
        a CRC-32 of the name, the map's size and resolution and the session-1 objects (name,
        category, position to the millimetre). The ``hard`` detector preset fixes its
        look-alikes and dark zones to places by it (:mod:`bomc_bt.sim.detector_hard`).

        Why not the name alone: every office the generator writes to ``office.yaml`` is named
        ``office``, and with a key from the name they all held their look-alikes and dark zones
        in the same floor squares (a false table at (35.7, 11.6) was a phantom in three
        generated 36 x 28 m offices of different seeds, session 99)."""
        parts = [self.name, f"{self.grid.width}x{self.grid.height}@{self.grid.resolution:.6f}"]
        parts += [f"{o.name}|{o.category}|" + ",".join(f"{v:.3f}" for v in o.position)
                  for o in sorted(self.objects.values(), key=lambda o: o.name)]
        return zlib.crc32("\n".join(parts).encode("utf-8"))

    @property
    def last_session(self) -> int:
        """The highest session the file mentions (1 if it has no changes)."""
        return max([1, *self.sessions, *(d.session for d in self.during)])

    def mentioned_sessions(self) -> list[int]:
        """The session numbers with changes before or during them, in order (1 always)."""
        return sorted({1, *self.sessions, *(d.session for d in self.during)})

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
        for k in self.mentioned_sessions():  # what happened in sessions 1..n-1 and before n
            if k >= n:
                if k == n and k in self.sessions:
                    state = apply_change(state, self.sessions[k], self.path, f"sessions[{k}]")
                break
            if k in self.sessions:
                state = apply_change(state, self.sessions[k], self.path, f"sessions[{k}]")
            for d in self.during_changes(k):
                state = apply_change(state, d.change, self.path, f"during[{d.index}]")
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
                            f"{where}.move.{entry_key(name)}")
        try:
            state[name] = state[name].moved_to(position)
        except (ValueError, TypeError):
            raise BomcError("expected [x, y] or [x, y, z] numbers", file,
                            f"{where}.move.{entry_key(name)}") from None
    for i, obj in enumerate(change.add):
        if obj.name in state:
            raise BomcError(f"cannot add {obj.name!r}: an object of that name already exists", file,
                            f"{where}.add[{i}].name")
        state[obj.name] = obj
    return state


def entry_key(key: Any) -> str:
    """A mapping key as it may appear in a one-line field path (odd text is quoted)."""
    text = str(key)
    return text if _PLAIN_KEY.fullmatch(text) else repr(text)



def lands_on(change: Change, objects: dict[str, WorldObject], xy: tuple[float, float], radius: float) -> bool:
    """Would ``change`` put a box (an object moved or added, an obstacle) within ``radius``
    of the point ``xy`` (the robot's centre)? ``objects``: what stands before the change."""
    boxes = [obj.footprint() for obj in apply_change(objects, Change(change.remove, change.move, change.add)).values()
             if obj.name in change.move or any(obj is added for added in change.add)]
    boxes += [obstacle.footprint() for obstacle in change.obstacles]
    point = (float(xy[0]), float(xy[1]))
    # pointPolygonTest: signed distance to the outline, positive inside
    return any(cv2.pointPolygonTest(box.astype(np.float32), point, True) > -radius for box in boxes)
