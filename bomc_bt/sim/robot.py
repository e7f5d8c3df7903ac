"""The built-in simulator: the default robot behind the robot port.

One :class:`SimRobot` simulates one session of a world. :meth:`SimRobot.step` advances
the simulated clock by ``dt`` and, in order: applies the session's ``during`` changes that
are due, moves people, lets the navigator choose a velocity, moves the robot (unicycle
kinematics; a translation into the true scene is deflected along it or refused, into a person refused:
:mod:`bomc_bt.sim.contact`),
updates the localization error, and keeps the map (build) or the obstacle layer
(monitor) current from the lidar.

Two modes, as in the paper's two missions:

* ``build``: the pose is the true pose (a stand-in for SLAM), the map is built from scans
  (:class:`~bomc_bt.sim.mapper.Mapper`), and navigation plans on it through unknown space.
* ``monitor``: :meth:`pose` is None until :meth:`relocalize` succeeds (scan matching in
  the map given to :meth:`use_map`); afterwards it is the true pose plus the estimate's
  error (decaying as AMCL would correct it, unless the estimate is grossly wrong) plus
  optional noise. Navigation plans on the saved map plus obstacles from recent scans.

Scans are computed lazily: a scan is *taken* at every lidar tick (its pose and people
are recorded) but only ray-cast when someone reads it, with noise seeded by its index,
so results do not depend on who asked. Everything random is seeded from ``seed``.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np

from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import LaserScan, RequestHandle, RGBDFrame, Status
from bomc_bt.sim.clock import SimClock
from bomc_bt.sim.contact import allowed, slide_along, slide_out
from bomc_bt.sim.faults import PERSON_RADIUS, People
from bomc_bt.sim.frame import SimFrame
from bomc_bt.sim.lidar import Lidar
from bomc_bt.sim.mapper import Mapper, ObstacleLayer
from bomc_bt.sim.navigation import NavHandle, Navigator
from bomc_bt.sim.params import SimParams
from bomc_bt.sim.planning import SimPlanners
from bomc_bt.sim.scene import Scene
from bomc_bt.world import World, WorldObject, apply_change, lands_on


class RelocHandle(RequestHandle):
    """A relocalization in flight: it completes after its duration of sim time."""

    def __init__(self, done_at: float, hint: Pose2D | None, global_search: bool):
        super().__init__("relocalizing")
        self.done_at = done_at
        self.hint = hint
        self.global_search = global_search


class SimRobot:
    """The simulated robot (implements :class:`bomc_bt.robot.RobotPort`)."""

    def __init__(self, world: World, session: int = 1, params: SimParams | None = None, seed: int = 0,
                 mode: Literal["build", "monitor"] = "build", camera: Any = None,
                 relocalization: Any = None, start: Pose2D | None = None):
        """``relocalization``: a :class:`bomc_bt.localization.RelocalizationParams` for the
        scan matcher (None: its defaults). ``start``: the true start pose (default the
        world's dock pose; a monitor pass starts near the dock, not exactly on it)."""
        if mode not in ("build", "monitor"):
            raise ValueError(f"mode must be 'build' or 'monitor', got {mode!r}")
        self.params = params or SimParams()
        self.world = world
        self.session = session
        self.mode = mode
        self.seed = seed
        self.camera = camera
        self.relocalization_params = relocalization
        p = self.params
        self.clock = SimClock(p.dt)
        streams = np.random.SeedSequence(seed).spawn(4)
        self._nav_rng = np.random.default_rng(streams[0])
        self._noise_rng = np.random.default_rng(streams[1])
        people_rng = np.random.default_rng(streams[2])
        self._reloc_rng = np.random.default_rng(streams[3])
        self._objects = world.objects_in_session(session)
        self._pending = list(world.during_changes(session))
        self._during_applied = 0  # how many of the session's during changes are applied
        self.scene = Scene(world, self._objects, world.obstacles_in_session(session), p.scene, p.lidar.height)
        self.people = People(self.scene, p.faults.people, p.faults.person_speed, people_rng,
                             keep_clear=(world.start.x, world.start.y))
        self.lidar = Lidar(p.lidar)
        self._true = start or world.start
        self.distance_travelled = 0.0
        self.navigator = Navigator(p.motion, p.planner.goal_tolerance, self._nav_rng,
                                   p.faults.nav_failure_probability)
        self.navigator.plan_patience = p.motion.plan_patience if mode == "monitor" else None
        self._stuck = False
        self._resumed_navigation: NavHandle | None = None  # the goal in flight when a pass was restored
        # Maps and localization.
        self.mapper = Mapper.like(world.grid, p.mapper) if mode == "build" else None
        self.planners = SimPlanners(p.planner, self.mapper)
        self.navigator.squeeze = self.planners.squeeze
        self._map: OccupancyGrid | None = None
        self._obstacles: ObstacleLayer | None = None
        self._next_obstacle_update = 0.0
        self._localized = mode == "build"
        self._offset = np.zeros(3)  # estimate - truth (x, y, yaw) while localized
        self._lost = False
        self._estimate: Pose2D | None = None
        self._reloc: RelocHandle | None = None
        self._matchers: dict[int, Any] = {}
        # Sensors.
        self._scan_index = -1
        self._scan_pose = self._true
        self._scan_people = self.people.positions.copy()
        self._scan: LaserScan | None = None
        self._last_frame = -math.inf
        self._apply_during(0.0)  # changes due "at: 0" hold from the start
        self._take_scan()
        self._update_estimate()
        self._perceive()

    # -- port: time and state --------------------------------------------------------------
    def now(self) -> float:
        return self.clock.now()

    @property
    def true_pose(self) -> Pose2D:
        """Ground truth, for tests and evaluation only: behaviours must use :meth:`pose`."""
        return self._true

    def pose(self) -> Pose2D | None:
        return self._estimate if self._localized else None

    @property
    def building_map(self) -> bool:
        """True while the map is built from scans (a build, before any saved map is in use)."""
        return self.mapper is not None and self._map is None

    def current_objects(self) -> dict[str, WorldObject]:
        return dict(self._objects)

    def current_obstacles(self) -> list:
        return list(self.scene.obstacles)

    def people_positions(self) -> list[tuple[float, float]]:
        return [(float(x), float(y)) for x, y in self.people.positions]

    def live_map(self) -> OccupancyGrid:
        if self._map is not None:
            return self._map
        if self.mapper is not None:
            return self.mapper.grid()
        g = self.world.grid
        return OccupancyGrid.unknown(g.width, g.height, g.resolution, g.origin)

    def use_map(self, grid: OccupancyGrid) -> None:
        self._map = grid
        self._obstacles = ObstacleLayer(grid, self.params.obstacles)
        self.planners.use_map(grid, self._obstacles)
        self._matchers.clear()

    def refresh_map(self, grid: OccupancyGrid) -> None:
        """Navigate and localize on ``grid`` from now on; the obstacle layer keeps its marks (its
        version moves on: the costmap, map and layer, changed)."""
        if self._obstacles is None:
            return self.use_map(grid)
        self._map, self._obstacles.version = grid, self._obstacles.version + 1
        self.planners.use_map(grid, self._obstacles)
        self._matchers.clear()

    # -- port: stepping --------------------------------------------------------------------
    def step(self) -> None:
        p = self.params
        now = self.clock.tick()
        self._apply_during(now)
        self.people.step(p.dt, self._true.xy, p.motion.body_radius)
        v, w = 0.0, 0.0
        if self._localized and self.navigator.active:
            v, w = self.navigator.update(self._estimate, now, self.planners.around, self.planners.path_clear,
                                           self._stuck)
        self._move(v, w, p.dt)
        self._update_relocalization(now)
        self._update_estimate()
        if self.clock.every(1.0 / p.lidar.rate) != self._scan_index:
            self._take_scan()
        self._perceive()

    def _apply_during(self, now: float) -> None:
        while self._pending and self._pending[0].at <= now + 1e-9:
            if lands_on(self._pending[0].change, self._objects, self._true.xy, self.params.motion.body_radius + 0.1):
                return  # held back until the robot has moved clear (world/timeline.py)
            self._apply_next_during()

    def _apply_next_during(self) -> None:
        change = self._pending.pop(0).change
        self._objects = apply_change(self._objects, change, self.world.path, "during")
        if change.obstacles:
            self.scene.obstacles.extend(change.obstacles)
        self._during_applied += 1
        self.scene.set_objects(self._objects)

    # -- exact resume (bomc_bt.sim.checkpoint) ---------------------------------------------
    def checkpoint(self) -> dict[str, Any]:
        """This step's state, JSON-able: saved with a pass's progress."""
        from bomc_bt.sim.checkpoint import robot_state

        return robot_state(self)

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from a :meth:`checkpoint` of this session (call after :meth:`use_map`)."""
        from bomc_bt.sim.checkpoint import restore_robot

        restore_robot(self, state)

    def _move(self, v: float, w: float, dt: float) -> None:
        """Unicycle step on the true pose; a translation into anything solid is deflected
        along it at a glancing angle and refused otherwise (:mod:`bomc_bt.sim.contact`)."""
        t = self._true
        yaw = wrap_angle(t.yaw + w * dt)
        mid = t.yaw + 0.5 * w * dt
        x, y = t.x + v * math.cos(mid) * dt, t.y + v * math.sin(mid) * dt
        self._stuck = False
        if v != 0:
            radius = self.params.motion.body_radius
            before = self.scene.clearance(t.x, t.y)
            after = self.scene.clearance(x, y)
            if self.people.blocks(np.array([x, y]), radius):  # a person in the way: stop, wait
                x, y = t.x, t.y
                self._stuck = True
            elif not allowed(before, after, radius):  # contact: deflected, or stopped (sim/contact.py)
                along = slide_along(self.scene, self.people, t, x, y, radius)
                if along is not None:
                    x, y = along
                else:
                    x, y = slide_out(self.scene, self.people, t, radius)
                    self._stuck = True
        self.distance_travelled += math.hypot(x - t.x, y - t.y)
        self._true = Pose2D(x, y, yaw)

    # -- sensing and maps ------------------------------------------------------------------
    def _take_scan(self) -> None:
        self._scan_index = self.clock.every(1.0 / self.params.lidar.rate)
        self._scan_pose = self._true
        self._scan_people = self.people.positions.copy()
        self._scan = None

    def scan(self) -> LaserScan | None:
        if self._scan is None:
            rng = np.random.default_rng([self.seed, 7, self._scan_index])
            self._scan = self.lidar.scan(self._scan_pose, self.scene.lidar_field, self._scan_stamp(), rng,
                                         self._scan_people, PERSON_RADIUS)
        return self._scan

    def _short_scan(self) -> LaserScan:
        """The latest scan cast only as far as the obstacle layer looks (unless already cast)."""
        if self._scan is not None:
            return self._scan
        rng = np.random.default_rng([self.seed, 7, self._scan_index])
        limit = self.params.obstacles.raytrace_range + 0.5
        return self.lidar.scan(self._scan_pose, self.scene.lidar_field, self._scan_stamp(), rng,
                               self._scan_people, PERSON_RADIUS, range_limit=limit)

    def _scan_stamp(self) -> float:
        return self._scan_index / self.params.lidar.rate

    def _perceive(self) -> None:
        """Integrate the latest scan into the map (build) or the obstacle layer (monitor)."""
        if self.mapper is not None and self._map is None:
            if self.mapper.needs_update(self._scan_pose):
                self.mapper.integrate(self.scan(), self._scan_pose)
        elif self._obstacles is not None and self._localized and self.now() >= self._next_obstacle_update:
            self._next_obstacle_update = self.now() + self.params.obstacles.update_period
            self._obstacles.update(self._short_scan(), self._estimate_at(self._scan_pose))

    # -- port: navigation ------------------------------------------------------------------
    def navigate(self, goal: Pose2D) -> NavHandle:
        resumed, self._resumed_navigation = self._resumed_navigation, None
        if resumed is not None and resumed.status() is Status.RUNNING and resumed.goal == goal:
            return resumed  # a resumed pass sends the goal it was driving to: drive on (sim/checkpoint.py)
        if not self._localized:
            self.navigator.cancel()
            handle = NavHandle(goal)
            handle.finish(Status.FAILED, "not localized")
            return handle
        if self.mapper is None and self._map is None:
            handle = NavHandle(goal)
            handle.finish(Status.FAILED, "no map in use")
            return handle
        return self.navigator.start(goal, self._estimate, self.now(), self.planners.around, self.planners.static)

    def clear_costmaps(self) -> None:
        """Empty the obstacle layer (monitor); the next scan starts refilling it at once."""
        if self._obstacles is not None:
            self._obstacles.clear()
            self._next_obstacle_update = self.now()

    def obstacle_layer(self) -> np.ndarray:
        """The obstacle layer's marked cells (monitor; empty while building)."""
        return self._obstacles.points() if self._obstacles is not None else np.zeros((0, 2))

    @property
    def costmap_version(self) -> int | None:
        """Changes whenever :meth:`costmap` does; None while no saved map is in use."""
        return None if self._obstacles is None else self._obstacles.version

    def costmap(self) -> OccupancyGrid | None:
        """The map in use with the obstacle layer's marks lethal: move_base's global costmap
        without inflation, as the sim-over-ROS bridge publishes it. None while building."""
        if self._obstacles is None or self._map is None:
            return None
        data = self._map.data.copy()
        data[self._obstacles.mask] = 100
        return OccupancyGrid(data, self._map.resolution, self._map.origin)

    def cancel_all(self) -> None:
        self.navigator.cancel()
        if self._reloc is not None:
            self._reloc.cancel()

    # -- port: localization ----------------------------------------------------------------
    def relocalize(self, hint: Pose2D | None, global_search: bool = False) -> RelocHandle:
        lp = self.params.localization
        if self._reloc is not None:
            self._reloc.cancel()
        duration = lp.global_duration if global_search or hint is None else lp.local_duration
        handle = RelocHandle(self.now() + duration, hint, global_search or hint is None)
        if self.mapper is not None and self._map is None:
            handle.finish(Status.SUCCEEDED, "localized (building the map)")
        elif self._map is None:
            handle.finish(Status.FAILED, "no map in use")
        else:
            self._reloc = handle
        return handle

    def _update_relocalization(self, now: float) -> None:
        handle = self._reloc
        if handle is None or handle.status() is not Status.RUNNING or now < handle.done_at - 1e-9:
            return
        self._reloc = None
        from bomc_bt.localization import ScanMatcher  # lazy: only monitor missions need it

        assert self._map is not None
        matcher = self._matchers.get(id(self._map))
        if matcher is None:
            matcher = ScanMatcher(self._map, self._relocalization_params())
            self._matchers[id(self._map)] = matcher
        self._take_scan()
        result = matcher.match(self.scan(), handle.hint, handle.global_search)
        if not result.confident:
            handle.finish(Status.FAILED, f"relocalization not confident (score {result.score:.2f})")
            return
        est = result.pose
        t = self._true
        self._offset = np.array([est.x - t.x, est.y - t.y, wrap_angle(est.yaw - t.yaw)])
        lp = self.params.localization
        self._lost = math.hypot(*self._offset[:2]) > lp.lost_distance or abs(self._offset[2]) > lp.lost_angle
        self._localized = True
        self._next_obstacle_update = now
        handle.finish(Status.SUCCEEDED, f"localized (score {result.score:.2f})")

    def _relocalization_params(self):
        if self.relocalization_params is not None:
            return self.relocalization_params
        from bomc_bt.localization import RelocalizationParams

        return RelocalizationParams()

    def _update_estimate(self) -> None:
        """The reported pose for this step: truth + decaying estimate error + noise."""
        if not self._localized:
            self._estimate = None
            return
        lp = self.params.localization
        if not self._lost and self._offset.any():
            self._offset *= math.exp(-self.params.dt / lp.correction_time)
        self._estimate = self._estimate_at(self._true, noisy=True)

    def _estimate_at(self, true: Pose2D, noisy: bool = False) -> Pose2D:
        o = self._offset
        x, y, yaw = true.x + o[0], true.y + o[1], true.yaw + o[2]
        sigma = self.params.faults.localization_noise
        if noisy and sigma > 0 and self.mode == "monitor":
            dx, dy, dyaw = self._noise_rng.normal(0.0, 1.0, 3) * np.array([sigma, sigma, sigma / 2.0])
            x, y, yaw = x + dx, y + dy, yaw + dyaw
        return Pose2D(float(x), float(y), wrap_angle(float(yaw)))

    # -- port: camera ----------------------------------------------------------------------
    def frame(self) -> RGBDFrame | None:
        if self.camera is None or not self._localized or self._estimate is None:
            return None
        rate = float(getattr(self.camera, "rate", 1.0))
        if self.now() < self._last_frame + 1.0 / rate - 1e-9:
            return None
        self._last_frame = self.now()
        frame = self.camera.render(self.world.walls(), self.world.grid, self.world.wall_height,
                                   list(self._objects.values()), list(self.scene.obstacles),
                                   self.people_positions(), self._true, self._estimate, self.now())
        if isinstance(frame, SimFrame):
            frame.world_key = self.world.key
        return frame
