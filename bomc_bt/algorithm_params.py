"""Parameter records of the robot-independent algorithms: planner, exploration,
traversal and back-projection (the scan matcher's are in :mod:`bomc_bt.relocalization_params`).

They live apart from the numeric code (which needs OpenCV) so that reading and checking
a configuration needs only this module. Each field's comment gives its unit and meaning;
``config/defaults.yaml`` is generated from them (see :mod:`bomc_bt.config_docs`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

_REFERENCE_WIDTH = 640  # stride and min_points are given for a 640 x 480 image
_REFERENCE_AREA = 640 * 480


@dataclass
class PlannerParams:
    """Costmap and search settings of the global planner (names follow the ROS navigation stack)."""

    robot_radius: float = 0.3  # [m] closer than this to an obstacle is lethal
    inflation_radius: float = 0.7  # [m] the clearance cost decays to zero at this distance
    cost_weight: float = 3.0  # [-] extra cost per metre next to lethal space (quadratic decay)
    resolution: float = 0.1  # [m] planning grid cell size (never finer than the map)
    allow_unknown: bool = False  # [bool] plan through unknown cells (navfn's allow_unknown)
    goal_tolerance: float = 0.3  # [m] a lethal goal may move this far to a traversable cell
    escape_radius: float = 1.0  # [m] how far to look for a traversable cell from a lethal start
    heuristic_weight: float = 1.0  # [-] above 1: weighted A* (fewer expansions, less clearance-optimal)
    # [m] while building, the clearance a last-resort plan keeps when none exists with robot_radius:
    # through a doorway that the lidar maps a cell narrower on each side than it is, or out of a
    # strip the robot entered while its walls were unknown. Above the base's body radius (0.24 m
    # in the simulator): mapped walls are thicker than true ones and the 0.1 m planning grid
    # under-reads clearance, so 0.25 m planned is about 0.28 m true. At or above robot_radius:
    # never squeeze.
    squeeze_radius: float = 0.25

    def __post_init__(self) -> None:
        if self.robot_radius < 0 or self.inflation_radius < self.robot_radius:
            raise ValueError("need 0 <= robot_radius <= inflation_radius")
        if not 0 < self.squeeze_radius < 10:
            raise ValueError(f"squeeze_radius: must be in (0, 10) m, got {self.squeeze_radius}")
        if self.heuristic_weight < 1.0:
            raise ValueError("heuristic_weight must be >= 1")
        if self.resolution <= 0 or self.goal_tolerance < 0 or self.cost_weight < 0:
            raise ValueError("resolution must be > 0; goal_tolerance, cost_weight >= 0")

    def squeezed(self) -> PlannerParams | None:
        """The last resort's settings: ``squeeze_radius`` of clearance through known space only;
        None when it is no narrower than ``robot_radius`` (never squeeze)."""
        if self.squeeze_radius >= self.robot_radius:
            return None
        return replace(self, robot_radius=self.squeeze_radius, allow_unknown=False)


@dataclass
class ExplorationParams:
    """Tunables of the exploration step (the gain explorer, DWFE or the explore_lite baseline)."""

    # [choice] gain: most new map per metre of path (docs/exploration.md); dwfe: the paper's
    # Algorithm 1; baseline: explore_lite's ranking
    explorer: Literal["gain", "dwfe", "baseline"] = "gain"
    # [m] r_l, the local window: a few metres is one room or one corridor segment for a
    # Fetch-class base: about what its laser clears well from one stop (indoor returns are
    # dense up to ~5 m), and small enough that the window does not reach into the next room.
    local_radius: float = 4.0
    global_radius: float = 1000.0  # [m] r_g, the global window: effectively the whole building (the fallback)
    # [count] T_l: stay local while at least this many frontiers remain nearby; a single
    # leftover local frontier is often a sliver (behind a chair, a laser shadow).
    local_threshold: int = 2
    global_threshold: int = 1  # [count] T_g: stop when fewer frontiers than this are left anywhere
    # [-] alpha, the weight of travel distance: 1 m of extra travel is worth 2 m of extra
    # frontier length (with beta 0.5), so a 1 m doorway 1 m further away still beats a 0.5 m
    # sliver close by, but the robot does not cross the window for a long frontier.
    alpha: float = 1.0
    beta: float = 0.5  # [-] beta, the weight of frontier length against alpha's distance
    potential_scale: float = 3.0  # [-] the baseline's weight of distance (explore_lite default)
    gain_scale: float = 1.0  # [-] the baseline's weight of frontier size (explore_lite default)
    min_frontier_size: float = 0.5  # [m] shorter frontiers are ignored (explore_lite's min_frontier_size)
    max_time: float = 0.0  # [s] robot-time limit of a build; 0: none, explore until no reachable frontier is left
    blacklist_radius: float = 0.5  # [m] frontiers this close to a failed goal are skipped
    progress_timeout: float = 30.0  # [s] robot time without progress before a goal is blacklisted
    # Less than min_progress_area newly mapped in no_progress_time ends a build ("no_progress"): a runaway guard.
    no_progress_time: float = 600.0  # [s] robot time without new mapped area after which exploration ends
    min_progress_area: float = 2.0  # [m2] new known-free area that counts as progress
    # A failed goal is tried again when the known area within blacklist_readmit_radius of it
    # changed by more than blacklist_readmit_area, or when the robot comes within
    # blacklist_near_radius of it; at most blacklist_max_retries times per place.
    blacklist_readmit_radius: float = 1.0  # [m] neighbourhood of a failed goal watched for map changes
    blacklist_readmit_area: float = 0.25  # [m2] change of known area there that re-admits it
    blacklist_near_radius: float = 1.5  # [m] the robot this close to a failed goal re-admits it
    blacklist_max_retries: int = 2  # [count] re-admissions per place
    # A robot that fails goals without moving backs out along its trajectory and replans before it is "stuck".
    backout_distance: float = 1.5  # [m] back along the trajectory driven, towards where it came from
    max_backouts: int = 2  # [count] back-outs without progress before "stuck" may be declared
    # [bool] frontiers count only where the planner can take the robot (its clearance, unknown
    # treated as a wall); the others are reported as unreachable border, never chosen. The
    # gain explorer always counts this way: it ranks by path length on the planner's grid.
    planner_reachable: bool = True
    # Goals are sent to a standoff: a reachable cell at least the robot's clearance from every
    # occupied and unknown cell, so a wall the lidar then reveals cannot put the goal inside
    # the planner's lethal zone (the cause of every failed goal measured on generated offices).
    max_standoff: float = 1.0  # [m] how far from its frontier cell a standoff goal may be
    # The gain explorer (explorer: gain) ranks frontiers by gain / (path + travel_offset).
    gain_radius: float = 6.0  # [m] how far the lidar's view is counted as information gain
    # [m2] frontiers whose view would add less are no goals; none left: done. On generated
    # offices a view estimated below 3 m2 added 0.6-1 m2 of map for 20-27 s of driving.
    min_gain: float = 3.0
    travel_offset: float = 2.0  # [m] fixed cost of any goal (stop, turn, decide), added to its path
    hysteresis: float = 0.25  # [-] utility bonus of the frontier the last goal served
    hysteresis_radius: float = 1.5  # [m] a frontier cell this near the last goal's is the same frontier
    turn_cost: float = 0.0  # [m] path a goal behind costs per radian turned on the spot (0.6: speed / turn rate)
    free_turn_deg: float = 45.8  # [deg] heading error turned while driving (navigation's turn-in-place angle)

    def __post_init__(self) -> None:
        if self.explorer not in ("gain", "dwfe", "baseline"):
            raise ValueError(f"explorer: must be 'gain', 'dwfe' or 'baseline', got {self.explorer!r}")
        _positive(self, "local_radius", "global_radius", "progress_timeout", "no_progress_time",
                  "blacklist_readmit_radius", "blacklist_near_radius", "gain_radius", "max_standoff")
        _non_negative(self, "alpha", "beta", "potential_scale", "gain_scale", "min_frontier_size", "turn_cost",
                      "blacklist_radius", "max_time", "min_progress_area", "blacklist_readmit_area", "free_turn_deg",
                      "backout_distance", "min_gain", "travel_offset", "hysteresis", "hysteresis_radius")
        if self.global_radius < self.local_radius:
            raise ValueError("global_radius: must be at least local_radius "
                             f"({self.global_radius} < {self.local_radius})")
        for name, low in (("local_threshold", 1), ("global_threshold", 1), ("blacklist_max_retries", 0),
                          ("max_backouts", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < low:
                raise ValueError(f"{name}: must be a whole number >= {low}, got {value!r}")

    @property
    def time_limit(self) -> float | None:
        """``max_time`` in seconds, or None when there is no limit (0)."""
        return self.max_time if self.max_time > 0 else None

    def min_size_cells(self, resolution: float) -> int:
        """``min_frontier_size`` as a cell count for :func:`find_frontiers` (explore_lite keeps
        frontiers with ``size * resolution >= min_frontier_size``)."""
        return max(1, math.ceil(self.min_frontier_size / resolution - 1e-9))


@dataclass
class RecoveryParams:
    """When a monitor pass that keeps failing waypoints looks for why, and what it tries
    (:mod:`bomc_bt.stuck`, ``trees/recover.yaml``)."""

    max_missed: int = 3  # [count] waypoints missed in a row that start a recovery round; 0: never
    no_progress_time: float = 600.0  # [s] robot time without reaching a waypoint that starts one; 0: never
    max_rounds: int = 2  # [count] recovery rounds with no waypoint reached in between before the pass ends early
    obstacle_range: float = 4.0  # [m] scan returns nearer than this count as obstacles in the diagnosis
    on_map_distance: float = 0.2  # [m] a scan return this near a wall of the saved map lies on the map
    min_agreement: float = 0.4  # [-] share of scan returns on the map's walls below which the pose is lost; 0: off
    # [-] and at least this share of the scan's returns must pass through a cell the saved map holds
    # as occupied (a wrong pose): with the pose right, things new since the map stop beams short and
    # none passes through; 0: the agreement alone, as before
    min_through: float = 0.1
    # [m] driven while waypoints failed, below which the robot is wedged; 0 (default): off, since
    # waypoints that fail at once (no plan) also leave the robot where it was
    wedged_distance: float = 0.0
    backout_distance: float = 1.5  # [m] how far back along the path driven a back-out goes
    rebuild_time: float = 2.0  # [s] robot time to let the lidar refill a cleared obstacle layer
    # [m2] occupied blobs of the saved map this small are furniture: where the lidar sees floor
    # through them (or through unknown map) a stuck pass may navigate on the map with it
    # cleared (bomc_bt.stale_map); 0: never
    stale_furniture_area: float = 2.0
    floor_range: float = 6.0  # [m] scans count as seeing floor this far from the robot
    floor_min_seen: int = 2  # [count] scans that must see a cell as floor before it counts
    floor_period: float = 1.0  # [s] robot time between scans folded into the floor seen

    def __post_init__(self) -> None:
        for name in ("max_missed", "max_rounds", "floor_min_seen"):
            value = getattr(self, name)
            least = 0 if name == "max_missed" else 1
            if isinstance(value, bool) or int(value) != value or value < least:
                raise ValueError(f"{name}: must be a whole number >= {least}, got {value!r}")
        _positive(self, "obstacle_range", "on_map_distance", "backout_distance", "floor_range", "floor_period")
        if not self.wedged_distance >= 0.0:
            raise ValueError(f"wedged_distance: must be >= 0, got {self.wedged_distance!r}")
        _non_negative(self, "no_progress_time", "rebuild_time", "stale_furniture_area")
        for name in ("min_agreement", "min_through"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name}: must be 0 to 1, got {getattr(self, name)!r}")


def _positive(params: ExplorationParams, *names: str) -> None:
    for name in names:
        value = getattr(params, name)
        if not (value > 0) or math.isnan(value) or (math.isinf(value) and name != "global_radius"):
            raise ValueError(f"{name}: must be a positive number, got {value!r}")


def _non_negative(params: ExplorationParams, *names: str) -> None:
    for name in names:
        value = getattr(params, name)
        if not (value >= 0) or not math.isfinite(value):
            raise ValueError(f"{name}: must be a finite number >= 0, got {value!r}")


@dataclass
class TraversalParams:
    """How the monitor pass's waypoints are planned: from the map and the camera, or the paper's way."""

    # [choice] "coverage": viewpoints on the saved map that together see all the floor, in a
    # short tour over grid path lengths (bomc_bt.coverage_plan); "paper": waypoints sampled
    # along the build trajectory, greedy TSP + 2-opt (the paper's method, kept as it was)
    plan: Literal["coverage", "paper"] = "coverage"
    spacing: float = 2.0  # [m] paper plan: minimum distance between any two waypoints
    two_opt: bool = True  # [bool] improve the greedy order by 2-opt (both plans)
    max_two_opt_passes: int = 20  # [count] 2-opt passes at most
    face_travel_direction: bool = True  # [bool] paper plan: yaw towards the next waypoint (else the recorded yaw)
    target_step: float = 0.25  # [m] coverage plan: spacing of the floor samples to be seen
    candidate_step: float = 0.75  # [m] coverage plan: spacing of candidate viewpoints (a multiple of target_step)
    clearance: float = 0.45  # [m] coverage plan: a viewpoint keeps this far from obstacles
    min_range: float = 1.0  # [m] coverage plan: nearer floor is below the tilted camera's image
    # [m] coverage plan: unknown map within this of free floor is floor to see (furniture's
    # lidar shadow), and a line of sight may cross unknown cells only that near its target
    shadow: float = 0.5
    hfov_deg: float = 50.0  # [deg] coverage plan: field of view of one heading (the camera's, less a margin)
    max_headings: int = 4  # [count] coverage plan: headings per viewpoint at most
    # [m] coverage plan: what one more stop costs, in metres of driving (slowing down, turning, dwelling);
    # greedy cover weighs newly seen floor against this plus the straight-line distance to the nearest stop
    stop_cost: float = 4.0
    min_gain: float = 0.5  # [m] coverage plan: a stop or heading newly sees at least this squared (a chair)
    path_resolution: float = 0.2  # [m] coverage plan: grid cell of the path-length matrix (pooled planner cells)
    # [bool] coverage plan: floor the camera sees while driving between stops (facing ahead)
    # needs no stop; the cover is chosen again with it seen
    drive_by: bool = True
    drive_by_step: float = 0.5  # [m] coverage plan: spacing of the views credited along the driven path
    drop_redundant: bool = True  # [bool] drive_by: drop stops whose floor the final tour's legs and other stops see
    closed_tour: bool = True  # [bool] coverage plan: order the tour from and back to the dock (else an open path)
    # [count] coverage plan and the later phases' tours: double-bridge kicks of the iterated local search
    # after 2-opt and Or-opt (bomc_bt.tour_search; 1.4 ms each on 328 stops); 0: none
    tour_kicks: int = 1000

    def __post_init__(self) -> None:
        if not (math.isfinite(self.spacing) and self.spacing > 0):
            raise ValueError("spacing must be a positive number")
        if self.max_two_opt_passes < 0:
            raise ValueError("max_two_opt_passes must not be negative")
        if not 0 <= self.tour_kicks <= 1_000_000:
            raise ValueError("tour_kicks must be in [0, 1000000]")
        if self.plan not in ("coverage", "paper"):
            raise ValueError(f"plan must be coverage or paper, not {self.plan!r}")
        if not (self.target_step > 0 and self.candidate_step >= self.target_step and self.path_resolution > 0
                and self.drive_by_step > 0):
            raise ValueError("need target_step, path_resolution, drive_by_step > 0 and candidate_step >= target_step")
        if self.clearance < 0 or self.min_range < 0 or self.shadow < 0 or self.stop_cost < 0 or self.min_gain < 0:
            raise ValueError("clearance, min_range, shadow, stop_cost and min_gain must be >= 0")
        if not 0 < self.hfov_deg <= 360 or self.max_headings < 1:
            raise ValueError("need 0 < hfov_deg <= 360 and max_headings >= 1")


@dataclass
class BudgetParams:
    """A pass with a budget of robot time (``bomc monitor --budget``): which viewpoints it
    visits first, from the site's change model (:mod:`bomc_bt.change_model`,
    :mod:`bomc_bt.budget_plan`)."""

    seconds: float = 0.0  # [s] robot time for the whole pass, back at the dock included; 0: a full pass
    # [choice] how a budget is spent: "expected_changes" (the viewpoints with most expected
    # changes waiting per second, from the change model), "uniform" (most floor per second,
    # every region alike), "cut" (the traversal.plan tour in order, cut when time runs out)
    strategy: Literal["expected_changes", "uniform", "cut"] = "expected_changes"
    speed: float = 0.55  # [m/s] average driving speed the planner assumes (slowing, turning included)
    heading_time: float = 2.55  # [s] planned time per heading at a stop (turn, look around, dwell; calibrate_budget.py)
    margin: float = 0.05  # [-] share of the budget kept back for what the plan cannot foresee
    # [-] a budget at most this share short of a typical full pass (the median of the last
    # three) runs the full pass: full passes vary by about this much from one to the next
    full_tolerance: float = 0.1
    # [count] candidate stops the tour is planned over first (those that see most value); a tour that
    # visits them all with a tenth of the budget left is planned again over twice as many, up to 1000
    max_stops: int = 60
    # [m] how far a stop is counted to see the floor it is valued for (near enough to detect
    # and confirm objects from a few looks); 0: the camera's planned reach (projection.expect_range)
    view_range: float = 3.0
    region_size: float = 4.0  # [m] side of the square regions the change model counts changes in
    seen_share: float = 0.3  # [-] a region counts as seen by a pass when the camera saw this share of its floor
    prior_rate: float = 0.3  # [count] changes per pass a region is assumed to have before any history
    prior_weight: float = 1.0  # [count] passes' worth of weight the prior rate keeps against history
    max_wait: int = 20  # [count] passes since last seen beyond which a region's waiting changes stop growing
    object_reach: float = 0.5  # [m] a look counts for an object when the floor it saw comes this near it

    def __post_init__(self) -> None:
        if self.strategy not in ("expected_changes", "uniform", "cut"):
            raise ValueError(f"strategy must be expected_changes, uniform or cut, not {self.strategy!r}")
        if not (0 <= self.seconds <= 1e7 and self.speed > 0 and self.heading_time >= 0):
            raise ValueError("need 0 <= seconds <= 1e7, speed > 0 and heading_time >= 0")
        if not (0 <= self.margin < 1 and 0 < self.seen_share <= 1 and self.region_size >= 0.5):
            raise ValueError("need 0 <= margin < 1, 0 < seen_share <= 1 and region_size >= 0.5")
        if not 0 <= self.full_tolerance < 1:
            raise ValueError("need 0 <= full_tolerance < 1")
        if not 1 <= self.max_stops <= 1000 or not 0 <= self.view_range <= 100:
            raise ValueError("need 1 <= max_stops <= 1000 and 0 <= view_range <= 100")
        if not (self.prior_rate > 0 and self.prior_weight > 0 and self.max_wait >= 1):
            raise ValueError("need prior_rate > 0, prior_weight > 0 and max_wait >= 1")
        if not 0 < self.object_reach <= 10:
            raise ValueError("need 0 < object_reach <= 10")


@dataclass
class ProjectionParams:
    """Back-projection of detections to map positions, and the camera's field of view."""

    min_points: int = 30  # [count] fewer valid sampled points than this (at 640 x 480) and the detection is skipped
    stride: int = 2  # [count] sample every stride-th pixel in both directions (at 640 x 480)
    max_depth: float = 6.0  # [m] farther pixels are not used; a mask mostly farther is skipped (a far object)
    # [m] a view with fewer than min_points masked points above this is floor, and so is one whose
    # own surface (the nearest range cluster) has less than half of its points above it (0: that test off)
    floor_height: float = 0.05
    fov_columns: int = 64  # [count] image columns sampled for the field-of-view polygon
    # [m] a node farther from the camera is not expected to be detected (robust mode): far
    # objects are small in the image and often missed, so their absence proves little. The
    # one camera reach every planner of views uses (Look Around, gap and refresh viewpoints).
    expect_range: float = 5.0
    # [-] robust: share of a node's body (centre and inset footprint corners) a frame must show
    # unoccluded for a miss to count: an object mostly hidden (a door leaf seen through its
    # doorway) is missed by any detector, and its absence there proves nothing. 0: centre only
    expect_visible: float = 0.6
    # [m] robust: a miss within this range of the camera counts fully; farther it weighs less,
    # down to nothing at expect_range (far objects are small in the image and often missed)
    miss_full_range: float = 2.5
    # [deg] robust: a flat node (floor footprint at least 3 times longer than wide: a door leaf)
    # seen farther than this from its face's normal is not expected: edge-on it is a sliver a
    # detector may miss, and its absence there proves nothing. 90 (default): off, always
    # expected; 65 helped the hard detector preset's corridor doors (README: detector presets)
    expect_edge_on_deg: float = 90.0
    # [deg] robust: a flat node's miss weighs in full seen within this of its face's normal,
    # less the more edge-on it is seen (as the cosine of the angle: the width the image shows),
    # nothing at expect_edge_on_deg: a door seen along its corridor is a sliver detectors miss.
    # 90 or more than expect_edge_on_deg (default): off; 45 measured on the hard preset, opt-in
    # (docs/association.md, "Where a door is missed from")
    miss_face_on_deg: float = 90.0
    # [m] robust: a miss counts only where the depth camera sees the node's place empty (more
    # than this beyond the node's centre), or a wall-high surface or one of the frame's
    # detections of its category there (one of another kind is what hides it). Something
    # undetected no higher than furniture standing where the node is (a chair seen only over
    # the table in front, which any detector misses) is no evidence of its absence, nor is a
    # wall's face more than this in front of the node's centre (the place lies behind it).
    # 0: off, every miss counts
    absence_margin: float = 0.1
    # [choice] how an object's position is taken from its points: "mean" is the paper's (the
    # mean of the masked point cloud); "footprint" keeps the mean height but takes x, y from
    # the middle of the points' spread on the floor (1st to 99th percentile). The mean of the
    # visible surface leans towards the viewer by up to half the object's depth, so a table
    # seen from two sides gives two centroids a metre apart; the footprint's middle stays put.
    centre: Literal["mean", "footprint"] = "footprint"
    # [m] only objects this near give a floor box (Observation.box) that association trusts
    # for footprints; depth noise grows with range squared, and a box from a far view is
    # inflated along the ray by it (at 7 m a typical sensor's noise is ~0.25 m).
    box_range: float = 4.0
    # [bool] an object's far part moves its view's centre: the mask's pixels beyond the range
    # cut that go on from the kept ones without a jump in range (a table seen end-on; see
    # bomc_bt.perception.far_part); the floor box stays the cut's; false: the range cut alone
    far_part: bool = True
    # [-] a view whose box is clear of the image border, whose own surface is flat and upright,
    # and with at least this share of the depth pixels round its box on that surface's plane
    # (within 5 cm) is a patch of a wall, not an object standing out from it: a false box on a
    # wall (bomc_bt.perception.surface_patch). Above 1 (e.g. 1.1): off
    patch_share: float = 0.9
    # [list] categories that stand flush in a wall or hang flat on one, never judged patches of
    # it: add any such category the detector is prompted for (a window, a whiteboard, a picture)
    flush_categories: list[str] = field(default_factory=lambda: ["door", "television"])

    def __post_init__(self) -> None:
        if not 0.0 < self.patch_share <= 2.0:
            raise ValueError("patch_share must be in (0, 2] (above 1: off)")
        if self.min_points < 1 or self.stride < 1:
            raise ValueError("min_points and stride must be >= 1")
        if not self.max_depth > 0.0:
            raise ValueError("max_depth must be positive")
        if self.miss_full_range < 0.0 or not 0.0 <= self.floor_height <= 1.0:
            raise ValueError("miss_full_range must be >= 0 and floor_height in [0, 1] m")
        if not 0.0 <= self.expect_visible <= 1.0:
            raise ValueError("expect_visible must be in [0, 1]")
        if not 0.0 <= self.expect_edge_on_deg <= 90.0 or not 0.0 <= self.miss_face_on_deg <= 90.0:
            raise ValueError("expect_edge_on_deg and miss_face_on_deg must be in [0, 90]")
        if not 0.0 <= self.absence_margin <= 1.0:
            raise ValueError("absence_margin must be in [0, 1] m (0: off)")
        if self.box_range < 0.0:
            raise ValueError("box_range must be >= 0 (0: no boxes)")
        if self.fov_columns < 2:
            raise ValueError("fov_columns must be >= 2")

    def scaled(self, shape: tuple[int, int]) -> tuple[int, int]:
        """(stride, min_points) for an image of ``shape`` (H, W).

        Both are given for 640 x 480 so one config serves a full-resolution camera and a
        simulator rendering at a quarter of it: a smaller image gets a finer stride and a
        smaller point minimum, so the same objects (same apparent size) pass or fail.
        """
        h, w = shape
        stride = max(1, round(self.stride * w / _REFERENCE_WIDTH))
        factor = (h * w / _REFERENCE_AREA) * (self.stride / stride) ** 2
        return stride, max(3, round(self.min_points * factor))
