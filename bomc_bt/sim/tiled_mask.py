"""The obstacle layer's mask as a checkpoint saves it: packed tile by tile, each tile once.

A monitor pass commits the simulated robot's state with every frame
(:mod:`bomc_bt.sim.checkpoint`), and the obstacle layer's mask changes with nearly every
scan (a person walking by, a chair seen again). Compressing the whole mask each time was
the largest single cost of a pass on an Environment-A-size office (3.4 million cells,
about 8 ms a frame, a quarter of the pass's wall time), yet a scan changes it only within
the lidar's reach. So the mask is cut into tiles; a tile is compressed again only when
its bits changed, and the saved value is the compressed tiles that are not empty.
Lossless: :func:`decode` gives the mask back exactly (tests/test_tiled_mask.py).

Packing the whole mask to find the changed tiles still cost about 1.5 ms a frame at that
size (24 s of a 450 s pass). Where the mask's owner says which windows changed since the
last encoding (``changed_since``, the obstacle layer's scan windows), only the tiles those
windows touch are packed and compared.
"""

from __future__ import annotations

import base64
import zlib
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

TILE = 256  # [count] cells per tile side (a multiple of 8: tiles split the packed bytes)

Window = tuple[int, int, int, int]  # rows r0:r1, columns c0:c1 of a mask


class TiledMaskText:
    """JSON-able tiles of one mask that changes in place, kept between calls (module docstring)."""

    def __init__(self, tile: int = TILE):
        self.tile = tile
        self._tiles: dict[str, tuple[bytes, str]] = {}  # key -> (packed bits, their text)
        self._last: tuple[int, tuple[int, ...], dict[str, Any]] | None = None

    def encode(self, mask: np.ndarray, version: int,
               changed_since: Callable[[int], Sequence[Window] | None] | None = None) -> dict[str, Any]:
        """The saved form of ``mask`` at ``version`` (the same version: the last value).

        ``changed_since(v)``: the windows of ``mask`` that changed after version ``v``, or None
        where that is not known (then every tile is looked at)."""
        last = self._last
        if last is not None and last[1] == mask.shape:
            if last[0] == version:
                return last[2]
            windows = None if changed_since is None else changed_since(last[0])
            if windows is not None:
                return self._encode_windows(mask, version, windows)
        packed = np.packbits(mask.astype(bool, copy=False), axis=1)
        t, tb = self.tile, self.tile // 8
        tiles: dict[str, str] = {}
        kept: dict[str, tuple[bytes, str]] = {}
        for r in range(0, packed.shape[0], t):
            for b in range(0, packed.shape[1], tb):
                bits = packed[r:r + t, b:b + tb].tobytes()
                if _empty(bits):
                    continue  # an empty tile is not saved
                key = f"{r // t},{b // tb}"
                kept[key] = self._tile(key, bits)
                tiles[key] = kept[key][1]
        self._tiles = kept
        value = {"tile": t, "shape": list(mask.shape), "tiles": tiles}
        self._last = (version, mask.shape, value)
        return value

    def _encode_windows(self, mask: np.ndarray, version: int, windows: Sequence[Window]) -> dict[str, Any]:
        """:meth:`encode` where only ``windows`` changed: their tiles packed again, the rest kept."""
        t = self.tile
        touched = {(i, j) for r0, r1, c0, c1 in windows if r1 > r0 and c1 > c0
                   for i in range(r0 // t, (r1 - 1) // t + 1) for j in range(c0 // t, (c1 - 1) // t + 1)}
        for i, j in touched:
            bits = np.packbits(mask[i * t:(i + 1) * t, j * t:(j + 1) * t].astype(bool, copy=False), axis=1).tobytes()
            key = f"{i},{j}"
            if _empty(bits):
                self._tiles.pop(key, None)
            else:
                self._tiles[key] = self._tile(key, bits)
        order = sorted(self._tiles, key=lambda k: tuple(int(v) for v in k.split(","))) if touched else self._tiles
        self._tiles = {k: self._tiles[k] for k in order}  # row by row, as a whole encoding lists them
        value = {"tile": t, "shape": list(mask.shape), "tiles": {k: v[1] for k, v in self._tiles.items()}}
        self._last = (version, mask.shape, value)
        return value

    def _tile(self, key: str, bits: bytes) -> tuple[bytes, str]:
        """(bits, text) of tile ``key``: the kept text while its bits are the same, else compressed anew."""
        old = self._tiles.get(key)
        if old is not None and old[0] == bits:
            return old
        return bits, base64.b64encode(zlib.compress(bits, 6)).decode("ascii")


def _empty(bits: bytes) -> bool:
    return bits.count(0) == len(bits)


def decode(value: dict[str, Any], shape: tuple[int, int]) -> np.ndarray:
    """The bool mask of :meth:`TiledMaskText.encode`'s ``value``; ValueError when it was
    saved for another shape or a tile does not fit."""
    if tuple(value["shape"]) != tuple(shape):
        raise ValueError("the saved obstacle layer does not fit the map")
    t = int(value["tile"])
    tb = t // 8
    h, w = shape
    packed = np.zeros((h, -(-w // 8)), dtype=np.uint8)
    for key, text in value["tiles"].items():
        r, b = (int(v) for v in key.split(","))
        block = packed[r * t:(r + 1) * t, b * tb:(b + 1) * tb]
        bits = np.frombuffer(zlib.decompress(base64.b64decode(text)), dtype=np.uint8)
        if bits.size != block.size:
            raise ValueError("the saved obstacle layer does not fit the map")
        block[...] = bits.reshape(block.shape)
    return np.unpackbits(packed, axis=1)[:, :w].astype(bool)
