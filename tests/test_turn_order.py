"""A stop's headings are turned through in the order that turns least, from the way the
robot drove in to the way it drives out."""

from __future__ import annotations

import math

import numpy as np
from test_coverage_plan import office

from bomc_bt.coverage_plan import turned_stops
from bomc_bt.geometry import Pose2D
from bomc_bt.planner import GridPlanner
from bomc_bt.turn_order import end_direction, turn_cost, turn_order

D = math.radians


def test_the_order_counts_the_turn_to_the_leg_that_leaves_the_stop():
    # nearest-first from the arrival turns 30, 120, 120 and 90 degrees; facing -90 before
    # 150 leaves the stop already facing (almost) the way out
    headings, arrive, depart = [D(30), D(150), D(-90)], 0.0, D(180)
    greedy = [D(30), D(150), D(-90)]
    best = turn_order(headings, arrive, depart)
    assert np.allclose(best, [D(30), D(-90), D(150)])
    assert abs(math.degrees(turn_cost(best, arrive, depart)) - 300.0) < 1e-6
    assert abs(math.degrees(turn_cost(greedy, arrive, depart)) - 360.0) < 1e-6


def test_the_end_directions_of_an_l_shaped_leg_are_its_own_not_the_straight_line():
    leg = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 2.0]])
    assert abs(end_direction(leg, at_start=True) - 0.0) < 1e-9
    assert abs(end_direction(leg, at_start=False) - math.pi / 2) < 1e-9
    assert end_direction(np.array([[1.0, 1.0], [1.0, 1.0]]), at_start=False) is None


def test_a_stop_entered_through_a_door_turns_first_to_the_heading_nearest_the_way_in():
    # the dock is in the corridor, the stop in the middle room: the straight line to it
    # points 25 degrees up, the robot arrives through the door heading north
    grid = office()
    planner = GridPlanner(grid)
    start = Pose2D(1.5, 3.0, 0.0)
    stop = np.array([[9.0, 6.5]])
    east, north_west = -0.2, 2.5
    (poses,) = turned_stops(planner, start, stop, [[east, north_west]])
    assert [p.yaw for p in poses] == [north_west, east]
    assert all((p.x, p.y) == (9.0, 6.5) for p in poses)
    # by the straight line the other order would have looked cheaper
    straight = math.atan2(6.5 - 3.0, 9.0 - 1.5)
    assert turn_order([east, north_west], straight) == [east, north_west]


def test_a_stop_without_headings_faces_the_way_it_arrived():
    grid = office()
    (poses,) = turned_stops(GridPlanner(grid), Pose2D(1.5, 3.0, 0.0), np.array([[9.0, 6.5]]), [[]])
    assert len(poses) == 1 and abs(poses[0].yaw - math.pi / 2) < 0.35
