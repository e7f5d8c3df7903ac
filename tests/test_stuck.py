"""Why a monitor pass stopped getting anywhere (bomc_bt/stuck.py), on a hand-made floor.

Two rooms joined by one doorway; the saved map has the doorway open. The scans are cast
in the world as it is now (an object dropped in the doorway after the map was built, or
not), so the diagnosis sees what a robot's lidar would.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bomc_bt.algorithm_params import RecoveryParams
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import LaserScan
from bomc_bt.stuck import BOXED_IN, CUT_OFF, LOST, STALE_OBSTACLES, StuckWatch, diagnose, diagnosis_line

RES = 0.05
RADIUS = 0.3


def two_rooms() -> OccupancyGrid:
    """10 x 3 m inside walls, a wall across at x = 5 m with a 1.2 m doorway (y 0.9 to 2.1)."""
    h, w = int(3.2 / RES), int(10.2 / RES)
    data = np.zeros((h, w), np.int8)
    data[:2, :] = data[-2:, :] = data[:, :2] = data[:, -2:] = 100
    col = int(5.1 / RES)
    data[:, col - 1:col + 1] = 100
    data[int(1.0 / RES):int(2.2 / RES), col - 1:col + 1] = 0
    return OccupancyGrid(data, RES, (-0.1, -0.1))


def with_box(grid: OccupancyGrid, x0: float, y0: float, x1: float, y1: float) -> OccupancyGrid:
    data = grid.data.copy()
    r0, c0 = grid.world_to_cell(x0, y0)
    r1, c1 = grid.world_to_cell(x1, y1)
    data[int(r0):int(r1) + 1, int(c0):int(c1) + 1] = 100
    return OccupancyGrid(data, grid.resolution, grid.origin)


def cast(world: OccupancyGrid, pose: Pose2D, beams: int = 360, max_range: float = 8.0) -> LaserScan:
    """A 360-degree scan of ``world`` from ``pose`` (first occupied cell along each ray)."""
    angles = -math.pi + np.arange(beams) * (2 * math.pi / beams)
    steps = np.arange(0.02, max_range, 0.02)
    xs = pose.x + np.cos(pose.yaw + angles)[:, None] * steps[None, :]
    ys = pose.y + np.sin(pose.yaw + angles)[:, None] * steps[None, :]
    rows, cols = world.world_to_cell(xs, ys)
    inside = world.in_bounds(rows, cols)
    hit = ~inside
    hit[inside] = world.data[rows[inside], cols[inside]] == 100
    first = np.where(hit.any(axis=1), hit.argmax(axis=1), -1)
    ranges = np.where(first >= 0, steps[np.maximum(first, 0)], np.inf).astype(np.float32)
    return LaserScan(0.0, -math.pi, 2 * math.pi / beams, ranges, max_range)


ROBOT = Pose2D(3.5, 1.5, 0.0)  # left room, 1.5 m from the doorway
BEYOND = [(8.0, 1.5)]  # the waypoints that failed, in the right room
PARAMS = RecoveryParams(min_agreement=0.4, wedged_distance=0.5)  # both checks on (off by default)


def test_an_object_dropped_in_the_only_doorway_boxes_the_robot_in():
    saved = two_rooms()
    now = with_box(saved, 4.9, 0.9, 5.3, 2.2)  # a cabinet in the doorway, after the map was built
    found = diagnose(saved, ROBOT, cast(now, ROBOT), BEYOND, [(8.0, 2.5), (9.0, 0.5)], PARAMS, RADIUS)
    assert found.cause == BOXED_IN
    assert "boxed in by objects the map does not have" in found.detail
    assert found.agreement > 0.6  # the pose is fine: most returns lie on the map's walls
    assert 0 < found.reachable_area_m2 < 16.0  # the left room, not the whole floor
    bx, by = found.blockers[0]
    assert 4.7 <= bx <= 5.4 and 0.8 <= by <= 2.3  # the nearest return off the map is the cabinet


def test_waypoints_behind_the_object_are_cut_off_when_others_are_reachable():
    saved = two_rooms()
    now = with_box(saved, 4.9, 0.9, 5.3, 2.2)
    found = diagnose(saved, ROBOT, cast(now, ROBOT), BEYOND, [(8.0, 2.5), (1.0, 2.5)], PARAMS, RADIUS)
    assert found.cause == CUT_OFF  # (1, 2.5) is in the robot's own room: nothing is wrong with the robot
    assert found.cut_off == []  # seen in the scan alone (a person is too): no waypoint is given up


def test_a_way_the_lidar_sees_open_means_the_obstacle_layer_is_stale():
    saved = two_rooms()
    found = diagnose(saved, ROBOT, cast(saved, ROBOT), BEYOND, [(8.0, 2.5)], PARAMS, RADIUS)
    assert found.cause == STALE_OBSTACLES
    assert found.blockers == []


def test_a_robot_that_did_not_move_while_waypoints_failed_is_wedged_not_misled_by_its_layer():
    saved = two_rooms()
    found = diagnose(saved, ROBOT, cast(saved, ROBOT), BEYOND, [(8.0, 2.5)], PARAMS, RADIUS, moved=0.2)
    assert found.cause == BOXED_IN and found.detail.startswith("wedged: the way looks open")
    moved_on = diagnose(saved, ROBOT, cast(saved, ROBOT), BEYOND, [(8.0, 2.5)], PARAMS, RADIUS, moved=6.0)
    assert moved_on.cause == STALE_OBSTACLES


def cells(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """(N, 2) centres of the cells of a box: what an obstacle layer marks for it."""
    xs, ys = np.meshgrid(np.arange(x0, x1, RES), np.arange(y0, y1, RES))
    return np.stack([xs.ravel(), ys.ravel()], axis=1)


def test_an_obstacle_marked_again_after_a_clear_cuts_off_waypoints_out_of_the_scans_sight():
    """A cabinet in the doorway, the robot round a corner from it: the scan sees only the
    map's walls. Before any clear that is a stale layer; once the layer was cleared and the
    lidar marked the cabinet again, the waypoints behind it are cut off, and which."""
    saved = two_rooms()
    cabinet = cells(4.9, 0.9, 5.3, 2.2)
    remaining = [(8.0, 2.5), (1.0, 2.5), (9.0, 0.5)]
    scan = cast(saved, ROBOT)  # nothing but walls in sight
    assert diagnose(saved, ROBOT, scan, BEYOND, remaining, PARAMS, RADIUS).cause == STALE_OBSTACLES
    found = diagnose(saved, ROBOT, scan, BEYOND, remaining, PARAMS, RADIUS, layer=cabinet)
    assert found.cause == CUT_OFF and found.cut_off == [0, 2]  # (1, 2.5) is in the robot's own room
    assert "marked again after the obstacle layer was cleared" in found.detail
    bx, by = found.blockers[0]
    assert 4.8 <= bx <= 5.4 and 0.8 <= by <= 2.3
    boxed = diagnose(saved, ROBOT, scan, BEYOND, [(8.0, 2.5), (9.0, 0.5)], PARAMS, RADIUS, layer=cabinet)
    assert boxed.cause == BOXED_IN and boxed.cut_off == []
    gone = diagnose(saved, ROBOT, scan, BEYOND, remaining, PARAMS, RADIUS, layer=cells(1.0, 0.2, 1.4, 0.6))
    assert gone.cause == STALE_OBSTACLES  # what the layer marks now does not stand in the way


def test_a_scan_that_does_not_fit_the_map_at_the_pose_means_the_pose_is_lost():
    saved = two_rooms()
    truth = Pose2D(8.0, 0.8, 0.0)
    wrong = Pose2D(3.0, 2.0, math.pi / 2)  # where the robot believes it is
    found = diagnose(saved, wrong, cast(saved, truth), BEYOND, [(8.0, 2.5)], PARAMS, RADIUS)
    assert found.cause == LOST and found.agreement < PARAMS.min_agreement
    assert diagnose(saved, None, None, BEYOND, [], PARAMS, RADIUS).cause == LOST


def test_a_robot_hemmed_in_by_things_new_since_the_map_is_not_lost():
    """Traced on a real bookstore map at 0.025 m (session 84): a cabinet moved and a chair
    brought in either side of the robot took most of its scan returns off the map's walls
    (38 %), so the pose read as lost; relocalization could not be confident among them either,
    and the pass ended early with a third of its floor unseen. A right pose lets no beam through
    what the map holds as occupied: objects new since stop beams short."""
    saved = two_rooms()
    now = with_box(with_box(with_box(saved, 3.0, 0.7, 4.2, 1.0), 3.0, 2.0, 4.2, 2.3), 3.9, 1.1, 4.2, 1.9)
    scan = cast(now, ROBOT)
    found = diagnose(saved, ROBOT, scan, BEYOND, [(8.0, 2.5)], PARAMS, RADIUS)
    assert found.agreement < PARAMS.min_agreement  # the old rule alone read this as lost
    assert found.cause != LOST
    shifted = Pose2D(ROBOT.x - 0.6, ROBOT.y, ROBOT.yaw)  # the same scan 0.6 m off: beams through the wall
    lost = diagnose(saved, shifted, scan, BEYOND, [(8.0, 2.5)], PARAMS, RADIUS)
    assert lost.cause == LOST and "pass through them" in lost.detail


def test_a_robot_pressed_against_the_object_still_finds_its_own_room():
    saved = two_rooms()
    now = with_box(saved, 4.9, 0.9, 5.3, 2.2)
    against = Pose2D(4.65, 1.5, 0.0)  # 0.25 m from the cabinet: its own cell is inside the margin
    found = diagnose(saved, against, cast(now, against), BEYOND, [(8.0, 2.5)], PARAMS, RADIUS)
    assert found.cause == BOXED_IN and found.reachable_area_m2 > 5.0


def test_a_robot_on_a_tables_lidar_shadow_reaches_what_the_planner_would():
    # the saved map holds the shadow a table cast while it was built as unknown; the robot
    # stands on its tip, two cells in (generated 36 x 28 m office, seed 7911, pass 8: it was
    # "boxed in, 0.0 of 0.0 m² within reach" and the pass ended there)
    saved = two_rooms()
    data = saved.data.copy()
    r0, c0 = saved.world_to_cell(3.4, 0.8)
    r1, c1 = saved.world_to_cell(4.4, 2.2)
    data[int(r0):int(r1) + 1, int(c0):int(c1) + 1] = -1
    shadowed = OccupancyGrid(data, RES, saved.origin)
    on_tip = Pose2D(3.45, 1.5, 0.0)
    found = diagnose(shadowed, on_tip, cast(saved, on_tip), BEYOND, [(8.0, 2.5)], PARAMS, RADIUS)
    assert found.cause == STALE_OBSTACLES  # the way to the right room is open
    assert found.reachable_area_m2 > 15.0  # both rooms, less the shadow


def test_the_watch_starts_a_round_after_missed_waypoints_in_a_row_or_no_progress():
    watch = StuckWatch(start=0.0)
    for i in range(2):
        watch.record(i, "missed", 10.0 * i, odometer=100.0 + i)
    assert watch.moved_since_first_miss(104.0) == 4.0
    assert watch.trigger(20.0, max_missed=3, no_progress_time=600.0) is None
    watch.record(2, "visited", 30.0)  # one reached: the count starts again
    for i in range(3, 6):
        watch.record(i, "missed", 10.0 * i)
    assert watch.trigger(60.0, 3, 600.0) == "3 waypoints missed in a row"
    watch.start_round(60.0, "3 waypoints missed in a row")
    assert watch.trigger(61.0, 3, 600.0) is None and watch.rounds == 1  # fresh evidence needed
    assert watch.trigger(700.0, 3, 600.0) == "no waypoint reached for 640 s"
    watch.act("back_out")
    watch.record(7, "detoured", 100.0)  # reached (round something): progress
    assert watch.rounds == 0 and watch.log[-1].result == "waypoint 8 reached 40 s later"
    assert watch.trigger(150.0, 0, 0.0) is None  # both triggers off


def test_the_diagnosis_line_names_the_place_the_rounds_and_the_cause():
    saved = two_rooms()
    now = with_box(saved, 4.9, 0.9, 5.3, 2.2)
    found = diagnose(saved, ROBOT, cast(now, ROBOT), BEYOND, [(8.0, 2.5)], PARAMS, RADIUS)
    watch = StuckWatch(0.0)
    for stamp in (100.0, 300.0):
        watch.start_round(stamp, "3 waypoints missed in a row")
        watch.act("clear_obstacles")
        watch.act("back_out")
    watch.start_round(500.0, "3 waypoints missed in a row")
    watch.act("end_pass")
    line = diagnosis_line(found, watch, "waypoint 9/40")
    assert line.startswith("pass ended early at waypoint 9/40 after 2 recovery round(s) (back_out, clear_obstacles): "
                           "boxed_in: boxed in by objects the map does not have")


@pytest.mark.parametrize("field,value", [("max_missed", -1), ("max_rounds", 0), ("min_agreement", 1.5),
                                         ("backout_distance", 0.0), ("no_progress_time", -1.0),
                                         ("stale_furniture_area", -1.0), ("floor_range", 0.0),
                                         ("floor_min_seen", 0), ("floor_min_seen", 1.5), ("floor_period", 0.0)])
def test_recovery_params_are_range_checked(field, value):
    with pytest.raises(ValueError, match=field):
        RecoveryParams(**{field: value})


def test_jambs_the_map_drew_thinner_are_no_stale_obstacles():
    """Real SLAM maps draw walls a cell thinner than the lidar sees them (willow, 0.1 m):
    returns 0.15 m off a jamb are "on the map" for the pose check, but they narrow a
    0.85 m doorway to 0.5 m, which the planner's 0.3 m radius cannot pass. The diagnosis
    called that stale obstacles, cleared the layer, which the next scan filled again, and
    the pass ended early; the way the lidar sees now is closed, so the robot is boxed in
    and backs out the way it came."""
    saved = two_rooms()
    saved = with_box(saved, 5.0, 0.0, 5.1, 1.05)  # the map's doorway: 0.8 m (y 1.1 to 1.9)
    saved = with_box(saved, 5.0, 1.95, 5.1, 3.0)
    now = with_box(saved, 5.0, 0.0, 5.1, 1.25)  # the jambs as the lidar sees them: 0.15-0.2 m thicker
    now = with_box(now, 5.0, 1.75, 5.1, 3.0)
    found = diagnose(saved, ROBOT, cast(now, ROBOT), BEYOND, BEYOND, PARAMS, RADIUS)
    assert found.cause == BOXED_IN, found
    assert "walls the lidar sees thicker than the map draws them" in found.detail
