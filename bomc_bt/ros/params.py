"""Topic and frame names, rates, timeouts and localization bounds of the ROS 1 robot.

Defaults are a Fetch running the ROS navigation stack (GMapping or map_server + AMCL +
move_base, the head camera's RGB-D driver). Another robot changes names in the ``ros:``
section of its config file; nothing else in the adapter knows a topic name.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal


@dataclass
class RosParams:
    # -- time --------------------------------------------------------------------------
    tick_rate: float = 10.0  # Hz of ROS time between tree ticks
    clock_timeout: float = 10.0  # wall s: ROS time that stops advancing this long is an error
    # -- maps, scans, localization -------------------------------------------------------
    map_topic: str = "/map"
    scan_topic: str = "/base_scan"
    map_frame: str = "map"
    odom_frame: str = "odom"
    base_frame: str = "base_link"
    initialpose_topic: str = "/initialpose"
    amcl_pose_topic: str = "/amcl_pose"
    global_localization_service: str = "/global_localization"
    nomotion_update_service: str = "/request_nomotion_update"  # "" to never ask AMCL for an update
    nomotion_update_period: float = 1.0  # s of ROS time between update requests while waiting
    initial_xy_std: float = 0.5  # m, the covariance /initialpose is published with
    initial_yaw_std: float = 0.3  # rad
    max_xy_std: float = 0.15  # m; localized when the /amcl_pose x and y std are below this
    max_yaw_std: float = 0.15  # rad; ... and the yaw std below this
    relocalize_timeout: float = 30.0  # s of ROS time before a relocalization is FAILED
    # -- navigation ------------------------------------------------------------------------
    move_base_action: str = "move_base"
    server_timeout: float = 10.0  # wall s to wait for the move_base action server at start
    goal_ack_timeout: float = 5.0  # s of ROS time for move_base to accept a goal
    progress_timeout: float = 60.0  # s of ROS time without moving -> BLOCKED (and cancelled)
    progress_distance: float = 0.1  # m of translation that counts as progress
    progress_angle: float = 0.3  # rad of rotation that counts as progress
    # -- camera ----------------------------------------------------------------------------
    rgb_topic: str = "/head_camera/rgb/image_raw"
    depth_topic: str = "/head_camera/depth_registered/image_raw"
    camera_info_topic: str = "/head_camera/rgb/camera_info"
    camera_frame: str = ""  # "" = the image header's frame_id (Fetch: head_camera_rgb_optical_frame)
    sync_slop: float = 0.05  # s; an RGB and a depth image this close in stamp are a pair
    frame_timeout: float = 5.0  # s of ROS time to wait for camera_info / tf of an image pair
    depth_min: float = 0.3  # m, the depth sensor's valid range
    depth_max: float = 8.0
    # Simulator bridge only: the per-pixel instance image that the simulated detector reads
    # (ground truth). Empty on a real robot.
    instances_topic: str = ""
    # -- what the executive publishes --------------------------------------------------------
    publish: bool = True
    publish_period: float = 1.0  # s of ROS time between marker / tree snapshots
    markers_topic: str = "/bomc/objects"
    frontiers_topic: str = "/bomc/frontiers"
    waypoints_topic: str = "/bomc/waypoints"
    tree_topic: str = "/bomc/tree"
    events_topic: str = "/bomc/events"
    tick_topic: str = "/bomc/tick"  # the executive's "waiting for time t" (the bridge steps on it)
    # The bridge's "stepped to t, having published this": in lockstep the executive waits for
    # it so each tick sees exactly what was published up to its time. "" = <tick_topic>/done.
    stepped_topic: str = ""
    # -- the sim-over-ROS bridge -------------------------------------------------------------
    depth_encoding: Literal["32FC1", "16UC1"] = "32FC1"
    # s of sim time between /map publications while building; 0 = on every mapper update,
    # as the direct simulator's explorer sees the map (GMapping itself throttles to ~5 s).
    map_period: float = 0.0

    @property
    def stepped(self) -> str:
        """The lockstep acknowledgement topic (derived from ``tick_topic`` unless set)."""
        return self.stepped_topic or self.tick_topic.rstrip("/") + "/done"

    def __post_init__(self) -> None:
        positive = (
            "tick_rate",
            "clock_timeout",
            "relocalize_timeout",
            "server_timeout",
            "goal_ack_timeout",
            "progress_timeout",
            "frame_timeout",
            "publish_period",
            "initial_xy_std",
            "initial_yaw_std",
            "max_xy_std",
            "max_yaw_std",
            "nomotion_update_period",
        )
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")
        if self.sync_slop < 0 or self.map_period < 0:
            raise ValueError("sync_slop and map_period must be >= 0")
        if not 0 <= self.depth_min < self.depth_max:
            raise ValueError("depth_min must be >= 0 and below depth_max")
        if self.depth_encoding not in ("32FC1", "16UC1"):
            raise ValueError("depth_encoding must be 32FC1 or 16UC1")
        for name in (
            "map_topic",
            "scan_topic",
            "rgb_topic",
            "depth_topic",
            "camera_info_topic",
            "map_frame",
            "base_frame",
            "move_base_action",
            "amcl_pose_topic",
            "initialpose_topic",
        ):
            if not getattr(self, name):
                raise ValueError(f"{name} must not be empty")
