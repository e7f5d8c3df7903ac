"""The sim bridge's serving loop: move_base, AMCL's inputs, and the lockstep stepping.

:class:`SimBridge` answers what a Fetch with AMCL and move_base answers (the ``move_base``
action, ``/initialpose``, ``/global_localization``, ``/request_nomotion_update``, and while
monitoring a new map on ``/map`` that move_base's static layer would take) from a
:class:`~bomc_bt.sim.robot.SimRobot`, and publishes its state through a
:class:`~bomc_bt.ros.bridge_publish.SimStatePublisher`.

In lockstep (the default) it steps the simulator only up to the time the executive
announces on the tick topic, after the goals, cancels and initial poses that announcement
counts have arrived, so a run through ROS interleaves ticks and steps as the direct
simulator run does. After each step it announces on ``ros.stepped_topic`` what it has
published by then (the newest stamp per topic, the newest tf, the last move_base result);
the executive's half is :mod:`bomc_bt.ros.lockstep`. Free-running, it steps at a factor
of real time and announces nothing.
"""

from __future__ import annotations

import json
import math
import threading
import time
from typing import Any

import numpy as np

from bomc_bt.robot import Status
from bomc_bt.ros import import_ros
from bomc_bt.ros.bridge_publish import SimStatePublisher
from bomc_bt.ros.convert import decimal_resolution, grid_from_msg, pose2d_from_msg
from bomc_bt.ros.params import RosParams

LOCALIZED_STD = (0.05, 0.03)  # m, rad: the covariance /amcl_pose reports once localized
LOST_STD = (2.0, 1.5)  # ... and while not localized (after a failed or global request)
COUNT_WAIT = 2.0  # wall s to wait for announced requests before stepping anyway (< ros.clock_timeout)
IDLE_ANNOUNCE = 0.1  # wall s between re-announcements (clock, stepped) while waiting for a tick


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
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from move_base_msgs.msg import MoveBaseAction
        from std_msgs.msg import String
        from std_srvs.srv import Empty, EmptyResponse

        self.rospy = rospy = import_ros()
        self.sim = sim
        self.p = params
        self.lockstep = lockstep
        self.realtime_factor = realtime_factor
        self.abort_goals = abort_goals
        self.wake = threading.Condition()
        self.inbox: list[tuple[str, Any]] = []
        self.until = sim.now()
        # requests the executive announced with its ticks / received here: a tick is stepped
        # once its requests are in, so a service call is applied at the tick it was made in
        self.wanted = {"goals": 0, "cancels": 0, "initialposes": 0, "services": 0, "maps": 0}
        self.got = {"goals": 0, "cancels": 0, "initialposes": 0, "services": 0, "maps": 0}
        self.stepped_without: dict[str, int] = {}  # requests stepped without (given up after COUNT_WAIT)
        self.goal: tuple[Any, Any] | None = None  # (server goal handle, sim NavHandle)
        self.reloc: Any = None
        self._srv_empty = EmptyResponse
        self.out = SimStatePublisher(rospy, sim, params, scan_rate=scan_rate,
                                     publish_camera_info=publish_camera_info, publish_tf_camera=publish_tf_camera)
        self.stepped_pub = None
        if lockstep:  # advertised only in lockstep: an executive that sees it waits for it
            self.stepped_pub = rospy.Publisher(params.stepped, String, queue_size=10)
        self.result_topic = rospy.resolve_name(rospy.remap_name(params.move_base_action) + "/result")
        self.server = _recording_server(actionlib.ActionServer)(
            params.move_base_action, MoveBaseAction, self._on_goal, self._on_cancel, auto_start=False
        )
        self.services = [
            rospy.Service(params.global_localization_service, Empty, self._on_global),
            rospy.Service(params.nomotion_update_service or "/request_nomotion_update", Empty, self._on_nomotion),
        ]
        if params.clear_costmaps_service:
            self.services.append(rospy.Service(params.clear_costmaps_service, Empty, self._on_clear_costmaps))
        self.subs = [
            rospy.Subscriber(
                params.initialpose_topic, PoseWithCovarianceStamped, self._on_initialpose, queue_size=5
            ),
            rospy.Subscriber(params.tick_topic, String, self._on_tick, queue_size=10),
        ]
        if map_grid is not None:  # monitor: a stuck pass may publish a refreshed map (bomc_bt.ros.map_refresh)
            from nav_msgs.msg import OccupancyGrid as GridMsg
            from rospy.numpy_msg import numpy_msg

            self.subs.append(rospy.Subscriber(params.map_topic, numpy_msg(GridMsg), self._on_map, queue_size=1))
        self.server.start()
        if map_grid is not None:
            self.out.publish_map(map_grid)
        self.out.publish_all()
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
        self._queue("global", None, "services")
        return self._srv_empty()

    def _on_clear_costmaps(self, _req: Any) -> Any:
        self._queue("clear_costmaps", None, "services")
        return self._srv_empty()

    def _on_nomotion(self, _req: Any) -> Any:
        self._queue("nomotion", None, "services")  # the simulated AMCL needs no nudge
        return self._srv_empty()

    def _apply_nomotion(self, _item: Any) -> None:
        """Nothing to apply: the simulator's localization updates without motion by itself. The call
        is queued and counted only so that the tick it was made in waits for it, as for the others."""

    def _apply_clear_costmaps(self, _item: Any) -> None:
        self.sim.clear_costmaps()

    def _on_map(self, msg: Any) -> None:
        if msg._connection_header.get("callerid") != self.rospy.get_name():  # not the map it serves itself
            self._queue("map", msg, "maps")

    def _apply_map(self, msg: Any) -> None:
        """A new map on /map: navigate on it, as move_base's static layer would."""
        self.sim.refresh_map(decimal_resolution(grid_from_msg(msg)))

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
        self.out.amcl_std = (math.sqrt(max(c[0, 0], 0.0)), math.sqrt(max(c[5, 5], 0.0)))
        self.out.publish_amcl()

    def _apply_resend(self, _item: Any) -> None:
        """Publish the newest message of every topic and tf again (then :meth:`announce`)."""
        self.out.resend()

    def _apply_global(self, _item: Any) -> None:
        self.reloc = self.sim.relocalize(None, global_search=True)
        self.out.amcl_std = LOST_STD
        self.out.publish_amcl()

    # -- stepping ---------------------------------------------------------------------------
    def run(self) -> None:
        rospy = self.rospy
        dt = self.sim.params.dt
        while not rospy.is_shutdown():
            start = time.monotonic()
            if self.lockstep:
                with self.wake:
                    while not rospy.is_shutdown() and self.until <= self.sim.now() + 1e-6 and not self.inbox:
                        if not self.wake.wait(IDLE_ANNOUNCE):  # idle: re-announce for late joiners
                            self.out.publish_clock()
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
                self.stepped_without[k] = self.stepped_without.get(k, 0) + behind[k]

    def step(self) -> None:
        """One simulator step, then everything it changed, then the clock."""
        self.sim.step()
        self._settle_goal()
        self._settle_reloc()
        self.out.publish_all()

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
        self.out.amcl_std = LOCALIZED_STD if self.reloc.status() is Status.SUCCEEDED else LOST_STD
        self.reloc = None

    def announce(self) -> None:
        """Lockstep only: tell the executive what it must have received to be at this time.

        The executive waits for every topic it listens to to reach the stamp given here,
        for tf at the newest stamp and for the last move_base result, so each tick sees
        exactly what was published up to its time, as the direct simulator run does.
        """
        from std_msgs.msg import String

        if self.stepped_pub is None:
            return
        data = {
            "until": self.sim.now(),  # the exact float: /clock's ns may be 1 ns short of it
            "until_ns": self.out.stamp().to_nsec(),
            "stamps": self.out.sent,
            "tf": self.out.tf_announcement(),
            "result": {self.result_topic: self.server.last_result},
            "stepped_without": self.stepped_without,  # requests given up on so far, per kind
        }
        self.stepped_pub.publish(String(data=json.dumps(data)))

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
