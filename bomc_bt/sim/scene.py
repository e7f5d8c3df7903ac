"""The true scene the simulated robot lives in: walls, objects and obstacles as masks.

Everything is rasterised onto the world map's grid once per change (objects and obstacles
change rarely: at session start and at ``during`` times), and each mask is turned into a
Euclidean distance field with OpenCV. Those fields make the two hot queries cheap: the
lidar sphere-traces the *lidar* field, and collision checks read the *collision* field at
the robot's centre.

What is solid for whom (kept deliberately simple):

* the lidar sees a box when its vertical extent spans the lidar height (a wall-mounted
  television or a table top above the scan plane is invisible, a chair's box is seen);
* the robot collides with a box whose bottom is below ``collision_height`` (the base of a
  mobile manipulator; a television at 0.8 m does not stop it, an obstacle on the floor
  does, even when it is too low for the lidar to see -- as on a real robot);
* walls (occupied or unknown map cells, and everything outside the image) are solid for
  both.
"""

from __future__ import annotations

from collections.abc import Iterable

import cv2
import numpy as np

from bomc_bt.grid import OccupancyGrid
from bomc_bt.sim.lidar import DistanceField
from bomc_bt.sim.params import LidarParams, SceneParams
from bomc_bt.world import Obstacle, World, WorldObject


def _spans(bottom: float, top: float, height: float) -> bool:
    return bottom <= height <= top


class Scene:
    """Walls + current objects + obstacles, with distance fields for lidar and collision."""

    def __init__(self, world: World, objects: dict[str, WorldObject], obstacles: Iterable[Obstacle],
                 params: SceneParams | None = None, lidar_height: float = LidarParams.height):
        """``lidar_height``: the scan plane's height (``sim.lidar.height``), which decides what
        the lidar sees."""
        self.params = params or SceneParams()
        self.lidar_height = lidar_height
        self.world = world
        self.grid: OccupancyGrid = world.grid
        self.walls = world.walls()
        self.objects = dict(objects)
        self.obstacles = list(obstacles)
        self.version = 0
        self._rebuild()

    # -- updates -------------------------------------------------------------------------
    def set_objects(self, objects: dict[str, WorldObject]) -> None:
        self.objects = dict(objects)
        self._rebuild()

    def add_obstacles(self, obstacles: Iterable[Obstacle]) -> None:
        self.obstacles.extend(obstacles)
        self._rebuild()

    def _rebuild(self) -> None:
        """Re-rasterise and recompute both distance fields (only when the scene changed)."""
        p = self.params
        seen: list[np.ndarray] = []
        solid: list[np.ndarray] = []
        for obj in self.objects.values():
            bottom = obj.position[2] - obj.size[2] / 2.0
            top = obj.position[2] + obj.size[2] / 2.0
            if _spans(bottom, top, self.lidar_height):
                seen.append(obj.footprint())
            if bottom < p.collision_height:
                solid.append(obj.footprint())
        for obs in self.obstacles:
            if _spans(0.0, obs.height, self.lidar_height):
                seen.append(obs.footprint())
            solid.append(obs.footprint())
        lidar = self.walls | self._rasterise(seen)
        collide = self.walls | self._rasterise(solid)
        self.lidar_mask = lidar
        self.collision_mask = collide
        self.lidar_distance = self._distance(lidar)
        self.lidar_field = DistanceField(self.grid, self.lidar_distance)
        self.collision_distance = self._distance(collide)
        self.version += 1

    def _rasterise(self, polygons: list[np.ndarray]) -> np.ndarray:
        """Bool mask of polygons (map-frame metres), drawn with sub-cell precision.

        Cell (r, c) covers [c, c+1) x [r, r+1) in cell units and OpenCV puts pixel centres
        at integers, hence the half-cell shift; the cell under each centre is always set so
        thin boxes never vanish. One shared buffer: each polygon costs only its own area.
        """
        g = self.grid
        buf = np.zeros(g.data.shape, dtype=np.uint8)
        origin = np.asarray(g.origin)
        for corners in polygons:
            cells = (np.asarray(corners) - origin) / g.resolution - 0.5
            pts = np.rint(cells * 16.0).astype(np.int32).reshape(-1, 1, 2)
            cv2.fillPoly(buf, [pts], 1, lineType=cv2.LINE_8, shift=4)
            centre = np.asarray(corners).mean(axis=0)
            r, c = g.world_to_cell(centre[0], centre[1])
            if g.in_bounds(r, c):
                buf[r, c] = 1
        return buf.astype(bool)

    def _distance(self, solid: np.ndarray) -> np.ndarray:
        """Metres from each cell centre to the nearest solid cell centre (0 inside)."""
        free = (~solid).astype(np.uint8)
        free[0, :] = free[-1, :] = 0  # outside the image is wall
        free[:, 0] = free[:, -1] = 0
        dist = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        return (dist * self.grid.resolution).astype(np.float32)

    # -- queries -------------------------------------------------------------------------
    def clearance(self, x: float, y: float) -> float:
        """Distance (m) from a point to the nearest collision-solid cell's face."""
        r, c = self.grid.world_to_cell(x, y)
        if not self.grid.in_bounds(r, c):
            return 0.0
        return max(float(self.collision_distance[r, c]) - 0.5 * self.grid.resolution, 0.0)

    def free_cells(self, min_clearance: float) -> np.ndarray:
        """(N, 2) map-frame centres of cells at least ``min_clearance`` from anything solid."""
        rows, cols = np.nonzero(self.collision_distance >= min_clearance + 0.5 * self.grid.resolution)
        x, y = self.grid.cell_to_world(rows, cols)
        return np.stack([x, y], axis=1)

    def is_solid(self, x: float, y: float) -> bool:
        r, c = self.grid.world_to_cell(x, y)
        return not bool(self.grid.in_bounds(r, c)) or bool(self.collision_mask[r, c])

