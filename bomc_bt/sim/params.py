"""The built-in simulator's parameter records (``sim``, ``camera`` and ``detector`` in the config).

They live apart from the simulator's code so that reading and checking a configuration
(``bomc config``, :mod:`bomc_bt.config`) needs neither OpenCV nor the simulator. Each
field's comment gives its unit and meaning; ``config/defaults.yaml`` is generated from them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from bomc_bt.algorithm_params import PlannerParams
from bomc_bt.params import Radians


@dataclass
class LidarParams:
    """The simulated planar laser scanner (defaults: the Fetch's base laser)."""

    fov_deg: float = 220.0  # [deg] field of view, centred on the robot's heading
    beams: int = 662  # [count] beams per scan (the Fetch's ~0.33 deg spacing)
    range_max: float = 25.0  # [m] farthest return; a beam that hits nothing reads this
    range_min: float = 0.05  # [m] nearest return
    noise_std: float = 0.01  # [m] standard deviation of the Gaussian noise on each range
    height: float = 0.25  # [m] height of the scan plane above the floor (what the scan cuts)
    rate: float = 10.0  # [Hz] scans per second of sim time
    max_iterations: int = 200  # [count] sphere-tracing steps per beam (a beam still flying then reads range_max)

    def __post_init__(self) -> None:
        if (self.beams < 2 or not 0 < self.fov_deg <= 360 or self.range_max <= self.range_min
                or self.rate <= 0):
            raise ValueError("lidar needs beams >= 2, 0 < fov_deg <= 360, range_max > range_min, rate > 0")


@dataclass
class MapperParams:
    """The occupancy mapper that stands in for SLAM while building."""

    resolution: float = 0.05  # [m] map cell size (the live map uses the world map's geometry; see Mapper)
    linear_update: float = 0.25  # [m] distance moved before the next scan is integrated (GMapping)
    # [deg] angle turned before the next scan is integrated (0.25 rad exactly)
    angular_update_deg: float = 14.32394487827058
    angular_update = Radians()
    hit_log_odds: float = 0.9  # [-] log-odds added to a cell a beam ends in
    miss_log_odds: float = -0.7  # [-] log-odds added to a cell a beam passes through
    clamp_log_odds: float = 5.0  # [-] a cell's log-odds stays within plus or minus this
    occupied_threshold: float = 0.6  # [-] log-odds above which a cell is occupied (100)
    free_threshold: float = -0.6  # [-] log-odds below which a cell is free (0)
    max_free_range: float = 25.0  # [m] a beam with no return clears free space up to this range

    def __post_init__(self) -> None:
        if self.resolution <= 0 or self.hit_log_odds <= 0 or self.miss_log_odds >= 0:
            raise ValueError("need resolution > 0, hit_log_odds > 0, miss_log_odds < 0")
        if not self.free_threshold < self.occupied_threshold:
            raise ValueError("free_threshold must be below occupied_threshold")


@dataclass
class ObstacleLayerParams:
    """The costmap's obstacle layer while monitoring: the saved map plus what the laser sees now."""

    obstacle_range: float = 4.0  # [m] returns nearer than this mark obstacles
    raytrace_range: float = 5.0  # [m] free space up to this range clears obstacles
    update_period: float = 0.2  # [s] sim time between updates (a 5 Hz costmap)


@dataclass
class MotionParams:
    """The simulated base and its path-following controller (a stand-in for move_base)."""

    max_speed: float = 0.6  # [m/s] forward speed limit
    max_turn_rate_deg: float = 57.29577951308232  # [deg/s] turn rate limit (1.0 rad/s exactly)
    max_turn_rate = Radians()
    progress_timeout: float = 15.0  # [s] sim time without progress along the plan before a goal is BLOCKED
    # [s] on a saved map (monitor passes): sim time with no plan at all from where the robot
    # stands (neither the live planner's nor a squeeze) before a goal is BLOCKED (move_base's
    # planner_patience); at least progress_timeout: the progress timeout says it, as before.
    # While building, only the progress timeout (not measured there)
    plan_patience: float = 5.0
    progress_step: float = 0.1  # [m] shortening of the remaining path that counts as progress
    replan_period: float = 2.0  # [s] between path checks (replan when the path is no longer clear)
    blocked_replan_period: float = 0.5  # [s] between replans while the robot cannot move
    lookahead: float = 0.6  # [m] distance along the path the controller steers to
    # [deg] heading error above which the robot turns on the spot (0.8 rad exactly)
    turn_in_place_angle_deg: float = 45.83662361046586
    turn_in_place_angle = Radians()
    heading_gain: float = 2.0  # [-] turn rate (rad/s) per rad of heading error
    # [m] radius of the base's footprint for collisions. Kept below the planner's lethal
    # radius by more than the planning grid's discretisation (0.1 m cells read clearance at
    # their centres), or plans that graze a pillar are refused step by step and the robot
    # rocks in place.
    body_radius: float = 0.24
    # [deg] at the goal position the robot turns to the goal's yaw until this close (0.15 rad exactly)
    yaw_tolerance_deg: float = 8.594366926962348
    yaw_tolerance = Radians()

    def __post_init__(self) -> None:
        if self.max_speed <= 0 or self.max_turn_rate_deg <= 0 or self.progress_timeout <= 0:
            raise ValueError("max_speed, max_turn_rate_deg and progress_timeout must be > 0")
        if self.plan_patience <= 0:
            raise ValueError("plan_patience must be > 0")
        if self.replan_period <= 0 or self.lookahead <= 0 or self.body_radius <= 0:
            raise ValueError("replan_period, lookahead and body_radius must be > 0")


@dataclass
class FaultParams:
    """Faults injected into a simulated session: failing goals, walking people, pose noise."""

    nav_failure_probability: float = 0.0  # [-] chance per goal that it aborts (FAILED) at a random moment
    people: int = 0  # [count] people walking back and forth in open space
    person_speed: float = 0.5  # [m/s] walking speed of the people
    localization_noise: float = 0.0  # [m] std of the noise on the reported position once localized (yaw: half, in rad)

    def __post_init__(self) -> None:
        if not 0.0 <= self.nav_failure_probability <= 1.0:
            raise ValueError("nav_failure_probability must be in [0, 1]")
        if self.people < 0 or self.person_speed < 0 or self.localization_noise < 0:
            raise ValueError("people, person_speed and localization_noise must be >= 0")


@dataclass
class SceneParams:
    """What of the world's 3-D scene the base collides with (the laser's plane is sim.lidar.height)."""

    collision_height: float = 0.4  # [m] boxes whose bottom is below this block the base


@dataclass
class LocalizationParams:
    """How the simulated localization (AMCL's stand-in) behaves after a relocalization."""

    local_duration: float = 2.0  # [s] sim time a relocalization from a hint takes
    global_duration: float = 6.0  # [s] sim time a global relocalization takes
    correction_time: float = 5.0  # [s] time constant of the estimate's error decaying (AMCL)
    lost_distance: float = 1.0  # [m] an estimate this wrong stays wrong (AMCL does not recover)
    lost_angle_deg: float = 28.64788975654116  # [deg] an estimate's yaw this wrong stays wrong (0.5 rad exactly)
    lost_angle = Radians()


@dataclass
class SimParams:
    """The built-in simulator: time step, sensors, mapping, navigation, faults."""

    dt: float = 0.1  # [s] sim time per step
    lidar: LidarParams = field(default_factory=LidarParams)
    mapper: MapperParams = field(default_factory=MapperParams)
    motion: MotionParams = field(default_factory=MotionParams)
    planner: PlannerParams = field(default_factory=PlannerParams)
    faults: FaultParams = field(default_factory=FaultParams)
    scene: SceneParams = field(default_factory=SceneParams)
    obstacles: ObstacleLayerParams = field(default_factory=ObstacleLayerParams)
    localization: LocalizationParams = field(default_factory=LocalizationParams)

    def __post_init__(self) -> None:
        if not 0.001 <= self.dt <= 1.0:
            raise ValueError("dt must be 0.001 to 1 s (a step longer than the robot's reaction makes no sense, "
                             "a shorter one only slows the simulation)")


@dataclass
class CameraParams:
    """The simulated head camera (defaults: Fetch's Primesense head camera)."""

    width: int = 640  # [count] image width in pixels before scaling
    height: int = 480  # [count] image height in pixels before scaling
    scale: float = 1.0  # [-] render at width*scale x height*scale; the intrinsics scale accordingly
    hfov_deg: float = 60.0  # [deg] horizontal field of view
    mount_height: float = 1.1  # [m] height of the optical centre above the floor
    mount_x: float = 0.1  # [m] distance of the optical centre ahead of base_link
    tilt_deg: float = 15.0  # [deg] pitch of the camera below the horizontal
    depth_min: float = 0.3  # [m] nearest valid depth
    depth_max: float = 8.0  # [m] farthest valid depth
    depth_noise: float = 0.005  # [m] depth standard deviation at 1 m; grows with depth squared
    rate: float = 2.0  # [Hz] frames per second of sim time

    def __post_init__(self) -> None:
        if not (0 < self.width <= 8192 and 0 < self.height <= 8192):
            raise ValueError("width and height must be 1 to 8192 pixels")
        if not 0.0 < self.scale <= 4.0:
            raise ValueError("scale must be in (0, 4]")
        if not 1.0 <= self.hfov_deg <= 170.0:
            raise ValueError("hfov_deg must be in [1, 170]")
        if not 0.0 <= self.depth_min < self.depth_max:
            raise ValueError("need 0 <= depth_min < depth_max")
        if self.depth_noise < 0.0:
            raise ValueError("depth_noise must be >= 0")
        if self.rate <= 0.0:
            raise ValueError("rate must be positive")
        if not -89.0 <= self.tilt_deg <= 89.0:
            raise ValueError("tilt_deg must be in [-89, 89]")

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) of the rendered images."""
        return max(1, round(self.width * self.scale)), max(1, round(self.height * self.scale))


@dataclass
class HardDetectorParams:
    """The ``hard`` preset's correlated failure modes (see bomc_bt.sim.detector_hard).

    Look-alikes and dark zones are fixed per world (a hash of the world's identity,
    :attr:`bomc_bt.world.World.key`, the place and, for look-alikes, the viewing sector),
    so they come back whenever the robot looks from a similar pose, pass after pass; none
    of these fields matter to other presets.
    """

    lookalike_cell: float = 3.0  # [m] side of the floor squares that each hold at most one look-alike
    lookalike_density: float = 0.1  # [-] share of those squares that hold a look-alike (a shadow, a box)
    lookalike_sectors: int = 8  # [count] viewing sectors around a look-alike (8: 45 deg each)
    lookalike_sector_share: float = 0.25  # [-] share of its sectors from which a look-alike is mistaken for an object
    lookalike_range: float = 4.0  # [m] a look-alike farther from the camera than this is not mistaken
    lookalike_rate: float = 0.8  # [-] chance per frame that a look-alike in view from one of its sectors is reported
    lookalike_size: float = 0.5  # [m] side of the look-alike's square footprint on the floor
    lookalike_height: float = 0.4  # [m] height of the look-alike (its box in the image)
    # [list] categories the grazing-angle misses apply to (thin, flat objects seen edge-on)
    grazing_categories: list[str] = field(default_factory=lambda: ["door"])
    grazing_start_deg: float = 50.0  # [deg] angle between view ray and the object's normal above which misses rise
    grazing_miss: float = 0.7  # [-] added miss probability edge-on (90 deg) with the camera close to the plane
    # [m] camera within this distance of the object's plane (a narrow corridor): the full grazing effect;
    # it fades to nothing at twice this distance
    grazing_lateral: float = 1.5
    dark_cell: float = 8.0  # [m] side of the floor squares that each hold at most one dark zone
    dark_share: float = 0.3  # [-] share of those squares that hold a dark zone
    dark_radius: float = 2.5  # [m] radius of a dark zone (at most dark_cell)
    dark_miss: float = 0.35  # [-] added miss probability of an object inside a dark zone
    dark_score_drop: float = 0.08  # [-] confidence lost by an object inside a dark zone

    def __post_init__(self) -> None:
        for name in ("lookalike_density", "lookalike_sector_share", "lookalike_rate", "grazing_miss",
                     "dark_share", "dark_miss", "dark_score_drop"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1]")
        for name in ("lookalike_cell", "lookalike_range", "lookalike_size", "lookalike_height", "grazing_lateral",
                     "dark_cell"):
            if not 0.0 < getattr(self, name) <= 1000.0:
                raise ValueError(f"{name} must be in (0, 1000] m")
        if not 1 <= self.lookalike_sectors <= 360:
            raise ValueError("lookalike_sectors must be 1 to 360")
        if not 0.0 <= self.grazing_start_deg < 90.0:
            raise ValueError("grazing_start_deg must be in [0, 90)")
        if not 0.0 <= self.dark_radius <= self.dark_cell:
            raise ValueError("dark_radius must be in [0, dark_cell]")


@dataclass
class SimDetectorParams:
    """Noise model of the simulated detector and segmenter (see bomc_bt.sim.detector)."""

    # [choice] "perfect": every visible object, no noise; "realistic": independent per-frame noise (below);
    # "hard": realistic plus correlated failures (look-alikes, grazing-angle and dark-zone misses; see hard)
    preset: Literal["perfect", "realistic", "hard"] = "realistic"
    score_threshold: float = 0.75  # [-] detections scoring below this are dropped (the paper's threshold)
    min_pixels: int = 50  # [count] visible pixels an object needs to be detected, at 640 x 480 (scaled with the image)
    miss_base: float = 0.05  # [-] probability of missing a fully visible object up close
    miss_per_metre: float = 0.04  # [-] added miss probability per metre of distance
    miss_occlusion: float = 0.6  # [-] added miss probability per occluded fraction of the object
    score_mean: float = 0.88  # [-] mean confidence score of a detection
    score_std: float = 0.05  # [-] standard deviation of the confidence score
    score_drop: float = 0.15  # [-] mean score lost per unit of miss probability
    false_positive_rate: float = 0.01  # [-] chance per frame of a detection where there is no object
    confusion_rate: float = 0.01  # [-] chance per detection of the wrong category
    mask_bleed: float = 0.1  # [-] fraction of the mask area added around it
    box_jitter: float = 0.03  # [-] standard deviation of each box side, as a fraction of the box size
    # [list] (start, end) intervals in s of sim time with no detections at all
    dropouts: list[tuple[float, float]] = field(default_factory=list)
    hard: HardDetectorParams = field(default_factory=HardDetectorParams)

    def __post_init__(self) -> None:
        for name in ("miss_base", "miss_per_metre", "miss_occlusion", "score_std", "score_drop",
                     "mask_bleed", "box_jitter"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"{name} must be >= 0")
        for name in ("false_positive_rate", "confusion_rate", "score_threshold"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1]")
        if self.min_pixels < 1:
            raise ValueError("min_pixels must be >= 1")
        for start, end in self.dropouts:
            if end < start or start < 0:
                raise ValueError(f"dropout ({start}, {end}) must start at 0 s or later and end after it starts")
