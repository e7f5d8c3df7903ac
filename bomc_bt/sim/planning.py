"""The planners the simulated navigator drives with, rebuilt only when their map changed.

While building, the robot plans on the sim mapper's grid through unknown space; once a
saved map is in use (monitoring), on that map plus the obstacle layer from recent scans.
Building a :class:`~bomc_bt.planner.GridPlanner` costs a distance transform, so each
planner is cached against its map's version.

On a saved map the obstacle layer changes with nearly every scan, and a distance
transform of an Environment-A-size map costs about 0.1 s: one per goal was a sixth of a
monitor pass's wall time. So a goal near the robot is planned in a window of the map
around the two ends (:class:`WindowPlanner`), as a local costmap would, and on the whole
map only when the window has no way through.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from bomc_bt.grid import OccupancyGrid
from bomc_bt.planner import GridPlanner, PlannerParams, path_clear_of
from bomc_bt.sim.mapper import Mapper, ObstacleLayer

WINDOW_MARGIN = 8.0  # [m] map kept around a goal's two ends when it is planned in a window
WINDOW_MAX_SHARE = 0.25  # [-] a window larger than this share of the map: plan on the whole map


class WindowPlanner:
    """A planner on a window of the map, falling back on the whole map's planner.

    The window's outer band, ``inflation_radius`` wide, is marked occupied: obstacles
    beyond the crop are unknown there, so nothing is planned through it, and every cell
    farther inside has the clearance cost the whole map would give it (a clearance beyond
    the inflation radius costs nothing). A goal whose way leaves the window is planned on
    the whole map.
    """

    def __init__(self, window: GridPlanner, whole: Callable[[], GridPlanner]):
        self.window, self._whole = window, whole

    def plan(self, start_xy, goal_xy) -> np.ndarray | None:
        path = self.window.plan(start_xy, goal_xy)
        return path if path is not None else self._whole().plan(start_xy, goal_xy)

    def nearest_traversable(self, xy, radius: float, visible: bool = False) -> np.ndarray | None:
        found = self.window.nearest_traversable(xy, radius, visible=visible)
        return found if found is not None else self._whole().nearest_traversable(xy, radius, visible=visible)

    def traversable(self, xy) -> bool:
        return self.window.traversable(xy) or self._whole().traversable(xy)


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

    def around(self, a: np.ndarray, b: np.ndarray) -> GridPlanner | WindowPlanner:
        """The live planner for a goal from ``a`` to ``b``: on a window of the saved map around
        them when that is much smaller than the map (see :class:`WindowPlanner`), else :meth:`live`."""
        if self.map is None:
            return self.live()
        assert self.obstacles is not None
        bounds = self._window(np.asarray(a, float), np.asarray(b, float))
        if bounds is None:
            return self.live()
        key = ("window", bounds, self.obstacles.version)
        return self._cached("window", key, lambda: WindowPlanner(self._window_planner(bounds), self.live))

    def _window(self, a: np.ndarray, b: np.ndarray) -> tuple[int, int, int, int] | None:
        """Map rows/cols (r0, r1, c0, c1) of the window, aligned to planning cells; None: too big."""
        grid = self.map
        factor = max(1, int(round(self.params.resolution / grid.resolution)))
        pad = WINDOW_MARGIN + self.params.inflation_radius
        (r0, c0), (r1, c1) = (grid.world_to_cell(*(np.minimum(a, b) - pad)),
                              grid.world_to_cell(*(np.maximum(a, b) + pad)))
        r0, c0 = max(int(r0) // factor * factor, 0), max(int(c0) // factor * factor, 0)
        r1, c1 = min(-(-(int(r1) + 1) // factor) * factor, grid.height), min(-(-(int(c1) + 1) // factor) * factor,
                                                                             grid.width)
        if (r1 - r0) * (c1 - c0) > WINDOW_MAX_SHARE * grid.height * grid.width:
            return None
        return r0, r1, c0, c1

    def _window_planner(self, bounds: tuple[int, int, int, int],
                        params: PlannerParams | None = None) -> GridPlanner:
        r0, r1, c0, c1 = bounds
        grid = self.map
        window = grid.crop(r0, r1, c0, c1)
        extra = self.obstacles.mask[r0:r1, c0:c1].copy()
        band = max(1, int(np.ceil(self.params.inflation_radius / grid.resolution)))
        sides = (r0 > 0, r1 < grid.height, c0 > 0, c1 < grid.width)  # the map's own edge needs no band
        if sides[0]:
            extra[:band] = True
        if sides[1]:
            extra[-band:] = True
        if sides[2]:
            extra[:, :band] = True
        if sides[3]:
            extra[:, -band:] = True
        return GridPlanner(window, params or self.params, extra)

    def squeeze(self, a: np.ndarray, b: np.ndarray) -> GridPlanner | WindowPlanner | None:
        """The last resort when the live planner has no path from ``a`` to ``b``: the same
        map with only ``squeeze_radius`` of clearance. While building, on known space of the
        mapper's grid (a robot inside a pocket whose way out is narrower than
        ``robot_radius`` allows). On a saved map, with the obstacle layer, in a window round
        the two ends as :meth:`around` plans: a passage the robot drove in by can be closed
        behind it by the lidar's returns off what the map drew a cell thinner (a real
        building's SLAM map, willow at 0.1 m), and the robot stood there for the rest of the
        pass. None when ``squeeze_radius`` is no narrower than ``robot_radius``."""
        params = self.params.squeezed()
        if params is None:
            return None
        if self.map is None:
            assert self.mapper is not None
            return self._cached("squeeze", ("mapper", self.mapper.updates),
                                lambda: GridPlanner(self.mapper.grid(), params))
        assert self.obstacles is not None
        obstacles = self.obstacles

        def whole() -> GridPlanner:
            return self._cached("squeeze", ("obstacles", obstacles.version),
                                lambda: GridPlanner(self.map, params, obstacles.mask))

        bounds = self._window(np.asarray(a, float), np.asarray(b, float))
        if bounds is None:
            return whole()
        return self._cached("squeeze window", ("window", bounds, obstacles.version),
                            lambda: WindowPlanner(self._window_planner(bounds, params), whole))

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
