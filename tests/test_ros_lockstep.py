"""The executive's half of the lockstep protocol, tick by tick, over a stand-in transport.

The whole protocol runs through a real roscore in ``test_ros.py``; these tests pin what a
loaded machine does to it, which a real roscore shows only now and then: a message the
bridge announced comes later than the wall-time bound. The transport here delivers
messages when the test says, so "late" is exact.
"""

from __future__ import annotations

import json
import threading
import time
from types import SimpleNamespace

import pytest

from bomc_bt.errors import BomcError
from bomc_bt.ros.params import RosParams

try:
    from bomc_bt.ros import import_ros

    import_ros()
    from bomc_bt.ros.lockstep import LockstepClient
except (BomcError, ImportError) as exc:  # no ROS 1 Python packages on this machine
    pytest.skip(f"ROS 1 is not importable: {exc}", allow_module_level=True)

TOPIC = "/bomc_sim/instances/info"
WAIT = 0.3  # wall s: the test's lockstep_wait


class Transport:
    """rospy's calls the client makes, with subscribers the test delivers to by hand."""

    def __init__(self) -> None:
        self.callbacks: dict[str, list] = {}
        self.warnings: list[str] = []

    def Subscriber(self, topic, _type, callback, **_kwargs):  # noqa: N802 (rospy's name)
        self.callbacks.setdefault(topic, []).append(callback)
        return SimpleNamespace(unregister=lambda: None, resolved_name=topic)

    def Publisher(self, _topic, _type, **_kwargs):  # noqa: N802
        return SimpleNamespace(publish=lambda _msg: None, unregister=lambda: None)

    def Time(self, secs, nsecs):  # noqa: N802
        return SimpleNamespace(to_nsec=lambda: secs * 10**9 + nsecs)

    resolve_name = staticmethod(lambda topic: topic)
    is_shutdown = staticmethod(lambda: False)

    def logwarn(self, text: str) -> None:
        self.warnings.append(text)

    def deliver(self, topic: str, msg) -> None:
        for callback in self.callbacks[topic]:
            callback(msg)


def _client(transport: Transport) -> tuple[LockstepClient, list[int]]:
    params = RosParams(lockstep_wait=WAIT)
    client = LockstepClient(transport, params, tf_buffer=None, use_sim_time=True)
    seen: list[int] = []
    client.track(TOPIC, object, lambda msg: seen.append(msg), stamp_ns=lambda msg: msg)
    return client, seen


def _announce(transport: Transport, client: LockstepClient, until_s: int) -> None:
    """The bridge stepped to ``until_s`` having published TOPIC stamped then."""
    data = {"until": float(until_s), "until_ns": until_s * 10**9, "stamps": {TOPIC: until_s * 10**9},
            "result": {}, "tf": None}
    transport.deliver(client.params.stepped, SimpleNamespace(data=json.dumps(data)))


def _deliver_later(transport: Transport, stamp_ns: int, after: float) -> threading.Thread:
    thread = threading.Thread(target=lambda: (time.sleep(after), transport.deliver(TOPIC, stamp_ns)))
    thread.start()
    return thread


def test_a_tick_waits_for_an_announced_message_until_it_comes():
    transport = Transport()
    client, seen = _client(transport)
    _announce(transport, client, 1)
    thread = _deliver_later(transport, 10**9, after=0.05)
    client.sync(1.0, awaits_result=lambda _goal: False)
    assert seen == [10**9] and not transport.warnings and client.gave_up == []
    thread.join()


def test_a_message_later_than_the_wait_is_waited_for_again_once_it_has_come():
    transport = Transport()
    client, seen = _client(transport)
    _announce(transport, client, 1)
    start = time.monotonic()
    client.sync(1.0, awaits_result=lambda _goal: False)  # the message is late: the tick goes on
    assert WAIT <= time.monotonic() - start < WAIT + 1.0
    assert len(transport.warnings) == 1 and TOPIC in transport.warnings[0] and "lockstep_wait" in transport.warnings[0]
    assert client.gave_up == [(1.0, [TOPIC])]  # what test_ros.py reads to tell a lost message

    _announce(transport, client, 2)  # the late topic is not waited for while nothing of it has come
    start = time.monotonic()
    client.sync(2.0, awaits_result=lambda _goal: False)
    assert time.monotonic() - start < WAIT

    transport.deliver(TOPIC, 10**9)  # the late message does come: the topic is connected after all
    _announce(transport, client, 3)
    thread = _deliver_later(transport, 3 * 10**9, after=0.1)
    client.sync(3.0, awaits_result=lambda _goal: False)
    assert seen[-1] == 3 * 10**9, "the tick at 3 s ran ahead of the message the bridge published at 3 s"
    assert len(transport.warnings) == 1
    thread.join()


def test_the_wait_is_a_parameter_checked_on_load():
    with pytest.raises(ValueError, match="lockstep_wait"):
        RosParams(lockstep_wait=0.0)
