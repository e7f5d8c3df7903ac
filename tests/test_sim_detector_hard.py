"""The ``hard`` detector preset: failures tied to places and views, each on a hand-built scene."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bomc_bt.cli import main
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.sim import detector_hard
from bomc_bt.sim.camera import CameraParams, SimCamera
from bomc_bt.sim.detector import SimDetector
from bomc_bt.sim.params import HardDetectorParams, SimDetectorParams
from bomc_bt.world import WorldObject

RES = 0.1
WORLD_KEY = 12345
QUIET = dict(false_positive_rate=0.0, confusion_rate=0.0)  # no per-frame noise from realistic's own FPs


def render(objects, pose: Pose2D, people=(), world_key=WORLD_KEY, scale=0.25):
    """A frame of an open floor (no walls) 40 m square around the origin, seen from ``pose``."""
    n = int(40.0 / RES)
    grid = OccupancyGrid(np.zeros((n, n), dtype=np.int8), RES, (-20.0, -20.0))
    cam = SimCamera(CameraParams(scale=scale, depth_noise=0.0), seed=0)
    frame = cam.render(np.zeros((n, n), dtype=bool), grid, 2.5, list(objects), [], list(people), pose, pose, 0.0)
    frame.world_key = world_key
    return frame


def facing(target, bearing: float, distance: float) -> Pose2D:
    """The pose ``distance`` from ``target`` in direction ``bearing`` (rad), looking at it."""
    x, y = target[0] + distance * math.cos(bearing), target[1] + distance * math.sin(bearing)
    return Pose2D(x, y, math.atan2(target[1] - y, target[0] - x))


def hits(frame, params, instance, category, stamps=60, seed=5):
    """Frames (of ``stamps``) in which the instance was reported as ``category``."""
    det = SimDetector(params, seed=seed)
    count = 0
    for k in range(stamps):
        frame.stamp = k * 0.5
        found = det.segment(frame, det.detect(frame, [category]))
        count += any(d.category == category and np.any(d.mask & (frame.instances == instance)) for d in found)
    return count


# -- look-alikes ---------------------------------------------------------------------------------
LOOKALIKES = HardDetectorParams(lookalike_cell=20.0, lookalike_density=1.0, dark_share=0.0)


def a_lookalike():
    """The look-alike of the 20 m square at the origin, for a world key that puts it mid-square."""
    everywhere = HardDetectorParams(lookalike_cell=20.0, lookalike_density=1.0, lookalike_sector_share=1.0,
                                    lookalike_range=30.0)
    for key in range(WORLD_KEY, WORLD_KEY + 200):
        for site, _ in detector_hard.lookalike_sites(key, np.array([10.0, 10.0]), everywhere, ["table"]):
            if 6.0 <= site[0] <= 14.0 and 6.0 <= site[1] <= 14.0:
                return key, site
    raise AssertionError("no mid-square look-alike")


def lookalikes_seen(frame, seed, stamps=10):
    """Per stamp, the map points (mask centroids on the floor) of boxes on no object."""
    det = SimDetector(SimDetectorParams(preset="hard", hard=LOOKALIKES, **QUIET), seed=seed)
    points = []
    for k in range(stamps):
        frame.stamp = k * 0.5
        for d in det.segment(frame, det.detect(frame, ["table"])):
            if not np.any(d.mask & (frame.instances > 0)):
                points.append(mask_centroid(frame, d.mask))
    return points


def mask_centroid(frame, mask):
    rows, cols = np.nonzero(mask & np.isfinite(frame.depth))
    z = frame.depth[rows, cols]
    K = frame.K
    optical = np.stack([(cols - K[0, 2]) * z / K[0, 0], (rows - K[1, 2]) * z / K[1, 1], z, np.ones_like(z)])
    return np.median((detector_hard.camera_pose(frame) @ optical)[:2], axis=1)


def test_a_lookalike_comes_back_from_the_same_sector_in_every_pass_and_never_from_another():
    key, site = a_lookalike()
    sectors = LOOKALIKES.lookalike_sectors
    centres = [-math.pi + (k + 0.5) * 2.0 * math.pi / sectors for k in range(sectors)]
    active = [k for k, b in enumerate(centres)
              if detector_hard.lookalike_sites(key, np.asarray(facing(site, b, 2.5).xy), LOOKALIKES, ["table"])]
    assert 0 < len(active) < sectors
    k = active[0]
    far = max((j for j in range(sectors) if j not in active), key=lambda j: min(abs(j - k), sectors - abs(j - k)))
    first = lookalikes_seen(render([], facing(site, centres[k], 2.5), world_key=key), seed=1)
    # Another pass (another seed), from a similar pose in the same sector: the same false object.
    again = lookalikes_seen(render([], facing(site, centres[k] + math.radians(12.0), 3.0), world_key=key), seed=2)
    other_side = lookalikes_seen(render([], facing(site, centres[far], 2.5), world_key=key), seed=1)
    assert len(first) >= 5 and len(again) >= 5  # lookalike_rate 0.8 of 10 frames
    assert other_side == []
    for point in first + again:
        assert np.hypot(*(point - site)) < 0.6
    # Another world has its look-alikes elsewhere.
    everywhere = HardDetectorParams(lookalike_cell=20.0, lookalike_density=1.0, lookalike_sector_share=1.0,
                                    lookalike_range=30.0)
    elsewhere = detector_hard.lookalike_sites(key + 1, np.array([10.0, 10.0]), everywhere, ["table"])
    assert all(np.hypot(*(other - site)) > 0.6 for other, _ in elsewhere)


def test_a_lookalike_hidden_behind_an_object_is_not_reported():
    key, site = a_lookalike()
    sectors = LOOKALIKES.lookalike_sectors
    bearing = next(b for b in (-math.pi + (k + 0.5) * 2.0 * math.pi / sectors for k in range(sectors))
                   if detector_hard.lookalike_sites(key, np.asarray(facing(site, b, 2.5).xy), LOOKALIKES, ["table"]))
    pose = facing(site, bearing, 2.5)
    between = (site[0] + 1.0 * math.cos(bearing), site[1] + 1.0 * math.sin(bearing))
    screen = WorldObject("screen", "sofa", (between[0], between[1], 1.0), (1.5, 1.5, 2.0), yaw=bearing)
    assert lookalikes_seen(render([screen], pose, world_key=key), seed=1) == []


# -- grazing angles ----------------------------------------------------------------------------------
DOOR = WorldObject("door", "door", (0.0, 0.0, 1.0), (0.9, 0.06, 2.0), yaw=0.0)  # its normal is the y axis
NO_PLACES = HardDetectorParams(lookalike_density=0.0, dark_share=0.0)


def test_a_door_is_missed_more_edge_on_in_a_narrow_corridor_than_head_on():
    lateral, along = 1.0, 3.4  # a 2 m corridor; the door on its side wall, 3.4 m ahead
    distance = math.hypot(lateral, along)
    grazing = render([DOOR], Pose2D(-along, -lateral, math.atan2(lateral, along)))
    head_on = render([DOOR], Pose2D(0.0, -distance, math.pi / 2))
    points = detector_hard.candidate_points(grazing, 1)
    angle, seen_lateral = detector_hard.grazing_angle(points[:, :2], np.array([-along, -lateral]))
    assert angle == pytest.approx(math.degrees(math.atan2(along, lateral)), abs=4.0)
    assert seen_lateral == pytest.approx(lateral, abs=0.1)
    hard = SimDetectorParams(preset="hard", hard=NO_PLACES, **QUIET)
    realistic = SimDetectorParams(**QUIET)
    n = 100
    head_on_hits = hits(head_on, hard, 1, "door", n)
    assert head_on_hits > 0.65 * n  # realistic's own misses at 3.5 m: about a fifth
    assert hits(grazing, hard, 1, "door", n) < head_on_hits - 0.25 * n
    assert hits(grazing, realistic, 1, "door", n) > 0.65 * n  # the same distance, no grazing term
    # The same angle seen from across a wide hall costs nothing; a chair is not a flat object.
    assert detector_hard.grazing_miss(74.0, 1.0, NO_PLACES) > 0.4
    assert detector_hard.grazing_miss(74.0, 2 * NO_PLACES.grazing_lateral, NO_PLACES) == 0.0
    assert detector_hard.grazing_miss(NO_PLACES.grazing_start_deg, 1.0, NO_PLACES) == 0.0


# -- dark zones -------------------------------------------------------------------------------------
def dark_and_bright_spots(key, p):
    """A point deep inside a dark zone and one far from any, on a 0.5 m lattice."""
    xs = np.arange(-12.0, 12.0, 0.5)
    points = np.stack(np.meshgrid(xs, xs), axis=-1).reshape(-1, 2)
    ring = np.array([[0.0, 0.0], [0.6, 0.0], [-0.6, 0.0], [0.0, 0.6], [0.0, -0.6]])
    around = (points[:, None, :] + ring[None, :, :]).reshape(-1, 2)
    dark = detector_hard.in_dark_zone(key, around, p).reshape(len(points), len(ring)).all(axis=1)
    wide = (points[:, None, :] + 2.0 * ring[None, :, :]).reshape(-1, 2)
    bright = ~detector_hard.in_dark_zone(key, wide, p).reshape(len(points), len(ring)).any(axis=1)
    assert dark.any() and bright.any()
    return points[np.flatnonzero(dark)[0]], points[np.flatnonzero(bright)[0]]


def test_objects_in_a_dark_zone_are_missed_more_and_score_lower():
    p = HardDetectorParams(lookalike_density=0.0)
    dark, bright = dark_and_bright_spots(WORLD_KEY, p)
    params = SimDetectorParams(preset="hard", hard=p, **QUIET)
    rates = {}
    for name, spot in (("dark", dark), ("bright", bright)):
        chair = WorldObject("c", "chair", (spot[0], spot[1], 0.45), (0.5, 0.5, 0.9))
        frame = render([chair], facing(spot, 0.3, 2.5))
        rates[name] = hits(frame, params, 1, "chair", 120)
    assert rates["bright"] > 0.8 * 120
    assert rates["dark"] < rates["bright"] - 0.2 * 120
    # Dark zones belong to the world: another key puts them elsewhere.
    inside = [detector_hard.in_dark_zone(k, dark, p)[0] for k in range(WORLD_KEY, WORLD_KEY + 20)]
    assert 0 < sum(inside) < len(inside)


# -- people ------------------------------------------------------------------------------------------
def test_an_object_behind_a_walking_person_is_not_detected_and_a_half_hidden_one_is_cut():
    chair = WorldObject("c", "chair", (3.0, 0.0, 0.45), (0.5, 0.5, 0.9))
    pose = Pose2D(0.0, 0.0, 0.0)
    params = SimDetectorParams(preset="hard", hard=NO_PLACES, mask_bleed=0.0, box_jitter=0.0, **QUIET)
    det = SimDetector(params, seed=3)
    seen = []
    for k, y in enumerate(np.linspace(-1.5, 1.5, 31)):  # a person crossing the line of sight 1.5 m ahead
        frame = render([chair], pose, people=[(1.5, float(y))])
        frame.stamp = k * 0.5
        chair_pixels = frame.instances == 1
        found = [d for d in det.segment(frame, det.detect(frame, ["chair"])) if d.category == "chair"]
        for d in found:
            assert not np.any(d.mask & ~chair_pixels)  # never a pixel of the person
        seen.append((abs(y), int(chair_pixels.sum()), bool(found)))
    full = max(pixels for _, pixels, _ in seen)
    assert not any(found for y, _, found in seen if y < 0.1)  # right in front: hidden, not reported
    assert all(pixels < 0.2 * full for y, pixels, _ in seen if y < 0.1)
    past = [found for y, _, found in seen if y > 1.05]
    assert sum(past) >= 0.6 * len(past)  # walked past: seen again


# -- presets and config ---------------------------------------------------------------------------
def test_hard_with_its_failures_off_is_realistic_frame_for_frame():
    chair = WorldObject("c", "chair", (3.0, 0.4, 0.45), (0.5, 0.5, 0.9))
    door = WorldObject("d", "door", (3.5, -1.0, 1.0), (0.9, 0.06, 2.0), yaw=0.3)
    frame = render([chair, door], Pose2D(0.0, 0.0, 0.0))
    off = HardDetectorParams(lookalike_density=0.0, dark_share=0.0, grazing_miss=0.0)
    realistic, hard = SimDetector(SimDetectorParams(), seed=9), SimDetector(SimDetectorParams(preset="hard", hard=off),
                                                                            seed=9)
    for k in range(40):
        frame.stamp = k * 0.5
        a = realistic.segment(frame, realistic.detect(frame, ["chair", "door"]))
        b = hard.segment(frame, hard.detect(frame, ["chair", "door"]))
        assert [(d.category, d.box, d.score) for d in a] == [(d.category, d.box, d.score) for d in b]
        assert all(np.array_equal(x.mask, y.mask) for x, y in zip(a, b, strict=True))


@pytest.mark.parametrize("text, says", [
    ("detector: {preset: harder}\n", "detector.preset"),
    ("detector: {hard: {dark_share: 1.5}}\n", "detector.hard: dark_share must be in [0, 1]"),
    ("detector: {hard: {lookalike_sectors: 0}}\n", "detector.hard: lookalike_sectors must be 1 to 360"),
    ("detector: {hard: {grazing_start_deg: 95}}\n", "detector.hard: grazing_start_deg must be in [0, 90)"),
    ("detector: {hard: {dark_radius: 9.0, dark_cell: 8.0}}\n", "detector.hard: dark_radius must be in [0, dark_cell]"),
    ("detector: {hard: {lookalike_range: -1}}\n", "detector.hard: lookalike_range must be in (0, 1000] m"),
    ("detector: {hard: {grazing_categories: door}}\n", "detector.hard.grazing_categories"),
])
def test_bad_hard_parameters_are_one_line_naming_file_and_field(tmp_path, capsys, text, says):
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    assert main(["config", "--config", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"{bad}: {says}" in err, err


def test_the_hard_preset_loads_from_a_config_file(tmp_path, capsys):
    good = tmp_path / "hard.yaml"
    good.write_text("detector:\n  preset: hard\n  hard: {lookalike_density: 0.2, grazing_categories: [door, window]}\n")
    assert main(["config", "--config", str(good)]) == 0
    out = capsys.readouterr().out
    assert "preset: hard" in out and "lookalike_density: 0.2" in out and "window" in out


def test_generated_offices_of_one_name_hold_their_lookalikes_in_different_places(tmp_path):
    """Every office the generator writes to ``office.yaml`` is named ``office``: keyed by the
    name alone, all of them shared one layout of look-alikes and dark zones."""
    from bomc_bt.officegen import OfficeParams, generate_office
    from bomc_bt.world import load_world

    worlds = [generate_office(OfficeParams(width=30, height=20, seed=seed), tmp_path / str(seed) / "office.yaml")
              for seed in (3, 4)]
    assert worlds[0].name == worlds[1].name == "office"
    assert worlds[0].key != worlds[1].key
    assert load_world(tmp_path / "3" / "office.yaml").key == worlds[0].key  # the same world, the same places
    p = HardDetectorParams(lookalike_sector_share=1.0, lookalike_range=40.0)
    centre = np.array([15.0, 10.0])
    sites = [{tuple(np.round(s, 2)) for s, _ in detector_hard.lookalike_sites(w.key, centre, p, ["table"])}
             for w in worlds]
    assert sites[0] and sites[1] and sites[0] != sites[1]
    dark = [detector_hard.in_dark_zone(w.key, np.stack(np.meshgrid(np.arange(0, 30.0), np.arange(0, 20.0)), -1)
                                       .reshape(-1, 2), p) for w in worlds]
    assert not np.array_equal(dark[0], dark[1])
