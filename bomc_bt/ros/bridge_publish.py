"""What the sim bridge publishes: a :class:`SimRobot`'s state as a ROS robot's topics.

``/map`` (the sim mapper while building, the saved map while monitoring, latched like
map_server), move_base's global costmap while monitoring (the map with the obstacle
layer's marks lethal, when the layer changed, at most every ``costmap_period``), the scan, tf
``map -> odom -> base_link -> camera``, RGB(-D) images with camera_info, ``/amcl_pose``
and ``/clock``, and the simulator-only ground-truth channel (:mod:`bomc_bt.ros.ground_truth`).
Every message's stamp is remembered per topic, so the bridge can announce what it has
published (the lockstep protocol), and the newest message per topic, so it can publish it
again for an executive that just connected.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bomc_bt.geometry import invert_se3
from bomc_bt.ros.convert import covariance, encode_depth, fill_grid, fill_pose, fill_transform
from bomc_bt.ros.ground_truth import info_topic, instance_messages
from bomc_bt.ros.params import RosParams
from bomc_bt.sim.frame import SimFrame


class SimStatePublisher:
    """Publishes one simulated robot's sensors, maps and poses with simulated stamps."""

    def __init__(self, rospy: Any, sim: Any, params: RosParams, *, scan_rate: float = 2.0,
                 publish_camera_info: bool = True, publish_tf_camera: bool = True):
        import tf2_ros
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from nav_msgs.msg import OccupancyGrid as GridMsg
        from rosgraph_msgs.msg import Clock
        from rospy.numpy_msg import numpy_msg
        from sensor_msgs.msg import CameraInfo, Image, LaserScan
        from std_msgs.msg import String

        self.rospy = rospy
        self.sim = sim
        self.p = params
        self.scan_period = 1.0 / scan_rate if scan_rate > 0 else math.inf
        self.publish_camera_info = publish_camera_info
        self.publish_tf_camera = publish_tf_camera
        self.amcl_std: tuple[float, float] | None = None  # (m, rad) /amcl_pose reports; None: no AMCL yet
        self.T_base_camera: np.ndarray | None = None
        self._next_scan = 0.0
        self._next_map = 0.0
        self._map_version: Any = None
        self._grid_msg_cls = numpy_msg(GridMsg)
        self.sent: dict[str, int] = {}  # resolved topic -> stamp (ns) of the newest message on it
        self.last: dict[str, Any] = {}  # pub key -> the newest message (re-sent on request)
        self.last_tf: list[Any] = []
        self.pub = {
            "clock": rospy.Publisher("/clock", Clock, queue_size=10),
            "map": rospy.Publisher(params.map_topic, self._grid_msg_cls, queue_size=1, latch=True),
            "scan": rospy.Publisher(params.scan_topic, LaserScan, queue_size=2),
            "amcl": rospy.Publisher(params.amcl_pose_topic, PoseWithCovarianceStamped, queue_size=5),
            "rgb": rospy.Publisher(params.rgb_topic, Image, queue_size=2),
            "depth": rospy.Publisher(params.depth_topic, Image, queue_size=2),
            "info": rospy.Publisher(params.camera_info_topic, CameraInfo, queue_size=2),
        }
        if params.costmap_topic:
            self.pub["costmap"] = rospy.Publisher(params.costmap_topic, self._grid_msg_cls, queue_size=1, latch=True)
        self._costmap_version: Any = None
        self._next_costmap = 0.0
        if params.instances_topic:
            self.pub["instances"] = rospy.Publisher(params.instances_topic, Image, queue_size=2)
            self.pub["instances_info"] = rospy.Publisher(info_topic(params.instances_topic), String, queue_size=2)
        self.tf = tf2_ros.TransformBroadcaster()

    def stamp(self, t: float | None = None) -> Any:
        return self.rospy.Time.from_sec(self.sim.now() if t is None else t)

    def _send(self, key: str, msg: Any, stamp: Any = None) -> None:
        """Publish on ``self.pub[key]`` and remember the stamp, for the bridge's announcement."""
        pub = self.pub[key]
        pub.publish(msg)
        self.last[key] = msg
        self.sent[pub.resolved_name] = (stamp if stamp is not None else msg.header.stamp).to_nsec()

    def resend(self) -> None:
        """Publish the newest message of every topic and tf again."""
        if self.last_tf:
            self.tf.sendTransform(self.last_tf)
        for key, msg in self.last.items():
            self.pub[key].publish(msg)

    def publish_clock(self, t: float | None = None) -> None:
        from rosgraph_msgs.msg import Clock

        self.pub["clock"].publish(Clock(clock=self.stamp(t)))

    def tf_announcement(self) -> list | None:
        """[stamp (ns), [[parent, child], ...]] of the newest transforms sent, or None."""
        if not self.last_tf:
            return None
        pairs = [[m.header.frame_id, m.child_frame_id] for m in self.last_tf]
        return [self.last_tf[0].header.stamp.to_nsec(), pairs]

    def publish_all(self) -> None:
        """Everything the last simulator step changed, then the clock."""
        now = self.sim.now()
        frame = self.sim.frame()
        if frame is not None:
            self.T_base_camera = frame.T_base_camera
        self._publish_tf(now)  # tf first: the images' stamp must be transformable on arrival
        if self.sim.building_map and now >= self._next_map:
            version = self.sim.mapper.updates
            if version != self._map_version:
                self._map_version = version
                self._next_map = now + self.p.map_period
                self.publish_map(self.sim.live_map())
        if ("costmap" in self.pub and now >= self._next_costmap
                and self.sim.costmap_version not in (None, self._costmap_version)):
            self._costmap_version = self.sim.costmap_version
            self._next_costmap = now + self.p.costmap_period
            self._send("costmap", self._grid_msg(self.sim.costmap()))
        if now >= self._next_scan:
            self._next_scan = now + self.scan_period
            self._publish_scan()
        if self.sim.pose() is not None and self.amcl_std is not None and self.sim.mode == "monitor":
            self.publish_amcl()
        if frame is not None:
            self._publish_frame(frame)
        self.publish_clock(now)

    def _transform(self, parent: str, child: str, matrix: np.ndarray, t: float) -> Any:
        from geometry_msgs.msg import TransformStamped

        msg = TransformStamped()
        msg.header.stamp = self.stamp(t)
        msg.header.frame_id = parent
        msg.child_frame_id = child
        fill_transform(msg.transform, matrix)
        return msg

    def _publish_tf(self, t: float) -> None:
        p = self.p
        true = self.sim.true_pose.to_matrix()
        out = [self._transform(p.odom_frame, p.base_frame, true, t)]
        estimate = self.sim.pose()
        if estimate is not None:  # AMCL / SLAM publish map -> odom only once localized
            out.append(self._transform(p.map_frame, p.odom_frame, estimate.to_matrix() @ invert_se3(true), t))
        if self.T_base_camera is not None and self.publish_tf_camera:
            out.append(self._transform(p.base_frame, self.camera_frame, self.T_base_camera, t))
        self.tf.sendTransform(out)
        self.last_tf = out

    @property
    def camera_frame(self) -> str:
        return self.p.camera_frame or "head_camera_rgb_optical_frame"

    def publish_map(self, grid: Any) -> None:
        self._send("map", self._grid_msg(grid))

    def _grid_msg(self, grid: Any) -> Any:
        msg = self._grid_msg_cls()
        msg.header.frame_id = self.p.map_frame
        msg.header.stamp = self.stamp()
        msg.info.map_load_time = msg.header.stamp
        fill_grid(msg, grid)
        return msg

    def _publish_scan(self) -> None:
        from sensor_msgs.msg import LaserScan

        scan = self.sim.scan()
        if scan is None:
            return
        msg = LaserScan()
        msg.header.stamp = self.stamp(scan.stamp)
        msg.header.frame_id = self.p.base_frame
        msg.angle_min = float(scan.angle_min)
        msg.angle_increment = float(scan.angle_increment)
        msg.angle_max = float(scan.angle_min + scan.angle_increment * (len(scan.ranges) - 1))
        msg.range_min, msg.range_max = 0.0, float(scan.range_max)
        msg.ranges = np.where(np.isfinite(scan.ranges), scan.ranges, np.inf).astype(float).tolist()
        self._send("scan", msg)

    def publish_amcl(self) -> None:
        from geometry_msgs.msg import PoseWithCovarianceStamped

        pose = self.sim.pose()
        if self.amcl_std is None:
            return
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = self.stamp()
        msg.header.frame_id = self.p.map_frame
        fill_pose(msg.pose.pose, pose or self.sim.true_pose)
        msg.pose.covariance = covariance(*self.amcl_std)
        self._send("amcl", msg)

    def _publish_frame(self, frame: SimFrame) -> None:
        from sensor_msgs.msg import Image

        h, w = frame.shape
        stamp = self.stamp(frame.stamp)

        def image(encoding: str, data: bytes, step: int) -> Any:
            msg = Image(height=h, width=w, encoding=encoding, is_bigendian=0, step=step, data=data)
            msg.header.stamp, msg.header.frame_id = stamp, self.camera_frame
            return msg

        if self.publish_camera_info:
            self._send("info", self._camera_info(frame, stamp))
        if "instances" in self.pub:
            instances, info, info_stamp = instance_messages(frame, image)
            self._send("instances_info", info, self.stamp(info_stamp))
            self._send("instances", instances)
        depth, step = encode_depth(frame.depth, self.p.depth_encoding)
        self._send("depth", image(self.p.depth_encoding, depth, step))
        if frame.rgb is not None:
            self._send("rgb", image("rgb8", np.ascontiguousarray(frame.rgb, np.uint8).tobytes(), w * 3))

    def _camera_info(self, frame: SimFrame, stamp: Any) -> Any:
        from sensor_msgs.msg import CameraInfo

        h, w = frame.shape
        K = frame.K
        info = CameraInfo(
            height=h,
            width=w,
            distortion_model="plumb_bob",
            D=[0.0] * 5,
            K=[float(v) for v in K.reshape(-1)],
            R=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            P=[float(K[0, 0]), 0.0, float(K[0, 2]), 0.0, 0.0, float(K[1, 1]), float(K[1, 2]), 0.0, 0.0, 0.0, 1.0, 0.0],
        )
        info.header.stamp, info.header.frame_id = stamp, self.camera_frame
        return info
