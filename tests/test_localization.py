"""Relocalization by scan matching: accuracy from rough hints, global recovery, refusals.

Scans are ray-marched here (independently of the simulator's lidar) in the same map the
matcher uses, with the Fetch-like geometry the simulator uses (220 deg, 25 m) and with a
360 deg / 10 m one, range noise, and short "people/clutter" readings.
"""

from __future__ import annotations

import math
import zlib
from pathlib import Path

import numpy as np
import pytest
from shared_data import require_shared, shared_path

from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.grid import OCCUPIED, OccupancyGrid, load_map
from bomc_bt.localization import RelocalizationParams, ScanMatcher
from bomc_bt.params import from_mapping
from bomc_bt.robot import LaserScan

LAB = shared_path("worlds/lab-b-map.yaml")
OFFICE = shared_path("worlds/office-s-map.yaml")
HOUSE = shared_path("maps/small_house.yaml")

_MAPS: dict[str, OccupancyGrid] = {}
_MATCHERS: dict[str, ScanMatcher] = {}


def matcher(path: str) -> ScanMatcher:
    require_shared(path)
    if path not in _MATCHERS:
        _MAPS[path] = load_map(path)
        _MATCHERS[path] = ScanMatcher(_MAPS[path], RelocalizationParams())
    return _MATCHERS[path]


def ray_scan(grid: OccupancyGrid, pose: Pose2D, fov_deg: float = 220.0, beams: int = 440,
             range_max: float = 25.0, noise: float = 0.0, clutter: float = 0.0, seed: int = 0) -> LaserScan:
    """March every beam in quarter-cell steps to the first occupied cell (inf if none)."""
    rng = np.random.default_rng(seed)
    fov = math.radians(fov_deg)
    angle_min = -fov / 2 if fov_deg < 360 else -math.pi
    inc = fov / (beams - 1) if fov_deg < 360 else 2 * math.pi / beams
    rel = angle_min + inc * np.arange(beams)
    step = grid.resolution / 4
    t = np.arange(step, range_max, step)
    a = pose.yaw + rel
    rows, cols = grid.world_to_cell(pose.x + np.cos(a)[:, None] * t, pose.y + np.sin(a)[:, None] * t)
    inside = grid.in_bounds(rows, cols)
    occ = np.zeros(rows.shape, dtype=bool)
    occ[inside] = grid.data[rows[inside], cols[inside]] >= 50
    ranges = np.where(occ.any(axis=1), t[occ.argmax(axis=1)], np.inf)
    if noise:
        ranges = ranges + rng.normal(0.0, noise, beams)
    if clutter:
        hit = rng.random(beams) < clutter  # people and clutter: short readings
        ranges[hit] = rng.uniform(0.3, 1.0, hit.sum()) * np.minimum(ranges[hit], 3.0)
    return LaserScan(0.0, angle_min, inc, ranges.astype(np.float32), range_max)


def random_free_pose(m: ScanMatcher, rng: np.random.Generator, clearance: float = 0.3) -> Pose2D:
    grid = m.grid
    cells = np.argwhere(grid.free_mask() & (m.likelihood.surface_distance > clearance))
    r, c = cells[rng.integers(len(cells))]
    x, y = grid.cell_to_world(r, c)
    return Pose2D(float(x) + rng.uniform(-0.02, 0.02), float(y) + rng.uniform(-0.02, 0.02),
                  rng.uniform(-math.pi, math.pi))


def perturbed(truth: Pose2D, rng: np.random.Generator, dist: float = 1.0,
              angle: float = math.radians(30)) -> Pose2D:
    d, th = rng.uniform(0.0, dist), rng.uniform(0.0, 2 * math.pi)
    yaw = truth.yaw + rng.uniform(-angle, angle)
    return Pose2D(truth.x + d * math.cos(th), truth.y + d * math.sin(th), yaw)


def assert_close(est: Pose2D, truth: Pose2D, lin: float = 0.1, ang: float = math.radians(3)) -> None:
    assert est.distance_to(truth) <= lin, (est, truth)
    assert abs(wrap_angle(est.yaw - truth.yaw)) <= ang, (est, truth)


@pytest.mark.parametrize("path", [LAB, OFFICE, HOUSE])
@pytest.mark.parametrize("geometry", [dict(fov_deg=220.0, beams=440, range_max=25.0),
                                      dict(fov_deg=360.0, beams=360, range_max=10.0)])
def test_rough_hint_converges_to_truth(path, geometry):
    """Hints up to 1 m and 30 deg off; noisy scans with 10% short readings."""
    m = matcher(path)
    rng = np.random.default_rng([zlib.crc32(Path(path).name.encode()), geometry["beams"]])  # not where shared/ is
    for i in range(8):
        truth = random_free_pose(m, rng)
        scan = ray_scan(m.grid, truth, noise=0.02, clutter=0.1, seed=i, **geometry)
        result = m.match(scan, perturbed(truth, rng))
        assert result.confident, result.message
        assert_close(result.pose, truth)
        assert result.score > 0.7


@pytest.mark.parametrize("path,poses", [
    # Lab B is a rectangle with one wall stub: poses that see the stub are unique.
    (LAB, [Pose2D(2.0, 5.0, 1.2), Pose2D(4.5, 8.0, -2.5), Pose2D(6.0, 6.0, 3.0)]),
    # Office S repeats its rooms; corridors see the doors, whose pattern differs.
    (OFFICE, [Pose2D(20.0, 7.5, 0.5), Pose2D(30.0, 22.5, 3.1)]),
])
def test_global_search_recovers_pose_without_hint(path, poses):
    m = matcher(path)
    for i, truth in enumerate(poses):
        scan = ray_scan(m.grid, truth, noise=0.02, clutter=0.05, seed=10 + i)
        result = m.match(scan, None)
        assert result.confident, result.message
        assert_close(result.pose, truth)
        # global_search=True ignores a (wrong) hint
        result = m.match(scan, Pose2D(truth.x + 5.0, truth.y, truth.yaw), global_search=True)
        assert_close(result.pose, truth)


def test_symmetric_room_is_ambiguous_globally():
    """A plain rectangle looks the same turned 180 deg: never confident without a hint."""
    data = np.zeros((120, 200), dtype=np.int8)
    data[:3, :] = data[-3:, :] = data[:, :3] = data[:, -3:] = OCCUPIED
    m = ScanMatcher(OccupancyGrid(data, 0.05), RelocalizationParams())
    truth = Pose2D(3.0, 2.0, 0.4)
    result = m.match(ray_scan(m.grid, truth, fov_deg=360, beams=360, range_max=25.0), None)
    assert not result.confident
    assert "ambiguous" in result.message
    # ... but with a hint near the truth the mirror pose is outside the window
    assert m.match(ray_scan(m.grid, truth, fov_deg=360, beams=360, range_max=25.0),
                   perturbed(truth, np.random.default_rng(0))).confident


def test_featureless_corridor_is_not_confident():
    """Two long parallel walls with the ends out of range: position along them is unknown."""
    data = np.zeros((60, 1200), dtype=np.int8)
    data[10:12, :] = data[48:50, :] = OCCUPIED
    m = ScanMatcher(OccupancyGrid(data, 0.05), RelocalizationParams())
    truth = Pose2D(30.0, 1.5, 0.1)
    scan = ray_scan(m.grid, truth, fov_deg=360, beams=360, range_max=10.0, noise=0.02, seed=3)
    result = m.match(scan, Pose2D(30.5, 1.6, 0.2))
    assert not result.confident
    assert abs(result.pose.y - truth.y) < 0.1  # across the corridor it is still well determined


def test_scan_from_another_building_is_not_confident():
    house = matcher(HOUSE)
    rng = np.random.default_rng(5)
    for path in (LAB, OFFICE):
        m = matcher(path)
        for i in range(3):
            scan = ray_scan(house.grid, random_free_pose(house, rng), noise=0.02, seed=i)
            hint = random_free_pose(m, rng)
            assert not m.match(scan, hint).confident


def test_empty_scan_and_hint_outside_map_are_refused():
    m = matcher(LAB)
    empty = LaserScan(0.0, -1.0, 0.01, np.full(200, np.inf, dtype=np.float32), 25.0)
    result = m.match(empty, Pose2D(2.0, 2.0, 0.0))
    assert not result.confident and "valid beams" in result.message
    scan = ray_scan(m.grid, Pose2D(2.0, 5.0, 1.2))
    far_away = m.match(scan, Pose2D(500.0, 500.0, 0.0))
    assert not far_away.confident


def test_noise_and_clutter_robustness_on_real_map():
    """Heavier clutter (25% short readings) still matches from a rough hint."""
    m = matcher(HOUSE)
    rng = np.random.default_rng(42)
    for i in range(4):
        truth = random_free_pose(m, rng)
        scan = ray_scan(m.grid, truth, noise=0.02, clutter=0.25, seed=i)
        result = m.match(scan, perturbed(truth, rng))
        assert_close(result.pose, truth)


def test_a_match_depends_only_on_its_scan_and_hint():
    """A matcher that has answered other queries gives the answer a fresh one gives: relocalization
    keeps no state between calls, so a retried Relocalize leaf sees the same result."""
    used = matcher(OFFICE)
    truth = Pose2D(14.0, 10.0, 0.7)
    scan = ray_scan(used.grid, truth, noise=0.02, clutter=0.1, seed=1)
    hint = Pose2D(14.6, 9.4, 1.1)
    used.match(ray_scan(used.grid, Pose2D(30.0, 22.5, 3.1), seed=2), Pose2D(29.0, 22.0, 2.5))
    fresh = ScanMatcher(load_map(OFFICE), RelocalizationParams())
    first, second = used.match(scan, hint), fresh.match(scan, hint)
    assert first == second
    assert math.hypot(first.pose.x - truth.x, first.pose.y - truth.y) < 0.2


def test_params_from_yaml_are_validated():
    p = from_mapping(RelocalizationParams, {"search_radius": 2, "min_score": 0.7}, "cfg.yaml",
                     "relocalization")
    assert p.search_radius == 2.0 and p.min_score == 0.7
    with pytest.raises(BomcError, match="cfg.yaml: relocalization"):
        from_mapping(RelocalizationParams, {"sigma": -1.0}, "cfg.yaml", "relocalization")
    with pytest.raises(BomcError, match="serch_radius"):
        from_mapping(RelocalizationParams, {"serch_radius": 1.0}, "cfg.yaml", "relocalization")


def _furnished_room(boxes: list[tuple[float, float]]) -> OccupancyGrid:
    """A 12 x 10 m room (0.05 m cells) with a 0.6 m square of furniture at each (x, y)."""
    data = np.zeros((200, 240), dtype=np.int8)
    data[:3, :] = data[-3:, :] = data[:, :3] = data[:, -3:] = OCCUPIED
    data[100:103, :90] = OCCUPIED  # a partition, so the room is not symmetric
    for x, y in boxes:
        r, c = int(y / 0.05), int(x / 0.05)
        data[r - 6:r + 6, c - 6:c + 6] = OCCUPIED
    return OccupancyGrid(data, 0.05)


def test_a_floor_whose_furniture_changed_since_the_build_still_relocalizes():
    """Days after the build, the furniture around the dock has been taken away and other pieces
    brought in: a fifth of the beams stop short on things the map lacks and others pass where the
    map has furniture. The pose is still the only one that fits, so it is trusted; judged as a
    map-perfect scan it would be refused (a pass that cannot start)."""
    built = _furnished_room([(2.0, 2.0), (4.0, 7.5), (9.5, 8.0), (10.0, 2.5), (7.0, 4.0)])
    now = _furnished_room([(3.0, 3.5), (5.0, 6.5), (8.0, 6.0), (9.0, 3.5), (4.5, 2.5), (7.5, 8.5),
                           (2.5, 8.0), (10.5, 6.0)])
    truth = Pose2D(6.0, 5.0, 0.3)
    scan = ray_scan(now, truth, fov_deg=360, beams=720, range_max=25.0, noise=0.01, seed=4)
    hint = Pose2D(6.4, 4.7, 0.5)
    result = ScanMatcher(built, RelocalizationParams()).match(scan, hint)
    assert result.confident, result.message
    assert_close(result.pose, truth)
    assert "things the map lacks" in result.message
    as_if_unchanged = RelocalizationParams(change_gap=1e9, furniture_area=0.0)
    assert not ScanMatcher(built, as_if_unchanged).match(scan, hint).confident


def test_a_floor_changed_beyond_recognition_is_not_trusted():
    """When most beams end on things the map lacks, too little is left to judge the pose by."""
    built = _furnished_room([])
    now = _furnished_room([(x, y) for x in np.arange(4.5, 8.0, 0.9) for y in (4.0, 6.0)]
                          + [(x, 5.0) for x in (4.5, 7.7)])
    truth = Pose2D(6.1, 5.0, 0.0)
    scan = ray_scan(now, truth, fov_deg=360, beams=720, range_max=25.0, seed=5)
    result = ScanMatcher(built, RelocalizationParams()).match(scan, Pose2D(6.3, 5.2, 0.1))
    assert not result.confident
    assert "too much has changed" in result.message
