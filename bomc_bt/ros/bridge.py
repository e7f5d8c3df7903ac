"""``bomc sim-ros``: the built-in simulator served through a ROS 1 robot's interfaces.

What a Fetch with GMapping / map_server + AMCL + move_base offers, the bridge offers from a
:class:`~bomc_bt.sim.robot.SimRobot`: the ``move_base`` action, ``/map`` (the sim mapper
while building, the saved map while monitoring, latched like map_server), the scan, tf
``map -> odom -> base_link -> camera``, RGB(-D) images with camera_info, ``/initialpose``,
``/global_localization``, ``/request_nomotion_update`` and ``/amcl_pose``. So the ROS
path can be tried, and tested, without a robot.

Time: the bridge owns ``/clock`` (it sets ``/use_sim_time``). In lockstep (the default)
it steps the simulator only up to the time the executive announces on the tick topic,
after the goals, cancels and initial poses that announcement counts have arrived, so a
run through ROS interleaves ticks and steps as the direct simulator run does, and runs
as fast as both sides can. After each step it announces on ``ros.stepped_topic`` what it
has published by then (the newest stamp per topic, the newest tf, the last move_base
result): topics are not ordered with respect to each other or to ``/clock``, so without
it a tick at time t may or may not see the map or tf of time t, and two runs differ.
``--realtime-factor F`` free-runs at F times real time instead (for RViz and
teleoperation) and announces nothing.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.geometry import invert_se3
from bomc_bt.robot import RGBDFrame, Status
from bomc_bt.ros import import_ros
from bomc_bt.ros.convert import (
    covariance,
    encode_depth,
    fill_grid,
    fill_pose,
    fill_transform,
    pose2d_from_msg,
)
from bomc_bt.ros.params import RosParams
from bomc_bt.ros.robot import check_master

LOCALIZED_STD = (0.05, 0.03)  # m, rad: the covariance /amcl_pose reports once localized
LOST_STD = (2.0, 1.5)  # ... and while not localized (after a failed or global request)
COUNT_WAIT = 2.0  # wall s to wait for announced goals to arrive before stepping anyway
IDLE_ANNOUNCE = 0.1  # wall s between re-announcements (clock, stepped) while waiting for a tick
SIM_INSTANCES_TOPIC = "/bomc_sim/instances"  # the per-pixel instance image the sim detector reads


class SimBridge:
    """Serves one :class:`SimRobot` over ROS; :meth:`run` loops until shut down."""

    def __init__(
        self,
        sim: Any,
        params: RosParams,
        *,
        lockstep: bool = True,
        realtime_factor: float = 1.0,
        abort_goals: int = 0,
        scan_rate: float = 2.0,
        publish_camera_info: bool = True,
        publish_tf_camera: bool = True,
        map_grid: Any = None,
    ):
        import actionlib
        import tf2_ros
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from move_base_msgs.msg import MoveBaseAction
        from nav_msgs.msg import OccupancyGrid as GridMsg
        from rosgraph_msgs.msg import Clock
        from rospy.numpy_msg import numpy_msg
        from sensor_msgs.msg import CameraInfo, Image, LaserScan
        from std_msgs.msg import String
        from std_srvs.srv import Empty, EmptyResponse

        self.rospy = rospy = import_ros()
        self.sim = sim
        self.p = params
        self.lockstep = lockstep
        self.realtime_factor = realtime_factor
        self.abort_goals = abort_goals
        self.scan_period = 1.0 / scan_rate if scan_rate > 0 else math.inf
        self.publish_camera_info = publish_camera_info
        self.publish_tf_camera = publish_tf_camera
        self.wake = threading.Condition()
        self.inbox: list[tuple[str, Any]] = []
        self.until = sim.now()
        self.wanted = {"goals": 0, "cancels": 0, "initialposes": 0}
        self.got = {"goals": 0, "cancels": 0, "initialposes": 0}
        self.goal: tuple[Any, Any] | None = None  # (server goal handle, sim NavHandle)
        self.reloc: Any = None
        self.amcl_std: tuple[float, float] | None = None
        self.T_base_camera: np.ndarray | None = None
        self._next_scan = 0.0
        self._next_map = 0.0
        self._map_version: Any = None
        self._grid_msg_cls = numpy_msg(GridMsg)
        self._srv_empty = EmptyResponse
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
        if lockstep:  # advertised only in lockstep: an executive that sees it waits for it
            self.pub["stepped"] = rospy.Publisher(params.stepped, String, queue_size=10)
        if params.instances_topic:
            self.pub["instances"] = rospy.Publisher(params.instances_topic, Image, queue_size=2)
            self.pub["instances_info"] = rospy.Publisher(
                params.instances_topic + "/info", String, queue_size=2
            )
        self.tf = tf2_ros.TransformBroadcaster()
        self.server = _recording_server(actionlib.ActionServer)(
            params.move_base_action, MoveBaseAction, self._on_goal, self._on_cancel, auto_start=False
        )
        self.services = [
            rospy.Service(params.global_localization_service, Empty, self._on_global),
            rospy.Service(
                params.nomotion_update_service or "/request_nomotion_update",
                Empty,
                lambda _r: EmptyResponse(),
            ),
        ]
        self.subs = [
            rospy.Subscriber(
                params.initialpose_topic, PoseWithCovarianceStamped, self._on_initialpose, queue_size=5
            ),
            rospy.Subscriber(params.tick_topic, String, self._on_tick, queue_size=10),
        ]
        self.server.start()
        if map_grid is not None:
            self._publish_map(map_grid)
        self.publish_all()
        self.announce()

    # -- callbacks (rospy threads): they only queue; the stepping thread owns the simulator --
    # (acting in a callback would take actionlib's lock and then ours while the stepping
    # thread, holding ours, answers a goal through actionlib: a deadlock).
    def _queue(self, kind: str, item: Any, count: str | None = None) -> None:
        with self.wake:
            self.inbox.append((kind, item))
            if count is not None:
                self.got[count] += 1
            self.wake.notify_all()

    def _on_tick(self, msg: Any) -> None:
        data = json.loads(msg.data)
        if data.get("resend"):  # an executive that just connected missed what came before
            self._queue("resend", None)
        with self.wake:
            self.until = max(self.until, float(data["until"]))
            for key in self.wanted:
                self.wanted[key] = max(self.wanted[key], int(data.get(key, 0)))
            self.wake.notify_all()

    def _on_goal(self, gh: Any) -> None:
        self._queue("goal", gh, "goals")

    def _on_cancel(self, gh: Any) -> None:
        self._queue("cancel", gh, "cancels")

    def _on_initialpose(self, msg: Any) -> None:
        self._queue("initialpose", msg, "initialposes")

    def _on_global(self, _req: Any) -> Any:
        self._queue("global", None)
        return self._srv_empty()

    def _drain(self) -> None:
        """Apply what the callbacks queued, in arrival order."""
        with self.wake:
            items, self.inbox = self.inbox, []
        for kind, item in items:
            getattr(self, f"_apply_{kind}")(item)

    def _apply_goal(self, gh: Any) -> None:
        if self.goal is not None:
            old, handle = self.goal
            handle.cancel()
            old.set_canceled(text="pre-empted by a new goal")
            self.goal = None
        gh.set_accepted()
        if self.abort_goals > 0:
            self.abort_goals -= 1
            gh.set_aborted(text="injected failure: goal aborted by the bridge")
            return
        goal = pose2d_from_msg(gh.get_goal().target_pose.pose)
        self.goal = (gh, self.sim.navigate(goal))
        self._settle_goal()

    def _apply_cancel(self, gh: Any) -> None:
        if self.goal is not None and self.goal[0].get_goal_id().id == gh.get_goal_id().id:
            self.goal[1].cancel()
            self.sim.navigator.cancel()
            self.goal = None
        gh.set_canceled(text="cancelled by the client")

    def _apply_initialpose(self, msg: Any) -> None:
        self.reloc = self.sim.relocalize(pose2d_from_msg(msg.pose.pose), global_search=False)
        # AMCL re-initialises its filter at the given covariance and reports it.
        c = np.asarray(msg.pose.covariance).reshape(6, 6)
        self.amcl_std = (math.sqrt(max(c[0, 0], 0.0)), math.sqrt(max(c[5, 5], 0.0)))
        self._publish_amcl()

    def _apply_resend(self, _item: Any) -> None:
        """Publish the newest message of every topic and tf again (then :meth:`announce`)."""
        if self.last_tf:
            self.tf.sendTransform(self.last_tf)
        for key, msg in self.last.items():
            self.pub[key].publish(msg)

    def _apply_global(self, _item: Any) -> None:
        self.reloc = self.sim.relocalize(None, global_search=True)
        self.amcl_std = LOST_STD
        self._publish_amcl()

    # -- stepping ---------------------------------------------------------------------------
    def run(self) -> None:
        from rosgraph_msgs.msg import Clock

        rospy = self.rospy
        dt = self.sim.params.dt
        while not rospy.is_shutdown():
            start = time.monotonic()
            if self.lockstep:
                with self.wake:
                    while not rospy.is_shutdown() and self.until <= self.sim.now() + 1e-6 and not self.inbox:
                        if not self.wake.wait(IDLE_ANNOUNCE):  # idle: re-announce for late joiners
                            self.pub["clock"].publish(Clock(clock=self.stamp()))
                            self.announce()
                    deadline = time.monotonic() + COUNT_WAIT
                    while any(self.got[k] < self.wanted[k] for k in self.got) and time.monotonic() < deadline:
                        self.wake.wait(0.005)
                    self._resync_counts()
                    until = self.until
                self._drain()
                while self.sim.now() < until - 1e-6:
                    self.step()
                self.announce()
            else:
                self._drain()
                self.step()
                time.sleep(max(0.0, dt / self.realtime_factor - (time.monotonic() - start)))

    def _resync_counts(self) -> None:
        """Give up on announced messages that did not arrive within COUNT_WAIT.

        A goal or cancel lost on the way (or dropped by a slow subscriber) would otherwise
        make every later step wait COUNT_WAIT wall seconds: the run would crawl at a few
        simulated steps a minute. Counting it as arrived costs what was lost, no more.
        """
        behind = {k: self.wanted[k] - self.got[k] for k in self.got if self.got[k] < self.wanted[k]}
        if behind:
            self.rospy.logwarn(f"bridge: stepping without {behind} announced but not received "
                               f"within {COUNT_WAIT} s")
            for k in behind:
                self.got[k] = self.wanted[k]

    def step(self) -> None:
        """One simulator step, then everything it changed, then the clock."""
        self.sim.step()
        self._settle_goal()
        self._settle_reloc()
        self.publish_all()

    def _settle_goal(self) -> None:
        if self.goal is None:
            return
        gh, handle = self.goal
        status = handle.status()
        if status is Status.RUNNING:
            return
        self.goal = None
        if status is Status.SUCCEEDED:
            gh.set_succeeded(text=handle.message)
        elif status is Status.CANCELLED:
            gh.set_canceled(text=handle.message)
        else:
            gh.set_aborted(text=f"{status.value}: {handle.message}")

    def _settle_reloc(self) -> None:
        if self.reloc is None or self.reloc.status() is Status.RUNNING:
            return
        self.amcl_std = LOCALIZED_STD if self.reloc.status() is Status.SUCCEEDED else LOST_STD
        self.reloc = None

    # -- publishing ---------------------------------------------------------------------------
    def stamp(self, t: float | None = None) -> Any:
        return self.rospy.Time.from_sec(self.sim.now() if t is None else t)

    def _send(self, key: str, msg: Any, stamp: Any = None) -> None:
        """Publish on ``self.pub[key]`` and remember the stamp, for :meth:`announce`."""
        pub = self.pub[key]
        pub.publish(msg)
        self.last[key] = msg
        self.sent[pub.resolved_name] = (stamp if stamp is not None else msg.header.stamp).to_nsec()

    def announce(self) -> None:
        """Lockstep only: tell the executive what it must have received to be at this time.

        The executive waits for every topic it listens to to reach the stamp given here,
        for tf at the newest stamp and for the last move_base result, so each tick sees
        exactly what was published up to its time, as the direct simulator run does.
        """
        from std_msgs.msg import String

        if not self.lockstep:
            return
        data = {
            "until": self.sim.now(),  # the exact float: /clock's ns may be 1 ns short of it
            "until_ns": self.stamp().to_nsec(),
            "stamps": self.sent,
            "tf": self._tf_announcement(),
            "result": {self.server.result_pub.resolved_name: self.server.last_result},
        }
        self.pub["stepped"].publish(String(data=json.dumps(data)))

    def _tf_announcement(self) -> list | None:
        """[stamp (ns), [[parent, child], ...]] of the newest transforms sent, or None."""
        if not self.last_tf:
            return None
        pairs = [[m.header.frame_id, m.child_frame_id] for m in self.last_tf]
        return [self.last_tf[0].header.stamp.to_nsec(), pairs]

    def publish_all(self) -> None:
        from rosgraph_msgs.msg import Clock

        now = self.sim.now()
        frame = self.sim.frame()
        if frame is not None:
            self.T_base_camera = frame.T_base_camera
        self._publish_tf(now)  # tf first: the images' stamp must be transformable on arrival
        if self.sim.mapper is not None and self.sim._map is None and now >= self._next_map:
            version = self.sim.mapper.updates
            if version != self._map_version:
                self._map_version = version
                self._next_map = now + self.p.map_period
                self._publish_map(self.sim.live_map())
        if now >= self._next_scan:
            self._next_scan = now + self.scan_period
            self._publish_scan()
        if self.sim.pose() is not None and self.amcl_std is not None and self.sim.mode == "monitor":
            self._publish_amcl()
        if frame is not None:
            self._publish_frame(frame)
        self.pub["clock"].publish(Clock(clock=self.stamp(now)))

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

    def _publish_map(self, grid: Any) -> None:
        msg = self._grid_msg_cls()
        msg.header.frame_id = self.p.map_frame
        msg.header.stamp = self.stamp()
        msg.info.map_load_time = msg.header.stamp
        fill_grid(msg, grid)
        self._send("map", msg)

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

    def _publish_amcl(self) -> None:
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

    def _publish_frame(self, frame: RGBDFrame) -> None:
        from sensor_msgs.msg import CameraInfo, Image
        from std_msgs.msg import String

        h, w = frame.shape
        stamp = self.stamp(frame.stamp)

        def image(encoding: str, data: bytes, step: int) -> Any:
            msg = Image(height=h, width=w, encoding=encoding, is_bigendian=0, step=step, data=data)
            msg.header.stamp, msg.header.frame_id = stamp, self.camera_frame
            return msg

        if self.publish_camera_info:
            info = CameraInfo(
                height=h,
                width=w,
                distortion_model="plumb_bob",
                D=[0.0] * 5,
                K=[float(v) for v in frame.K.reshape(-1)],
                R=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                P=[
                    float(frame.K[0, 0]),
                    0.0,
                    float(frame.K[0, 2]),
                    0.0,
                    0.0,
                    float(frame.K[1, 1]),
                    float(frame.K[1, 2]),
                    0.0,
                    0.0,
                    0.0,
                    1.0,
                    0.0,
                ],
            )
            info.header.stamp, info.header.frame_id = stamp, self.camera_frame
            self._send("info", info)
        if "instances" in self.pub and frame.instances is not None:
            info_stamp = round(frame.stamp, 6)  # the executive keys instance data by this
            data = {
                "stamp": info_stamp,
                "categories": {str(k): v for k, v in frame.instance_categories.items()},
                "unoccluded": {str(k): int(v) for k, v in frame.instance_unoccluded.items()},
            }
            self._send("instances_info", String(data=json.dumps(data)), self.stamp(info_stamp))
            self._send("instances", image("32SC1", frame.instances.astype("<i4").tobytes(), w * 4))
        depth, step = encode_depth(frame.depth, self.p.depth_encoding)
        self._send("depth", image(self.p.depth_encoding, depth, step))
        if frame.rgb is not None:
            self._send("rgb", image("rgb8", np.ascontiguousarray(frame.rgb, np.uint8).tobytes(), w * 3))

    def close(self) -> None:
        for sub in self.subs:
            sub.unregister()
        for srv in self.services:
            srv.shutdown()


def _recording_server(base: type) -> type:
    """``actionlib.ActionServer`` (passed in: no ROS import at module level) that remembers
    the goal id of the last result it published, for :meth:`SimBridge.announce`."""

    class RecordingActionServer(base):
        last_result = ""

        def publish_result(self, status: Any, result: Any) -> None:
            super().publish_result(status, result)
            self.last_result = status.goal_id.id

    return RecordingActionServer


# -- command line -------------------------------------------------------------------------------
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="bomc sim-ros", description=__doc__.split("\n")[0])
    ap.add_argument("--world", required=True, help="world file (the simulator's ground truth)")
    ap.add_argument("--mode", choices=("build", "monitor"), default="build")
    ap.add_argument("--session", type=int, default=1)
    ap.add_argument("--map", help="map_server YAML to serve on /map in monitor mode (the site's map.yaml)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--config", action="append", default=[], help="config file(s) (sim, camera, ros sections)"
    )
    ap.add_argument("--port", type=int, help="ROS master port on 127.0.0.1 (default: ROS_MASTER_URI)")
    ap.add_argument("--depth-encoding", choices=("32FC1", "16UC1"))
    ap.add_argument("--realtime-factor", type=float, help="free-run at this speed instead of lockstep")
    ap.add_argument("--abort-goals", type=int, default=0, help="abort the first N move_base goals (testing)")
    ap.add_argument("--scan-rate", type=float, default=2.0, help="Hz of sim time /scan is published at")
    ap.add_argument("--no-camera-info", action="store_true", help="never publish camera_info (testing)")
    ap.add_argument("--no-camera-tf", action="store_true", help="never publish the camera's tf (testing)")
    return ap.parse_args(argv)


def build_bridge(args: argparse.Namespace) -> SimBridge:
    from bomc_bt.config import load_config
    from bomc_bt.grid import load_map
    from bomc_bt.run import parked_near
    from bomc_bt.sim.camera import SimCamera
    from bomc_bt.sim.robot import SimRobot
    from bomc_bt.world import load_world

    config = load_config(args.config, robot="sim")
    params = replace(config.ros)  # a copy: the command-line overrides below stay local
    if args.depth_encoding:
        params.depth_encoding = args.depth_encoding
    # The simulated detector needs the per-pixel instances: served on a sim-only topic.
    params.instances_topic = params.instances_topic or SIM_INSTANCES_TOPIC
    world = load_world(args.world)
    grid = None
    if args.mode == "monitor":
        if not args.map:
            raise BomcError("monitor mode needs the map to serve (the site's map.yaml)", None, "--map")
        grid = load_map(args.map)
        camera = SimCamera(config.camera, seed=args.seed)
        # Parked near the dock, as `bomc monitor` without ROS does: relocalization has work to do.
        start = parked_near(world, world.start, args.seed, config.sim.planner.robot_radius + 0.1)
        sim = SimRobot(
            world,
            session=args.session,
            params=config.sim,
            seed=args.seed,
            mode="monitor",
            camera=camera,
            relocalization=config.relocalization,
            start=start,
        )
        sim.use_map(grid)
    else:
        sim = SimRobot(world, session=1, params=config.sim, seed=args.seed, mode="build")
    rospy = import_ros()
    check_master()  # init_node alone would retry an absent master for ever
    rospy.init_node("bomc_sim_bridge", disable_signals=False)
    rospy.set_param("/use_sim_time", True)
    return SimBridge(
        sim,
        params,
        lockstep=args.realtime_factor is None,
        realtime_factor=args.realtime_factor or 1.0,
        abort_goals=args.abort_goals,
        scan_rate=args.scan_rate,
        publish_camera_info=not args.no_camera_info,
        publish_tf_camera=not args.no_camera_tf,
        map_grid=grid,
    )


def main(argv: list[str] | None = None) -> int:
    try:
        args = parse_args(argv)
        if args.port:
            os.environ["ROS_MASTER_URI"] = f"http://127.0.0.1:{args.port}"
            os.environ.setdefault("ROS_IP", "127.0.0.1")
        bridge = build_bridge(args)
    except BomcError as exc:
        print(f"bomc sim-ros: {exc}", file=sys.stderr)
        return 2
    print(
        f"bomc sim-ros: serving {Path(args.world).name} ({args.mode}) on {os.environ.get('ROS_MASTER_URI')}",
        flush=True,
    )
    bridge.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
