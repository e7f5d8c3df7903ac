"""The ROS 1 path against a real roscore and the sim-over-ROS bridge.

A module-wide ``roscore -p PORT`` on 127.0.0.1 (a free port); each test starts the bridge
(``python -m bomc_bt.ros.bridge``) in a subprocess and drives a :class:`RosRobot` from
this process (rospy allows one node per process, so the executive node lives for the
whole module). Skipped, with the reason, only where ROS cannot be imported.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bomc_bt.errors import BomcError, MissionFailed
from bomc_bt.geometry import Pose2D
from bomc_bt.robot import Status

pytestmark = pytest.mark.ros

try:
    from bomc_bt.ros import import_ros

    import_ros()
    ROS_MISSING = ""
except BomcError as exc:
    ROS_MISSING = str(exc)
if not ROS_MISSING and shutil.which("roscore") is None:
    ROS_MISSING = "roscore is not on PATH (apt-get install ros-core)"
if ROS_MISSING:
    pytest.skip(f"ROS 1 unavailable: {ROS_MISSING}", allow_module_level=True)

from bomc_bt.ros.params import RosParams  # noqa: E402
from bomc_bt.ros.robot import RosRobot  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
WORLD = Path("/work/shared/worlds/lab-b.yaml")
if not WORLD.exists():
    WORLD = ROOT / "examples" / "worlds" / "lab-b.yaml"
SIM_PARAMS = dict(
    instances_topic="/bomc_sim/instances", frame_timeout=2.0, clock_timeout=5.0, server_timeout=10.0
)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def roscore():
    port = _free_port()
    env = dict(
        os.environ,
        ROS_MASTER_URI=f"http://127.0.0.1:{port}",
        ROS_IP="127.0.0.1",
        ROS_HOSTNAME="127.0.0.1",
        ROS_HOME=str(Path(os.environ.get("TMPDIR", "/tmp")) / f"bomc-ros-{port}"),
    )
    saved = {k: os.environ.get(k) for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOSTNAME", "ROS_HOME")}
    os.environ.update({k: env[k] for k in saved})
    proc = subprocess.Popen(
        ["roscore", "-p", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 20.0
    while True:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                break
        if time.monotonic() > deadline or proc.poll() is not None:
            proc.kill()
            pytest.fail("roscore did not start")
        time.sleep(0.1)
    import rosgraph

    rosgraph.Master("/bomc_test").setParam("/use_sim_time", True)  # before this process's node starts
    yield env
    proc.terminate()
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


class Bridge:
    """``python -m bomc_bt.ros.bridge`` in a subprocess, stopped by its pid."""

    def __init__(self, env: dict, *args: str):
        cmd = [sys.executable, "-m", "bomc_bt.ros.bridge", "--world", str(WORLD), *args]
        self.proc = subprocess.Popen(
            cmd, env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        line = self.proc.stdout.readline()
        if "serving" not in line:
            self.stop()
            pytest.fail(f"bridge did not start: {line}")

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()


@pytest.fixture
def bridge(roscore):
    started: list[Bridge] = []

    def start(*args: str) -> Bridge:
        b = Bridge(roscore, *args)
        started.append(b)
        return b

    yield start
    for b in started:
        b.stop()


def _robot(mode: str, **overrides) -> RosRobot:
    return RosRobot(RosParams(**{**SIM_PARAMS, **overrides}), mode=mode)


def _until_done(robot: RosRobot, handle, limit: float = 120.0) -> Status:
    end = robot.now() + limit
    while handle.status() is Status.RUNNING and robot.now() < end:
        robot.step()
    return handle.status()


def _settle(robot: RosRobot) -> None:
    """A few ticks: a bridge restarted at time 0 makes tf2 drop its buffer first."""
    for _ in range(5):
        robot.step()
    assert robot.pose() is not None


def _localize(robot: RosRobot) -> None:
    robot.use_map(robot.live_map())
    assert robot.pose() is None  # monitor: no pose before AMCL says so
    assert _until_done(robot, robot.relocalize(Pose2D(4.5, 6.5, 0.0)), 30.0) is Status.SUCCEEDED
    assert robot.pose() is not None


def test_build_mode_map_pose_and_goal(bridge):
    bridge("--mode", "build")
    robot = _robot("build")
    try:
        for _ in range(3):
            robot.step()
        assert robot.now() == pytest.approx(0.3, abs=1e-6)  # lockstep: ticks advance ROS time
        grid = robot.live_map()
        assert grid.data.shape[0] > 10 and (grid.data == 0).any()  # the sim mapper's /map
        start = robot.pose()
        assert start is not None and start.distance_to(Pose2D(4.5, 6.5, 0.0)) < 0.05
        handle = robot.navigate(Pose2D(6.0, 6.5, 0.0))
        assert _until_done(robot, handle) is Status.SUCCEEDED
        assert robot.pose().distance_to(start) > 1.0
    finally:
        robot.close()


def test_move_base_abort_is_a_failure_then_a_retry_succeeds(bridge):
    bridge("--mode", "build", "--abort-goals", "1")
    robot = _robot("build")
    try:
        _settle(robot)
        first = robot.navigate(Pose2D(6.0, 6.5, 0.0))
        assert _until_done(robot, first) is Status.FAILED
        assert "aborted" in first.message
        retry = robot.navigate(Pose2D(6.0, 6.5, 0.0))
        assert _until_done(robot, retry) is Status.SUCCEEDED
    finally:
        robot.close()


def test_cancel_maps_to_cancelled(bridge):
    bridge("--mode", "build")
    robot = _robot("build")
    try:
        _settle(robot)
        handle = robot.navigate(Pose2D(6.5, 6.5, 0.0))
        robot.step()
        handle.cancel()
        assert handle.status() is Status.CANCELLED
        before = robot.pose()
        for _ in range(10):
            robot.step()
        assert robot.pose().distance_to(before) < 0.3  # the bridge's move_base stopped
    finally:
        robot.close()


@pytest.mark.parametrize("encoding", ["32FC1", "16UC1"])
def test_rgbd_frames_in_both_depth_encodings(bridge, tmp_path, encoding):
    bridge("--mode", "monitor", "--map", str(WORLD.parent / "lab-b-map.yaml"), "--depth-encoding", encoding)
    robot = _robot("monitor")
    try:
        _localize(robot)
        frame = None
        end = robot.now() + 5.0
        while frame is None and robot.now() < end:
            robot.step()
            frame = robot.frame()
        assert frame is not None
        assert frame.depth.dtype.name == "float32" and frame.rgb.shape == (*frame.shape, 3)
        valid = frame.depth[frame.depth == frame.depth]
        assert valid.size > 0.5 * frame.depth.size and float(valid.min()) > 0.2 and float(valid.max()) < 9.0
        assert frame.K[0, 0] > 100 and frame.K[2, 2] == 1.0  # from camera_info
        assert frame.instances is not None and frame.instance_categories  # the sim detector's input
        pose = robot.pose()
        assert abs(frame.T_map_base[0, 3] - pose.x) < 0.3 and abs(frame.T_base_camera[2, 3]) > 0.5
    finally:
        robot.close()


@pytest.mark.parametrize("flag, words", [("--no-camera-info", "camera_info"), ("--no-camera-tf", "no tf")])
def test_missing_camera_info_or_tf_is_an_error_not_a_hang(bridge, flag, words):
    bridge("--mode", "monitor", "--map", str(WORLD.parent / "lab-b-map.yaml"), flag)
    robot = _robot("monitor")
    try:
        _localize(robot)
        start = time.monotonic()
        with pytest.raises(MissionFailed, match=words):
            for _ in range(200):
                robot.step()
                robot.frame()
        assert time.monotonic() - start < 30.0
    finally:
        robot.close()


def test_no_move_base_server_is_a_clear_error(roscore):
    with pytest.raises(MissionFailed, match="/clock|move_base"):
        RosRobot(
            RosParams(
                **{
                    **SIM_PARAMS,
                    "move_base_action": "no_such_move_base",
                    "server_timeout": 1.0,
                    "clock_timeout": 1.0,
                }
            ),
            mode="build",
        )
