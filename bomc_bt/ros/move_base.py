"""move_base goals: the action's topics, spoken with goal ids this executive generates.

:class:`MoveBaseClient` talks the actionlib protocol through its public pieces: it
publishes ``<action>/goal`` and ``<action>/cancel`` and reads ``<action>/status`` and
``<action>/result``, with goal ids from actionlib's ``GoalIDGenerator``. So it knows which
results are its own (what the lockstep wait needs) without reading an action client's
internals, and a result updates a goal's state and the lockstep bookkeeping in one
callback.

:class:`NavGoal` is one goal as a robot-port handle: SUCCEEDED stays SUCCEEDED, ABORTED
and REJECTED become FAILED with move_base's text, PREEMPTED and RECALLED CANCELLED; a
goal the server never accepts, or a robot that has not moved for ``progress_timeout`` s
of ROS time, is cancelled and reported (FAILED, BLOCKED).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any, Protocol

from bomc_bt.geometry import Pose2D
from bomc_bt.robot import RequestHandle, Status
from bomc_bt.ros.convert import fill_pose
from bomc_bt.ros.params import RosParams


class MoveBaseClient:
    """The client side of the ``move_base`` action over its topics."""

    def __init__(self, rospy: Any, params: RosParams, on_result: Callable[[], None] = lambda: None):
        from actionlib import GoalIDGenerator
        from actionlib_msgs.msg import GoalID, GoalStatusArray
        from move_base_msgs.msg import MoveBaseActionGoal, MoveBaseActionResult

        self.rospy = rospy
        self._goal_id_msg = GoalID
        self._ids = GoalIDGenerator()
        self._lock = threading.Lock()
        self._on_result_cb = on_result
        self._latest: dict[str, Any] = {}  # own goal id -> its newest GoalStatus
        self._results: dict[str, Any] = {}  # own goal id -> the GoalStatus of its result
        self._status_seen = False
        ns = rospy.remap_name(params.move_base_action)
        self.result_topic = rospy.resolve_name(ns + "/result")
        self._action_goal = MoveBaseActionGoal
        self.goal_pub = rospy.Publisher(ns + "/goal", MoveBaseActionGoal, queue_size=10)
        self.cancel_pub = rospy.Publisher(ns + "/cancel", GoalID, queue_size=10)
        self.subs = [
            rospy.Subscriber(ns + "/status", GoalStatusArray, self._on_status, queue_size=None),
            rospy.Subscriber(ns + "/result", MoveBaseActionResult, self._on_result, queue_size=None),
        ]

    def send(self, goal: Any) -> str:
        """Publish a MoveBaseGoal under a new goal id; returns the id."""
        from actionlib_msgs.msg import GoalStatus

        goal_id = self._ids.generate_ID()
        msg = self._action_goal(goal_id=goal_id, goal=goal)
        msg.header.stamp = self.rospy.get_rostime()
        with self._lock:
            self._latest[goal_id.id] = GoalStatus(goal_id=goal_id, status=GoalStatus.PENDING)
        self.goal_pub.publish(msg)
        return goal_id.id

    def cancel(self, goal_id: str) -> None:
        self.cancel_pub.publish(self._goal_id_msg(stamp=self.rospy.Time(0), id=goal_id))

    def state(self, goal_id: str) -> int:
        """The goal's newest GoalStatus code (PENDING until the server says otherwise)."""
        with self._lock:
            return self._latest[goal_id].status

    def result(self, goal_id: str) -> Any:
        """The GoalStatus the server's result for this goal carried, or None before it."""
        with self._lock:
            return self._results.get(goal_id)

    def awaits_result(self, goal_id: str) -> bool:
        """True for an own goal whose result has not arrived (the lockstep waits for it)."""
        with self._lock:
            return goal_id in self._latest and goal_id not in self._results

    def ready(self) -> bool:
        """The server has published its status and every topic is connected both ways."""
        with self._lock:
            seen = self._status_seen
        return seen and all(t.get_num_connections() > 0 for t in (self.goal_pub, self.cancel_pub, *self.subs))

    def _on_status(self, msg: Any) -> None:
        with self._lock:
            self._status_seen = True
            for status in msg.status_list:
                if status.goal_id.id in self._latest and status.goal_id.id not in self._results:
                    self._latest[status.goal_id.id] = status

    def _on_result(self, msg: Any) -> None:
        goal_id = msg.status.goal_id.id
        with self._lock:
            if goal_id not in self._latest:
                return  # another client's goal
            self._latest[goal_id] = self._results[goal_id] = msg.status
        self._on_result_cb()

    def close(self) -> None:
        for topic in (*self.subs, self.goal_pub, self.cancel_pub):
            topic.unregister()
        self.subs = []


class GoalSender(Protocol):
    """What a :class:`NavGoal` needs of its robot (:class:`bomc_bt.ros.robot.RosRobot`)."""

    rospy: Any
    params: RosParams
    move_base: MoveBaseClient
    counts: dict[str, int]  # requests sent, announced to the sim bridge

    def now(self) -> float: ...

    def pose(self) -> Pose2D | None: ...


class NavGoal(RequestHandle):
    """One move_base goal in flight (a :class:`bomc_bt.robot.Handle`)."""

    def __init__(self, robot: GoalSender, goal: Pose2D):
        super().__init__("sent to move_base")
        from move_base_msgs.msg import MoveBaseGoal

        self.robot = robot
        self.goal = goal
        msg = MoveBaseGoal()
        msg.target_pose.header.frame_id = robot.params.map_frame
        msg.target_pose.header.stamp = robot.rospy.Time.from_sec(robot.now())
        fill_pose(msg.target_pose.pose, goal)
        self.sent_at = robot.now()
        self.accepted = False
        self._progress_at = self.sent_at
        self._progress_pose = robot.pose()
        self.goal_id = robot.move_base.send(msg)
        robot.counts["goals"] += 1

    def status(self) -> Status:
        if self._status is not Status.RUNNING:
            return self._status
        from actionlib_msgs.msg import GoalStatus as gs

        client = self.robot.move_base
        done = client.result(self.goal_id)
        if done is not None:
            state, text = done.status, done.text or ""
            if state == gs.SUCCEEDED:
                self.finish(Status.SUCCEEDED, "reached")
            elif state in (gs.ABORTED, gs.REJECTED):
                kind = "aborted" if state == gs.ABORTED else "rejected"
                self.finish(Status.FAILED, f"move_base {kind}" + (f": {text}" if text else ""))
            elif state in (gs.PREEMPTED, gs.RECALLED):
                self.finish(Status.CANCELLED, "cancelled" + (f": {text}" if text else ""))
            else:
                self.finish(Status.FAILED, f"move_base lost the goal (status {state})")
            return self._status
        now = self.robot.now()
        if client.state(self.goal_id) == gs.ACTIVE:
            self.accepted = True
        if not self.accepted and now - self.sent_at > self.robot.params.goal_ack_timeout:
            client.cancel(self.goal_id)
            self.finish(
                Status.FAILED,
                f"move_base did not accept the goal within {self.robot.params.goal_ack_timeout:.0f} s",
            )
        elif self.accepted:
            self._check_progress(now)
        return self._status

    def _check_progress(self, now: float) -> None:
        p = self.robot.params
        pose = self.robot.pose()
        if pose is not None and (self._progress_pose is None or self._moved(pose, self._progress_pose)):
            self._progress_pose, self._progress_at = pose, now
        elif now - self._progress_at > p.progress_timeout:
            self.robot.move_base.cancel(self.goal_id)
            self.finish(Status.BLOCKED, f"no progress for {p.progress_timeout:.0f} s")

    def _moved(self, a: Pose2D, b: Pose2D) -> bool:
        p = self.robot.params
        turn = abs(math.remainder(a.yaw - b.yaw, 2 * math.pi))
        return a.distance_to(b) >= p.progress_distance or turn >= p.progress_angle

    def cancel(self) -> None:
        if self._status is Status.RUNNING:
            self.robot.move_base.cancel(self.goal_id)
            self.robot.counts["cancels"] += 1
            self.finish(Status.CANCELLED, "cancelled")
