"""The live viewer hook: samples a running mission into a :class:`~bomc_bt.viewer.store.StateStore`.

:class:`ViewerHook` is the ``on_tick`` hook of a live mission. Ticks are the mission's hot
loop, so a tick costs a pose read (the path is tracked every tick, or a fast simulation
would draw a coarse path) and, at most ``interval_wall_s`` of *wall* time apart, one
sample of the mission. Wall time only paces the display; nothing the robot does depends on
it. The map is copied at most every ``map_interval_sim_s`` robot seconds and only when the
robot port handed out a new grid object (the simulated mapper caches its grid between scans).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import py_trees
from py_trees.common import Status

from bomc_bt.grid import OccupancyGrid
from bomc_bt.tree.view import tree_ports
from bomc_bt.viewer.sections import (
    blackboard_section,
    events_section,
    frontiers_json,
    node_json,
    progress_section,
    rounded,
    tree_section,
    waypoints_json,
)
from bomc_bt.viewer.store import StateStore, ViewerParams


class PathTracker:
    """The robot's path, one point per ``step`` metres, thinned by half when it grows too long."""

    def __init__(self, step: float, limit: int):
        self.step = step
        self.limit = max(limit, 2)
        self.points: list[tuple[float, float]] = []

    def add(self, x: float, y: float) -> None:
        if self.points:
            lx, ly = self.points[-1]
            if math.hypot(x - lx, y - ly) < self.step:
                return
        self.points.append((x, y))
        if len(self.points) > self.limit:
            self.points = self.points[::2] + ([self.points[-1]] if len(self.points) % 2 == 0 else [])

    def flat(self) -> list[float]:
        return [rounded(v) for xy in self.points for v in xy]


class ViewerHook:
    """``on_tick`` hook that samples a running mission into a :class:`StateStore`.

    ``sink`` is the store or anything with a ``state`` store (the :class:`~.server.Server`).
    ``wall_clock`` is injectable for tests; it paces the display only.
    """

    def __init__(self, sink: Any, ctx: Any, params: ViewerParams | None = None,
                 wall_clock: Callable[[], float] = time.monotonic):
        self.store: StateStore = sink if isinstance(sink, StateStore) else sink.state
        self.ctx = ctx
        self.params = params or ViewerParams()
        self.wall_clock = wall_clock
        self.path = PathTracker(self.params.path_step, self.params.max_path_points)
        self.samples = 0
        self._last_wall: float | None = None
        self._grid: OccupancyGrid | None = None
        self._map_sim: float | None = None
        self._ports: dict | None = None  # the tree's declared keys, read once

    def __call__(self, runner: Any) -> None:
        pose = self.ctx.robot.pose()
        if pose is not None:
            self.path.add(float(pose.x), float(pose.y))
        done = runner.root.status in (Status.SUCCESS, Status.FAILURE)
        now = self.wall_clock()
        if not done and self._last_wall is not None and now - self._last_wall < self.params.interval_wall_s:
            return
        self._last_wall = now
        self.sample(runner, force_map=done)

    def sample(self, runner: Any, force_map: bool = False) -> None:
        """Read the mission once and hand the sections to the store (the server thread sends them)."""
        ctx = self.ctx
        grid = self._maybe_map(force_map)
        self.store.update({
            "mode": "live",
            "tree": tree_section(runner.root),
            "blackboard": blackboard_section(py_trees.blackboard.Blackboard.storage, self.params, self.ports(runner)),
            "progress": progress_section(ctx, runner),
            "scene": self._scene(grid),
            "events": self._events(),
        })
        self.samples += 1

    def ports(self, runner: Any) -> dict:
        if self._ports is None:
            self._ports = tree_ports(runner.root)
        return self._ports

    def _maybe_map(self, force: bool) -> OccupancyGrid | None:
        """The live grid; copied into the store when it is a new grid and the interval passed."""
        try:
            grid = self.ctx.robot.live_map()
        except Exception:  # a robot without a map yet (ROS before the first /map message)
            return self._grid
        sim_now = self.ctx.now()
        due = self._map_sim is None or sim_now - self._map_sim >= self.params.map_interval_sim_s
        if grid is not None and grid is not self._grid and (due or force):
            self.store.set_map(grid)
            self._grid, self._map_sim = grid, sim_now
        return self._grid

    def _scene(self, grid: OccupancyGrid | None) -> dict[str, Any]:
        ctx = self.ctx
        pose = ctx.robot.pose()
        graph = ctx.graph
        explorer = ctx.explorer
        scene: dict[str, Any] = {
            "robot": None if pose is None else [rounded(pose.x), rounded(pose.y), rounded(pose.yaw)],
            "path": self.path.flat(),
            "objects": [node_json(n) for n in (graph.nodes.values() if graph is not None else [])],
            "waypoints": waypoints_json(ctx.plan, ctx.traverse),
            "frontiers": [], "blacklist": [],
        }
        if explorer is not None:
            scene["frontiers"] = frontiers_json(explorer.frontiers, grid, self.params.max_frontier_cells)
            scene["blacklist"] = [[rounded(x), rounded(y)] for x, y in explorer.blacklist.points]
        scene["highlight"] = self._highlight()
        return scene

    def _highlight(self) -> dict[str, str]:
        """Object id -> the kind of its latest recent change, for the map's halo."""
        events = self.events()
        horizon = self.ctx.now() - self.params.highlight_s
        marks: dict[str, str] = {}
        for e in reversed(events):
            if e.stamp < horizon:
                break
            if e.kind != "updated":
                marks.setdefault(str(e.node_id), e.kind)
        return marks

    def events(self) -> list:
        """The graph events of this pass so far (none before perception starts)."""
        return self.ctx.perception.events if self.ctx.perception is not None else []

    def _events(self) -> dict[str, Any]:
        return events_section(self.events(), self.params)
