"""The mission context: what every leaf of a running tree shares.

A tree's leaves are built by the YAML loader with one :class:`MissionContext`. It holds
the robot port, the validated configuration, the site being written and the per-run
library objects (the explorer, the trajectory recorder, the object graph and store, the
traversal plan). Leaves use these long-lived objects through typed attributes; what one
leaf tells another (the goal, how the robot was localized, whether a goal was reached by
a detour) goes through the blackboard keys the leaves declare (their ports, listed in
``trees/README.md``), so the viewer's blackboard panel shows the mission's decisions
without megabytes of maps.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from bomc_bt.config import Config
from bomc_bt.geometry import Pose2D
from bomc_bt.robot import RobotPort
from bomc_bt.site import Site, TrajectoryRecorder
from bomc_bt.trail import Trail

if TYPE_CHECKING:  # annotations only: a context does not import the planners and the graph
    import numpy as np

    from bomc_bt.budget_plan import PassBudget
    from bomc_bt.exploration.explorer import Explorer
    from bomc_bt.graph import ObjectGraph
    from bomc_bt.monitoring import Perception, TraversalState
    from bomc_bt.planner import GridPlanner
    from bomc_bt.stale_map import FloorSeen
    from bomc_bt.store import SiteStore
    from bomc_bt.stuck import StuckWatch
    from bomc_bt.traversal import TraversalPlan


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
    restored: bool = False  # the robot's state was put back from the pass's resume point
    progress: Progress = field(default_factory=Progress)
    trajectory: TrajectoryRecorder | None = None
    explorer: Explorer | None = None  # during a build
    store: SiteStore | None = None  # during a monitor pass
    graph: ObjectGraph | None = None
    plan: TraversalPlan | None = None
    traverse: TraversalState | None = None
    perception: Perception | None = None
    map_planner: GridPlanner | None = None  # shortest paths on the saved map (NavigateTo's detour test)
    dock_field: np.ndarray | None = None  # map_planner's path lengths to the dock (a budgeted pass's way home)
    trail: Trail = field(default_factory=Trail)  # the way the robot drove in (NavigateTo adds; a back-out follows)
    budget: PassBudget | None = None  # a pass with a budget of robot time (bomc_bt.budget_pass); None: full
    watch: StuckWatch | None = None  # missed waypoints in a row and the recovery log (behaviours/recover.py)
    floor: FloorSeen | None = None  # floor the lidar saw this pass where the map holds furniture (WatchFloor)
    outcome: str = ""
    reason: str = ""

    def now(self) -> float:
        return self.robot.now()
