"""The simulated detector + segmenter: prompts, perfect masks, the realistic noise model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.params import from_mapping
from bomc_bt.perception.frames import Detection
from bomc_bt.robot import RGBDFrame
from bomc_bt.sim.camera import CameraParams, SimCamera
from bomc_bt.sim.detector import SimDetector, SimDetectorParams
from bomc_bt.world import Obstacle, WorldObject

RES = 0.05
N_STAMPS = 150


def scene(objects, obstacles=(), people=(), wall_x=None, scale=0.25):
    n = int(30.0 / RES)
    grid = OccupancyGrid(np.zeros((n, n), dtype=np.int8), RES, (-15.0, -15.0))
    walls = np.zeros((n, n), dtype=bool)
    if wall_x is not None:
        _, col = grid.world_to_cell(wall_x, 0.0)
        walls[:, int(col):int(col) + 3] = True
    cam = SimCamera(CameraParams(scale=scale, depth_noise=0.0), seed=0)
    pose = Pose2D(0.0, 0.0, 0.0)
    return cam.render(walls, grid, 2.5, list(objects), list(obstacles), list(people), pose, pose, 0.0)


def at_stamp(frame, stamp):
    frame.stamp = stamp
    return frame


def chair(name, x, y, category="chair"):
    return WorldObject(name, category, (x, y, 0.45), (0.5, 0.5, 0.9))


def test_perfect_reports_every_visible_prompted_instance_with_its_exact_mask():
    objects = [chair("a", 2.5, 0.6), chair("b", 3.5, -0.8), chair("t", 3.0, 0.0, "table"),
               chair("u", 2.5, -0.1, "umbrella")]
    frame = scene(objects, [Obstacle((4.0, 1.5), (0.5, 0.5), 1.0)], [(4.5, -1.8)])
    det = SimDetector(SimDetectorParams(preset="perfect"))
    found = det.segment(frame, det.detect(frame, ["chair", "table", "sofa"]))
    assert sorted(d.category for d in found) == ["chair", "chair", "table"]  # no umbrella: not prompted
    for d in found:
        assert d.score == 1.0
        ids = np.unique(frame.instances[d.mask])
        assert len(ids) == 1 and frame.instance_categories[int(ids[0])] == d.category
        assert np.array_equal(d.mask, frame.instances == ids[0])
        x0, y0, x1, y1 = d.box
        rows, cols = np.nonzero(d.mask)
        assert (x0, y0, x1, y1) == (cols.min(), rows.min(), cols.max() + 1, rows.max() + 1)
    assert det.detect(frame, []) == []


def test_tiny_instances_are_not_detected():
    cups = [WorldObject("small", "cup", (5.0, 0.0, 0.9), (0.05, 0.05, 0.05)),
            WorldObject("big", "cup", (5.0, -0.5, 0.9), (0.15, 0.15, 0.15))]
    frame = scene(cups, scale=1.0)
    assert 0 < (frame.instances == 1).sum() < 50 < (frame.instances == 2).sum()
    det = SimDetector(SimDetectorParams(preset="perfect"))
    found = det.segment(frame, det.detect(frame, ["cup"]))
    assert len(found) == 1 and np.array_equal(found[0].mask, frame.instances == 2)


def detection_rate(frame, params, category="chair", instance=1):
    det = SimDetector(params, seed=11)
    hits = 0
    for k in range(N_STAMPS):
        found = det.segment(frame, det.detect(at_stamp(frame, k * 0.5), [category, "table"]))
        hits += any(np.any(d.mask & (frame.instances == instance)) and d.category == category for d in found)
    return hits / N_STAMPS


def test_realistic_misses_more_far_away_and_behind_occluders():
    params = SimDetectorParams(false_positive_rate=0.0, confusion_rate=0.0)
    near = detection_rate(scene([chair("a", 2.0, 0.0)]), params)
    far = detection_rate(scene([chair("a", 7.5, 0.0)]), params)
    assert near > 0.75 and far < near - 0.15
    occluder = WorldObject("box", "table", (2.0, 0.2, 0.4), (0.3, 0.5, 0.8))
    hidden = detection_rate(scene([chair("a", 3.5, 0.0), occluder]), params)
    free = detection_rate(scene([chair("a", 3.5, 0.0)]), params)
    assert hidden < free - 0.1


def test_realistic_scores_respect_the_threshold_and_masks_bleed():
    frame = scene([chair("a", 2.5, 0.0)], wall_x=5.0)
    params = SimDetectorParams(false_positive_rate=0.0, confusion_rate=0.0, mask_bleed=0.2,
                               box_jitter=0.0)
    det = SimDetector(params, seed=3)
    truth = frame.instances == 1
    seen = 0
    for k in range(30):
        for d in det.segment(frame, det.detect(at_stamp(frame, k * 0.5), ["chair"])):
            seen += 1
            assert params.score_threshold <= d.score <= 1.0
            assert (d.mask & truth).sum() == truth.sum()  # the object plus
            assert (d.mask & ~truth).sum() == pytest.approx(0.2 * truth.sum(), abs=1)  # bleed around it
    assert seen > 15


def test_false_positives_and_confusions():
    frame = scene([chair("a", 2.5, 0.0)], wall_x=5.0)
    fp = SimDetector(SimDetectorParams(false_positive_rate=1.0, miss_base=1.0, score_std=0.0), seed=2)
    found = fp.segment(frame, fp.detect(frame, ["chair", "sofa"]))
    assert len(found) == 1 and found[0].category in ("chair", "sofa")
    mask = found[0].mask
    assert mask.sum() > 0 and not (mask & (frame.instances == 1)).any()  # a blob on the background
    swap = SimDetector(SimDetectorParams(confusion_rate=1.0, miss_base=0.0, miss_per_metre=0.0,
                                         false_positive_rate=0.0, score_std=0.0))
    labels = {d.category for k in range(10) for d in swap.detect(at_stamp(frame, k), ["chair", "sofa"])}
    assert labels == {"sofa"}
    alone = {d.category for k in range(10) for d in swap.detect(at_stamp(frame, k), ["chair"])}
    assert alone == {"chair"}  # nothing to confuse it with


def test_dropouts_yield_nothing():
    frame = scene([chair("a", 2.0, 0.0)])
    det = SimDetector(SimDetectorParams(preset="perfect", dropouts=[(10.0, 20.0)]))
    assert det.detect(at_stamp(frame, 15.0), ["chair"]) == []
    assert det.detect(at_stamp(frame, 10.0), ["chair"]) == []
    assert len(det.detect(at_stamp(frame, 20.0), ["chair"])) == 1
    assert len(det.detect(at_stamp(frame, 9.9), ["chair"])) == 1


def test_deterministic_per_seed_and_stamp():
    objects = [chair(f"c{i}", 2.0 + i, 0.5 * math.sin(i), "chair" if i % 2 else "table") for i in range(5)]
    frame = scene(objects, wall_x=8.0)

    def run(seed, stamps):
        det = SimDetector(SimDetectorParams(false_positive_rate=0.3, confusion_rate=0.2), seed=seed)
        out = []
        for s in stamps:
            found = det.segment(frame, det.detect(at_stamp(frame, s), ["chair", "table"]))
            out.append([(d.category, d.box, d.score, int(d.mask.sum())) for d in found])
        return out

    assert run(1, [0.0, 0.5, 1.0])[2] == run(1, [1.0])[0]  # independent of earlier frames
    many = run(1, np.arange(20) * 0.5)
    assert many != run(2, np.arange(20) * 0.5)
    assert many == run(1, np.arange(20) * 0.5)


def test_foreign_boxes_get_the_dominant_instance():
    frame = scene([chair("a", 2.5, 0.0)])
    rows, cols = np.nonzero(frame.instances == 1)
    box = (float(cols.min()), float(rows.min()), float(cols.max() + 1), float(rows.max() + 1))
    det = SimDetector(SimDetectorParams(preset="perfect"))
    (seg,) = det.segment(frame, [Detection("chair", box, 0.9)])
    assert np.array_equal(seg.mask, frame.instances == 1)


def test_needs_the_simulated_instance_image_and_valid_params():
    sim = scene([chair("a", 2.5, 0.0)])
    # What a real camera delivers: the same pixels, no simulator ground truth.
    frame = RGBDFrame(sim.stamp, sim.rgb, sim.depth, sim.K, sim.T_map_base, sim.T_base_camera, sim.depth_range)
    assert not hasattr(frame, "instances")
    with pytest.raises(BomcError, match="simulated camera"):
        SimDetector().detect(frame, ["chair"])
    with pytest.raises(BomcError, match="confusion_rate"):
        from_mapping(SimDetectorParams, {"confusion_rate": 2.0}, "cfg.yaml", "detector")
    p = from_mapping(SimDetectorParams, {"preset": "perfect", "dropouts": [[1, 2]]}, "cfg.yaml", "detector")
    assert p.dropouts == [(1.0, 2.0)]
