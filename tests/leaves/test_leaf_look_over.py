"""Look Around, tick by tick: a chair caught once behind the chair in front gets a turn over it."""

from __future__ import annotations

import math

import numpy as np
from fake_robot import tick
from py_trees.common import Status

from behaviours.look_around import LookAround
from behaviours.plan_pass import PlanRefreshStops
from bomc_bt.geometry import Pose2D
from bomc_bt.graph import AssociationParams, Node, ObjectGraph, Observation
from bomc_bt.grid import OccupancyGrid
from bomc_bt.look_around import LookAroundParams
from bomc_bt.monitoring import VISITED, TraversalState
from bomc_bt.refresh import RefreshParams
from bomc_bt.traversal import TraversalPlan


def room_with_a_table() -> OccupancyGrid:
    """10 x 10 m inside walls; a table's lidar shadow (unknown) round x 3.7-5.5, y 5.7-7.2 and
    the outline of the chair at its side at (5, 7) (occupied, y = 7.25)."""
    data = np.zeros((200, 200), np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[114:145, 74:111] = -1
    data[145, 95:106] = 100
    return OccupancyGrid(data, 0.05, (0.0, 0.0))


def test_look_around_turns_over_the_chair_in_front_and_leaves_the_sighting_to_the_refresh_tour(ctx, robot):
    robot.use_map(room_with_a_table())
    robot.place(Pose2D(5.0, 8.5, 0.0))
    ctx.session = 2
    chair = Node(0, "chair", np.array([5.0, 7.0, 0.45]), 0.9, 1, 1, footprint=np.array([4.75, 6.75, 5.25, 7.25]))
    table = Node(1, "table", np.array([4.2, 6.6, 0.375]), 0.9, 1, 1, footprint=np.array([3.8, 5.8, 4.6, 7.4]))
    ctx.graph = ObjectGraph(AssociationParams(mode="robust", confirm_detections=2, tentative_ttl=10.0), [chair, table])
    ctx.graph.associate([Observation("chair", np.array([5.0, 6.2, 0.8]), 0.9)], [], 2, ctx.now())
    leaf = LookAround("Look", LookAroundParams(dwell=1.5), ctx)
    assert leaf.params.camera_height == ctx.config.camera.mount_height
    assert tick(leaf) == Status.RUNNING
    assert robot.goals == [Pose2D(5.0, 8.5, -math.pi / 2)]  # on the spot, over the chair in front
    assert ctx.graph.unconfirmed_sightings() == []  # Look Around's one look at the place
    robot.advance(30.0)
    ctx.graph.associate([], [], 2, ctx.now())  # not seen again; its ttl ran out
    ctx.plan = TraversalPlan([Pose2D(5.0, 8.5, 0.0)], euclidean_length=100.0)
    ctx.traverse = TraversalState(ctx.plan)
    ctx.traverse.mark(ctx.traverse.next(), VISITED)
    refresh = PlanRefreshStops("Refresh", RefreshParams(stale_after=600.0, budget=0.3), ctx)
    assert tick(refresh) == Status.SUCCESS
    assert refresh.feedback_message.endswith("and 1 unconfirmed sightings")  # still the tour's to decide
