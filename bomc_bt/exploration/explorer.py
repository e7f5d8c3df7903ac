"""The state of one exploration run: what the Explore leaves ask between ticks.

Frontier search (:mod:`.frontiers`) and the DWFE choice (:mod:`.dwfe`) are pure
functions of a map; an exploration also remembers things across goals: goals that
failed (the :mod:`.blacklist`, whose entries come back when the map around them
changes), how many failed in a row, the way the robot came (:mod:`.progress`), the
mapped area over time, and why it ended. Keeping that here leaves the behaviours thin and
lets tests drive an exploration without a tree.

How an exploration ends (``status``):

* ``done``: no frontier the planner can reach is left (the others may remain as
  unreachable border, or as goals that failed and may no longer be retried);
* ``time_limit``: the user's time limit (``--max-time`` or ``exploration.max_time``);
* ``no_progress``: less than ``min_progress_area`` newly mapped in ``no_progress_time``
  seconds of robot time (the runaway guard; there is no time limit by default);
* ``stuck``: goals keep failing without the robot moving, even after it backed out along
  the way it came ``max_backouts`` times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from bomc_bt.exploration.blacklist import Blacklist
from bomc_bt.exploration.decision_cache import DecisionCache
from bomc_bt.exploration.dwfe import Choice, ExplorationParams, choose_frontier
from bomc_bt.exploration.frontiers import Frontier, find_frontiers, touches_unknown
from bomc_bt.exploration.gain import visible_unknown
from bomc_bt.exploration.gain_choice import Candidate, choose_by_gain
from bomc_bt.exploration.progress import AreaWatch
from bomc_bt.exploration.reachability import Reachability
from bomc_bt.exploration.turn_look import TurnLooks
from bomc_bt.grid import OccupancyGrid
from bomc_bt.planner import PlannerParams
from bomc_bt.trail import Trail

EXPLORING = "exploring"
DONE = "done"
TIME_LIMIT = "time_limit"
NO_PROGRESS = "no_progress"
STUCK = "stuck"


@dataclass
class Goal:
    """A frontier chosen as a navigation goal, or a back-out point on the way the robot came."""

    xy: tuple[float, float]
    frontier: Frontier | None
    window: str
    chosen_at: float
    backout: bool = False
    anchor: tuple[float, float] | None = None  # the frontier cell the goal looks at (default: xy)

    @property
    def looks_at(self) -> tuple[float, float]:
        """Where the frontier this goal serves is: its anchor, else the goal itself."""
        return self.anchor if self.anchor is not None else self.xy


class Explorer:
    """Chooses frontier goals until none is reachable, a limit is hit, or the robot is stuck.

    ``planner`` (the navigation planner's parameters) enables the planner-reachability
    filter (``params.planner_reachable``); without it frontiers are reachable through
    free cells, as explore_lite counts them.
    """

    def __init__(self, params: ExplorationParams, start_time: float, max_time: float | None = None,
                 max_consecutive_failures: int = 5, clearance: float = 0.35, min_goal_distance: float = 0.6,
                 planner: PlannerParams | None = None):
        self.params = params
        self.start_time = start_time
        self.max_time = params.time_limit if max_time is None else (max_time if max_time > 0 else None)
        self.max_consecutive_failures = max_consecutive_failures
        self.clearance = clearance
        self.min_goal_distance = min_goal_distance
        self.planner = planner if params.planner_reachable else None
        # The gain explorer ranks by path length on the planner's grid: it always needs one.
        self.gain_planner = planner or PlannerParams()
        self.blacklist = Blacklist.for_params(params)
        self.status = EXPLORING
        self.reason = ""
        self.goals = 0
        self.failures = 0
        self.backouts = 0
        self.consecutive_failures = 0
        self.last_choice: Choice | None = None
        self._streak_start: tuple[float, float] | None = None
        self._streak_backouts = 0
        self._backout_due = False
        self._last_anchor: tuple[float, float] | None = None
        self._yaw: float | None = None
        self.frontiers: list[Frontier] = []
        self.unreachable: list[Frontier] = []
        self.area = AreaWatch(params.no_progress_time, params.min_progress_area, start_time)
        self.trail = Trail()
        self.turns = TurnLooks()
        # standoff goals and gains kept across decisions, per reachable-area radius (decision_cache)
        self._caches: dict[float, DecisionCache] = {}

    def time_up(self, now: float) -> bool:
        return self.max_time is not None and now - self.start_time >= self.max_time

    def observe(self, robot_xy: tuple[float, float] | None, now: float, area: float | None = None) -> None:
        """The robot's position and (when known) the mapped area at ``now``; called every tick."""
        if robot_xy is not None:
            self.trail.add(robot_xy)
        if area is not None and self.area.update(area, now):
            self._streak_backouts = 0  # new map: back-outs are allowed again

    def limit_reached(self, now: float) -> bool:
        """Whether the time limit or the progress guard ends the exploration (sets the status)."""
        if self.status != EXPLORING:
            return True
        if self.time_up(now):
            self._finish(TIME_LIMIT, f"time limit of {self.max_time:.0f} s reached")
        elif self.area.stalled(now):
            self._finish(NO_PROGRESS, f"less than {self.params.min_progress_area:g} m² newly mapped in "
                                      f"{self.params.no_progress_time:.0f} s")
        return self.status != EXPLORING

    def next_goal(self, grid: OccupancyGrid, robot_xy: tuple[float, float], now: float,
                  robot_yaw: float | None = None) -> Goal | None:
        """The next frontier (or back-out point) to drive to, or None with :attr:`status`
        saying why not. ``robot_yaw`` (rad), when known, lets the gain explorer count the
        turn on the spot a goal behind the robot costs."""
        self.observe(robot_xy, now, grid.free_area())
        if self.limit_reached(now):
            return None
        gain = self.params.explorer == "gain"
        planner = self.gain_planner if gain else self.planner
        reach = Reachability(grid, planner, robot_xy) if planner is not None else None
        if self._backout_due:
            self._backout_due = False
            goal = self._backout(robot_xy, now, reach)
            if goal is not None:
                return goal
        self.blacklist.readmit(grid, robot_xy)
        # A frontier whose best target is where the robot already stands (the blind sector
        # behind a 220-degree lidar) is mapped by the turn towards any other goal: _choose
        # skips those.
        self._yaw = robot_yaw
        candidates = self._candidates(grid, robot_xy, reach)
        choice, best = self._choose(grid, robot_xy, reach, candidates)
        self.last_choice = choice
        window = choice.window
        if best is None and self.unreachable and reach is not None:
            choice, best = self._from_pocket(grid, robot_xy, reach, choice)
            window = "squeeze"
        if best is None:  # last resort: turn to face a frontier at the robot's feet (.turn_look)
            gain = self._cache(reach).gains if self.params.explorer == "gain" and reach is not None else None
            best, window = self.turns.pick(candidates, robot_xy, self.min_goal_distance, self.blacklist, gain,
                                           self.params.min_gain), "turn"
        if best is None:
            unreachable = f"; {len(self.unreachable)} more the planner cannot reach" if self.unreachable else ""
            return self._finish(DONE, (choice.reason or "no frontiers left") + unreachable)
        self.goals += 1
        self._last_anchor = best.anchor
        if window == "turn":  # stay, and face the way the robot's back faced (the blind sector)
            return Goal(robot_xy, best.frontier, window, now, anchor=self.turns.behind(robot_xy, robot_yaw, best))
        return Goal(best.goal, best.frontier, window, now, anchor=best.anchor)

    def _choose(self, grid: OccupancyGrid, robot_xy: tuple[float, float], reach: Reachability | None,
                candidates: list[Candidate]) -> tuple[Choice, Candidate | None]:
        """The explorer's pick among ``candidates`` (those far enough from the robot)."""
        far = [c for c in candidates if math.dist(c.goal, robot_xy) >= self.min_goal_distance]
        if self.params.explorer == "gain":
            return choose_by_gain(grid, far, robot_xy, reach, self.params, self.blacklist, self._last_anchor,
                                  self._yaw, gain_of=self._cache(reach).gains)
        choice = choose_frontier([c.frontier for c in far], robot_xy, self.params, self.blacklist)
        return choice, next((c for c in far if c.frontier is choice.frontier), None)

    def _from_pocket(self, grid: OccupancyGrid, robot_xy: tuple[float, float], reach: Reachability,
                     choice: Choice) -> tuple[Choice, Candidate | None]:
        """A goal the robot reaches only by squeezing, or (``choice``, None) when there is none.

        The planner's radius (0.3 m) is wider than the body (0.24 m), and the lidar maps a
        wall about a cell thicker than it is: a 0.7 m doorway reads as no way through.
        Planning through unknown space also takes the robot through gaps that, once seen,
        are that narrow (the strip between a building and the map's edge). Every frontier
        beyond is then "unreachable" and the build ended "done" with most of the floor
        unmapped (hospital, issue 16). So when the planner's component has no goal left,
        frontiers are chosen in the component of the squeeze radius
        (:attr:`PlannerParams.squeeze_radius`, still wider than the body), and the navigator
        squeezes through to them (:mod:`bomc_bt.sim.navigation`).
        """
        planner = reach.params
        if planner.squeeze_radius >= planner.robot_radius:
            return choice, None
        wide = Reachability(grid, replace(planner, robot_radius=planner.squeeze_radius), robot_xy)
        if np.count_nonzero(wide.component) <= np.count_nonzero(reach.component):
            return choice, None
        kept = self.frontiers, self.unreachable
        squeezed, best = self._choose(grid, robot_xy, wide, self._candidates(grid, robot_xy, wide))
        if best is None:
            self.frontiers, self.unreachable = kept
            return choice, None
        return squeezed, best

    def _candidates(self, grid: OccupancyGrid, robot_xy: tuple[float, float],
                    reach: Reachability | None) -> list[Candidate]:
        """Frontiers the robot can be driven to, each with its goal point; sets
        :attr:`frontiers` (those) and :attr:`unreachable` (the rest).

        With the planner's reachable area known, the goal is a safe standoff
        (:class:`.gain.Standoffs`); a frontier with none within ``max_standoff`` (a narrow
        passage) falls back to its own cell nearest the centroid that the robot fits on.
        """
        found = find_frontiers(grid, robot_xy, min_size=self.params.min_size_cells(grid.resolution))
        if reach is None:
            distance = obstacle_distance(grid)
            self.frontiers, self.unreachable = found, []
            return [_plain(f, frontier_target(grid, f, distance, self.clearance)) for f in found]
        reachable, self.unreachable = reach.split(found)
        self.frontiers = [f for f, _ in reachable]
        cache = self._cache(reach)
        cache.update(grid, reach)
        out, distance = [], None
        for f, ok in reachable:
            safe = cache.standoff(f)
            if safe is None and distance is None:
                distance = obstacle_distance(grid)  # only the fallback needs it
            out.append(Candidate(f, *safe) if safe is not None
                       else _plain(f, frontier_target(grid, f, distance, self.clearance, ok)))
        return out

    def _cache(self, reach: Reachability) -> DecisionCache:
        """The decision cache of ``reach``'s radius (the planner's, or the squeeze radius)."""
        radius = reach.params.robot_radius
        if radius not in self._caches:
            self._caches[radius] = DecisionCache(self.clearance, self.params.max_standoff, self.params.gain_radius)
        return self._caches[radius]

    def _backout(self, robot_xy, now: float, reach: Reachability | None) -> Goal | None:
        accept = reach.contains if reach is not None else None
        xy = self.trail.back(robot_xy, self.params.backout_distance, accept)
        if xy is None:
            self._streak_backouts = self.params.max_backouts  # nowhere to back out to
            return None
        self.backouts += 1
        self._streak_backouts += 1
        return Goal(xy, None, "backout", now, backout=True)

    def goal_reached(self, goal: Goal | None = None, still_open: bool = False,
                     grid: OccupancyGrid | None = None, robot_xy: tuple[float, float] | None = None) -> None:
        """A goal was reached; one reached but still unmapped (e.g. it looks into a glass
        wall or an unreachable pocket) is not chosen again."""
        self.consecutive_failures = 0
        self._streak_start = None
        if goal is not None and goal.backout:
            return
        self._streak_backouts = 0
        if goal is not None and still_open:
            self._blacklist(goal, grid, robot_xy, permanent=True)

    def goal_failed(self, goal: Goal, why: str, robot_xy: tuple[float, float] | None = None,
                    now: float | None = None, grid: OccupancyGrid | None = None) -> None:
        """Blacklist an unreachable goal; failing again and again *without moving* first
        backs the robot out along the way it came, and only then is stuck.

        Failures alone are not enough: near the end of an exploration the frontiers left
        are often shadows behind furniture that no goal reaches, and those are simply
        blacklisted until none remain ("done"). A robot that fails goal after goal while
        staying where it is, though, may be wedged or facing a blocked corridor: after
        the second such failure it drives back ``backout_distance`` along its trail and
        replans from there. Only when that did not help ``max_backouts`` times is it stuck.
        """
        if not goal.backout:
            self._blacklist(goal, grid, robot_xy)
            self.failures += 1
            if now is not None and now - goal.chosen_at < 2.0:
                return  # refused at once (no path, goal in a wall): a bad goal, not a stuck robot
        self.consecutive_failures += 1
        if robot_xy is not None:
            if self.consecutive_failures == 1 or self._streak_start is None:
                self._streak_start = robot_xy
            moved = math.dist(self._streak_start, robot_xy)
        else:
            moved = 0.0
        if moved >= 1.0:
            return
        if self._streak_backouts < self.params.max_backouts:
            self._backout_due = self.consecutive_failures >= 2
        elif self.consecutive_failures >= self.max_consecutive_failures:
            self._finish(STUCK, f"{self.consecutive_failures} goals failed in a row without moving, after "
                                f"{self._streak_backouts} back-out(s) (last: {why})")

    def border(self, grid: OccupancyGrid, robot_xy: tuple[float, float] | None) -> dict:
        """The unknown border left: frontier count and length, reachable and not, how many
        of the reachable ones are blacklisted and, for the gain explorer, how many of the
        others would add less than ``min_gain`` (the build record's ``frontiers_left``)."""
        if robot_xy is None:
            return {}
        gain = self.params.explorer == "gain"
        planner = self.gain_planner if gain else self.planner
        reach = Reachability(grid, planner, robot_xy) if planner is not None else None
        candidates = self._candidates(grid, robot_xy, reach)
        found = [c.frontier for c in candidates]
        allowed = {id(f) for f in self.blacklist.filter(found)}
        out = {"reachable": len(found), "reachable_m": round(sum(f.length for f in found), 2),
               "unreachable": len(self.unreachable),
               "unreachable_m": round(sum(f.length for f in self.unreachable), 2),
               "blacklisted": len(found) - len(allowed), "readmitted": self.blacklist.readmitted}
        if gain:
            gains = visible_unknown(grid, [c.goal for c in candidates if id(c.frontier) in allowed],
                                    self.params.gain_radius)
            out["below_min_gain"] = int(np.count_nonzero(gains < self.params.min_gain))
            out["best_gain_m2"] = round(float(gains.max()), 2) if len(gains) else 0.0
        return out

    def _blacklist(self, goal: Goal, grid: OccupancyGrid | None, robot_xy, permanent: bool = False) -> None:
        # The target and the frontier's centroid: the blacklist matches frontiers by their
        # nearest cell or centroid, and a target may lie away from both on a long frontier.
        self.blacklist.add(goal.xy, goal.frontier.centroid, grid=grid, robot_xy=robot_xy, permanent=permanent)

    def _finish(self, status: str, reason: str) -> None:
        self.status = status
        self.reason = reason
        return None


def _plain(frontier: Frontier, xy: tuple[float, float]) -> Candidate:
    return Candidate(frontier, xy, xy)


def obstacle_distance(grid: OccupancyGrid) -> np.ndarray:
    """Metres from each cell to the nearest occupied cell (unknown is not an obstacle)."""
    return cv2.distanceTransform((~grid.occupied_mask()).astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution


def frontier_target(grid: OccupancyGrid, frontier: Frontier, distance: np.ndarray | None = None,
                    clearance: float = 0.0, usable: np.ndarray | None = None) -> tuple[float, float]:
    """The frontier cell closest to the cluster's centroid among those the robot fits on.

    The centroid of a curved frontier can lie in unknown space or inside a wall; a cell
    of the frontier is a known free cell on the boundary, so the robot sees into the
    unknown from there. Cells nearer a wall than ``clearance`` would be refused by the
    planner as lethal, so they are used only when the whole frontier hugs a wall (then
    the roomiest cell is taken). ``usable`` (a bool per cell) restricts the choice to the
    cells the planner can drive to (:class:`.reachability.Reachability`).
    """
    cells = frontier.cells if usable is None or not usable.any() else frontier.cells[usable]
    rows, cols = cells[:, 0], cells[:, 1]
    xs, ys = grid.cell_to_world(rows, cols)
    cx, cy = frontier.centroid
    d2 = (xs - cx) ** 2 + (ys - cy) ** 2
    if distance is None or clearance <= 0:
        i = int(np.argmin(d2))
        return float(xs[i]), float(ys[i])
    room = distance[rows, cols]
    fits = room >= clearance
    if fits.any():
        i = int(np.argmin(np.where(fits, d2, np.inf)))
        return float(xs[i]), float(ys[i])
    i = int(np.argmin(d2))
    if usable is not None:
        return float(xs[i]), float(ys[i])  # within the planner's goal tolerance of its reachable area
    return standoff(grid, distance, rows[i], cols[i], clearance, search=1.0) or (float(xs[i]), float(ys[i]))


def standoff(grid: OccupancyGrid, distance: np.ndarray, row: int, col: int, clearance: float,
             search: float) -> tuple[float, float] | None:
    """The known free cell nearest (row, col), within ``search`` m, where the robot fits.

    A frontier squeezed between walls (a half-seen doorway) has no cell the robot can
    stand on; a cell a little back in the open still looks through it.
    """
    r = int(math.ceil(search / grid.resolution))
    r0, r1 = max(0, row - r), min(grid.height, row + r + 1)
    c0, c1 = max(0, col - r), min(grid.width, col + r + 1)
    ok = (distance[r0:r1, c0:c1] >= clearance) & (grid.data[r0:r1, c0:c1] == 0)
    if not ok.any():
        return None
    rr, cc = np.nonzero(ok)
    k = int(np.argmin((rr + r0 - row) ** 2 + (cc + c0 - col) ** 2))
    x, y = grid.cell_to_world(rr[k] + r0, cc[k] + c0)
    return float(x), float(y)


def still_open(grid: OccupancyGrid, xy: tuple[float, float], radius: float, min_cells: int) -> bool:
    """Whether the frontier at ``xy`` is still there: at least ``min_cells`` frontier cells
    (free cells with an unknown 4-neighbour) within ``radius``; once it is mapped, drive elsewhere.

    Counting frontier cells, not unknown cells: the unknown inside a wall or behind a
    cabinet next to a frontier that the lidar closed stays unknown for good, and counting
    it kept mapped goals "open" (they were then driven to, and failed or were blacklisted).
    """
    r = int(math.ceil(radius / grid.resolution))
    row, col = grid.world_to_cell(xy[0], xy[1])
    r0, r1 = max(0, int(row) - r - 1), min(grid.height, int(row) + r + 2)
    c0, c1 = max(0, int(col) - r - 1), min(grid.width, int(col) + r + 2)
    window = grid.data[r0:r1, c0:c1]
    cells = (window == 0) & touches_unknown(window < 0)
    return int(np.count_nonzero(cells[1:-1, 1:-1])) >= min_cells
