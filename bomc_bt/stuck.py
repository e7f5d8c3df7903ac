"""When a monitor pass stops getting anywhere: notice it, find out why, decide what to try.

A pass whose robot is boxed in (furniture moved behind it after the map was built), whose
navigation plans with a stale obstacle layer, or whose pose is wrong fails waypoint after
waypoint the same way: each is retried, detoured and marked missed, and a pass of a hundred
waypoints spends hours getting nowhere (issue 15 item 6). This module is the plain logic
behind the recovery subtree of ``trees/recover.yaml``:

* :class:`StuckWatch` notices it: ``max_missed`` waypoints missed in a row, or no
  waypoint reached for ``no_progress_time`` seconds of robot time. It also keeps the log
  of what the pass tried, for the session report.
* :func:`diagnose` finds out why, from what the robot port gives (the saved map, the
  pose, the latest scan) and the waypoints still to visit:

  - ``lost``: too few scan returns lie on the map's walls at the estimated pose, and some
    pass through what the map holds as occupied (things brought in since the map was made
    stop beams short, off its walls; only a wrong pose sends them through its walls);
  - ``stale_obstacles``: with the map and what the lidar sees *now* (every return, those on
    the map's walls too: a wall the map drew thinner narrows a doorway), a waypoint that just
    failed is reachable, so the navigation's obstacle layer holds what is no longer there;
  - ``boxed_in``: none of the waypoints left is reachable past the objects the lidar sees
    that the map does not have, though the map alone has a way: the robot is shut in; or
    the robot has not moved while the waypoints failed (wedged: the way looks open, but
    every goal fails where it stands);
  - ``stale_map``: they are unreachable as the map draws the building, but the lidar saw
    floor this pass where the map holds furniture (:class:`bomc_bt.stale_map.FloorSeen`),
    and with those cells cleared a waypoint that failed, or more of those left, are
    reachable: the robot is hemmed in by a table that has gone since the build;
  - ``cut_off``: the failed waypoints lie behind such objects, but others are reachable:
    the robot is fine, those waypoints are blocked, the pass carries on. When the objects
    are obstacles seen again after a clear (below), it gives up on every waypoint behind
    them (:attr:`Diagnosis.cut_off`; missed, with no second chance at the end of the loop).

  Once this spell of failures has cleared the obstacle layer and waypoints still fail, the
  layer as the lidar rebuilt it counts as well (``layer``): an obstacle seen again after a
  clear is real even where the current scan cannot see it (a table moved across a corridor
  round a corner), so the waypoints behind it are cut off, not failed for a stale layer.

The tree acts on the cause (back out along :class:`bomc_bt.trail.Trail`, clear the
obstacle layer, navigate on the map with the floor seen cleared, relocalize) and, after
``max_rounds`` rounds with no waypoint reached in between, ends the pass early with the
diagnosis (:func:`diagnosis_line`) in the report.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import cv2
import numpy as np

from bomc_bt.algorithm_params import RecoveryParams
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import LaserScan
from bomc_bt.scan_likelihood import crosses, surface_distance, to_world, valid_beams
from bomc_bt.stale_map import with_floor

LOST, STALE_OBSTACLES, BOXED_IN, CUT_OFF = "lost", "stale_obstacles", "boxed_in", "cut_off"
STALE_MAP = "stale_map"
CAUSES = (LOST, STALE_OBSTACLES, STALE_MAP, BOXED_IN, CUT_OFF)
VISITED_STATES = ("visited", "detoured")  # a waypoint in one of these states was reached
# m: a beam may graze a mapped wall this near its end and still count as ending on it (a
# wall's cell and the range noise); relocalization's ``see_through_tolerance`` default
SEE_THROUGH_TOLERANCE = 0.1


@dataclass
class Diagnosis:
    """Why the pass is not getting anywhere, with the evidence, in the operator's words."""

    cause: str  # one of CAUSES
    detail: str  # one line: what was found
    agreement: float  # share of scan returns on the map's walls
    reachable_area_m2: float  # floor the robot can reach past what the lidar sees
    blockers: list[tuple[float, float]] = field(default_factory=list)  # scan returns off the map, nearest first
    # cut_off from a layer seen again after a clear: the remaining waypoints (indices) behind the obstacles
    cut_off: list[int] = field(default_factory=list)
    # stale_map: (K, 2) rows and columns of the map to navigate on as floor
    floor: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))

    def __str__(self) -> str:
        return f"{self.cause}: {self.detail}"


def diagnose(grid: OccupancyGrid, pose: Pose2D | None, scan: LaserScan | None,
             failed: Sequence[tuple[float, float]], remaining: Sequence[tuple[float, float]],
             params: RecoveryParams, robot_radius: float, moved: float | None = None,
             layer: np.ndarray | None = None, floor: np.ndarray | None = None) -> Diagnosis:
    """Why waypoints ``failed`` in a row, given the ``remaining`` ones (see the module docstring).

    ``robot_radius`` is the planner's: a way must keep that far from every obstacle.
    ``moved``: metres driven since the first of the failed waypoints (None: not known).
    ``layer``: (N, 2) cells the navigation's obstacle layer marks, given once the layer was
    cleared in this spell and rebuilt since: what the lidar saw again after a clear is there,
    though out of the current scan's sight (a table round a corner). None: the scan alone.
    ``floor``: (K, 2) rows and columns of map cells the lidar saw as floor this pass where the
    map holds furniture or unknown (:class:`bomc_bt.stale_map.FloorSeen`). None: not looked at.
    """
    if pose is None:
        return Diagnosis(LOST, "the robot is not localized", 0.0, 0.0)
    hits = _hits(pose, scan, params.obstacle_range)
    marked = np.zeros((0, 2)) if layer is None else np.asarray(layer, float).reshape(-1, 2)
    on_map = surface_distance(grid) if len(hits) or len(marked) else None
    agreement, off_map = _agreement(grid, on_map, hits, params.on_map_distance)
    if len(hits) and agreement < params.min_agreement:
        through = _through_walls(grid, pose, scan)
        if through >= params.min_through:
            return Diagnosis(LOST, f"only {agreement:.0%} of the scan returns lie on the map's walls and "
                                   f"{through:.0%} pass through them at ({pose.x:.2f}, {pose.y:.2f})",
                             agreement, 0.0, _nearest(off_map, pose, 5))
    marked_off = _agreement(grid, on_map, marked, params.on_map_distance)[1]
    blockers = _nearest(np.concatenate([off_map, marked_off]), pose, 5)
    # Every return counts for the way open now, not only those off the map: a return within
    # on_map_distance of a wall the map drew thinner still narrows a doorway for navigation.
    now = reachable_from(grid, pose, np.concatenate([hits, marked]), robot_radius)
    on_map_only = reachable_from(grid, pose, np.zeros((0, 2)), robot_radius)
    area = float(np.count_nonzero(now)) * grid.resolution ** 2
    where = _at(blockers)
    what = ("obstacles the lidar marked again after the obstacle layer was cleared" if len(marked_off)
            else "objects the map does not have" if blockers
            else "walls the lidar sees thicker than the map draws them")
    if any(_inside(grid, now, xy) for xy in failed):
        if moved is not None and failed and moved < params.wedged_distance:
            return Diagnosis(BOXED_IN, f"wedged: the way looks open, but the robot moved {moved:.1f} m while "
                                       f"{len(failed)} waypoint(s) failed{where}", agreement, area, blockers)
        return Diagnosis(STALE_OBSTACLES, "the map and the lidar show a way to the waypoints that failed; the "
                                          "navigation's obstacle layer holds obstacles that are gone",
                         agreement, area, blockers)
    stale = _stale_map(grid, pose, floor, failed, remaining, np.concatenate([hits, marked]), now, robot_radius)
    if stale is not None:
        return replace(stale, agreement=agreement, reachable_area_m2=area, blockers=blockers)
    wanted = [k for k, xy in enumerate(remaining) if _inside(grid, on_map_only, xy)]
    behind = [k for k in wanted if not _inside(grid, now, remaining[k])]
    if len(behind) < len(wanted):
        # Only obstacles seen again after a clear are sure enough to give waypoints up for
        # (a person in a doorway is in the scan too, and gone a minute later).
        return Diagnosis(CUT_OFF, f"the waypoints that failed lie behind {what}{where}, with {len(behind)} of "
                                  f"the {len(wanted)} left; the robot can reach the other {len(wanted) - len(behind)}",
                         agreement, area, blockers, behind if layer is not None else [])
    floor = float(np.count_nonzero(on_map_only)) * grid.resolution ** 2
    return Diagnosis(BOXED_IN, f"boxed in by {what}{where}: none of the "
                               f"{len(wanted) or len(remaining)} waypoint(s) left is reachable, "
                               f"{area:.1f} of {floor:.1f} m² of floor within reach", agreement, area, blockers)


def _stale_map(grid: OccupancyGrid, pose: Pose2D, floor: np.ndarray | None, failed: Sequence[tuple[float, float]],
               remaining: Sequence[tuple[float, float]], obstacles: np.ndarray, now: np.ndarray,
               robot_radius: float) -> Diagnosis | None:
    """``stale_map`` when the map with ``floor`` cleared lets the robot reach a waypoint that
    failed, or more of those left, than the map as saved (see the module docstring)."""
    if floor is None or not len(floor):
        return None
    opened = reachable_from(with_floor(grid, floor), pose, obstacles, robot_radius)
    reached = sum(_inside(grid, opened, xy) for xy in failed)
    gained = sum(_inside(grid, opened, xy) for xy in remaining) - sum(_inside(grid, now, xy) for xy in remaining)
    if not reached and gained <= 0:
        return None
    seen = len(floor) * grid.resolution ** 2
    return Diagnosis(STALE_MAP, f"the lidar saw floor where the map holds furniture ({seen:.1f} m²); with it "
                                f"cleared {reached} of the {len(failed)} waypoint(s) that failed and "
                                f"{max(gained, 0)} more of the {len(remaining)} left are reachable", 0.0, 0.0,
                     floor=np.asarray(floor, dtype=np.int64))


def _through_walls(grid: OccupancyGrid, pose: Pose2D, scan: LaserScan | None,
                   tolerance: float = SEE_THROUGH_TOLERANCE) -> float:
    """Share of the scan's returns whose beam passes through a cell the saved map holds as
    occupied more than ``tolerance`` before it ends."""
    if scan is None:
        return 0.0
    beams = valid_beams(scan)
    if beams.count == 0:
        return 0.0
    x, y = to_world(pose, beams.xy)
    length = np.hypot(beams.xy[:, 0], beams.xy[:, 1]) - tolerance
    return float(np.mean(crosses(grid, grid.occupied_mask(), pose, x, y, length)))


def _hits(pose: Pose2D, scan: LaserScan | None, max_range: float) -> np.ndarray:
    """(N, 2) map-frame scan returns nearer than ``max_range``."""
    if scan is None:
        return np.zeros((0, 2))
    beams = valid_beams(scan)
    near = np.hypot(beams.xy[:, 0], beams.xy[:, 1]) < max_range
    x, y = to_world(pose, beams.xy[near])
    return np.stack([x, y], axis=1)


def _agreement(grid: OccupancyGrid, on_map: np.ndarray | None, hits: np.ndarray,
               distance: float) -> tuple[float, np.ndarray]:
    """Share of ``hits`` within ``distance`` of a map wall, and the hits that are not."""
    if on_map is None or not len(hits):
        return 1.0, np.zeros((0, 2))
    rows, cols = grid.world_to_cell(hits[:, 0], hits[:, 1])
    inside = grid.in_bounds(rows, cols)
    d = np.full(len(hits), np.inf)
    d[inside] = on_map[rows[inside], cols[inside]]
    near = d <= distance
    return float(np.count_nonzero(near)) / len(hits), hits[~near & inside]


def reachable_from(grid: OccupancyGrid, pose: Pose2D, extra: np.ndarray, radius: float) -> np.ndarray:
    """Bool mask of the cells a robot of ``radius`` at ``pose`` can drive to on ``grid``
    with the points ``extra`` (scan returns off the map) as obstacles too.

    As the planner sees it: a cell is open when it keeps ``radius`` from every occupied
    cell and return, and is not unknown (the planner does not plan through unknown map),
    except within ``radius`` of the robot: it stands there (on a table's lidar shadow on the
    saved map, say), so that is free. A robot whose own cell is too near an obstacle
    (pressed against a chair) starts from the open cells within ``radius`` of it.
    """
    walls = grid.occupied_mask()
    if len(extra):
        rows, cols = grid.world_to_cell(extra[:, 0], extra[:, 1])
        ok = grid.in_bounds(rows, cols)
        walls = walls.copy()
        walls[rows[ok], cols[ok]] = True
    clearance = cv2.distanceTransform((~walls).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    room = (clearance * grid.resolution >= radius) & ~grid.unknown_mask()
    r, c = grid.world_to_cell(pose.x, pose.y)
    k = int(np.ceil(radius / grid.resolution))
    r0, c0 = max(int(r) - k, 0), max(int(c) - k, 0)
    rr, cc = np.mgrid[r0:int(r) + k + 1, c0:int(c) + k + 1]
    under = grid.in_bounds(rr, cc) & (np.hypot(rr - r, cc - c) * grid.resolution <= radius)
    room[rr[under], cc[under]] |= clearance[rr[under], cc[under]] * grid.resolution >= radius
    count, labels = cv2.connectedComponents(room.astype(np.uint8), connectivity=8)
    seeds = np.unique(labels[r0:int(r) + k + 1, c0:int(c) + k + 1])
    seeds = seeds[seeds > 0]
    return np.isin(labels, seeds) if len(seeds) else np.zeros_like(room)


def _inside(grid: OccupancyGrid, mask: np.ndarray, xy: tuple[float, float], tolerance: float = 0.3) -> bool:
    """Is ``xy`` (a waypoint) on ``mask``, or within ``tolerance`` of it (a goal near a wall)?"""
    r, c = grid.world_to_cell(xy[0], xy[1])
    k = int(np.ceil(tolerance / grid.resolution))
    window = mask[max(int(r) - k, 0):int(r) + k + 1, max(int(c) - k, 0):int(c) + k + 1]
    return bool(window.any())


def _nearest(points: np.ndarray, pose: Pose2D, n: int) -> list[tuple[float, float]]:
    if not len(points):
        return []
    order = np.argsort(np.hypot(points[:, 0] - pose.x, points[:, 1] - pose.y), kind="stable")
    return [(round(float(x), 2), round(float(y), 2)) for x, y in points[order[:n]]]


def _at(blockers: list[tuple[float, float]]) -> str:
    return f" (nearest at ({blockers[0][0]:.1f}, {blockers[0][1]:.1f}))" if blockers else ""


@dataclass
class Recovery:
    """One round of the recovery: why it started, what was found, what was done."""

    stamp: float  # [s] robot time
    trigger: str
    cause: str = ""
    detail: str = ""
    action: str = ""  # back_out | clear_obstacles | relocalize | none | end_pass
    result: str = ""


class StuckWatch:
    """Waypoints missed in a row and robot time since one was reached; the recovery log."""

    def __init__(self, start: float):
        self.missed_in_row = 0
        self.since = start  # robot time the no-progress clock started (a waypoint reached, a recovery)
        self.rounds = 0  # recovery rounds since a waypoint was last reached
        self.log: list[Recovery] = []
        self.missed: list[int] = []  # the waypoints missed in a row, in order
        self.odometer_at_first_miss: float | None = None  # metres driven when the spell began
        self.spell_start = 0  # index in ``log`` of the first round since a waypoint was last reached

    def record(self, index: int | None, state: str, now: float, odometer: float | None = None) -> None:
        """Waypoint ``index`` ended as ``state`` (called once per waypoint the loop finished);
        ``odometer`` is the metres the robot had driven by then."""
        if index is None:
            return
        if state in VISITED_STATES:
            if self.rounds and self.log and not self.log[-1].result:
                self.log[-1].result = f"waypoint {index + 1} reached {now - self.log[-1].stamp:.0f} s later"
            self.missed_in_row, self.since, self.rounds = 0, now, 0
            self.missed.clear()
            self.odometer_at_first_miss = None
            self.spell_start = len(self.log)
        elif state == "missed":
            if not self.missed:
                self.odometer_at_first_miss = odometer
            self.missed_in_row += 1
            self.missed.append(index)

    def cleared_in_spell(self) -> bool:
        """Did a round since a waypoint was last reached clear the obstacle layer? (What the
        layer marks now, the lidar saw again after that.)"""
        return any("clear_obstacles" in r.action for r in self.log[self.spell_start:])

    def moved_since_first_miss(self, odometer: float) -> float | None:
        """Metres driven since the spell of missed waypoints began (None: not known)."""
        if self.odometer_at_first_miss is None:
            return None
        return odometer - self.odometer_at_first_miss

    def trigger(self, now: float, max_missed: int, no_progress_time: float) -> str | None:
        """Why the pass should look for a cause now, or None while it is getting somewhere."""
        if max_missed > 0 and self.missed_in_row >= max_missed:
            return f"{self.missed_in_row} waypoints missed in a row"
        if no_progress_time > 0 and now - self.since >= no_progress_time:
            return f"no waypoint reached for {now - self.since:.0f} s"
        return None

    def start_round(self, now: float, trigger: str) -> Recovery:
        """A recovery round begins: the next trigger needs fresh evidence."""
        self.rounds += 1
        self.missed_in_row, self.since = 0, now
        self.log.append(Recovery(round(now, 1), trigger))
        return self.log[-1]

    def act(self, action: str, result: str = "") -> None:
        """What this round did about it (the session report lists it)."""
        if self.log:
            self.log[-1].action = f"{self.log[-1].action}, {action}" if self.log[-1].action else action
            if result:
                self.log[-1].result = result

    def carry_on(self) -> None:
        """The robot is fine (the waypoints were cut off): this was no recovery round."""
        self.rounds = max(self.rounds - 1, 0)

    def summary(self) -> list[dict[str, Any]]:
        return [asdict(r) for r in self.log]


def diagnosis_line(d: Diagnosis, watch: StuckWatch, waypoint: str) -> str:
    """The sentence an early-ended pass reports (session report and CLI line)."""
    spell = watch.log[watch.spell_start:]  # the rounds since a waypoint was last reached
    acted = [[a for a in r.action.split(", ") if a and a not in ("none", "end_pass")] for r in spell]
    tried = sorted({a for actions in acted for a in actions})
    rounds = sum(1 for actions in acted if actions)
    after = f" after {rounds} recovery round(s) ({', '.join(tried)})" if tried else ""
    return f"pass ended early at {waypoint}{after}: {d}"
