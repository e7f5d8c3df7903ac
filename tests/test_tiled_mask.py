"""The obstacle layer's mask saved tile by tile comes back exactly (sim/tiled_mask.py).

A resumed pass plans around the obstacles the killed one had seen; a bit lost or moved
between tiles would put a phantom obstacle in a corridor or drop a real one.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

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
