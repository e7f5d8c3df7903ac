"""The ROS 1 robot behind the robot port: move_base, GMapping / map_server, AMCL, RGB-D, tf2.

Subscriber callbacks only store the latest messages (under a lock); every port call reads
them, so no call blocks a tick. Long work is a handle polled by the tree: a move_base goal
(:class:`~bomc_bt.ros.move_base.NavGoal`) or an AMCL relocalization
(:class:`~bomc_bt.ros.amcl.AmclRelocalization`).

Time is ROS time. With ``use_sim_time`` and the sim-over-ROS bridge, each tick also runs
the lockstep protocol (:mod:`bomc_bt.ros.lockstep`), and the simulated detector's ground
truth comes through its own channel (:mod:`bomc_bt.ros.ground_truth`); a real robot has
neither, and nothing waits. Wall time is used only to bound waits: ROS time that has
stopped (a dead ``/clock``) must be an error, not a hang.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import numpy as np

from bomc_bt.errors import MissionFailed
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import Handle, LaserScan, RequestHandle, RGBDFrame, Status
from bomc_bt.ros.amcl import AmclRelocalization
from bomc_bt.ros.convert import (
    decimal_resolution,
    decode_depth,
    decode_rgb,
    grid_from_msg,
    intrinsics,
    pose2d_from_matrix,
    scan_from_msg,
    transform_matrix,
)
from bomc_bt.ros.costmap import GlobalCostmap
from bomc_bt.ros.image_pairs import ImagePairs
from bomc_bt.ros.lockstep import LockstepClient
from bomc_bt.ros.map_refresh import MapRefresh
from bomc_bt.ros.move_base import MoveBaseClient, NavGoal
from bomc_bt.ros.node import check_master, ensure_node
from bomc_bt.ros.params import RosParams

__all__ = ["RosRobot", "check_master", "ensure_node"]


class RosRobot:
    """The robot port over ROS 1 (implements :class:`bomc_bt.robot.RobotPort`)."""

    def __init__(self, params: RosParams | None = None, mode: str = "build"):
        if mode not in ("build", "monitor"):
            raise ValueError(f"mode must be 'build' or 'monitor', got {mode!r}")
        self.rospy = rospy = ensure_node()
        import tf2_ros
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from nav_msgs.msg import OccupancyGrid as GridMsg
        from rospy.numpy_msg import numpy_msg
        from sensor_msgs.msg import CameraInfo, Image
        from sensor_msgs.msg import LaserScan as ScanMsg

        self.params = p = params or RosParams()
        self.mode = mode
        self.localized = mode == "build"
        self._lock = threading.Lock()
        self._map_msg: Any = None
        self._map_cache: tuple[int, OccupancyGrid] | None = None
        self._map_version = 0
        self._grid: OccupancyGrid | None = None
        self._scan_msg: Any = None
        self._info: Any = None
        self._amcl: tuple[int, Any] | None = None
        self.amcl_count = 0
        self.images = ImagePairs(p.sync_slop)  # its passed_over: camera images that never became frames
        self._pending: dict[str, Any] | None = None
        self.pose_gaps = 0  # pose() calls that found no map <- base tf while localized
        self.counts = {"goals": 0, "cancels": 0, "initialposes": 0, "services": 0, "maps": 0}
        self._nav: NavGoal | None = None
        self._reloc: AmclRelocalization | None = None
        self.use_sim_time = bool(rospy.get_param("/use_sim_time", False))
        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self._tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.lockstep = LockstepClient(rospy, p, self.tf_buffer, self.use_sim_time)
        track = self.lockstep.track
        self._subs = [
            track(p.map_topic, numpy_msg(GridMsg), self._on_map, queue_size=1),
            track(p.scan_topic, ScanMsg, self._keep("_scan_msg"), queue_size=1),
            track(p.amcl_pose_topic, PoseWithCovarianceStamped, self._on_amcl, queue_size=5),
            track(p.rgb_topic, Image, self._on_image("rgb"), queue_size=5, buff_size=2**24),
            track(p.depth_topic, Image, self._on_image("depth"), queue_size=5, buff_size=2**24),
            track(p.camera_info_topic, CameraInfo, self._keep("_info"), queue_size=1),
        ]
        self.costmap = GlobalCostmap()
        if p.costmap_topic:
            self._subs.append(track(p.costmap_topic, numpy_msg(GridMsg), self.costmap.on_message, queue_size=1))
        self.ground_truth = None
        if p.instances_topic:  # the sim-over-ROS bridge's simulator-only channel
            from bomc_bt.ros.ground_truth import GroundTruthChannel

            self.ground_truth = GroundTruthChannel(rospy, p.instances_topic, track)
        self.initialpose_pub = rospy.Publisher(
            p.initialpose_topic, PoseWithCovarianceStamped, queue_size=1, latch=True
        )
        self.move_base = MoveBaseClient(rospy, p, on_result=self.lockstep.notify)
        self.map_refresh = MapRefresh(rospy, p)
        self._wait_for_start()
        self._last_tick = self.now()
        self.distance_travelled = 0.0  # m along odom -> base_link (the session report's path length)
        self._odom_xy: tuple[float, float] | None = None

    # -- start-up --------------------------------------------------------------------------
    def _wait_for_start(self) -> None:
        """Wait (wall-bounded) for /clock and the move_base server: absent ones are errors."""
        p = self.params
        if self.use_sim_time and not self.lockstep.clock_seen.wait(p.clock_timeout):
            self.close()
            raise MissionFailed(f"use_sim_time is set but nothing publishes /clock (waited {p.clock_timeout:.0f} s)")
        deadline = time.monotonic() + p.server_timeout
        while not self.move_base.ready():  # on the wall clock: ROS time may wait for the first tick
            if time.monotonic() > deadline:
                self.close()
                raise MissionFailed(f"no move_base action server at {p.move_base_action!r} within "
                                    f"{p.server_timeout:.0f} s (ros.move_base_action)")
            time.sleep(0.02)
        self.lockstep.wait_for_bridge(self._all_subs(), self.now(), self.counts, self.move_base.awaits_result,
                                      pubs=(self.initialpose_pub,))

    def _all_subs(self) -> list[Any]:
        truth = self.ground_truth.subs if self.ground_truth is not None else []
        return [*self._subs, *truth, *self.lockstep.subs, *self.move_base.subs, self._tf_listener.tf_sub]

    def close(self) -> None:
        """Unsubscribe and stop publishing (the node itself lives on for the process)."""
        for sub in self._subs + (self.ground_truth.subs if self.ground_truth is not None else []):
            sub.unregister()
        self._subs = []
        self._tf_listener.unregister()  # else it fills this robot's buffer for the process's life
        self.initialpose_pub.unregister()
        self.lockstep.close()
        self.move_base.close()
        self.map_refresh.close()

    # -- callbacks -------------------------------------------------------------------------
    def _keep(self, attr: str):
        def callback(msg: Any) -> None:
            with self._lock:
                setattr(self, attr, msg)

        return callback

    def _on_map(self, msg: Any) -> None:
        with self._lock:
            self._map_msg = msg
            self._map_version += 1

    def _on_amcl(self, msg: Any) -> None:
        with self._lock:
            self.amcl_count += 1
            self._amcl = (self.amcl_count, msg)

    def _on_image(self, kind: str):
        def callback(msg: Any) -> None:
            with self._lock:
                self.images.add(kind, msg, self.now())

        return callback

    def latest_amcl(self) -> tuple[int, Any] | None:
        with self._lock:
            return self._amcl

    # -- port: time ------------------------------------------------------------------------
    def now(self) -> float:
        """ROS time (s); in lockstep, the bridge's own float for the time on its /clock."""
        return self.lockstep.exact_time(self.rospy.Time.now())

    def step(self) -> None:
        """Sleep to the next tick on ROS time (a rospy.Rate that also notices a dead clock)."""
        period = 1.0 / self.params.tick_rate
        target = self._last_tick + period
        if self.now() > target + period:  # fell behind (a slow tick): do not try to catch up
            target = self.now()
        self.lockstep.publish_tick(target, self.counts)
        wall_start = last_change = time.monotonic()
        seen = self.now()
        while self.now() < target - 1e-6:  # ROS time has ns resolution (truncated)
            if self.rospy.is_shutdown():
                raise MissionFailed("ROS shut down")
            time.sleep(0.0005 if self.use_sim_time else min(0.01, period / 10))
            wall = time.monotonic()
            if self.now() != seen:
                seen, last_change = self.now(), wall
            elif wall - last_change > self.params.clock_timeout:
                raise MissionFailed(
                    f"ROS time stopped at {seen:.2f} s for {self.params.clock_timeout:.0f} s "
                    "(is /clock still published?)"
                )
            if self.use_sim_time and wall - wall_start > 0.2:  # re-announce: a tick may be lost
                wall_start = wall
                self.lockstep.publish_tick(target, self.counts)
        self.lockstep.sync(target, self.move_base.awaits_result)
        self._last_tick = target
        self._track_odometry()

    def _track_odometry(self) -> None:
        """Add the odom-frame translation since the last tick: smooth, unlike map -> base_link."""
        if not self.params.odom_frame:
            return
        m = self._lookup(self.params.odom_frame, self.params.base_frame, None)
        if m is None:
            return
        xy = (float(m[0, 3]), float(m[1, 3]))
        if self._odom_xy is not None:
            self.distance_travelled += math.hypot(xy[0] - self._odom_xy[0], xy[1] - self._odom_xy[1])
        self._odom_xy = xy

    # -- port: pose and maps -----------------------------------------------------------------
    def _lookup(self, target: str, source: str, stamp: Any = None) -> np.ndarray | None:
        """``target <- source`` at ``stamp`` (a rospy.Time from a header; None = latest)."""
        import tf2_ros

        when = self.rospy.Time(0) if stamp is None else stamp
        try:
            tf = self.tf_buffer.lookup_transform(target, source, when)
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException):
            return None
        return transform_matrix(tf.transform)

    def pose_now(self) -> Pose2D | None:
        """map <- base_link from tf2, whether or not a relocalization has confirmed it."""
        m = self._lookup(self.params.map_frame, self.params.base_frame, None)
        return None if m is None else pose2d_from_matrix(m)

    def pose(self) -> Pose2D | None:
        if not self.localized:
            return None
        pose = self.pose_now()
        self.pose_gaps += pose is None
        return pose

    def live_map(self) -> OccupancyGrid:
        with self._lock:
            msg, version = self._map_msg, self._map_version
        if msg is None:
            if self._grid is not None:
                return self._grid
            return OccupancyGrid(data=np.full((1, 1), -1, np.int8), resolution=0.05, origin=(0.0, 0.0))
        if self._map_cache is None or self._map_cache[0] != version:
            self._map_cache = (version, decimal_resolution(grid_from_msg(msg)))
        return self._map_cache[1]

    def use_map(self, grid: OccupancyGrid) -> None:
        """Keep the saved map: on the robot map_server serves it to AMCL and move_base.

        ``live_map`` returns /map once it arrives, else this grid (planning-free uses:
        waypoints, reports).
        """
        self._grid = grid

    def refresh_map(self, grid: OccupancyGrid) -> None:
        """Navigate on ``grid``: published where move_base reads its map (:mod:`bomc_bt.ros.map_refresh`)."""
        self._grid = grid
        self.counts["maps"] += self.map_refresh.publish(grid)  # the bridge steps once it has it

    def scan(self) -> LaserScan | None:
        with self._lock:
            msg = self._scan_msg
        return None if msg is None else scan_from_msg(msg)

    # -- port: camera ------------------------------------------------------------------------
    def frame(self) -> RGBDFrame | None:
        """The newest synchronised RGB-D pair, once camera_info and tf at its stamp are there."""
        p = self.params
        now = self.now()
        with self._lock:
            if self._pending is None:
                self._pending = self.images.newest(now)
            pending, info = self._pending, self._info
            self.images.check_unpaired(now, p.frame_timeout, p.rgb_topic, p.depth_topic)
        if pending is None:
            return None
        waited = now - pending["received"]
        if info is None:
            if waited > p.frame_timeout:
                raise MissionFailed(
                    f"no camera_info on {p.camera_info_topic} within {p.frame_timeout:.0f} s "
                    "of an image (ros.camera_info_topic)"
                )
            return None
        camera = p.camera_frame or pending["depth"].header.frame_id or info.header.frame_id
        header_stamp = pending["depth"].header.stamp  # exact: a float round trip may miss the tf sample
        T_map_base = self._lookup(p.map_frame, p.base_frame, header_stamp)
        T_base_camera = self._lookup(p.base_frame, camera, header_stamp)
        truth_missing = self.ground_truth is not None and not self.ground_truth.ready(pending["stamp"])
        if truth_missing and self.ground_truth.lost(pending["stamp"]):
            self._pending = None  # the next call takes a newer pair
            self.images.drop(pending["stamp"], "ground truth lost")
            self.rospy.logwarn(f"bomc: the instance image of {pending['stamp']:.2f} s was lost; frame skipped")
            return None
        if T_map_base is None or T_base_camera is None or truth_missing:
            if waited > p.frame_timeout:
                self._pending = None
                if truth_missing:
                    raise MissionFailed(self.ground_truth.missing(pending["stamp"]))
                missing = f"{p.map_frame} <- {p.base_frame}" if T_map_base is None else f"{p.base_frame} <- {camera}"
                raise MissionFailed(
                    f"no tf {missing} at the image stamp {pending['stamp']:.2f} s within "
                    f"{p.frame_timeout:.0f} s (ros.map_frame / ros.base_frame / ros.camera_frame)"
                )
            return None
        self._pending = None
        frame = RGBDFrame(
            stamp=pending["stamp"],
            rgb=decode_rgb(pending["rgb"]),
            depth=decode_depth(pending["depth"]),
            K=intrinsics(info),
            T_map_base=T_map_base,
            T_base_camera=T_base_camera,
            depth_range=(p.depth_min, p.depth_max),
        )
        return frame if self.ground_truth is None else self.ground_truth.attach(frame)

    # -- port: navigation and localization ---------------------------------------------------
    def navigate(self, goal: Pose2D) -> Handle:
        if not self.localized:
            return RequestHandle.refused("not localized")
        if self._nav is not None:
            self._nav.finish(Status.CANCELLED, "pre-empted by a new goal")  # move_base pre-empts it
        self._nav = NavGoal(self, goal)
        return self._nav

    def relocalize(self, hint: Pose2D | None, global_search: bool = False) -> AmclRelocalization:
        if self._reloc is not None:
            self._reloc.cancel()
        if self.mode == "monitor":
            self.localized = False
        self._reloc = AmclRelocalization(self, hint, global_search)
        return self._reloc

    def clear_costmaps(self) -> None:
        """move_base's ``clear_costmaps`` service (``ros.clear_costmaps_service``), in the background."""
        self.costmap.cleared(self.now())
        if self.params.clear_costmaps_service:
            self.call_service(self.params.clear_costmaps_service)

    def obstacle_layer(self) -> np.ndarray:
        """The lethal cells of move_base's global costmap (``ros.costmap_topic``): the map's
        walls and what the obstacle layer marks, from a full costmap stamped after the last
        clear (:class:`bomc_bt.ros.costmap.GlobalCostmap`); else empty."""
        return self.costmap.cells()

    def cancel_all(self) -> None:
        if self._nav is not None:
            self._nav.cancel()
        if self._reloc is not None:
            self._reloc.cancel()

    def call_service(self, name: str, required: bool = True) -> None:
        """Call a std_srvs/Empty service in the background (never blocks a tick)."""
        from std_srvs.srv import Empty

        rospy = self.rospy
        self.counts["services"] += 1

        def call() -> None:
            try:
                rospy.wait_for_service(name, timeout=self.params.server_timeout)
                rospy.ServiceProxy(name, Empty)()
            except Exception as exc:  # the handle times out on ROS time and says so
                if required:
                    rospy.logwarn(f"bomc: service {name} failed: {exc}")

        threading.Thread(target=call, name=f"bomc-{name}", daemon=True).start()

