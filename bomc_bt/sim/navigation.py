"""Simulated move_base: goal handles, periodic replanning, path following, progress checks.

The navigator only *decides* (a velocity command per step and the goal's status); the
robot applies the command to the true pose and checks collisions. Planning goes through
a callback that returns a :class:`GridPlanner` for the current map (cached by the robot),
so the navigator never knows whether the map is being built or was loaded.

Status rules (what a behaviour sees):

* SUCCEEDED: the (estimated) position is within ``goal_tolerance`` of the goal.
* FAILED: there is no path on the map at all when the goal is given, or an injected
  failure fired (``FaultParams.nav_failure_probability``).
* BLOCKED: the goal is inside an obstacle (no traversable cell within the tolerance, in
  the obstacle-aware map), or the robot made no progress along its plan for
  ``progress_timeout`` seconds of sim time (a blocked corridor with no way around, a
  person who will not move, an obstacle the lidar cannot see), or, on a saved map, had no
  plan at all from where it stands for ``plan_patience`` seconds (move_base's
  ``planner_patience``). A monitor pass's robot hemmed in by furniture new since the map
  (a small house at 0.1 m with 25 objects, generated world seed 8553, pass 6) waited out the
  whole progress timeout at every goal and detour: 15 s each, about 60 s per waypoint,
  22 waypoints, before the stuck diagnosis ended the pass.
* CANCELLED: a new goal or :meth:`cancel` pre-empted it.

Squeezing: when the live planner has no path, the navigator tries the ``squeeze`` planner
(known space only, the clearance of ``PlannerParams.squeeze_radius``) before it waits or
fails. Planning through unknown space can take the robot through a gap that, once seen, is
narrower than twice the planner's radius: the strip between a building and the map's
edge, a gap between furniture. Without it the robot waited there for the progress timeout
and exploration ended "done" with the rest of the building unreachable (issue 16,
hospital). On a saved map the same happens with the obstacle layer: the passage the robot
came in by, a hand's width wider than the robot, is closed behind it by returns the map
drew a cell thinner, and the robot waited out the rest of its pass (a real office's SLAM
map at 0.1 m, session 3: 680 s and 144 waypoints).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.planner import GridPlanner, path_length
from bomc_bt.robot import RequestHandle, Status
from bomc_bt.sim.params import MotionParams


class NavHandle(RequestHandle):
    """One navigation goal's status, as returned by ``navigate``."""

    def __init__(self, goal: Pose2D):
        super().__init__("driving")
        self.goal = goal


PlannerSource = Callable[[], GridPlanner]
GoalPlannerSource = Callable[[np.ndarray, np.ndarray], Any]  # (start, goal) -> a planner for that goal
SqueezeSource = Callable[[np.ndarray, np.ndarray], Any]  # (start, goal) -> the last-resort planner or None
PathCheck = Callable[[np.ndarray, float], bool]  # (path ahead, metres to skip) -> still clear?


class Navigator:
    """Drives one goal at a time; call :meth:`update` once per sim step."""

    def __init__(self, params: MotionParams, goal_tolerance: float, rng: np.random.Generator,
                 failure_probability: float = 0.0):
        self.params = params
        self.goal_tolerance = goal_tolerance
        self.rng = rng
        self.failure_probability = failure_probability
        self.handle: NavHandle | None = None
        self.path: np.ndarray | None = None
        self._cum: np.ndarray | None = None
        self._best = math.inf
        self._last_progress = 0.0
        self._marks = np.zeros((0, 3))  # (time, x, y) where progress was counted lately
        self._next_check = 0.0
        self._fail_at = math.inf
        self._stuck_since: float | None = None
        self._backup_until = -math.inf
        self._at_position = False
        self._no_plan_since: float | None = None  # sim time the robot began waiting with no plan
        self.plan_patience: float | None = None  # s (set by the robot on a saved map); None: none
        self.squeeze: SqueezeSource | None = None  # the last-resort planner (set by the robot)

    # -- goals ---------------------------------------------------------------------------
    def start(self, goal: Pose2D, pose: Pose2D, now: float, planner: GoalPlannerSource,
              static_planner: PlannerSource) -> NavHandle:
        """Begin driving to ``goal`` from the estimated ``pose`` (pre-empts the old goal)."""
        if self.handle is not None:
            self.handle.finish(Status.CANCELLED, "pre-empted by a new goal")
        handle = NavHandle(goal)
        self.handle = handle
        self.path = None
        self._at_position = False
        self._best = math.inf
        self._last_progress = now
        self._marks = np.array([[now, pose.x, pose.y]])
        self._fail_at = math.inf
        self._no_plan_since = None
        current = planner(pose.xy, goal.xy)
        if current.nearest_traversable(goal.xy, self.goal_tolerance) is None:
            handle.finish(Status.BLOCKED, "goal is inside an obstacle")
            return handle
        path = current.plan(pose.xy, goal.xy)
        if path is None:
            path = self._squeeze_plan(pose, goal)
        if path is None:
            static = static_planner()
            if static is current or static.plan(pose.xy, goal.xy) is None:
                handle.finish(Status.FAILED, "no path to the goal")
                return handle
            handle._message = "waiting: the way is blocked by obstacles"
            self._no_plan_since = now
        else:
            self._set_path(path)
        self._next_check = now + self.params.replan_period
        if self.failure_probability > 0 and self.rng.random() < self.failure_probability:
            expected = path_length(path) / self.params.max_speed if path is not None else 10.0
            self._fail_at = now + self.rng.uniform(0.0, max(expected, 1.0))
        return handle

    def cancel(self) -> None:
        if self.handle is not None:
            self.handle.cancel()
        self.path = None

    @property
    def active(self) -> bool:
        return self.handle is not None and self.handle.status() is Status.RUNNING

    def _set_path(self, path: np.ndarray) -> None:
        self.path = path
        seg = np.hypot(*np.diff(path, axis=0).T) if len(path) > 1 else np.zeros(0)
        self._cum = np.concatenate([[0.0], np.cumsum(seg)])
        if self.handle is not None:
            self.handle._message = "driving"

    # -- per step ------------------------------------------------------------------------
    def update(self, pose: Pose2D, now: float, planner: GoalPlannerSource, path_clear: PathCheck,
               stuck: bool) -> tuple[float, float]:
        """The (v, w) command for this step from the estimated ``pose``; updates the status.

        ``stuck`` says the robot could not move last step (collision): replan sooner.
        """
        handle = self.handle
        if handle is None or handle.status() is not Status.RUNNING:
            return 0.0, 0.0
        goal = handle.goal
        p = self.params
        if now >= self._fail_at:
            return self._end(Status.FAILED, "navigation aborted (injected failure)")
        if self._at_position or math.hypot(goal.x - pose.x, goal.y - pose.y) <= self.goal_tolerance:
            self._at_position = True  # then only the heading is left: turn on the spot
            err = wrap_angle(goal.yaw - pose.yaw)
            if abs(err) <= p.yaw_tolerance:
                return self._end(Status.SUCCEEDED, "goal reached")
            return 0.0, math.copysign(min(p.max_turn_rate, max(0.3, p.heading_gain * abs(err))), err)
        if now >= self._next_check:
            result = self._check_path(pose, planner, path_clear, stuck, now)
            if result is not None:
                return result
            self._next_check = now + (p.blocked_replan_period if stuck or self.path is None
                                      else p.replan_period)
        patience = self.plan_patience
        if patience is not None and self.path is None and self._no_plan_since is not None \
                and now - self._no_plan_since >= patience:
            return self._end(Status.BLOCKED, f"no plan for {patience:g} s")
        if self._made_progress(pose, now):
            self._last_progress = now
        if now - self._last_progress >= p.progress_timeout:
            return self._end(Status.BLOCKED, f"no progress for {p.progress_timeout:g} s")
        if stuck and now + p.blocked_replan_period < self._next_check:
            self._next_check = now + p.blocked_replan_period
        recovery = self._recovery(now, stuck)
        if recovery is not None:
            return recovery
        if self.path is None:
            return 0.0, 0.0
        return self._follow(pose, goal)

    def _made_progress(self, pose: Pose2D, now: float) -> bool:
        """Whether the remaining path shrank by ``progress_step`` *and* the robot stands
        ``progress_step`` from everywhere progress was counted in the last ``progress_timeout``.

        Each replan resets the best remaining length to the new path's. A robot stopped by
        something the map does not show, whose plan flips between two paths (a wall mapped
        with flickering holes, noise on the live map), backed up, drove back to the same
        spot or to the same spot on the other path, and "progressed" at every flip: its
        goal never became BLOCKED and it pushed for 250 s until the time limit (hospital,
        20-start draw, gain start 16). Progress is reaching new ground, as move_base's
        oscillation check has it; ground from more than ``progress_timeout`` ago counts again
        (a robot backing out of a dead end retraces its way).
        """
        p = self.params
        remaining = self._remaining(pose)
        if remaining >= self._best - p.progress_step:
            return False
        marks = self._marks[self._marks[:, 0] > now - p.progress_timeout]
        if len(marks) and np.hypot(marks[:, 1] - pose.x, marks[:, 2] - pose.y).min() < p.progress_step:
            self._marks = marks
            return False
        self._best = remaining
        self._marks = np.vstack([marks, [now, pose.x, pose.y]])
        return True

    def _recovery(self, now: float, stuck: bool) -> tuple[float, float] | None:
        """move_base's back-up recovery: wedged against something for a while, reverse a little.

        A robot whose every forward step is refused (it brushed a chair, its planned path
        starts inside the inflated zone) would otherwise wait for the progress timeout;
        backing off 0.3 m frees it and the next replan goes around.
        """
        if now < self._backup_until:
            return -0.2, 0.0
        if not stuck:
            self._stuck_since = None
            return None
        if self._stuck_since is None:
            self._stuck_since = now
        if now - self._stuck_since >= 1.0:
            self._stuck_since = None
            self._backup_until = now + 1.5
            self._next_check = now + 1.5
            return -0.2, 0.0
        return None

    def _end(self, status: Status, message: str) -> tuple[float, float]:
        assert self.handle is not None
        self.handle.finish(status, message)
        self.path = None
        return 0.0, 0.0

    def _check_path(self, pose: Pose2D, planner: GoalPlannerSource, path_clear: PathCheck,
                    stuck: bool, now: float) -> tuple[float, float] | None:
        """Replan when the current path is no longer clear, there is none, or we are stuck."""
        assert self.handle is not None
        if self.path is not None and not stuck and path_clear(self._ahead(pose), self.params.body_radius):
            return None
        goal = self.handle.goal
        current = planner(pose.xy, goal.xy)
        if current.nearest_traversable(goal.xy, self.goal_tolerance) is None:
            return self._end(Status.BLOCKED, "goal is inside an obstacle")
        path = current.plan(pose.xy, goal.xy)
        if path is None:
            path = self._squeeze_plan(pose, goal)
        escape = (None if path is not None or current.traversable(pose.xy)
                  else current.nearest_traversable(pose.xy, 1.0, visible=True))
        if escape is not None and math.hypot(*(escape - pose.xy)) > 0.02:
            # Wedged inside the inflated zone with no plan from here: first step out of it
            # (move_base's recovery would clear the costmap or back up), then replan.
            self._set_path(np.array([pose.xy, escape]))
            self._best = math.inf
            self.handle._message = "escaping the inflated zone"
            self._next_check = min(self._next_check, 0.0)
        elif path is None:
            self.path = None
            self.handle._message = "waiting: the way is blocked by obstacles"
            self._best = math.inf
            self._no_plan_since = now if self._no_plan_since is None else self._no_plan_since
            return None
        else:
            self._set_path(path)
            self._best = path_length(path)
        self._no_plan_since = None
        return None

    def _squeeze_plan(self, pose: Pose2D, goal: Pose2D) -> np.ndarray | None:
        """A path that keeps only ``squeeze_radius`` from walls, through known space; None
        without a squeeze planner or a path."""
        planner = self.squeeze(pose.xy, goal.xy) if self.squeeze is not None else None
        if planner is None or planner.nearest_traversable(goal.xy, self.goal_tolerance) is None:
            return None
        path = planner.plan(pose.xy, goal.xy)
        if path is not None and self.handle is not None:
            self.handle._message = "squeezing through a gap narrower than the planner's clearance"
        return path

    # -- path geometry -------------------------------------------------------------------
    def _closest(self, pose: Pose2D) -> float:
        """Arc length of the path point closest to the robot."""
        assert self.path is not None and self._cum is not None
        a, b = self.path[:-1], self.path[1:]
        if len(a) == 0:
            return 0.0
        ab = b - a
        denom = np.maximum((ab**2).sum(axis=1), 1e-12)
        t = np.clip(((pose.xy - a) * ab).sum(axis=1) / denom, 0.0, 1.0)
        proj = a + ab * t[:, None]
        i = int(np.argmin(np.hypot(*(proj - pose.xy).T)))
        return float(self._cum[i] + t[i] * (self._cum[i + 1] - self._cum[i]))

    def _remaining(self, pose: Pose2D) -> float:
        if self.path is None or self._cum is None:
            return math.inf
        return float(self._cum[-1] - self._closest(pose))

    def _point_at(self, s: float) -> np.ndarray:
        assert self.path is not None and self._cum is not None
        s = min(max(s, 0.0), float(self._cum[-1]))
        return np.array([np.interp(s, self._cum, self.path[:, 0]), np.interp(s, self._cum, self.path[:, 1])])

    def _ahead(self, pose: Pose2D) -> np.ndarray:
        """The rest of the path from the robot's closest point."""
        assert self.path is not None and self._cum is not None
        s = self._closest(pose)
        later = self._cum > s
        return np.vstack([self._point_at(s), self.path[later]])

    def _follow(self, pose: Pose2D, goal: Pose2D) -> tuple[float, float]:
        """Pure pursuit with turn-in-place for large heading errors."""
        p = self.params
        target = self._point_at(self._closest(pose) + p.lookahead)
        dx, dy = target[0] - pose.x, target[1] - pose.y
        if math.hypot(dx, dy) < 1e-6:
            dx, dy = goal.x - pose.x, goal.y - pose.y
        err = wrap_angle(math.atan2(dy, dx) - pose.yaw)
        w = max(-p.max_turn_rate, min(p.max_turn_rate, p.heading_gain * err))
        if abs(err) > p.turn_in_place_angle:
            return 0.0, math.copysign(p.max_turn_rate, err)
        to_goal = math.hypot(goal.x - pose.x, goal.y - pose.y)
        v = min(p.max_speed, max(0.15, to_goal)) * max(math.cos(err), 0.0)
        return v, w
