"""The executive's half of the sim bridge's lockstep protocol.

With ``use_sim_time`` the executive publishes the time each tick waits for on
``tick_topic`` (with how many goals, cancels, initial poses and service calls it has sent,
so the bridge waits for those before stepping). The bridge steps its simulator to that
time and answers on ``stepped_topic`` with what it has published by then: the newest
stamp per topic, the newest tf, the goal id of its last move_base result. A tick then
waits for those messages too, so it sees the same map, tf and move_base results as the
direct simulator run at that time (topics are not ordered with respect to ``/clock`` or
to each other). A real robot announces no steps, and nothing waits here then.

Wall time only bounds the waits (``lockstep_wait``): an announced message that never comes
is a warning, not a hang, and its topic is not waited for again until one of its messages
does come in. A topic that was only late (a loaded machine) is then waited for as before,
so the ticks after it see its messages again instead of running ahead of them.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from typing import Any

from bomc_bt.ros.params import RosParams


class LockstepClient:
    """Announces ticks, keeps the bridge's announcements and waits for what they list."""

    def __init__(self, rospy: Any, params: RosParams, tf_buffer: Any, use_sim_time: bool):
        from std_msgs.msg import String

        self.rospy = rospy
        self.params = params
        self.tf_buffer = tf_buffer
        self.use_sim_time = use_sim_time
        self._arrived = threading.Condition()  # notified when a tracked message comes in
        self._stepped: dict[str, Any] | None = None  # the bridge's newest announcement
        self._received: dict[str, int] = {}  # resolved topic -> newest stamp (ns) received
        self._tracked: set[str] = set()  # the resolved topics track() subscribed to
        self._unsynced: set[str] = set()  # announced things that once never came: not waited for
        self.gave_up: list[tuple[float, list[str]]] = []  # (tick time, what it / the bridge waited for in vain)
        self.bridge_stepped_without: dict[str, int] = {}  # the bridge's count of requests it stepped without
        self.clock_seen = threading.Event()
        self.subs: list[Any] = []
        if use_sim_time:
            from rosgraph_msgs.msg import Clock

            self.subs += [
                rospy.Subscriber("/clock", Clock, lambda _m: self.clock_seen.set(), queue_size=1),
                rospy.Subscriber(params.stepped, String, self._on_stepped, queue_size=10),
            ]
        self.tick_pub = rospy.Publisher(params.tick_topic, String, queue_size=10)

    # -- subscriptions -----------------------------------------------------------------------
    def track(self, topic: str, msg_type: Any, callback: Callable[[Any], None],
              stamp_ns: Callable[[Any], int] | None = None, **kwargs: Any) -> Any:
        """A subscriber that also notes the newest stamp received, for the lockstep wait.

        ``stamp_ns`` reads a message's stamp (ns) where it has no header.
        """
        name = self.rospy.resolve_name(topic)
        self._tracked.add(name)
        stamp_of = stamp_ns or _header_stamp_ns

        def tracked(msg: Any) -> None:
            callback(msg)
            stamp = stamp_of(msg)
            with self._arrived:
                self._received[name] = max(self._received.get(name, -1), stamp)
                self._unsynced.discard(name)  # it is connected after all: wait for it again
                self._arrived.notify_all()

        return self.rospy.Subscriber(topic, msg_type, tracked, **kwargs)

    def notify(self) -> None:
        """Something the wait may be waiting for came in (a move_base result)."""
        with self._arrived:
            self._arrived.notify_all()

    def _on_stepped(self, msg: Any) -> None:
        data = json.loads(msg.data)
        for kind, count in data.get("stepped_without", {}).items():  # the bridge gave up on requests
            if count > self.bridge_stepped_without.get(kind, 0):
                self.bridge_stepped_without[kind] = count
                self.gave_up.append((float(data["until"]), [f"bridge: {kind}"]))
        with self._arrived:
            self._stepped = data  # one publisher, in order: the last one is the newest
            self._unsynced.discard(self.params.stepped)
            self._arrived.notify_all()

    # -- time --------------------------------------------------------------------------------
    def exact_time(self, t: Any) -> float:
        """The bridge's own float for the rospy.Time ``t`` when it announced that time.

        rospy.Time.from_sec truncates to whole ns, so the simulator's 8.1 s reads as
        8.099999999 s, and "once a second" decisions (the trajectory rows) fall a tick
        later than in the direct simulator run.
        """
        ann = self._stepped
        if ann is not None and ann.get("until_ns") == t.to_nsec():
            return ann["until"]
        return t.to_sec()

    def publish_tick(self, target: float, counts: dict[str, int], resend: bool = False) -> None:
        from std_msgs.msg import String

        data = {"until": target, **counts, **({"resend": True} if resend else {})}
        self.tick_pub.publish(String(data=json.dumps(data)))

    # -- waiting -----------------------------------------------------------------------------
    def sync(self, target: float, awaits_result: Callable[[str], bool]) -> None:
        """Wait until everything the bridge published up to ``target`` is here.

        Bounded by ``lockstep_wait`` wall seconds; what did not come in time is not waited
        for again until a message of it arrives (a topic this robot is not connected to), with
        a warning, so a mismatch costs one wait, not one per tick. ``awaits_result(goal_id)``
        says whether a move_base result is still owed to one of this executive's goals.
        """
        if self._stepped is None or self.params.stepped in self._unsynced:
            return  # no bridge announces steps (a real robot, a free-running bridge)
        wait = self.params.lockstep_wait
        deadline = time.monotonic() + wait
        while missing := self._missing(target, awaits_result):
            if self.rospy.is_shutdown():
                from bomc_bt.errors import MissionFailed

                raise MissionFailed("ROS shut down")
            if time.monotonic() > deadline:
                with self._arrived:
                    self._unsynced |= missing
                self.gave_up.append((target, sorted(missing)))
                self.rospy.logwarn(
                    f"bomc: {', '.join(sorted(missing))} not received within {wait:g} s of the bridge's "
                    f"step to {target:.2f} s; not waited for until one comes (ros.lockstep_wait)"
                )
                return
            with self._arrived:  # woken by a tracked message; tf (tf2's own callback) is polled
                self._arrived.wait(0.001)

    def _missing(self, target: float, awaits_result: Callable[[str], bool]) -> set[str]:
        """What the newest announcement lists that this robot has not received yet."""
        with self._arrived:
            ann, received = self._stepped, dict(self._received)
        if ann is None or ann["until"] < target - 1e-6:
            return {self.params.stepped}
        skip = self._unsynced
        missing = {
            topic
            for topic, ns in ann["stamps"].items()
            if topic in self._tracked and topic not in skip and received.get(topic, -1) < ns
        }
        for topic, goal_id in ann["result"].items():
            if topic not in skip and awaits_result(goal_id):
                missing.add(topic)
        if ann["tf"] and "/tf" not in skip:
            when = self.rospy.Time(0, ann["tf"][0])
            if not all(self.tf_buffer.can_transform(parent, child, when) for parent, child in ann["tf"][1]):
                missing.add("/tf")
        return missing

    def wait_for_bridge(self, subs: list[Any], now: float, counts: dict[str, int],
                        awaits_result: Callable[[str], bool], pubs: tuple[Any, ...] = ()) -> None:
        """A bridge announcing its steps: be connected to it before the first tick.

        A message published before a subscription connects is lost to it, and the first
        tick would wait for it in vain, so every topic the bridge publishes and this robot
        reads (``subs``) must be connected, and its first announcement in, before ticking.
        Without such a bridge (a real robot, Gazebo) this returns at once.
        """
        if not self.use_sim_time or not self._advertised(self.params.stepped):
            return
        deadline = time.monotonic() + self.params.server_timeout
        while not self._bridge_connected(subs, pubs):
            if time.monotonic() > deadline:
                self.rospy.logwarn("bomc: not connected to every topic of the sim bridge; ticks may not be exact")
                self.gave_up.append((now, ["connections to the bridge"]))
                break
            time.sleep(0.01)
        # What the bridge published before the connections were up is lost to them: ask for
        # it again, so that the first tick, too, sees the state at its time.
        self.publish_tick(now, counts, resend=True)
        self.sync(now, awaits_result)

    def _advertised(self, topic: str) -> bool:
        name = self.rospy.resolve_name(topic)
        return any(t == name for t, _type in self.rospy.get_published_topics())

    def _bridge_connected(self, subs: list[Any], pubs: tuple[Any, ...] = ()) -> bool:
        """Every topic the bridge publishes that this robot reads, the ticks and ``pubs`` (other
        requests the bridge reads from this robot) connected: a request sent before would be late."""
        with self._arrived:
            stepped = self._stepped is not None
        published = {t for t, _type in self.rospy.get_published_topics()}
        connected = [s for s in subs if s.resolved_name in published]
        return stepped and all(pub.get_num_connections() > 0 for pub in (self.tick_pub, *pubs)) and all(
            s.get_num_connections() > 0 for s in connected
        )

    def close(self) -> None:
        for topic in (*self.subs, self.tick_pub):
            topic.unregister()
        self.subs = []


def _header_stamp_ns(msg: Any) -> int:
    return msg.header.stamp.to_nsec()
