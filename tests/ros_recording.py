"""Recording a simulated monitor pass into a ROS 1 bag: roscore, `bomc sim-ros`, `rosbag record`.

What an operator does by hand (README: Replaying a recording), as processes a test or a
benchmark can start and stop by their ids: a roscore on a free loopback port, the sim
bridge serving the site's map, ``rosbag record`` on the topics a replay reads
(:func:`bomc_bt.ros.bag.recorded_topics`), and the live pass ``bomc monitor --ros`` in its
own process (rospy allows one node per process, and the test process may hold one bound
to another master).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(proc: subprocess.Popen, sig: int = signal.SIGTERM, wait: float = 15.0) -> None:
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(wait)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@contextlib.contextmanager
def roscore(tmp: Path):
    """A roscore on a free port; yields the environment its clients need."""
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_IP="127.0.0.1",
               ROS_HOSTNAME="127.0.0.1", ROS_HOME=str(tmp / "ros-home"),
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    proc = subprocess.Popen(["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 20.0
        while True:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            if time.monotonic() > deadline or proc.poll() is not None:
                raise RuntimeError("roscore did not start")
            time.sleep(0.1)
        yield env
    finally:
        _stop(proc, signal.SIGINT)


def _subscribed(env: dict, topic: str, node_prefix: str) -> bool:
    code = ("import sys; sys.path.append('/usr/lib/python3/dist-packages'); import rosgraph;"
            "_, subs, _ = rosgraph.Master('/probe').getSystemState();"
            f"print(any(t == {topic!r} and any(n.startswith({node_prefix!r}) for n in ns) for t, ns in subs))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=20)
    return out.stdout.strip() == "True"


def record_pass(env: dict, world: Path, site: Path, session: int, bag: Path, config: Path,
                topics: list[str], seed: int = 0, timeout: float = 300.0) -> subprocess.CompletedProcess:
    """Run ``bomc monitor --ros`` against ``bomc sim-ros`` while ``rosbag record`` records ``topics``.

    Returns the monitor's completed process; the bag is closed (``rosbag record`` stopped
    with SIGINT, as Ctrl-C does) when this returns.
    """
    bridge = subprocess.Popen([sys.executable, "-m", "bomc_bt.cli", "sim-ros", "--world", str(world),
                               "--mode", "monitor", "--session", str(session), "--seed", str(seed),
                               "--map", str(site / "map.yaml"), "--config", str(config)],
                              env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    recorder = None
    try:
        line = bridge.stdout.readline()
        if "serving" not in line:
            raise RuntimeError(f"sim-ros did not start: {line}{bridge.stdout.read() if bridge.poll() else ''}")
        recorder = subprocess.Popen(["rosbag", "record", "--tcpnodelay", "-b", "1024", "-O", str(bag),
                                     "__name:=bomc_recorder", *topics],
                                    env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                    start_new_session=True)
        deadline = time.monotonic() + 30.0
        while not _subscribed(env, topics[0], "/bomc_recorder"):
            if time.monotonic() > deadline or recorder.poll() is not None:
                raise RuntimeError("rosbag record did not subscribe")
            time.sleep(0.2)
        time.sleep(1.0)  # its other subscriptions connect too
        return subprocess.run([sys.executable, "-m", "bomc_bt.cli", "monitor", "--ros", "--site", str(site),
                               "--session", str(session), "--seed", str(seed), "--quiet", "--config", str(config)],
                              env=env, cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    finally:
        if recorder is not None:
            time.sleep(1.0)  # the last messages reach the recorder
            _stop(recorder, signal.SIGINT, 30.0)
        _stop(bridge)
