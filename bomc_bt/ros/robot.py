"""The ROS 1 robot behind the robot port: move_base, GMapping / map_server, AMCL, RGB-D, tf2.

Subscriber callbacks only store the latest messages (under a lock); every port call reads
them, so no call blocks a tick. Long work is a handle polled by the tree:

* :class:`NavGoal` wraps one move_base goal (actionlib): SUCCEEDED stays SUCCEEDED,
  ABORTED and REJECTED become FAILED with move_base's text, PREEMPTED and RECALLED
  CANCELLED; a goal the server never accepts, or a robot that has not moved for
  ``progress_timeout`` s of ROS time, is cancelled and reported (FAILED, BLOCKED).
* :class:`AmclRelocalization` publishes ``/initialpose`` (or calls
  ``/global_localization``) and waits for an ``/amcl_pose`` whose covariance is within the
  configured bounds, asking AMCL for no-motion updates meanwhile (a standing robot
  otherwise never converges).

Time is ROS time; with ``use_sim_time`` (the sim-over-ROS bridge) the executive publishes
the time it waits for on ``tick_topic`` so the bridge can step its simulator in lockstep.
The bridge answers on ``stepped_topic`` with what it published up to that time; a tick
then also waits for those messages, so it sees the same map, tf and move_base results as
the direct simulator run at that time (topics are not ordered with respect to ``/clock``
or to each other). A real robot announces no steps, and nothing waits there. Wall time is
used only to bound waits: ROS time that has stopped (a dead ``/clock``) must be an error,
an announced message that never comes a warning, and neither a hang.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections import deque
from typing import Any

import numpy as np

from bomc_bt.errors import BomcError, MissionFailed
from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import LaserScan, RGBDFrame, Status
from bomc_bt.ros import import_ros
from bomc_bt.ros.convert import (
    covariance,
    decode_depth,
    decode_rgb,
    fill_pose,
    grid_from_msg,
    intrinsics,
    planar_std,
    pose2d_from_matrix,
    scan_from_msg,
    transform_matrix,
)
from bomc_bt.ros.params import RosParams

NODE_NAME = "bomc_executive"
MASTER_TIMEOUT = 3.0  # wall s to wait for the ROS master to answer before init_node
SYNC_WAIT = 2.0  # wall s a lockstep tick waits for announced messages before going on without


def ensure_node(name: str = NODE_NAME) -> Any:
    """Initialise this process's ROS node once (rospy allows one per process).

    ``rospy.init_node`` retries an unreachable master for ever, so the master is asked
    first with a socket timeout: no roscore is a one-line error within seconds.
    """
    rospy = import_ros()
    if not rospy.core.is_initialized():
        check_master()
        try:
            rospy.init_node(name, anonymous=False, disable_signals=True)
        except Exception as exc:  # master unreachable: rospy raises several kinds
            raise _no_master(exc) from None
    return rospy


def check_master(timeout: float = MASTER_TIMEOUT) -> None:
    """Ask the master for its pid, bounded by ``timeout``; a BomcError if it does not answer."""
    import xmlrpc.client

    import rosgraph

    class Transport(xmlrpc.client.Transport):  # xmlrpc's default connection never times out
        def make_connection(self, host: Any) -> Any:
            conn = super().make_connection(host)
            conn.timeout = timeout
            return conn

    try:
        proxy = xmlrpc.client.ServerProxy(rosgraph.get_master_uri(), transport=Transport())
        proxy.getPid(f"/{NODE_NAME}_probe")
    except Exception as exc:  # refused, timed out, unresolvable host, a bad URI
        raise _no_master(exc) from None


def _no_master(exc: Exception) -> BomcError:
    import rosgraph

    return BomcError(
        f"cannot reach the ROS master at {rosgraph.get_master_uri()} ({exc}); "
        "is roscore running and ROS_MASTER_URI set?",
        None,
        "ROS_MASTER_URI",
    )


class _Handle:
    """Shared status bookkeeping of the ROS handles."""

    def __init__(self, message: str):
        self._status = Status.RUNNING
        self._message = message

    @property
    def message(self) -> str:
        return self._message

    def finish(self, status: Status, message: str) -> None:
        if self._status is Status.RUNNING:
            self._status = status
            self._message = message


class Refused(_Handle):
    """A request refused before reaching ROS (e.g. a goal while not localized)."""

    def __init__(self, message: str):
        super().__init__(message)
        self.finish(Status.FAILED, message)

    def status(self) -> Status:
        return self._status

    def cancel(self) -> None:
        """Nothing is in flight."""


class NavGoal(_Handle):
    """One move_base goal in flight (a :class:`bomc_bt.robot.Handle`)."""

    def __init__(self, robot: RosRobot, goal: Pose2D):
        super().__init__("sent to move_base")
        from actionlib_msgs.msg import GoalStatus
        from move_base_msgs.msg import MoveBaseGoal

        self.robot = robot
        self.goal = goal
        self._gs = GoalStatus
        msg = MoveBaseGoal()
        msg.target_pose.header.frame_id = robot.params.map_frame
        msg.target_pose.header.stamp = robot.rospy.Time.from_sec(robot.now())
        fill_pose(msg.target_pose.pose, goal)
        self.sent_at = robot.now()
        self.accepted = False
        self._progress_at = self.sent_at
        self._progress_pose = robot.pose()
        self.gh = robot.action_client.send_goal(msg)
        robot.goal_ids.add(self.gh.comm_state_machine.action_goal.goal_id.id)
        robot.counts["goals"] += 1

    def status(self) -> Status:
        if self._status is not Status.RUNNING:
            return self._status
        from actionlib.action_client import CommState

        gs = self._gs
        state = self.gh.get_goal_status()
        if self.gh.get_comm_state() == CommState.DONE:
            state = self.gh.get_terminal_state()
            text = self.gh.get_goal_status_text() or ""
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
        if state == gs.ACTIVE:
            self.accepted = True
        if not self.accepted and now - self.sent_at > self.robot.params.goal_ack_timeout:
            self.gh.cancel()
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
            self.gh.cancel()
            self.finish(Status.BLOCKED, f"no progress for {p.progress_timeout:.0f} s")

    def _moved(self, a: Pose2D, b: Pose2D) -> bool:
        p = self.robot.params
        turn = abs(math.remainder(a.yaw - b.yaw, 2 * math.pi))
        return a.distance_to(b) >= p.progress_distance or turn >= p.progress_angle

    def cancel(self) -> None:
        if self._status is Status.RUNNING:
            self.gh.cancel()
            self.robot.counts["cancels"] += 1
            self.finish(Status.CANCELLED, "cancelled")


class AmclRelocalization(_Handle):
    """Relocalize through AMCL and wait for a confident /amcl_pose."""

    def __init__(self, robot: RosRobot, hint: Pose2D | None, global_search: bool):
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
            if (
                sx <= p.max_xy_std
                and sy <= p.max_xy_std
                and syaw <= p.max_yaw_std
                and robot.pose_now() is not None
            ):
                robot.localized = True
                self.finish(Status.SUCCEEDED, f"localized ({self._message})")
                return self._status
        if now - self.started > p.relocalize_timeout:
            self.finish(Status.FAILED, f"not confident after {p.relocalize_timeout:.0f} s ({self._message})")
        elif p.nomotion_update_service and now >= self._next_update:
            self._next_update = now + p.nomotion_update_period
            robot.call_service(p.nomotion_update_service, required=False)
        return self._status

    def cancel(self) -> None:
        self.finish(Status.CANCELLED, "cancelled")


class RosRobot:
    """The robot port over ROS 1 (implements :class:`bomc_bt.robot.RobotPort`)."""

    def __init__(self, params: RosParams | None = None, mode: str = "build"):
        if mode not in ("build", "monitor"):
            raise ValueError(f"mode must be 'build' or 'monitor', got {mode!r}")
        self.rospy = rospy = ensure_node()
        import actionlib
        import tf2_ros
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from move_base_msgs.msg import MoveBaseAction, MoveBaseActionResult
        from nav_msgs.msg import OccupancyGrid as GridMsg
        from rospy.numpy_msg import numpy_msg
        from sensor_msgs.msg import CameraInfo, Image
        from sensor_msgs.msg import LaserScan as ScanMsg
        from std_msgs.msg import String

        self.params = p = params or RosParams()
        self.mode = mode
        self.localized = mode == "build"
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)  # notified when a tracked message comes in
        self._map_msg: Any = None
        self._map_cache: tuple[int, OccupancyGrid] | None = None
        self._map_version = 0
        self._grid: OccupancyGrid | None = None
        self._scan_msg: Any = None
        self._info: Any = None
        self._amcl: tuple[int, Any] | None = None
        self.amcl_count = 0
        self._rgb: deque = deque(maxlen=30)
        self._depth: deque = deque(maxlen=30)
        self._instances: dict[float, Any] = {}
        self._pending: dict[str, Any] | None = None
        self._last_stamp = -math.inf
        self._image_seen_at: dict[str, float] = {}
        self.counts = {"goals": 0, "cancels": 0, "initialposes": 0, "services": 0}
        self._nav: NavGoal | None = None
        self._reloc: AmclRelocalization | None = None
        self._clock_seen = threading.Event()
        # Lockstep bookkeeping (see _sync): the bridge's newest "stepped" announcement, the
        # newest stamp (ns) received per topic, the move_base results received for our goals.
        self._stepped: dict[str, Any] | None = None
        self._received: dict[str, int] = {}
        self._tracked: set[str] = set()  # the resolved topics _track subscribed to
        self.goal_ids: set[str] = set()
        self._results: set[str] = set()
        self._unsynced: set[str] = set()  # announced things that once never came: not waited for
        self.use_sim_time = bool(rospy.get_param("/use_sim_time", False))
        self.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        self._tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        track = self._track
        self._subs = [
            track(p.map_topic, numpy_msg(GridMsg), self._on_map, queue_size=1),
            track(p.scan_topic, ScanMsg, self._keep("_scan_msg"), queue_size=1),
            track(p.amcl_pose_topic, PoseWithCovarianceStamped, self._on_amcl, queue_size=5),
            track(p.rgb_topic, Image, self._on_image("rgb"), queue_size=5, buff_size=2**24),
            track(p.depth_topic, Image, self._on_image("depth"), queue_size=5, buff_size=2**24),
            track(p.camera_info_topic, CameraInfo, self._keep("_info"), queue_size=1),
        ]
        if p.instances_topic:
            self._subs += [
                track(p.instances_topic, Image, self._on_image("instances"), queue_size=5, buff_size=2**24),
                track(p.instances_topic + "/info", String, self._on_instance_info, queue_size=5),
            ]
        if self.use_sim_time:
            from rosgraph_msgs.msg import Clock

            self._subs += [
                rospy.Subscriber("/clock", Clock, lambda _m: self._clock_seen.set(), queue_size=1),
                rospy.Subscriber(p.stepped, String, self._on_stepped, queue_size=10),
            ]
        self.initialpose_pub = rospy.Publisher(
            p.initialpose_topic, PoseWithCovarianceStamped, queue_size=1, latch=True
        )
        self._tick_pub = rospy.Publisher(p.tick_topic, String, queue_size=10)
        self.action_client = actionlib.ActionClient(p.move_base_action, MoveBaseAction)
        # After the client's own result subscriber: rospy calls a topic's callbacks in order,
        # so a result counted here has already moved its goal handle to DONE.
        result_topic = rospy.remap_name(p.move_base_action) + "/result"
        self._subs.append(rospy.Subscriber(result_topic, MoveBaseActionResult, self._on_result, queue_size=10))
        self._wait_for_start()
        self._last_tick = self.now()
        self.distance_travelled = 0.0  # m along odom -> base_link (the session report's path length)
        self._odom_xy: tuple[float, float] | None = None

    # -- start-up --------------------------------------------------------------------------
    def _wait_for_start(self) -> None:
        """Wait (wall-bounded) for /clock and the move_base server: absent ones are errors."""
        p = self.params
        if self.use_sim_time and not self._clock_seen.wait(p.clock_timeout):
            self.close()
            raise MissionFailed(
                f"use_sim_time is set but nothing publishes /clock (waited {p.clock_timeout:.0f} s)"
            )
        deadline = time.monotonic() + p.server_timeout
        while not self._server_ready():
            if time.monotonic() > deadline:
                self.close()
                raise MissionFailed(
                    f"no move_base action server at {p.move_base_action!r} within "
                    f"{p.server_timeout:.0f} s (ros.move_base_action)"
                )
            time.sleep(0.02)
        self._wait_for_bridge()

    def _wait_for_bridge(self) -> None:
        """A bridge announcing its steps: be connected to it before the first tick.

        A message published before a subscription connects is lost to it, and the first
        tick would wait for it in vain, so every topic the bridge publishes and this robot
        reads must be connected, and its first announcement in, before ticking. Without
        such a bridge (a real robot, Gazebo) this returns at once.
        """
        p = self.params
        if not self.use_sim_time or not self._advertised(p.stepped):
            return
        deadline = time.monotonic() + p.server_timeout
        while not self._bridge_connected():
            if time.monotonic() > deadline:
                self.rospy.logwarn("bomc: not connected to every topic of the sim bridge; ticks may not be exact")
                break
            time.sleep(0.01)
        # What the bridge published before the connections were up is lost to them: ask for
        # it again, so that the first tick, too, sees the state at its time.
        self._publish_tick(self.now(), resend=True)
        self._sync(self.now())

    def _advertised(self, topic: str) -> bool:
        rospy = self.rospy
        name = rospy.resolve_name(topic)
        return any(t == name for t, _type in rospy.get_published_topics())

    def _bridge_connected(self) -> bool:
        with self._lock:
            stepped = self._stepped is not None
        published = {t for t, _type in self.rospy.get_published_topics()}
        subs = [s for s in self._subs if s.resolved_name in published] + [self._tf_listener.tf_sub]
        return stepped and self._tick_pub.get_num_connections() > 0 and all(
            s.get_num_connections() > 0 for s in subs
        )

    def _server_ready(self) -> bool:
        """actionlib's wait_for_server test, without its wait on ROS time.

        ROS time may not advance before the first tick (lockstep simulation), so the
        waiting is done here on the wall clock, bounded by ``server_timeout``.
        """
        ac = self.action_client
        status = ac.last_status_msg
        if not status:
            return False
        server = status._connection_header["callerid"]
        return (
            ac.pub_goal.impl.has_connection(server)
            and ac.pub_cancel.impl.has_connection(server)
            and any(c.callerid_pub == server for c in ac.result_sub.impl.connections)
            and any(c.callerid_pub == server for c in ac.feedback_sub.impl.connections)
        )

    def close(self) -> None:
        """Unsubscribe and stop publishing (the node itself lives on for the process)."""
        for sub in self._subs:
            sub.unregister()
        self._subs = []
        listener = getattr(self, "_tf_listener", None)
        if listener is not None:  # else it fills this robot's buffer for the process's life
            listener.unregister()
        for pub in (getattr(self, "initialpose_pub", None), getattr(self, "_tick_pub", None)):
            if pub is not None:
                pub.unregister()
        client = getattr(self, "action_client", None)
        if client is not None:
            client.stop()

    # -- callbacks -------------------------------------------------------------------------
    def _track(self, topic: str, msg_type: Any, callback: Any, **kwargs: Any) -> Any:
        """A subscriber that also notes the newest stamp received, for the lockstep wait."""
        name = self.rospy.resolve_name(topic)
        self._tracked.add(name)

        def tracked(msg: Any) -> None:
            callback(msg)
            stamp = _stamp_ns(msg)
            with self._arrived:
                self._received[name] = max(self._received.get(name, -1), stamp)
                self._arrived.notify_all()

        return self.rospy.Subscriber(topic, msg_type, tracked, **kwargs)

    def _on_stepped(self, msg: Any) -> None:
        data = json.loads(msg.data)
        with self._arrived:
            self._stepped = data  # one publisher, in order: the last one is the newest
            self._arrived.notify_all()

    def _on_result(self, msg: Any) -> None:
        goal_id = msg.status.goal_id.id
        with self._arrived:
            if goal_id in self.goal_ids:
                self._results.add(goal_id)
                self._arrived.notify_all()

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
                if kind == "instances":
                    self._instances.setdefault(_stamp(msg), {})["image"] = msg
                    self._trim_instances()
                    return
                (self._rgb if kind == "rgb" else self._depth).append(msg)
                self._image_seen_at.setdefault(kind, self.now())

        return callback

    def _on_instance_info(self, msg: Any) -> None:
        data = json.loads(msg.data)
        with self._lock:
            self._instances.setdefault(round(float(data["stamp"]), 6), {})["info"] = data
            self._trim_instances()

    def _trim_instances(self) -> None:
        while len(self._instances) > 30:
            del self._instances[min(self._instances)]

    def latest_amcl(self) -> tuple[int, Any] | None:
        with self._lock:
            return self._amcl

    # -- port: time ------------------------------------------------------------------------
    def now(self) -> float:
        """ROS time (s); in lockstep, the bridge's own float for the time on its /clock.

        rospy.Time.from_sec truncates to whole ns, so the simulator's 8.1 s reads as
        8.099999999 s, and "once a second" decisions (the trajectory rows) fall a tick
        later than in the direct simulator run.
        """
        t = self.rospy.Time.now()
        ann = self._stepped
        if ann is not None and ann.get("until_ns") == t.to_nsec():
            return ann["until"]
        return t.to_sec()

    def step(self) -> None:
        """Sleep to the next tick on ROS time (a rospy.Rate that also notices a dead clock)."""
        period = 1.0 / self.params.tick_rate
        target = self._last_tick + period
        if self.now() > target + period:  # fell behind (a slow tick): do not try to catch up
            target = self.now()
        self._publish_tick(target)
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
                self._publish_tick(target)
        self._sync(target)
        self._last_tick = target
        self._track_odometry()

    def _sync(self, target: float) -> None:
        """Lockstep: wait until everything the bridge published up to ``target`` is here.

        Bounded by ``SYNC_WAIT`` wall seconds; what did not come in time is not waited for
        again (a topic this robot is not connected to), with a warning, so a mismatch costs
        one wait, not one per tick.
        """
        if self._stepped is None or self.params.stepped in self._unsynced:
            return  # no bridge announces steps (a real robot, a free-running bridge)
        deadline = time.monotonic() + SYNC_WAIT
        while missing := self._missing(target):
            if self.rospy.is_shutdown():
                raise MissionFailed("ROS shut down")
            if time.monotonic() > deadline:
                self._unsynced |= missing
                self.rospy.logwarn(
                    f"bomc: {', '.join(sorted(missing))} not received within {SYNC_WAIT:.0f} s of the bridge's "
                    f"step to {target:.2f} s; no longer waited for"
                )
                return
            with self._arrived:  # woken by a tracked message; tf (tf2's own callback) is polled
                self._arrived.wait(0.001)

    def _missing(self, target: float) -> set[str]:
        """What the newest announcement lists that this robot has not received yet."""
        with self._lock:
            ann, received, results = self._stepped, dict(self._received), set(self._results)
        if ann is None or ann["until"] < target - 1e-6:
            return {self.params.stepped}
        skip = self._unsynced
        missing = {
            topic
            for topic, ns in ann["stamps"].items()
            if topic in self._tracked and topic not in skip and received.get(topic, -1) < ns
        }
        for topic, goal_id in ann["result"].items():
            if topic not in skip and goal_id in self.goal_ids and goal_id not in results:
                missing.add(topic)
        if ann["tf"] and "/tf" not in skip:
            when = self.rospy.Time(0, ann["tf"][0])
            if not all(self.tf_buffer.can_transform(parent, child, when) for parent, child in ann["tf"][1]):
                missing.add("/tf")
        return missing

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

    def _publish_tick(self, target: float, resend: bool = False) -> None:
        from std_msgs.msg import String

        data = {"until": target, **self.counts, **({"resend": True} if resend else {})}
        self._tick_pub.publish(String(data=json.dumps(data)))

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
        return self.pose_now() if self.localized else None

    def live_map(self) -> OccupancyGrid:
        with self._lock:
            msg, version = self._map_msg, self._map_version
        if msg is None:
            if self._grid is not None:
                return self._grid
            return OccupancyGrid(data=np.full((1, 1), -1, np.int8), resolution=0.05, origin=(0.0, 0.0))
        if self._map_cache is None or self._map_cache[0] != version:
            self._map_cache = (version, _decimal_resolution(grid_from_msg(msg)))
        return self._map_cache[1]

    def use_map(self, grid: OccupancyGrid) -> None:
        """Keep the saved map: on the robot map_server serves it to AMCL and move_base.

        ``live_map`` returns /map once it arrives, else this grid (planning-free uses:
        waypoints, reports).
        """
        self._grid = grid

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
                self._pending = self._newest_pair(now)
            pending, info = self._pending, self._info
            self._check_unpaired(now)
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
        extra = self._instance_data(pending["stamp"]) if p.instances_topic else {}
        if T_map_base is None or T_base_camera is None or extra is None:
            if waited > p.frame_timeout:
                self._pending = None
                if extra is None:
                    raise MissionFailed(
                        f"no instance image on {p.instances_topic} for the image at {pending['stamp']:.2f} s"
                    )
                missing = (
                    f"{p.map_frame} <- {p.base_frame}"
                    if T_map_base is None
                    else f"{p.base_frame} <- {camera}"
                )
                raise MissionFailed(
                    f"no tf {missing} at the image stamp {pending['stamp']:.2f} s within "
                    f"{p.frame_timeout:.0f} s (ros.map_frame / ros.base_frame / ros.camera_frame)"
                )
            return None
        self._pending = None
        return RGBDFrame(
            stamp=pending["stamp"],
            rgb=decode_rgb(pending["rgb"]),
            depth=decode_depth(pending["depth"]),
            K=intrinsics(info),
            T_map_base=T_map_base,
            T_base_camera=T_base_camera,
            depth_range=(p.depth_min, p.depth_max),
            **extra,
        )

    def _newest_pair(self, now: float) -> dict[str, Any] | None:
        """The newest RGB/depth pair within ``sync_slop`` newer than the last frame returned."""
        slop = self.params.sync_slop
        for depth in reversed(self._depth):
            ds = _stamp(depth)
            if ds <= self._last_stamp:
                break
            best = min(self._rgb, key=lambda m: abs(_stamp(m) - ds), default=None)
            if best is not None and abs(_stamp(best) - ds) <= slop:
                self._last_stamp = ds
                return {"stamp": ds, "rgb": best, "depth": depth, "received": now}
        return None

    def _check_unpaired(self, now: float) -> None:
        """Images on one topic but never a partner on the other: a misnamed topic."""
        p = self.params
        seen = self._image_seen_at
        for kind, other, topic in (("rgb", "depth", p.depth_topic), ("depth", "rgb", p.rgb_topic)):
            if kind in seen and other not in seen and now - seen[kind] > p.frame_timeout:
                raise MissionFailed(
                    f"{kind} images arrive but none on {topic} within {p.frame_timeout:.0f} s "
                    f"(ros.{other}_topic)"
                )

    def _instance_data(self, stamp: float) -> dict[str, Any] | None:
        with self._lock:
            entry = self._instances.get(round(stamp, 6))
        if entry is None or "image" not in entry or "info" not in entry:
            return None
        img = entry["image"]
        instances = np.frombuffer(img.data, dtype="<i4").reshape(img.height, img.width).astype(np.int32)
        info = entry["info"]
        return {
            "instances": instances,
            "instance_categories": {int(k): str(v) for k, v in info["categories"].items()},
            "instance_unoccluded": {int(k): int(v) for k, v in info.get("unoccluded", {}).items()},
        }

    # -- port: navigation and localization ---------------------------------------------------
    def navigate(self, goal: Pose2D) -> NavGoal | Refused:
        if not self.localized:
            return Refused("not localized")
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


def _decimal_resolution(grid: OccupancyGrid) -> OccupancyGrid:
    """The grid with the decimal resolution its float32 message field stands for.

    nav_msgs/OccupancyGrid carries the resolution as float32: 0.05 arrives as
    0.0500000007, which moves cell boundaries (world_to_cell floors) off the saved map's
    and the simulator's. The shortest decimal that round-trips the float32 is what the
    sender (map_server reads a YAML decimal) meant.
    """
    resolution = float(str(np.float32(grid.resolution)))
    return OccupancyGrid(grid.data, resolution, tuple(grid.origin))


def _stamp(msg: Any) -> float:
    return round(msg.header.stamp.to_sec(), 6)


def _stamp_ns(msg: Any) -> int:
    """A message's stamp in ns: its header's, or the ``stamp`` of the JSON instance info."""
    import rospy

    if hasattr(msg, "header"):
        return msg.header.stamp.to_nsec()
    return rospy.Time.from_sec(float(json.loads(msg.data)["stamp"])).to_nsec()
