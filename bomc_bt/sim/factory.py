"""The simulator as a robot factory for the mission runner (:mod:`bomc_bt.run`).

What is particular to a simulated mission: a world file is the ground truth, the robot
starts a build on the world's dock pose and a monitor pass parked near it, the camera is
the simulated one, and the objects to look for default to every category in the world.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from bomc_bt.config import Config
from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.mission import MissionContext
from bomc_bt.site import Site
from bomc_bt.world import World


def world_categories(world: World) -> list[str]:
    """Every category that appears in the world in any session (the sim's default prompts)."""
    cats = {o.category for o in world.objects.values()}
    for change in world.sessions.values():
        cats.update(o.category for o in change.add)
    for during in world.during:
        cats.update(o.category for o in during.change.add)
    return sorted(cats)


def parked_near(world: World, dock: Pose2D, seed: int, clearance: float, max_offset: float = 0.5,
                max_angle: float = 0.35) -> Pose2D:
    """Where the simulated robot really is at the start of a pass: near the dock, not on it.

    A robot parked by hand or by a previous run is off by decimetres and degrees; the
    monitor tree's relocalization has to find it from the dock pose. Seeded, and always
    on free floor with room for the robot.
    """
    rng = np.random.default_rng([seed, 4242])
    walls = world.walls()
    grid = world.grid
    for _ in range(50):
        r, a = max_offset * math.sqrt(rng.random()), rng.uniform(0.0, 2.0 * math.pi)
        x, y = dock.x + r * math.cos(a), dock.y + r * math.sin(a)
        rows, cols = grid.world_to_cell(x + clearance * np.cos(np.linspace(0, 6.28, 12)),
                                        y + clearance * np.sin(np.linspace(0, 6.28, 12)))
        inside = grid.in_bounds(rows, cols)
        if inside.all() and not walls[rows, cols].any():
            return Pose2D(x, y, wrap_angle(dock.yaw + rng.uniform(-max_angle, max_angle)))
    return dock


class SimRobots:
    """Makes :class:`~bomc_bt.sim.robot.SimRobot` s of one world (a :class:`bomc_bt.run.RobotFactory`)."""

    def __init__(self, world_path: str | Path, seed: int = 0):
        self.world_path = world_path
        self.seed = seed
        self.world: World | None = None

    def default_config(self) -> Config:
        from bomc_bt.config import load_config

        return load_config([], robot="sim")

    def connect(self) -> None:
        """Nothing to reach: the simulator runs in this process."""

    def prepare(self, config: Config) -> None:
        from bomc_bt.world import load_world

        self.world = load_world(self.world_path)

    def build_robot(self, config: Config):
        from bomc_bt.sim.robot import SimRobot

        return SimRobot(self._world, session=1, params=config.sim, seed=self.seed, mode="build")

    def monitor_robot(self, config: Config, session: int):
        from bomc_bt.sim.camera import SimCamera
        from bomc_bt.sim.robot import SimRobot

        world = self._world
        camera = SimCamera(config.camera, seed=self.seed)
        return SimRobot(world, session=session, params=config.sim, seed=self.seed, mode="monitor", camera=camera,
                        relocalization=config.relocalization,
                        start=parked_near(world, world.start, self.seed, config.sim.planner.robot_radius + 0.1))

    def dock(self, site: Site) -> Pose2D:
        """The world's start pose: where the build started and the pass's relocalization hint."""
        return self._world.start

    def categories(self, config: Config) -> list[str]:
        return config.perception.categories or world_categories(self._world)

    def mission_hooks(self, ctx: MissionContext) -> list:
        return []

    def release(self, robot) -> None:
        """Nothing to let go of: the simulated robot ends with the mission."""

    @property
    def _world(self) -> World:
        if self.world is None:
            raise RuntimeError("SimRobots.prepare() loads the world first")
        return self.world
