"""Where a pass detected objects of each category: the evidence that an object was there.

A node the map adds in pass N is a change only if the object was not there at pass N-1.
Where pass N-1 looked and saw nothing, it was not (:mod:`bomc_bt.first_seen`). But pass
N-1 may also have *detected* the object and still left no node for it: it folded the views
into a neighbouring chair 0.8 m away, or dropped a first sighting that was not confirmed in
time. On an Environment-A-size floor most of session 2's phantom additions were such
objects (issue 17): the chairs pass 1 had merged or wrongly removed, found again (a node
removed on its misses is now a reported removal, and its place no sighting's: below). An
operator told "a chair was added here" goes to look at a chair that stood there all along.

So every pass records where its detections put objects, per category: the map cell of
each observation's centre (``Perception.sightings``), saved per session in the store's
``progress`` table under ``sightings/<n>`` ({category: packed mask}) with the coverage
masks (each waypoint's commit and the session's end; :mod:`bomc_bt.pass_resume`). The
next pass's :class:`~bomc_bt.first_seen.SeenBefore` calls a new node that stands within
``association.sighting_radius`` of a previous-pass sighting of its category *first seen*
(new to the map, not a change), and says why in the event's detail
(``{"first_seen": true, "sighted_in": N-1}``).

Only the previous recorded pass counts: a chair seen in pass 1, taken away before pass 2
(which saw the place empty) and brought back before pass 3 *was* added for pass 3. So
does a node the previous pass removed on evidence of absence (missed frames, not a merge,
and not brought back in that pass): its sightings there were of an object it then saw
gone, and that pass reported the removal, so the object back there is an addition; and so
does one it removed so and then paired with an addition elsewhere as a move
(:meth:`~bomc_bt.first_seen.SeenBefore.mark`; a bin taken away during a pass after the
robot saw it and brought back before the next was first seen, and the map's story stayed
"removed"). A true addition that lands where the previous pass saw another object of its
category (within the radius, less than an object's size) is the price: it is not reported,
unless their colours tell them apart (:func:`other_looks`).
"""

from __future__ import annotations

import base64
import math
import zlib
from collections.abc import Iterable, Mapping

import numpy as np

from bomc_bt.graph.looks import alike
from bomc_bt.grid import OccupancyGrid
from bomc_bt.pass_resume import pack_mask, unpack_mask


class Sightings:
    """Per category, the map cells the centres of a pass's observations fell in."""

    def __init__(self, grid: OccupancyGrid):
        self.grid = grid
        self.masks: dict[str, np.ndarray] = {}
        self.since: list[list] = []  # [category, x, y] since the last snapshot (a resume point's part)
        self._packed: dict[str, str] = {}  # category -> its mask packed, while no cell was marked since

    def add(self, observations: Iterable) -> None:
        """Mark each observation's cell in its category's mask."""
        for o in observations:
            x, y = float(o.position[0]), float(o.position[1])
            if self._mark(str(o.category), x, y):
                self.since.append([str(o.category), round(x, 3), round(y, 3)])

    def add_points(self, points: Iterable[Iterable]) -> None:
        """Marks from a resume point's ``[category, x, y]`` list."""
        points = [list(p) for p in points]
        for category, x, y in points:
            self._mark(str(category), float(x), float(y))
        self.since = points

    def _mark(self, category: str, x: float, y: float) -> bool:
        rows, cols = self.grid.world_to_cell(np.array([x]), np.array([y]))
        if not self.grid.in_bounds(rows, cols)[0]:
            return False
        mask = self.masks.get(category)
        if mask is None:
            mask = self.masks[category] = np.zeros(self.grid.data.shape, dtype=bool)
        if mask[rows[0], cols[0]]:
            return False
        mask[rows[0], cols[0]] = True
        self._packed.pop(category, None)
        return True

    def packed(self) -> dict[str, str]:
        """{category: packed mask}: the value saved under
        :func:`~bomc_bt.pass_resume.sightings_key`. A mask is packed again only when a cell of
        it was marked since (every waypoint saves them all; most categories were not seen)."""
        for category, mask in self.masks.items():
            if category not in self._packed:
                self._packed[category] = pack_mask(mask)
        return {category: self._packed[category] for category in sorted(self.masks)}

    def restore(self, saved: Mapping[str, str]) -> None:
        """Put back a snapshot saved by :meth:`packed` (a resumed pass); ValueError when a mask
        is not one of this map."""
        self.masks = unpack_sightings(dict(saved), self.grid.data.shape) or {}
        self._packed = {}


def unpack_sightings(saved, shape: tuple[int, int]) -> dict[str, np.ndarray] | None:
    """A saved ``sightings/<n>`` value as {category: bool mask}; None when it is not one
    (a pass recorded before sightings were saved), ValueError when a mask does not fit."""
    if not isinstance(saved, dict):
        return None
    size = -(-int(np.prod(shape)) // 8)  # packed bytes of one mask of this map, exactly
    out = {}
    for category, text in saved.items():
        if len(zlib.decompress(base64.b64decode(text, validate=True))) != size:
            raise ValueError(f"the {category!r} mask is not one of a {shape[1]} x {shape[0]} map")
        out[str(category)] = unpack_mask(text, shape).astype(bool)
    return out


def other_looks(mask: np.ndarray, grid: OccupancyGrid, xy: np.ndarray, radius: float, colour: np.ndarray | None,
                looks: tuple[np.ndarray, np.ndarray] | None, tolerance: float) -> bool:
    """Whether every sighting of ``mask`` (one category's cells, not widened) within ``radius``
    (m) of ``xy`` lies within ``radius`` of a node of another look than ``colour`` and of none
    of that look: the previous pass's views there were of that other object. ``looks``: the
    (x, y) and colours of the nodes that pass left on the map (None, or ``colour`` None, or
    ``tolerance`` 0: False, the sightings stand as they are).

    Traced: a blue chair carried 2.6 m and a red one brought to 0.63 m from where it had stood
    (36 x 28 m office, seed 9105, pass 3): the blue chair's views of the pass before fell within
    the radius of the red one's place, and the red chair, a true addition, was called first seen.
    """
    if colour is None or looks is None or tolerance <= 0.0 or len(looks[0]) == 0:
        return False
    reach = int(math.ceil(radius / grid.resolution)) + 1
    row, col = (int(v[0]) for v in grid.world_to_cell(np.array([xy[0]]), np.array([xy[1]])))
    r0, c0 = max(row - reach, 0), max(col - reach, 0)
    rows, cols = np.nonzero(mask[r0:max(row + reach + 1, 0), c0:max(col + reach + 1, 0)])
    cx, cy = grid.cell_to_world(rows + r0, cols + c0)
    cells = np.stack([cx, cy], axis=1)[np.hypot(cx - xy[0], cy - xy[1]) <= radius]
    if len(cells) == 0:
        return False
    near = np.hypot(cells[:, None, 0] - looks[0][None, :, 0], cells[:, None, 1] - looks[0][None, :, 1]) <= radius
    same = np.array([alike(colour, c, tolerance) for c in looks[1]], dtype=bool)
    return bool((near[:, ~same].any(axis=1) & ~near[:, same].any(axis=1)).all())
