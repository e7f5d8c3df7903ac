"""Parameters of the scan matcher that relocalizes the robot in a saved map.

Kept apart from :mod:`bomc_bt.algorithm_params` (which re-exports it) because the scan
matcher's search and its confidence test need many knobs of their own. Each field's
comment gives its unit and meaning; ``config/defaults.yaml`` is generated from them.
"""

from __future__ import annotations

from dataclasses import dataclass

from bomc_bt.params import Radians


@dataclass
class RelocalizationParams:
    """Search windows, resolutions and the confidence test of the scan matcher (relocalization)."""

    search_radius: float = 1.2  # [m] search window around the hint (covers a hint that is up to 1 m off)
    # [deg] search window around the hint's yaw; covers up to 30 deg of error (0.6 rad exactly)
    search_angle_deg: float = 34.37746770784939
    search_angle = Radians()
    linear_step: float = 0.1  # [m] coarse grid step (rounded to whole map cells)
    angular_step_deg: float = 2.0  # [deg] coarse grid step
    angular_step = Radians()
    fine_linear_step: float = 0.02  # [m] first refinement's step
    fine_angular_step_deg: float = 0.5  # [deg] first refinement's step
    fine_angular_step = Radians()
    final_linear_step: float = 0.01  # [m] last refinement's step
    final_angular_step_deg: float = 0.2  # [deg] last refinement's step
    final_angular_step = Radians()
    sigma: float = 0.1  # [m] likelihood field std for refinement and the reported score
    coarse_sigma: float = 0.25  # [m] wider field for the coarse grid, so its steps cannot miss the peak
    min_score: float = 0.6  # [-] mean beam likelihood needed to be confident
    min_margin: float = 0.05  # [-] the best must beat the far runner-up by this fraction of its score
    # [m] a beam ending in mapped free floor this far from every mapped surface hit something the map
    # lacks (an object brought in or moved there since the build): it counts for neither side of min_score
    change_gap: float = 0.3
    # [m2] mapped occupied blobs up to this area are furniture that may have gone since the build: a
    # beam passing through one is scored by where it ends, not failed as a beam through a wall
    furniture_area: float = 2.0
    min_explained: float = 0.5  # [-] share of the beams that must be left to score after change_gap
    see_through_tolerance: float = 0.1  # [m] a beam may pass this close to a wall before its end
    wall_probe: tuple[float, ...] = (0.12, 0.2, 0.3)  # [list] m before each beam's end checked during refinement
    ambiguity_distance: float = 1.0  # [m] a runner-up farther than this is a different pose
    ambiguity_angle_deg: float = 45.0  # [deg] a runner-up facing this much elsewhere is a different pose
    ambiguity_angle = Radians()
    max_beams: int = 180  # [count] beams used for the local coarse grid and refinement (evenly subsampled)
    final_beams: int = 720  # [count] beams used by the last refinement, where few poses are left to score
    min_beams: int = 20  # [count] fewer valid beams than this can never be confident
    max_recentre: int = 8  # [count] times a refinement grid may move to follow a peak off its edge
    rivals: int = 3  # [count] distinct coarse peaks far from the winner refined to find the runner-up
    # [count] distinct coarse peaks refined in a local search (a floor changed round the dock puts
    # the true pose's peak below several wrong ones)
    local_candidates: int = 12
    global_linear_step: float = 0.3  # [m] coarse grid of candidate positions over the free space
    global_angular_step_deg: float = 3.0  # [deg] coarse grid step of a global search
    global_angular_step = Radians()
    global_sigma: float = 0.3  # [m] likelihood field std for the global coarse grid
    global_beams: int = 60  # [count] beams used by the global coarse grid
    global_clearance: float = 0.2  # [m] candidate positions keep this distance from obstacles
    global_candidates: int = 16  # [count] distinct coarse peaks refined in a global search

    def __post_init__(self) -> None:
        positive = ("search_radius", "linear_step", "angular_step_deg", "fine_linear_step", "fine_angular_step_deg",
                    "final_linear_step", "final_angular_step_deg", "sigma", "coarse_sigma", "global_linear_step",
                    "global_angular_step_deg", "global_sigma", "ambiguity_distance", "ambiguity_angle_deg")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")
        if min(self.search_angle_deg, self.global_clearance, self.see_through_tolerance, self.max_recentre,
               *self.wall_probe) < 0:
            raise ValueError("search_angle_deg, global_clearance, see_through_tolerance, max_recentre and "
                             "wall_probe must not be negative")
        if not 0.0 <= self.min_margin < 1.0:
            raise ValueError("min_margin must be in [0, 1)")
        if not 0.0 < self.min_explained <= 1.0:
            raise ValueError("min_explained must be in (0, 1]")
        if self.change_gap < 0 or self.furniture_area < 0:
            raise ValueError("change_gap and furniture_area must not be negative")
        for name in ("max_beams", "final_beams", "global_beams", "local_candidates",
                     "global_candidates", "rivals", "min_beams"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1")
