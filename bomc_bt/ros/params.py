"""Topic and frame names, rates, timeouts and localization bounds of the ROS 1 robot.

Defaults are a Fetch running the ROS navigation stack (GMapping or map_server + AMCL +
move_base, the head camera's RGB-D driver). Another robot changes names in the ``ros:``
section of its config file; nothing else in the adapter knows a topic name.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from bomc_bt.params import Radians


@dataclass
class RosParams:
    """The ROS 1 robot: topics, frames, timeouts, and what the executive publishes."""

    # -- time --------------------------------------------------------------------------
    tick_rate: float = 10.0  # [Hz] tree ticks per second of ROS time
    clock_timeout: float = 10.0  # [s] wall time: ROS time that stops advancing this long is an error
    # [s] wall time a lockstep tick waits for a message the sim bridge announced before going on
    # without it (and not waiting for that topic again until one of its messages comes in)
    lockstep_wait: float = 10.0
    # -- maps, scans, localization -------------------------------------------------------
    map_topic: str = "/map"  # [text] the map (nav_msgs/OccupancyGrid)
    # [text] where a stuck pass publishes the map with floor the lidar saw where furniture stood
    # at the build cleared (latched; move_base's static layer reads /map); "" never publishes
    refreshed_map_topic: str = "/map"
    scan_topic: str = "/base_scan"  # [text] the base laser (sensor_msgs/LaserScan)
    map_frame: str = "map"  # [text] tf frame of the map
    odom_frame: str = "odom"  # [text] tf frame of odometry
    base_frame: str = "base_link"  # [text] tf frame of the robot base
    initialpose_topic: str = "/initialpose"  # [text] where a relocalization hint is published (AMCL)
    amcl_pose_topic: str = "/amcl_pose"  # [text] AMCL's pose estimate with covariance
    global_localization_service: str = "/global_localization"  # [text] AMCL's global relocalization
    nomotion_update_service: str = "/request_nomotion_update"  # [text] AMCL update without motion; "" never asks
    # [text] move_base's service that empties its costmaps' obstacle layers (std_srvs/Empty); "" never asks
    clear_costmaps_service: str = "/move_base/clear_costmaps"
    # [text] move_base's global costmap (nav_msgs/OccupancyGrid); its lethal cells (100) are the
    # obstacle layer a pass that keeps failing waypoints reads after a clear, from the first full
    # costmap stamped after it (global_costmap: publish_frequency > 0, always_send_full_costmap: true); ""
    # never reads it
    costmap_topic: str = "/move_base/global_costmap/costmap"
    nomotion_update_period: float = 1.0  # [s] ROS time between update requests while waiting
    initial_xy_std: float = 0.5  # [m] position std /initialpose is published with
    initial_yaw_std_deg: float = 17.188733853924695  # [deg] yaw std /initialpose is published with (0.3 rad exactly)
    initial_yaw_std = Radians()
    max_xy_std: float = 0.15  # [m] localized when the /amcl_pose x and y std are below this
    max_yaw_std_deg: float = 8.594366926962348  # [deg] ... and when the yaw std is below this (0.15 rad exactly)
    max_yaw_std = Radians()
    relocalize_timeout: float = 30.0  # [s] ROS time before a relocalization is FAILED
    # -- navigation ------------------------------------------------------------------------
    move_base_action: str = "move_base"  # [text] the move_base action server
    server_timeout: float = 10.0  # [s] wall time to wait for the move_base action server at start
    goal_ack_timeout: float = 5.0  # [s] ROS time for move_base to accept a goal
    progress_timeout: float = 60.0  # [s] ROS time without moving before a goal is BLOCKED (and cancelled)
    progress_distance: float = 0.1  # [m] translation that counts as progress
    progress_angle_deg: float = 17.188733853924695  # [deg] rotation that counts as progress (0.3 rad exactly)
    progress_angle = Radians()
    # -- camera ----------------------------------------------------------------------------
    rgb_topic: str = "/head_camera/rgb/image_raw"  # [text] colour images
    depth_topic: str = "/head_camera/depth_registered/image_raw"  # [text] depth images registered to colour
    camera_info_topic: str = "/head_camera/rgb/camera_info"  # [text] the colour camera's intrinsics
    camera_frame: str = ""  # [text] the camera's tf frame; "" = the image header's frame_id
    sync_slop: float = 0.05  # [s] an RGB and a depth image this close in stamp are a pair
    frame_timeout: float = 5.0  # [s] ROS time to wait for camera_info / tf of an image pair
    depth_min: float = 0.3  # [m] nearest valid depth of the depth sensor
    depth_max: float = 8.0  # [m] farthest valid depth of the depth sensor
    # [text] simulator bridge only: the per-pixel instance image that the simulated detector
    # reads (ground truth). Empty on a real robot.
    instances_topic: str = ""
    # -- what the executive publishes --------------------------------------------------------
    publish: bool = True  # [bool] publish markers, frontiers, waypoints, the tree and events
    publish_period: float = 1.0  # [s] ROS time between marker / tree snapshots
    markers_topic: str = "/bomc/objects"  # [text] the object graph as RViz markers
    frontiers_topic: str = "/bomc/frontiers"  # [text] exploration frontiers as RViz markers
    waypoints_topic: str = "/bomc/waypoints"  # [text] the monitor pass's waypoints as RViz markers
    tree_topic: str = "/bomc/tree"  # [text] the behaviour tree's snapshot
    events_topic: str = "/bomc/events"  # [text] graph change events
    tick_topic: str = "/bomc/tick"  # [text] the executive's "waiting for time t" (the bridge steps on it)
    # [text] the bridge's "stepped to t, having published this": in lockstep the executive waits
    # for it so each tick sees exactly what was published up to its time. "" = <tick_topic>/done.
    stepped_topic: str = ""
    # -- the sim-over-ROS bridge -------------------------------------------------------------
    depth_encoding: Literal["32FC1", "16UC1"] = "32FC1"  # [choice] the bridge's depth images: float m or uint16 mm
    # [s] sim time between /map publications while building; 0 = on every mapper update,
    # as the direct simulator's explorer sees the map (GMapping itself throttles to ~5 s).
    map_period: float = 0.0
    costmap_period: float = 1.0  # [s] sim time between global costmaps while the layer changes (publish_frequency)

    @property
    def stepped(self) -> str:
        """The lockstep acknowledgement topic (derived from ``tick_topic`` unless set)."""
        return self.stepped_topic or self.tick_topic.rstrip("/") + "/done"

    def __post_init__(self) -> None:
        positive = (
            "tick_rate",
            "clock_timeout",
            "lockstep_wait",
            "relocalize_timeout",
            "server_timeout",
            "goal_ack_timeout",
            "progress_timeout",
            "frame_timeout",
            "publish_period",
            "initial_xy_std",
            "initial_yaw_std_deg",
            "max_xy_std",
            "max_yaw_std_deg",
            "nomotion_update_period",
        )
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")
        if self.sync_slop < 0 or self.map_period < 0 or self.costmap_period < 0:
            raise ValueError("sync_slop, map_period and costmap_period must be >= 0")
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
