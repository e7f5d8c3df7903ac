"""``bomc build --ros`` / ``bomc monitor --ros``: the same trees against a ROS 1 robot.

The mission runner (:mod:`bomc_bt.run`) does the wiring; :class:`RosRobots` is what it
is given instead of the simulator: a :class:`~bomc_bt.ros.robot.RosRobot`. There is no
world: the dock pose (the relocalization hint) is where the build started (the first row
of the site's trajectory), and perception prompts come from ``perception.categories``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TextIO

from bomc_bt.config import Config
from bomc_bt.errors import BomcError
from bomc_bt.geometry import Pose2D
from bomc_bt.mission import MissionContext
from bomc_bt.params import from_mapping
from bomc_bt.ros import import_ros
from bomc_bt.ros.params import RosParams
from bomc_bt.run import MissionResult, build_config, run_build_mission, run_monitor_mission
from bomc_bt.site import Site


def ros_params(config: Config) -> RosParams:
    """The ``ros:`` section as a validated record (errors name the config file).

    The simulated detector reads the per-pixel instance image that only the sim-over-ROS
    bridge publishes, so with ``perception.backend: sim`` an unset ``ros.instances_topic``
    means the bridge's topic (a real robot runs the ONNX backend and never needs it).
    """
    if isinstance(config.ros, RosParams):
        params = replace(config.ros)
    else:  # a plain mapping (configs built by hand)
        params = from_mapping(RosParams, config.ros, config.source[-1] if config.source else None, "ros")
    if config.perception.backend == "sim" and not params.instances_topic:
        from bomc_bt.ros.ground_truth import SIM_INSTANCES_TOPIC

        params.instances_topic = SIM_INSTANCES_TOPIC
    return params


def dock_pose(site: Site) -> Pose2D:
    """Where the build started: the first pose of ``trajectory.csv``."""
    try:
        with open(site.trajectory_csv) as f:
            f.readline()
            t, x, y, yaw = (float(v) for v in f.readline().split(",")[:4])
    except (OSError, ValueError):
        raise BomcError(
            "no start pose in the trajectory (run `bomc build` first)", site.trajectory_csv
        ) from None
    return Pose2D(x, y, yaw)


class RosRobots:
    """Makes :class:`~bomc_bt.ros.robot.RosRobot` s (a :class:`bomc_bt.run.RobotFactory`)."""

    def __init__(self) -> None:
        self.params: RosParams | None = None

    def default_config(self) -> Config:
        return build_config(robot="fetch")

    def connect(self) -> None:
        """Import rospy: a missing ROS is a one-line error with the apt command."""
        import_ros()

    def prepare(self, config: Config) -> None:
        self.params = ros_params(config)

    def build_robot(self, config: Config):
        from bomc_bt.ros.robot import RosRobot

        return RosRobot(self.params, mode="build")

    def monitor_robot(self, config: Config, session: int):
        from bomc_bt.ros.robot import RosRobot

        return RosRobot(self.params, mode="monitor")

    def dock(self, site: Site) -> Pose2D:
        return dock_pose(site)

    def categories(self, config: Config) -> list[str]:
        categories = list(config.perception.categories)
        if not categories:  # no world to take them from
            raise BomcError(
                "set the objects to look for (perception.categories) when running on ROS",
                config.source[-1] if config.source else None,
                "perception.categories",
            )
        return categories

    def mission_hooks(self, ctx: MissionContext) -> list[Callable]:
        if self.params is None or not self.params.publish:
            return []
        from bomc_bt.ros.publish import MissionPublisher

        return [MissionPublisher(ctx, self.params)]

    def release(self, robot) -> None:
        robot.cancel_all()
        robot.close()


def run_build_ros(
    site_dir: str | Path,
    config: Config | None = None,
    *,
    max_time: float | None = None,
    explorer: str | None = None,
    tree: str | Path | None = None,
    quiet: bool = True,
    stream: TextIO = sys.stdout,
    hooks: list[Callable] = (),
    context_hooks: list[Callable] = (),
) -> MissionResult:
    """Explore with the build tree on the ROS robot (GMapping's /map, move_base); save the map."""
    return run_build_mission(RosRobots(), site_dir, config=config, max_time=max_time, explorer=explorer,
                             tree=tree, quiet=quiet, stream=stream, hooks=hooks, context_hooks=context_hooks)


def run_monitor_ros(
    site_dir: str | Path,
    session: int,
    config: Config | None = None,
    *,
    seed: int = 0,
    tree: str | Path | None = None,
    resume: bool = False,
    quiet: bool = True,
    stream: TextIO = sys.stdout,
    hooks: list[Callable] = (),
    context_hooks: list[Callable] = (),
    max_time: float = 4 * 3600.0,
) -> MissionResult:
    """One monitoring pass on the ROS robot (map_server + AMCL + move_base + the head camera)."""
    return run_monitor_mission(RosRobots(), site_dir, session, config=config, seed=seed, tree=tree,
                               resume=resume, quiet=quiet, stream=stream, hooks=hooks,
                               context_hooks=context_hooks, max_time=max_time)
