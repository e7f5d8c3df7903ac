"""The gain explorer and the goal placement every explorer shares, on scripted grids:
safe standoff goals, visible-unknown gain, path distance, the remaining-gain stop, and
the frontier-cell test that says a goal's frontier was mapped."""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.exploration.dwfe import ExplorationParams
from bomc_bt.exploration.explorer import DONE, EXPLORING, Explorer, still_open
from bomc_bt.exploration.gain import visible_unknown
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from bomc_bt.planner import GridPlanner, PlannerParams

RES = 0.05


def grid_of(data: np.ndarray) -> OccupancyGrid:
    return OccupancyGrid(data.astype(np.int8), RES, (0.0, 0.0))


def cell(m: float) -> int:
    return int(round(m / RES))


def two_rooms_and_a_pocket() -> np.ndarray:
    """A 4 x 3 m room (x 0.5-4.5, y 0.5-3.5) whose east wall has a doorway into an
    unknown room, and a wall-bounded 0.6 x 0.5 m unknown pocket in its north-west corner
    (the inside of a cabinet the lidar never sees)."""
    data = np.full((cell(5.0), cell(10.0)), OCCUPIED, np.int8)
    data[cell(0.5):cell(3.5), cell(0.5):cell(4.5)] = FREE
    data[cell(1.5):cell(2.5), cell(4.5):cell(4.7)] = FREE  # 1 m doorway through a 0.2 m wall
    data[cell(0.5):cell(4.5), cell(4.7):cell(9.5)] = UNKNOWN  # the room beyond
    data[cell(2.9):cell(3.5), cell(0.5):cell(1.0)] = UNKNOWN  # the pocket, walls on three sides
    data[cell(2.85):cell(2.9), cell(0.5):cell(1.0)] = FREE
    return data


def test_standoff_goals_keep_the_robots_clearance_from_walls_and_from_the_unknown():
    grid = grid_of(two_rooms_and_a_pocket())
    ex = Explorer(ExplorationParams(), 0.0, clearance=0.35, planner=PlannerParams())
    goal = ex.next_goal(grid, (1.5, 1.5), 0.0)
    assert goal is not None and goal.frontier is not None
    blocked = grid.occupied_mask() | grid.unknown_mask()
    rows, cols = np.nonzero(blocked)
    xs, ys = grid.cell_to_world(rows, cols)
    assert np.hypot(xs - goal.xy[0], ys - goal.xy[1]).min() >= 0.35 - RES  # a wall revealed in the unknown
    # cannot put it inside the planner's lethal zone, and the live planner accepts it as sent
    live = GridPlanner(grid, PlannerParams(allow_unknown=True))
    assert live.traversable(goal.xy)
    assert math.dist(goal.xy, goal.looks_at) <= ExplorationParams().max_standoff + RES
    assert goal.looks_at[0] > 4.0  # the doorway, not the pocket


def test_gain_counts_what_the_lidar_would_see_not_what_hides_behind_walls():
    data = two_rooms_and_a_pocket()
    at_door, in_corner = (4.0, 2.0), (1.0, 2.3)
    door_gain, = visible_unknown(grid_of(data), [at_door], radius=6.0)
    assert door_gain > 8.0  # the room beyond the doorway
    data[cell(1.5):cell(2.5), cell(4.5):cell(4.7)] = OCCUPIED  # the door shut: only the pocket is left
    grid = grid_of(data)
    pocket_gain, = visible_unknown(grid, [in_corner], radius=6.0)
    assert 0.0 < pocket_gain <= 0.3 + 0.05  # the 0.3 m² pocket, nothing behind the walls


def test_gain_explorer_prefers_the_doorway_and_ends_when_only_slivers_are_left():
    data = two_rooms_and_a_pocket()
    ex = Explorer(ExplorationParams(), 0.0, planner=PlannerParams())
    goal = ex.next_goal(grid_of(data), (1.2, 1.5), 0.0)
    assert goal is not None and goal.looks_at[0] > 4.0  # the pocket is nearer, the room behind the door worth more
    data[cell(0.5):cell(4.5), cell(4.7):cell(9.5)] = FREE  # the room is mapped
    data[cell(0.5):cell(4.5), cell(9.5):] = OCCUPIED
    assert ex.next_goal(grid_of(data), (3.0, 2.0), 10.0) is None
    assert ex.status == DONE and "remaining gain" in ex.reason
    dwfe = Explorer(ExplorationParams(explorer="dwfe"), 0.0, planner=PlannerParams())
    assert dwfe.next_goal(grid_of(data), (3.0, 2.0), 10.0) is not None  # DWFE still drives to the pocket
    assert dwfe.status == EXPLORING


def test_gain_explorer_ranks_by_the_path_not_the_straight_line():
    """Room A lies 5 m from the robot across a wall but 14 m away by the corridors; room B
    opens 6 m away along the robot's own corridor."""
    data = np.full((cell(8.0), cell(14.0)), OCCUPIED, np.int8)
    data[cell(0.5):cell(2.0), cell(2.7):cell(13.5)] = FREE  # corridor 1, the robot's
    data[cell(2.3):cell(3.8), cell(3.0):cell(13.5)] = FREE  # corridor 2, behind a 0.3 m wall
    data[cell(0.5):cell(3.8), cell(12.0):cell(13.5)] = FREE  # joined at the east end
    data[cell(3.8):cell(7.5), cell(3.5):cell(6.5)] = UNKNOWN  # room A, off corridor 2
    data[cell(0.5):cell(7.5), cell(0.5):cell(2.7)] = UNKNOWN  # room B, off corridor 1's west end
    robot = (9.0, 1.25)
    gain = Explorer(ExplorationParams(), 0.0, planner=PlannerParams()).next_goal(grid_of(data), robot, 0.0)
    assert gain is not None and gain.looks_at[0] < 3.0  # room B
    dwfe = Explorer(ExplorationParams(explorer="dwfe"), 0.0, planner=PlannerParams()).next_goal(
        grid_of(data), robot, 0.0)
    assert dwfe is not None and dwfe.looks_at[1] > 3.0  # straight-line distance: room A, the long way round


def test_a_frontier_closed_by_a_wall_is_mapped_although_unknown_stays_behind_the_wall():
    data = np.full((cell(3.0), cell(3.0)), UNKNOWN, np.int8)
    data[:, :cell(1.5)] = FREE
    grid = grid_of(data)
    assert still_open(grid, (1.45, 1.5), 0.6, 3)
    data[:, cell(1.5):cell(1.6)] = OCCUPIED  # the lidar saw a wall; its inside stays unknown
    assert not still_open(grid_of(data), (1.45, 1.5), 0.6, 3)


def corridor_between_two_unknown_rooms() -> np.ndarray:
    """A 1 m wide corridor (x 2-7 m) between two equal unknown rooms (x 0-2 and 7-9 m)."""
    data = np.full((cell(3.0), cell(9.0)), OCCUPIED, np.int8)
    data[cell(1.0):cell(2.0), cell(2.0):cell(7.0)] = FREE
    data[:, :cell(2.0)] = UNKNOWN
    data[:, cell(7.0):] = UNKNOWN
    return data


def test_a_goal_behind_the_robot_costs_the_turn_on_the_spot():
    grid = grid_of(corridor_between_two_unknown_rooms())
    robot = (4.3, 1.5)  # the west room is 0.6 m nearer

    def choose(yaw):
        params = ExplorationParams(turn_cost=0.6)  # opt-in (docs/exploration.md 7.6)
        return Explorer(params, 0.0, planner=PlannerParams()).next_goal(grid, robot, 0.0, yaw)

    assert choose(None).xy[0] < robot[0]  # heading unknown: the nearer room
    assert choose(math.pi).xy[0] < robot[0]  # facing it
    assert choose(0.0).xy[0] > robot[0]  # facing east: turning 180 degrees costs more than 0.6 m
    no_turn_cost = Explorer(ExplorationParams(turn_cost=0.0), 0.0, planner=PlannerParams())
    assert no_turn_cost.next_goal(grid, robot, 0.0, 0.0).xy[0] < robot[0]

