"""The simulated SLAM mapper on walls seen at grazing angles (issue 16, 7.7 of docs/exploration.md).

A robot driving along a wall sees most of it at a few degrees of incidence: neighbouring
beams end centimetres apart near the robot and tens of centimetres apart farther on. What
GMapping would map is the wall's cells occupied where beams ended and never cleared, since
no beam passes through a wall; what lies behind the wall stays unknown. A mapper that
carves free space past the returns opens a gap through which exploration values the
outside of the building as gain and whose frontier never closes.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from bomc_bt.sim.lidar import Lidar, LidarParams
from bomc_bt.sim.mapper import Mapper
from bomc_bt.sim.scene import Scene
from bomc_bt.world import World

RES = 0.05
WIDTH, HEIGHT = 14.0, 6.0


def hall(wall: np.ndarray) -> World:
    """A 14 x 6 m hall with a border wall and ``wall`` (cell mask) inside it."""
    data = np.full(wall.shape, FREE, dtype=np.int8)
    data[:2] = data[-2:] = OCCUPIED
    data[:, :2] = data[:, -2:] = OCCUPIED
    data[wall] = OCCUPIED
    grid = OccupancyGrid(data, RES, (0.0, 0.0))
    return World("hall", Path("hall.yaml"), Path("hall-map.yaml"), grid, Pose2D(1.0, 1.0, 0.0), 2.5, {}, {}, [])


def centres() -> tuple[np.ndarray, np.ndarray]:
    rows, cols = np.mgrid[0:int(HEIGHT / RES), 0:int(WIDTH / RES)]
    return (cols + 0.5) * RES, (rows + 0.5) * RES


def wall_line(y0: float, slope: float, thickness: float = 0.1) -> np.ndarray:
    """Cells whose centre lies within ``thickness`` above the line y = y0 + slope x."""
    x, y = centres()
    above = y - (y0 + slope * x)
    return (above >= 0.0) & (above < thickness)


def drive_along(world: World, y0: float, slope: float, side: float, lidar: Lidar) -> np.ndarray:
    """Map from ten poses 0.3 m from the line (``side`` -1: below it, +1: above), heading along it."""
    scene, mapper = Scene(world, {}, []), Mapper.like(world.grid)
    rng = np.random.default_rng(7)
    normal = np.array([-slope, 1.0]) / np.hypot(slope, 1.0)
    for k, x in enumerate(np.arange(0.6, 3.1, 0.25)):
        on_line = np.array([x, y0 + slope * x])
        px, py = on_line + side * (0.3 + (0.1 if side > 0 else 0.0)) * normal
        pose = Pose2D(float(px), float(py), float(np.arctan(slope)))
        mapper.integrate(lidar.scan(pose, scene.lidar_field, 0.1 * k, rng), pose)
    return mapper.grid().data


CASES = {  # name: (y0 of the wall's lower face, slope, robot side)
    "wall on the +y side": (2.0, 0.0, -1.0),
    "wall on the -y side": (2.0, 0.0, +1.0),
    "diagonal wall on the +y side": (1.5, 0.15, -1.0),
    "diagonal wall on the -y side": (3.0, -0.15, +1.0),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_wall_seen_at_a_grazing_angle_stays_a_wall_and_hides_what_is_behind_it(case):
    y0, slope, side = CASES[case]
    wall = wall_line(y0, slope)
    world = hall(wall)
    live = drive_along(world, y0, slope, side, Lidar(LidarParams()))
    x, y = centres()
    above = y - (y0 + slope * x)
    far = (x > 4.0) & (x < 12.0)  # 1-9 m ahead of the robot: 2-15 degrees of incidence
    face = wall & far & ((above < RES) if side < 0 else (above >= 0.1 - RES))
    assert face.sum() > 100
    # No cell of the wall is mapped free; most of its face is mapped occupied.
    assert (live[wall & far] == FREE).sum() == 0
    assert (live[face] == OCCUPIED).mean() > 0.25
    # Nothing behind the wall was seen.
    behind = far & ((above >= 0.1) if side < 0 else (above < 0.0))
    behind &= ~world.grid.occupied_mask()
    assert (live[behind] == UNKNOWN).all()
    # The floor the robot drove along is mapped up to the wall.
    gap = (above < 0.0) & (above > -0.3) if side < 0 else (above >= 0.1) & (above < 0.4)
    near = gap & (x > 1.5) & (x < 6.0)
    assert (live[near] == FREE).mean() > 0.9


def test_integrating_a_building_scale_scan_takes_milliseconds():
    """The mapper runs every 0.25 m of a build; a 25 m scan in an open 93 x 90 m floor
    must stay cheap (a few ms; 50 ms allows for a loaded machine)."""
    data = np.full((1800, 1860), FREE, dtype=np.int8)
    data[:2] = data[-2:] = OCCUPIED
    data[:, :2] = data[:, -2:] = OCCUPIED
    for k in range(1, 9):  # pillars to give the scan an outline
        data[200 * k:200 * k + 10, 100:1800:150] = OCCUPIED
    grid = OccupancyGrid(data, RES, (0.0, 0.0))
    world = World("floor", Path("f.yaml"), Path("f-map.yaml"), grid, Pose2D(46.0, 45.0, 0.0), 2.5, {}, {}, [])
    scene, mapper, lidar = Scene(world, {}, []), Mapper.like(grid), Lidar(LidarParams())
    scans = [(Pose2D(46.0 + 0.25 * k, 45.0, 0.3 * k), None) for k in range(10)]
    scans = [(pose, lidar.scan(pose, scene.lidar_field, 0.0)) for pose, _ in scans]
    started = time.perf_counter()
    for pose, scan in scans:
        mapper.integrate(scan, pose)
    per_scan = (time.perf_counter() - started) / len(scans)
    assert per_scan < 0.05
    assert mapper.grid().free_area() > 1000.0
