"""Fixtures of the leaf tests: a clean blackboard, the scripted robot, a mission context."""

from __future__ import annotations

import py_trees
import pytest
from fake_robot import FakeRobot

from bomc_bt.config import load_config
from bomc_bt.geometry import Pose2D
from bomc_bt.graph import AssociationParams, ObjectGraph
from bomc_bt.mission import MissionContext
from bomc_bt.site import Site
from bomc_bt.store import SiteStore


@pytest.fixture(autouse=True)
def clean_blackboard():
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()


@pytest.fixture
def robot() -> FakeRobot:
    return FakeRobot()


@pytest.fixture
def ctx(robot, tmp_path) -> MissionContext:
    """A monitor-pass context on the fake robot, with an empty graph and a real site store."""
    store = SiteStore(tmp_path / "site.db")
    context = MissionContext(robot=robot, config=load_config(), site=Site(tmp_path), mission="monitor",
                             session=1, store=store, graph=ObjectGraph(AssociationParams()),
                             dock=Pose2D(1.0, 1.0, 0.0))
    yield context
    store.close()
