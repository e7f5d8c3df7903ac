"""A false box on a wall is no object; a cabinet against that wall, a door in it, are."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bomc_bt.geometry import Pose2D
from bomc_bt.perception.frames import Detection
from bomc_bt.perception.projection import ProjectionParams, ProjectionStats, detections_to_observations
from bomc_bt.perception.surface_patch import on_plane_share, plane
from bomc_bt.sim.detector import SimDetector, SimDetectorParams
from bomc_bt.world import WorldObject
from tests.test_projection import empty_world, see

WALL_X = 3.0  # m ahead of the camera


def wall_scene():
    """A wall across the view 3 m ahead and a cabinet standing against it, left of centre."""
    walls, grid = empty_world()
    _, col = grid.world_to_cell(WALL_X, 0.0)
    walls[:, int(col):int(col) + 4] = True
    cabinet = WorldObject("c", "cabinet", (WALL_X - 0.3, 0.6, 0.6), (0.5, 0.8, 1.2), 0.0)
    frame = see([cabinet], Pose2D(0.0, 0.0, 0.0), 10.0, walls=walls, grid=grid)
    return frame, cabinet


def wall_box(frame, y_lo: float, y_hi: float) -> np.ndarray:
    """The pixels that see the wall's face between y_lo and y_hi, 0.6-1.0 m up: a false box's mask."""
    rows, cols = np.indices(frame.depth.shape)
    K, z = frame.K, frame.depth.astype(float)
    cam = np.stack([(cols - K[0, 2]) / K[0, 0] * z, (rows - K[1, 2]) / K[1, 1] * z, z], axis=-1)
    world = cam @ frame.T_map_camera[:3, :3].T + frame.T_map_camera[:3, 3]
    x, y, height = world[..., 0], world[..., 1], world[..., 2]
    return (x > WALL_X - 0.05) & (height > 0.6) & (height < 1.0) & (y > y_lo) & (y < y_hi)


def test_a_false_box_on_a_wall_is_dropped_and_counted():
    """The realistic detector's false box on plain wall, named "cabinet": its points stand
    above the floor, so the floor tests kept it, and two such boxes on one patch made a
    cabinet inside a corridor wall (93 x 90 m office, seed 9611, pass 2). The wall goes on
    round the box at the same depth: no observation, counted as on the wall."""
    frame, _ = wall_scene()
    mask = wall_box(frame, -0.9, -0.4)
    assert mask.sum() > 50 and not mask[:, 0].any() and not mask[:, -1].any()
    stats = ProjectionStats()
    assert detections_to_observations(frame, [Detection("cabinet", (0, 0, 1, 1), 0.8, mask=mask)],
                                      ProjectionParams(), stats) == []
    assert stats.on_wall == 1 and stats.observations == 0
    off = detections_to_observations(frame, [Detection("cabinet", (0, 0, 1, 1), 0.8, mask=mask)],
                                     ProjectionParams(patch_share=1.1))
    assert len(off) == 1 and abs(off[0].position[0] - WALL_X) < 0.1  # what it was: a cabinet in the wall


def test_a_door_in_the_wall_and_a_cabinet_against_it_are_kept():
    """A door leaf is flush with its wall, a screen flat on it (``flush_categories``); a cabinet stands out from
    the wall behind it and the floor in front, so its ring is off its face's plane."""
    frame, cabinet = wall_scene()
    door = Detection("door", (0, 0, 1, 1), 0.8, mask=wall_box(frame, -0.9, -0.4))
    assert len(detections_to_observations(frame, [door], ProjectionParams())) == 1
    screen = replace(door, category="television")  # a flat screen hangs a few cm off its wall
    assert len(detections_to_observations(frame, [screen], ProjectionParams())) == 1
    det = SimDetector(SimDetectorParams(preset="perfect"))
    views = det.segment(frame, det.detect(frame, ["cabinet"]))
    stats = ProjectionStats()
    [seen] = detections_to_observations(frame, views, ProjectionParams(), stats)
    assert stats.on_wall == 0
    assert np.hypot(seen.position[0] - cabinet.position[0], seen.position[1] - cabinet.position[1]) < 0.3


def test_a_box_at_the_image_border_is_not_judged():
    """A sliver at the border has its ring on one side only (the views of true objects that
    came nearest the rule were such slivers): never judged a patch."""
    frame, _ = wall_scene()
    mask = wall_box(frame, -9.0, -0.4)  # the wall patch runs off the image's right edge
    assert mask[:, -1].any()
    stats = ProjectionStats()
    kept = detections_to_observations(frame, [Detection("chair", (0, 0, 1, 1), 0.8, mask=mask)],
                                      ProjectionParams(), stats)
    assert len(kept) == 1 and stats.on_wall == 0


def test_plane_fit_and_ring_share():
    """A flat upright surface and a ring on its plane: share 1; the ring 0.4 m behind: 0; a
    floor-level (horizontal) surface or a curved one is not judged (None)."""
    rng = np.random.default_rng(0)
    face = np.column_stack([rng.uniform(-0.3, 0.3, 200), rng.uniform(-0.3, 0.3, 200), np.full(200, 3.0)])
    ring = np.column_stack([rng.uniform(-0.6, 0.6, 100), rng.uniform(-0.6, 0.6, 100), np.full(100, 3.0)])
    _, normal, rms = plane(face)
    assert rms < 1e-9 and abs(abs(normal[2]) - 1.0) < 1e-9
    upright = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # camera z ahead, y down
    assert on_plane_share(face, ring, upright) == 1.0
    assert on_plane_share(face, replace_z(ring, 3.4), upright) == 0.0
    assert on_plane_share(face, ring, np.eye(3)) is None  # that plane would lie flat on the floor
    bowl = face.copy()
    bowl[:, 2] += 2.0 * (bowl[:, 0] ** 2 + bowl[:, 1] ** 2)
    assert on_plane_share(bowl, ring, upright) is None
    assert on_plane_share(face[:2], ring, upright) is None and on_plane_share(face, ring[:10], upright) is None


def replace_z(points: np.ndarray, z: float) -> np.ndarray:
    out = points.copy()
    out[:, 2] = z
    return out


def test_patch_share_is_validated():
    with pytest.raises(ValueError):
        replace(ProjectionParams(), patch_share=0.0)


def test_over_a_generated_office_no_true_object_s_view_is_a_patch(tmp_path):
    """``benchmarks/bench_wall_patches.py`` on a small generated office: of the views that
    give an observation, the test drops none of a true object's and some of the false boxes
    (those on plain wall)."""
    from bomc_bt.officegen import OfficeParams, generate_office
    from tests.benchmark_scripts import load

    world = tmp_path / "office.yaml"
    generate_office(OfficeParams(width=16.0, height=12.0, seed=5, sessions=1), world)
    counts = load("bench_wall_patches").judged(world, 150, 5, 0.5)
    assert counts["true object", "kept off"] >= 10 and counts["true object", "dropped"] == 0
    assert counts["false box", "kept off"] >= 20 and counts["false box", "dropped"] >= 5
