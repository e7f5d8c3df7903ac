"""Relocalization through AMCL, as a robot-port handle.

:class:`AmclRelocalization` publishes ``/initialpose`` (or calls ``/global_localization``)
and waits for an ``/amcl_pose`` whose covariance is within the configured bounds, asking
AMCL for no-motion updates meanwhile (a standing robot otherwise never converges).
"""

from __future__ import annotations

from typing import Any, Protocol

from bomc_bt.geometry import Pose2D
from bomc_bt.robot import RequestHandle, Status
from bomc_bt.ros.convert import covariance, fill_pose, planar_std
from bomc_bt.ros.params import RosParams


class AmclRobot(Protocol):
    """What a relocalization needs of its robot (:class:`bomc_bt.ros.robot.RosRobot`)."""

    rospy: Any
    params: RosParams
    initialpose_pub: Any
    counts: dict[str, int]  # requests sent, announced to the sim bridge
    amcl_count: int  # /amcl_pose messages received so far
    localized: bool

    def now(self) -> float: ...

    def latest_amcl(self) -> tuple[int, Any] | None: ...

    def pose_now(self) -> Pose2D | None: ...

    def call_service(self, name: str, required: bool = True) -> None: ...


class AmclRelocalization(RequestHandle):
    """Relocalize through AMCL and wait for a confident /amcl_pose."""

    def __init__(self, robot: AmclRobot, hint: Pose2D | None, global_search: bool):
        super().__init__("relocalizing")
        self.robot = robot
        p = robot.params
        self.started = robot.now()
        self.first_seq = robot.amcl_count  # only poses AMCL publishes after this request count
        self._next_update = self.started + p.nomotion_update_period
        if global_search or hint is None:
            robot.call_service(p.global_localization_service)
            self._message = "global localization requested"
        else:
            from geometry_msgs.msg import PoseWithCovarianceStamped

            msg = PoseWithCovarianceStamped()
            msg.header.frame_id = p.map_frame
            msg.header.stamp = robot.rospy.Time.from_sec(self.started)
            fill_pose(msg.pose.pose, hint)
            msg.pose.covariance = covariance(p.initial_xy_std, p.initial_yaw_std)
            robot.initialpose_pub.publish(msg)
            robot.counts["initialposes"] += 1
            self._message = "initial pose published"

    def status(self) -> Status:
        if self._status is not Status.RUNNING:
            return self._status
        robot, p = self.robot, self.robot.params
        now = robot.now()
        latest = robot.latest_amcl()
        if latest is not None and latest[0] > self.first_seq:
            sx, sy, syaw = planar_std(latest[1].pose.covariance)
            self._message = f"std x {sx:.2f} m, y {sy:.2f} m, yaw {syaw:.2f} rad"
            if sx <= p.max_xy_std and sy <= p.max_xy_std and syaw <= p.max_yaw_std and robot.pose_now() is not None:
                robot.localized = True
                self.finish(Status.SUCCEEDED, f"localized ({self._message})")
                return self._status
        if now - self.started > p.relocalize_timeout:
            self.finish(Status.FAILED, f"not confident after {p.relocalize_timeout:.0f} s ({self._message})")
        elif p.nomotion_update_service and now >= self._next_update:
            self._next_update = now + p.nomotion_update_period
            robot.call_service(p.nomotion_update_service, required=False)
        return self._status
