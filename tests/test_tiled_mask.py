"""The obstacle layer's mask saved tile by tile comes back exactly (sim/tiled_mask.py).

A resumed pass plans around the obstacles the killed one had seen; a bit lost or moved
between tiles would put a phantom obstacle in a corridor or drop a real one.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import LaserScan
from bomc_bt.sim.mapper import ObstacleLayer
from bomc_bt.sim.tiled_mask import TiledMaskText, decode


@pytest.mark.parametrize("shape", [(1820, 1880), (300, 517), (7, 9)])
def test_a_mask_edited_in_place_decodes_exactly_after_every_change(shape):
    rng = np.random.default_rng(sum(shape))
    mask = np.zeros(shape, dtype=bool)
    encoder = TiledMaskText()
    assert decode(json.loads(json.dumps(encoder.encode(mask, 0))), shape).sum() == 0
    for version in range(1, 8):
        r, c = int(rng.integers(0, shape[0])), int(rng.integers(0, shape[1]))
        mask[max(r - 60, 0):r + 60, max(c - 60, 0):c + 60] ^= rng.random((min(r + 60, shape[0]) - max(r - 60, 0),
                                                                          min(c + 60, shape[1]) - max(c - 60, 0))) < 0.3
        value = json.loads(json.dumps(encoder.encode(mask, version)))  # what the store keeps
        assert np.array_equal(decode(value, shape), mask)


def test_only_changed_tiles_are_compressed_again_and_an_unchanged_version_is_not_read():
    mask = np.zeros((1024, 1024), dtype=bool)
    mask[::7, ::5] = True
    encoder = TiledMaskText(tile=256)
    first = encoder.encode(mask, 1)
    assert len(first["tiles"]) == 16
    mask[7, 10] = False  # one tile changes
    second = encoder.encode(mask, 2)
    same = [k for k in first["tiles"] if first["tiles"][k] is second["tiles"][k]]
    assert len(same) == 15 and "0,0" not in same
    mask[600, 600] = True  # not seen: the version did not change
    assert encoder.encode(mask, 2) is second
    with pytest.raises(ValueError):
        decode(second, (1024, 1000))


@pytest.mark.parametrize("shape", [(1820, 1880), (300, 517)])
def test_told_which_windows_changed_the_tiles_are_those_of_a_whole_encoding(shape):
    """A scan changes the mask within its window; the encoder told so packs only the tiles the
    windows touch, and its value (tiles, their order, the text) is the whole encoding's."""
    rng = np.random.default_rng(shape[1])
    mask = np.zeros(shape, dtype=bool)
    told, whole = TiledMaskText(), TiledMaskText()
    log: list[tuple[int, tuple[int, int, int, int]]] = []

    def changed_since(version):
        return None if version < 2 else [w for v, w in log if v > version]  # version 1: "not known"

    for version in range(1, 14):
        r0, c0 = int(rng.integers(0, shape[0] - 5)), int(rng.integers(0, shape[1] - 5))
        r1, c1 = min(r0 + int(rng.integers(1, 400)), shape[0]), min(c0 + int(rng.integers(1, 400)), shape[1])
        mask[r0:r1, c0:c1] = rng.random((r1 - r0, c1 - c0)) < (0.0 if version % 4 == 0 else 0.2)  # cleared too
        log.append((version, (r0, r1, c0, c1)))
        value = told.encode(mask, version, changed_since)
        assert json.dumps(value) == json.dumps(whole.encode(mask, version))
        assert np.array_equal(decode(json.loads(json.dumps(value)), shape), mask)


def test_the_obstacle_layer_tells_its_scan_windows_and_nothing_after_a_clear():
    layer = ObstacleLayer(OccupancyGrid.unknown(400, 300, 0.05, (0.0, 0.0)))
    scan = LaserScan(0.0, -np.pi, np.pi / 90, np.full(180, 2.0, dtype=np.float32), 8.0)
    layer.update(scan, Pose2D(5.0, 5.0, 0.0))
    assert layer.version == 1 and layer.mask.any()
    (r0, r1, c0, c1), = layer.changed_since(0)
    rows, cols = np.nonzero(layer.mask)
    assert r0 <= rows.min() and rows.max() < r1 and c0 <= cols.min() and cols.max() < c1
    assert layer.changed_since(1) == []
    layer.clear()
    assert layer.changed_since(1) is None  # cleared: the whole mask changed
