"""Occupancy grids and the ROS map_server file format.

The grid follows ROS ``nav_msgs/OccupancyGrid``: ``data[row, col]`` with row 0 at the
map origin (the *bottom* of the image), values ``-1`` unknown, ``0`` free, ``100``
occupied. map_server images are stored top row first, so reading and writing flips rows.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from bomc_bt.atomic import atomic_write
from bomc_bt.errors import BomcError
from bomc_bt.yaml_io import read_yaml

UNKNOWN = -1
FREE = 0
OCCUPIED = 100

# The pixel values map_saver writes (trinary mode, negate 0).
PGM_FREE = 254
PGM_OCCUPIED = 0
PGM_UNKNOWN = 205


@dataclass
class OccupancyGrid:
    """A 2D occupancy grid in the map frame (origin yaw must be 0)."""

    data: np.ndarray  # int8 (H, W): -1 unknown, 0 free, 100 occupied
    resolution: float  # metres per cell
    origin: tuple[float, float] = (0.0, 0.0)  # map-frame position of cell (0, 0)'s corner
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def unknown(cls, width: int, height: int, resolution: float, origin=(0.0, 0.0)) -> OccupancyGrid:
        return cls(np.full((height, width), UNKNOWN, dtype=np.int8), resolution, tuple(origin))

    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    def copy(self) -> OccupancyGrid:
        return OccupancyGrid(self.data.copy(), self.resolution, tuple(self.origin))

    def crop(self, r0: int, r1: int, c0: int, c1: int) -> OccupancyGrid:
        """Rows ``r0:r1`` and columns ``c0:c1`` as a grid of their own, in the same map frame
        (a view of the cells, not a copy: planning in a window round a leg or a goal)."""
        res = self.resolution
        return OccupancyGrid(self.data[r0:r1, c0:c1], res, (self.origin[0] + c0 * res, self.origin[1] + r0 * res))

    # -- coordinates -----------------------------------------------------------------
    def world_to_cell(self, x, y):
        """Map-frame metres to (row, col) integer indices (vectorised; may be out of bounds)."""
        col = np.floor((np.asarray(x, dtype=float) - self.origin[0]) / self.resolution).astype(np.int64)
        row = np.floor((np.asarray(y, dtype=float) - self.origin[1]) / self.resolution).astype(np.int64)
        return row, col

    def cell_to_world(self, row, col):
        """(row, col) to the map-frame centre of the cell (vectorised)."""
        x = self.origin[0] + (np.asarray(col, dtype=float) + 0.5) * self.resolution
        y = self.origin[1] + (np.asarray(row, dtype=float) + 0.5) * self.resolution
        return x, y

    def cell_centres(self, mask: np.ndarray) -> np.ndarray:
        """(N, 2) map-frame centres of the cells where the grid-shaped bool ``mask`` is set."""
        x, y = self.cell_to_world(*np.nonzero(mask))
        return np.stack([x, y], axis=1).reshape(-1, 2)

    def in_bounds(self, row, col):
        row, col = np.asarray(row), np.asarray(col)
        return (row >= 0) & (row < self.height) & (col >= 0) & (col < self.width)

    def value_at(self, x: float, y: float) -> int:
        """Cell value at a map-frame point; outside the grid counts as unknown."""
        r, c = self.world_to_cell(x, y)
        if not self.in_bounds(r, c):
            return UNKNOWN
        return int(self.data[r, c])

    # -- masks -----------------------------------------------------------------------
    def free_mask(self) -> np.ndarray:
        return self.data == FREE

    def occupied_mask(self) -> np.ndarray:
        return self.data >= 50

    def unknown_mask(self) -> np.ndarray:
        return self.data < 0

    def free_area(self) -> float:
        """Known-free area in square metres."""
        return float(np.count_nonzero(self.free_mask())) * self.resolution**2

    def inflate(self, radius: float, unknown_is_obstacle: bool = False) -> np.ndarray:
        """Cells within ``radius`` metres of an obstacle (bool mask), as a costmap does."""
        obstacles = self.occupied_mask()
        if unknown_is_obstacle:
            obstacles = obstacles | self.unknown_mask()
        return inflate_mask(obstacles, radius / self.resolution)


def inflate_mask(mask: np.ndarray, radius_cells: float) -> np.ndarray:
    """Dilate a bool mask by a disc of ``radius_cells`` (vectorised through OpenCV)."""
    r = int(math.ceil(radius_cells))
    if r <= 0 or not mask.any():
        return mask.copy()
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool)


def any_per_block(mask: np.ndarray, size: int) -> np.ndarray:
    """Bool per ``size`` x ``size`` block of ``mask`` (the last ones padded with False): any
    cell of it is set. Coarser grids (tiles, pooled planners, looked-at squares) are built so."""
    h, w = mask.shape
    padded = np.zeros((-(-h // size) * size, -(-w // size) * size), dtype=bool)
    padded[:h, :w] = mask
    return padded.reshape(padded.shape[0] // size, size, padded.shape[1] // size, size).any(axis=(1, 3))


# -- map_server format -------------------------------------------------------------------
def load_map(yaml_path: str | Path) -> OccupancyGrid:
    """Read a map_server map (YAML + image) with its negate, thresholds and mode."""
    yaml_path = Path(yaml_path)
    meta = read_yaml(yaml_path, "map file")
    if not isinstance(meta, dict):
        raise BomcError("expected a mapping of map_server keys", yaml_path)
    image = _require(meta, "image", str, yaml_path)
    resolution = _number(meta, "resolution", None, 1e-4, 100.0, yaml_path)
    origin = meta.get("origin", [0.0, 0.0, 0.0])
    if not (isinstance(origin, list) and len(origin) in (2, 3)
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and abs(v) <= 1e6 and math.isfinite(v)
                    for v in origin)):
        raise BomcError("must be [x, y, yaw], each a number of at most 1e6", yaml_path, "origin")
    if len(origin) == 3 and abs(origin[2]) > 1e-9:
        raise BomcError(f"yaw {origin[2]:g}: a rotated map origin is not supported; ROS 1's amcl and "
                        "costmap_2d ignore the yaw, set it to 0 to use the map as they do", yaml_path, "origin")
    negate = meta.get("negate", 0)
    if negate not in (0, 1) or isinstance(negate, float):
        raise BomcError(f"must be 0 or 1, got {str(negate)[:40]}", yaml_path, "negate")
    occ_t = _number(meta, "occupied_thresh", 0.65, 0.0, 1.0, yaml_path)
    free_t = _number(meta, "free_thresh", 0.196, 0.0, 1.0, yaml_path)
    if not 0.0 <= free_t <= occ_t <= 1.0:
        raise BomcError("need 0 <= free_thresh <= occupied_thresh <= 1", yaml_path, "free_thresh")
    mode = str(meta.get("mode", "trinary"))
    if mode not in ("trinary", "scale", "raw"):
        raise BomcError(f"unknown mode {mode[:40]!r} (trinary, scale, raw)", yaml_path, "mode")
    image_path = (yaml_path.parent / image) if not os.path.isabs(image) else Path(image)
    check_image_size(image_path, yaml_path)
    pixels = cv2.imread(str(image_path), cv2.IMREAD_UNCHANGED)
    if pixels is None:
        raise BomcError(f"cannot read map image {image_path}", yaml_path, "image")
    if pixels.ndim == 3:  # colour images: map_server averages the channels
        pixels = pixels[..., :3].mean(axis=2)
    pixels = pixels.astype(np.float64)
    if pixels.max(initial=0) > 255:
        pixels = pixels / 257.0
    data = _pixels_to_occupancy(pixels, negate, occ_t, free_t, mode)
    return OccupancyGrid(np.flipud(data).copy(), resolution, (float(origin[0]), float(origin[1])))


def _pixels_to_occupancy(pixels, negate, occ_t, free_t, mode) -> np.ndarray:
    if mode == "raw":
        out = pixels.astype(np.int16)
        out[out > 100] = -1
        return out.astype(np.int8)
    occ = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
    data = np.full(pixels.shape, UNKNOWN, dtype=np.int8)
    data[occ > occ_t] = OCCUPIED
    data[occ < free_t] = FREE
    if mode == "scale":
        between = (occ >= free_t) & (occ <= occ_t)
        scaled = np.rint(99.0 * (occ - free_t) / max(occ_t - free_t, 1e-9))
        data[between] = scaled[between].astype(np.int8)
    return data


def save_map(grid: OccupancyGrid, yaml_path: str | Path) -> None:
    """Write ``grid`` as map_saver does (trinary PGM + YAML), atomically.

    Both files are written to temporaries and renamed into place, so a crash during the
    save leaves the previous map intact.
    """
    yaml_path = Path(yaml_path)
    yaml_path.parent.mkdir(parents=True, exist_ok=True)
    pgm_path = yaml_path.with_suffix(".pgm")
    pixels = np.full(grid.data.shape, PGM_UNKNOWN, dtype=np.uint8)
    pixels[grid.data == FREE] = PGM_FREE
    pixels[grid.data >= 65] = PGM_OCCUPIED
    pixels = np.flipud(pixels)
    header = f"P5\n# CREATOR: bomc-bt {grid.resolution:.3f} m/pix\n{grid.width} {grid.height}\n255\n"
    atomic_write(pgm_path, header.encode("ascii") + pixels.tobytes())
    meta = (
        f"image: {pgm_path.name}\n"
        f"resolution: {grid.resolution:.6f}\n"
        f"origin: [{grid.origin[0]:.6f}, {grid.origin[1]:.6f}, 0.000000]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n"
    )
    atomic_write(yaml_path, meta.encode("ascii"))


MAX_MAP_CELLS = 10**8  # 500 x 500 m at 5 cm: far beyond a building, within memory


def check_image_size(image_path: Path, yaml_path: Path) -> None:
    """Refuse an image whose header announces more than :data:`MAX_MAP_CELLS` before it is
    decoded (a 100000 x 100000 header would ask for 10 GB). PGM and PNG headers are read
    here; other formats are left to OpenCV's own limit."""
    try:
        with open(image_path, "rb") as f:
            head = f.read(64)
    except OSError as exc:
        raise BomcError(f"cannot read map image {image_path} ({exc.strerror})", yaml_path, "image") from None
    size = None
    if head[:8] == b"\x89PNG\r\n\x1a\n" and len(head) >= 24:
        size = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    elif head[:2] in (b"P2", b"P5"):
        fields = b" ".join(line.split(b"#")[0] for line in head.splitlines()).split()[1:3]
        if len(fields) == 2 and all(f.isdigit() for f in fields):
            size = int(fields[0]), int(fields[1])
    if size is not None and size[0] * size[1] > MAX_MAP_CELLS:
        raise BomcError(f"map image of {size[0]} x {size[1]} pixels is larger than {MAX_MAP_CELLS:.0e} cells",
                        yaml_path, "image")


def _number(meta: dict, key: str, default: float | None, low: float, high: float, path: Path) -> float:
    """``meta[key]`` (or ``default``; None: required) as a float within [low, high]."""
    value = _require(meta, key, (int, float), path) if default is None else meta.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            abs(value) <= 1e9 and math.isfinite(value) and low <= value <= high):
        raise BomcError(f"must be a number from {low:g} to {high:g}, got {str(value)[:40]}", path, key)
    return float(value)


def _require(meta: dict, key: str, types, path: Path):
    if key not in meta:
        raise BomcError("missing", path, key)
    value = meta[key]
    if not isinstance(value, types) or isinstance(value, bool):
        raise BomcError(f"has the wrong type ({type(value).__name__})", path, key)
    return value
