"""The planners the simulated navigator drives with, rebuilt only when their map changed.

While building, the robot plans on the sim mapper's grid through unknown space; once a
saved map is in use (monitoring), on that map plus the obstacle layer from recent scans.
Building a :class:`~bomc_bt.planner.GridPlanner` costs a distance transform, so each
planner is cached against its map's version.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from bomc_bt.grid import OccupancyGrid
from bomc_bt.planner import GridPlanner, PlannerParams, path_clear_of
from bomc_bt.sim.mapper import Mapper, ObstacleLayer


class SimPlanners:
    """The live planner, the map-only planner and a cheap path check of one simulated robot."""

    def __init__(self, params: PlannerParams, mapper: Mapper | None):
        self.params = params
        self.mapper = mapper
        self.map: OccupancyGrid | None = None
        self.obstacles: ObstacleLayer | None = None
        self._cache: dict[str, tuple[Any, GridPlanner]] = {}

    def use_map(self, grid: OccupancyGrid, obstacles: ObstacleLayer) -> None:
        """Plan on this saved map and obstacle layer from now on."""
        self.map, self.obstacles = grid, obstacles
        self._cache.clear()

    def live(self) -> GridPlanner:
        """The obstacle-aware planner for the current map (rebuilt only when it changed)."""
        if self.map is None:
            assert self.mapper is not None
            key = ("mapper", self.mapper.updates)
            params = replace(self.params, allow_unknown=True)
            return self._cached("live", key, lambda: GridPlanner(self.mapper.grid(), params))
        assert self.obstacles is not None
        key = ("obstacles", self.obstacles.version)
        return self._cached("live", key, lambda: GridPlanner(self.map, self.params, self.obstacles.mask))

    def squeeze(self) -> GridPlanner | None:
        """While building, the planner with ``squeeze_radius`` on known space only: the last
        resort when the live planner has no path (a robot inside a pocket whose way out is
        narrower than ``robot_radius`` allows). None once a saved map is in use."""
        if self.map is not None or self.params.squeeze_radius >= self.params.robot_radius:
            return None
        assert self.mapper is not None
        params = replace(self.params, robot_radius=self.params.squeeze_radius, allow_unknown=False)
        return self._cached("squeeze", ("mapper", self.mapper.updates),
                            lambda: GridPlanner(self.mapper.grid(), params))

    def path_clear(self, path: np.ndarray, skip: float) -> bool:
        """Cheap check of the plan against what is known to be occupied now (no rebuild)."""
        if self.map is None:
            assert self.mapper is not None
            grid = self.mapper.grid()
            obstacles = grid.occupied_mask()
        else:
            assert self.obstacles is not None
            grid = self.map
            obstacles = grid.occupied_mask() | self.obstacles.mask
        return path_clear_of(obstacles, grid, path, self.params.robot_radius, skip)

    def static(self) -> GridPlanner:
        """The planner on the map alone (tells "no path at all" from "blocked for now")."""
        if self.map is None:
            return self.live()
        return self._cached("static", id(self.map), lambda: GridPlanner(self.map, self.params))

    def _cached(self, slot: str, key: Any, build: Callable[[], GridPlanner]) -> GridPlanner:
        hit = self._cache.get(slot)
        if hit is None or hit[0] != key:
            hit = (key, build())
            self._cache[slot] = hit
        return hit[1]
