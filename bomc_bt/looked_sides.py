"""From which sides a pass looked at each place: a flat object looked at edge-on was not seen.

:mod:`bomc_bt.first_seen` calls an object *added* when it appears where an earlier pass
looked and saw nothing. A door leaf is seen only from in front of or behind it: looked at
from along its wall it is a sliver in the image that detectors miss. On a generated 36 x 28 m
office (seed 10131, ``realistic`` preset) passes 1 and 2 never detected door-19, on the side
wall of a corridor; pass 2 looked at its place in twelve frames, all 51-77 degrees off its
normal, and pass 3, which saw it from in front, reported it added: a change nobody made.

So each pass also keeps, per square of about :data:`CELL` (:func:`coarse_grid`), a bit per
viewing side it looked at the square from: the sector of the bearing from it to the camera,
of ``association.miss_sides`` sectors, the sides :mod:`bomc_bt.graph.view_sides` uses.
Each frame's looked-at fan (:func:`bomc_bt.perception.looked.looked_polygon`, vertex 0 the
camera) is cut along the sector boundaries into one fan per side (:func:`fan_sides`). The bits are saved per pass
(``looked_sides/<n>`` in the store's ``progress`` table, beside ``looked/<n>``: each
waypoint's snapshot, replayed with the fans since on resume, and the session's end). When a
pass ends, a node it added that is flat (a floor footprint three or more times longer than
wide: :func:`~bomc_bt.graph.faces.flat_normal`) counts as looked at only where an
earlier pass looked at its place from a side whose middle lies within
``association.face_on_deg`` of its face's normal (:func:`face_sides`); from none, it
is first seen (``{"first_seen": true, "unseen_sides": [...]}``).

Only flat nodes: judging every addition by the sides its own detections came from (measured
first) turned true additions into first sightings: a chair brought into a room, counted as
detected from one side only, where the previous pass had looked at its place from others
(36 x 28 m offices, seeds 10131 pass 3 and 10151 pass 2, the latter the new place of a chair
moved 2.7 m, so its removal was reported alone). A chair, a bin or a table is seen from every
side; an empty place looked at from any side was empty.

The claim is only made on evidence: an earlier pass that saved no bits (a site recorded
before them, bits of another count of sides) counts as having looked at its whole looked-at
floor from every side, as does any square of that floor without a bit (a resumed pass's floor
looked at before its last snapshot, where none was saved; a stray square on a cut). Sides are
judged from the camera here and from the robot's base in :mod:`bomc_bt.graph.view_sides`; the
two are a few tens of centimetres apart, a few degrees at the ranges objects are detected
from, which matters only at a sector's edge. Footprints are axis-aligned boxes, so a flat
object standing diagonally has a square box and is judged as before.
"""

from __future__ import annotations

import base64
import math
import zlib

import cv2
import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.graph.faces import flat_normal
from bomc_bt.graph.records import Node
from bomc_bt.grid import OccupancyGrid, any_per_block, inflate_mask

MAX_SIDES = 32  # the bits a square holds (uint32); more sides keep no per-side looks
CELL = 0.2  # [m] the side of the squares the looks are kept on: the map's cells, a few to a square


def looked_sides_key(session: int) -> str:
    """The per-side bits of the floor pass ``session`` looked at."""
    return f"looked_sides/{session}"


def bits_dtype(sides: int) -> type[np.unsignedinteger]:
    """The smallest unsigned type that holds a bit per side."""
    return np.uint8 if sides <= 8 else np.uint16 if sides <= 16 else np.uint32


def coarse_grid(grid: OccupancyGrid) -> OccupancyGrid:
    """``grid`` in squares of about :data:`CELL` (a whole number of its cells): a square is
    occupied where any of its cells is, else free where any is, else unknown. Why squares: a
    per-side look changes little over 0.2 m, and on the map's own 0.05 m cells an
    Environment-A-size floor's bits took 0.8 MB a pass and 50 ms to pack at every waypoint."""
    factor = square_cells(grid)
    if factor == 1:
        return grid
    h, w = grid.data.shape
    padded = np.full((-(-h // factor) * factor, -(-w // factor) * factor), -1, dtype=np.int16)
    padded[:h, :w] = grid.data
    blocks = padded.reshape(padded.shape[0] // factor, factor, padded.shape[1] // factor, factor)
    return OccupancyGrid(blocks.max(axis=(1, 3)).astype(np.int8), grid.resolution * factor, tuple(grid.origin))


def square_cells(grid: OccupancyGrid) -> int:
    """How many of ``grid``'s cells a square's side holds (:func:`coarse_grid`)."""
    return max(1, round(CELL / grid.resolution))


def fan_sides(polygon: np.ndarray, sides: int) -> list[tuple[int, np.ndarray]]:
    """``polygon`` (a fan, vertex 0 the camera, the rest in order round it) cut along the
    sector boundaries: (side, sub-fan) pairs, the side that of the bearing from the sub-fan's
    cells to the camera (:func:`bomc_bt.graph.view_sides.side_of`)."""
    camera, rim = polygon[0], polygon[1:]
    ray = rim - camera
    angle = np.unwrap(np.arctan2(ray[:, 1], ray[:, 0]))
    step = 2.0 * math.pi / sides
    sector = np.floor(angle / step).astype(int)  # the side is this modulo ``sides``
    out: list[tuple[int, np.ndarray]] = []
    current = [rim[0]]
    for i in range(1, len(rim)):
        for k in _crossed(sector[i - 1], sector[i]):  # the boundary at angle k * step lies between
            t = (k * step - angle[i - 1]) / (angle[i] - angle[i - 1])
            edge = rim[i - 1] + t * (rim[i] - rim[i - 1])
            current.append(edge)
            leaving = k - 1 if sector[i] > sector[i - 1] else k
            out.append((int(leaving % sides), np.vstack([camera, *current])))
            current = [edge]
        current.append(rim[i])
    out.append((int(sector[-1] % sides), np.vstack([camera, *current])))
    return [(s, fan) for s, fan in out if len(fan) >= 3]


def _crossed(a: int, b: int) -> list[int]:
    """The sector boundaries (by index k: angle k * step) between sectors ``a`` and ``b``, in
    the order a walk from ``a`` to ``b`` meets them."""
    return list(range(a + 1, b + 1)) if b > a else list(range(a, b, -1))


class LookedSides:
    """Per square, a bit per viewing side a pass looked at it from (module docstring)."""

    def __init__(self, grid: OccupancyGrid, sides: int):
        if not 1 <= sides <= MAX_SIDES:
            raise ValueError(f"looked sides need 1 to {MAX_SIDES} sides, not {sides}")
        self.grid = coarse_grid(grid)  # squares of about CELL
        self.factor = square_cells(grid)
        self.sides = sides
        self.bits = np.zeros(self.grid.data.shape, dtype=bits_dtype(sides))

    def add(self, polygon: np.ndarray) -> None:
        """Set each side's bit on the squares of ``polygon`` (a looked-at fan) seen from it."""
        polygon = np.asarray(polygon, dtype=float)
        if len(polygon) < 3:
            return
        h, w = self.bits.shape
        for side, fan in fan_sides(polygon, self.sides):
            rows, cols = self.grid.world_to_cell(fan[:, 0], fan[:, 1])
            r0, r1 = max(int(rows.min()), 0), min(int(rows.max()) + 1, h)
            c0, c1 = max(int(cols.min()), 0), min(int(cols.max()) + 1, w)
            if r0 >= r1 or c0 >= c1:
                continue
            scratch = np.zeros((r1 - r0, c1 - c0), dtype=np.uint8)
            pts = np.stack([cols - c0, rows - r0], axis=1).astype(np.int32)
            cv2.fillPoly(scratch, [pts], 1)
            self.bits[r0:r1, c0:c1] |= scratch.astype(self.bits.dtype) << self.bits.dtype.type(side)

    def packed(self) -> str:
        """The bits as compressed text, after their count of sides and a colon (zlib level 1:
        each waypoint's snapshot writes them)."""
        return f"{self.sides}:" + base64.b64encode(zlib.compress(self.bits.tobytes(), 1)).decode("ascii")

    def restore(self, text, looked: np.ndarray) -> None:
        """Put a killed pass's saved bits back (the polygons since are added after); where it
        saved none of this count of sides (a snapshot written before they were kept, or with
        another ``miss_sides``), the floor it had ``looked`` at (the map's cells) counts as
        looked at from every side."""
        if isinstance(text, str) and text.startswith(f"{self.sides}:"):
            self.bits[:] = unpack_sides(text, self.bits.shape, self.sides)
        else:
            self.bits[any_per_block(np.asarray(looked, dtype=bool), self.factor)] = ~self.bits.dtype.type(0)


def saved_side_count(text: str) -> int:
    """How many sides saved bits (:meth:`LookedSides.packed`) hold; ValueError when not such text."""
    count, colon, _ = text.partition(":")
    if not colon or not count.isdigit() or not 1 <= int(count) <= MAX_SIDES:
        raise ValueError("no count of sides")
    return int(count)


def unpack_sides(text: str, shape: tuple[int, int], sides: int) -> np.ndarray:
    """Saved bits (:meth:`LookedSides.packed`) of ``sides`` sides on a map of ``shape``;
    ValueError when they are not."""
    if saved_side_count(text) != sides:
        raise ValueError(f"saved with {saved_side_count(text)} sides")
    dtype = bits_dtype(sides)
    data = zlib.decompress(base64.b64decode(text.partition(":")[2], validate=True))
    if len(data) != int(np.prod(shape)) * np.dtype(dtype).itemsize:
        raise ValueError("the saved sides do not fit the map")
    return np.frombuffer(data, dtype=dtype).reshape(shape).copy()


def widen_sides_into_walls(bits: np.ndarray, grid: OccupancyGrid, margin: float, sides: int) -> np.ndarray:
    """Each side's looked-at floor and the occupied cells within ``margin`` (m) of it (as
    :func:`bomc_bt.first_seen.widen_into_walls` widens the floor: a door's centre lies in its wall)."""
    occupied = grid.occupied_mask()
    out = bits.copy()
    one = bits.dtype.type(1)
    for side in range(sides):
        plane = (bits >> bits.dtype.type(side)) & one
        if plane.any():
            out[inflate_mask(plane.astype(bool), margin / grid.resolution) & occupied] |= one << bits.dtype.type(side)
    return out


def side_bits(sides: list[int] | tuple[int, ...]) -> int:
    """The bit mask of ``sides``."""
    return int(sum(1 << int(s) for s in set(sides)))


def looked_sides_for(grid: OccupancyGrid, params) -> LookedSides | None:
    """A pass's per-side looks on ``grid`` where the association (``params``) judges flat
    additions by side (:func:`side_count`)."""
    sides = side_count(params)
    return LookedSides(grid, sides) if sides else None


def side_count(params) -> int:
    """The viewing sides additions are judged by: ``miss_sides`` in robust mode with
    ``face_on_deg`` under 90 and 1 to :data:`MAX_SIDES` sides; 0: off."""
    if params is None or getattr(params, "mode", None) != "robust" \
            or getattr(params, "face_on_deg", 90.0) >= 90.0:
        return 0
    sides = int(getattr(params, "miss_sides", 0))
    return sides if 1 <= sides <= MAX_SIDES else 0


def face_sides(node: Node, sides: int, face_deg: float) -> list[int]:
    """The viewing sides (of ``sides``) whose middle bearing lies within ``face_deg`` of a flat
    node's face normal, either face; none for a node that is not flat
    (:func:`~bomc_bt.graph.faces.flat_normal`)."""
    normal = flat_normal(node)
    if normal is None:
        return []
    step = 2.0 * math.pi / sides
    middles = -math.pi + (np.arange(sides) + 0.5) * step  # the bearing from the node to the robot
    facing = math.atan2(normal[1], normal[0])
    out = []
    for face in (facing, facing + math.pi):
        off = np.abs(np.angle(np.exp(1j * (middles - face))))
        out += np.nonzero(off <= math.radians(face_deg) + 1e-9)[0].tolist()
    return sorted(set(out))


def earlier_side_looks(store, looked: dict[int, np.ndarray], grid: OccupancyGrid, margin: float,
                       sides: int) -> tuple[np.ndarray, OccupancyGrid]:
    """The union of the per-side looks of the passes in ``looked`` (session -> its looked-at
    floor on ``grid``, bool), widened into walls by ``margin`` (m), and the squares they are
    on (:func:`coarse_grid`). A pass that saved no bits, and any square of its floor without
    one, counts as looked at from every side (the old judgement)."""
    squares = coarse_grid(grid)
    everywhere = ~bits_dtype(sides)(0)
    out = np.zeros(squares.data.shape, dtype=bits_dtype(sides))
    for session, floor in looked.items():
        text = store.get_progress(looked_sides_key(session))
        bits = _saved_sides(store, session, text, squares, sides) if _of_sides(text, sides) else np.zeros_like(out)
        bits[any_per_block(floor, square_cells(grid)) & (bits == 0)] = everywhere
        out |= bits
    return widen_sides_into_walls(out, squares, margin, sides), squares


def _of_sides(text, sides: int) -> bool:
    """Whether saved bits are of ``sides`` sides (another count: saved before ``miss_sides``
    was changed, no use here); text that is not such bits at all is left to :func:`_saved_sides`."""
    try:
        return text is not None and saved_side_count(text) == sides
    except (ValueError, AttributeError):
        return text is not None


def _saved_sides(store, session: int, text, grid: OccupancyGrid, sides: int) -> np.ndarray:
    try:
        if not isinstance(text, str):
            raise ValueError("not text")
        return unpack_sides(text, grid.data.shape, sides)
    except (ValueError, zlib.error) as exc:  # binascii.Error is a ValueError
        raise BomcError(f"corrupt site store: the saved looked-at sides of session {session} are not "
                        f"{sides} sides of this map ({exc})", store.path,
                        f"progress.{looked_sides_key(session)}") from None
