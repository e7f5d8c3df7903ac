"""The mission context: what every leaf of a running tree shares.

A tree's leaves are built by the YAML loader with one :class:`MissionContext`. It holds
the robot port, the validated configuration, the site being written and the per-run
library objects (the explorer, the trajectory recorder, the object graph and store, the
traversal plan). Leaves read and write these through plain attributes; blackboard keys
carry only what the tree itself branches on (goals, statuses), so the py_trees viewer
shows the mission's decisions without megabytes of maps.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from bomc_bt.config import Config
from bomc_bt.geometry import Pose2D
from bomc_bt.robot import RobotPort
from bomc_bt.site import Site, TrajectoryRecorder


@dataclass
class Progress:
    """Numbers for the progress line and the summary, updated by the leaves."""

    explored_area: float = 0.0
    path_length: float = 0.0
    waypoint: int = 0
    waypoints: int = 0
    frames: int = 0
    nodes: int = 0
    message: str = ""


@dataclass
class MissionContext:
    robot: RobotPort
    config: Config
    site: Site
    mission: str  # "build" | "monitor"
    session: int = 0
    seed: int = 0
    max_time: float | None = None
    dock: Pose2D | None = None  # where the robot starts a pass: the hint for relocalization
    resume: bool = False  # continue the session's pass where a killed run left it
    progress: Progress = field(default_factory=Progress)
    trajectory: TrajectoryRecorder | None = None
    explorer: Any = None  # bomc_bt.exploration.explorer.Explorer during a build
    store: Any = None  # bomc_bt.store.SiteStore during a monitor pass
    graph: Any = None  # bomc_bt.graph.ObjectGraph
    plan: Any = None  # bomc_bt.traversal.TraversalPlan
    traverse: Any = None  # bomc_bt.monitoring.TraversalState
    perception: Any = None  # bomc_bt.monitoring.Perception
    outcome: str = ""
    reason: str = ""
    extras: dict[str, Any] = field(default_factory=dict)

    def now(self) -> float:
        return self.robot.now()
