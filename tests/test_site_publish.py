"""``bomc publish SITE`` against a real roscore: a subscriber receives the latched map and markers.

A roscore on a free loopback port; ``bomc publish`` runs in its own process, and so does
the subscriber (rospy allows one node per process, and other test modules may own this
process's node). The subscriber connects *after* the messages went out: latching is what
is tested.
"""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from site_files import LAB_B, REPO, bomc_command, bomc_env, error_line

from bomc_bt import run
from bomc_bt.errors import BomcError
from bomc_bt.grid import load_map
from bomc_bt.site import Site, open_site

pytestmark = pytest.mark.ros

SUBSCRIBER = """
import json, sys
sys.path.append("/usr/lib/python3/dist-packages")
import rospy
from nav_msgs.msg import OccupancyGrid
from visualization_msgs.msg import Marker, MarkerArray
rospy.init_node("bomc_probe", anonymous=True, disable_signals=True)
grid = rospy.wait_for_message(sys.argv[1], OccupancyGrid, timeout=30)
markers = rospy.wait_for_message(sys.argv[2], MarkerArray, timeout=30)
print(json.dumps({
    "map": {"frame": grid.header.frame_id, "width": grid.info.width, "height": grid.info.height,
            "resolution": grid.info.resolution, "origin": [grid.info.origin.position.x, grid.info.origin.position.y],
            "data": list(grid.data)},
    "markers": [{"ns": m.ns, "id": m.id, "type": m.type, "action": m.action, "frame": m.header.frame_id,
                 "xyz": [m.pose.position.x, m.pose.position.y, m.pose.position.z], "text": m.text}
                for m in markers.markers]}))
"""


def _ros_missing() -> str:
    try:
        from bomc_bt.ros import import_ros

        import_ros()
    except BomcError as exc:
        return str(exc)
    return "" if shutil.which("roscore") else "roscore is not on PATH (apt-get install ros-core)"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def master(tmp_path_factory):
    """A roscore of this module's own; the environment that reaches it."""
    missing = _ros_missing()
    if missing:
        pytest.skip(f"ROS 1 unavailable: {missing}")
    port = _free_port()
    env = {**bomc_env(), "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_IP": "127.0.0.1",
           "ROS_HOSTNAME": "127.0.0.1", "ROS_HOME": str(tmp_path_factory.mktemp("ros-home"))}
    proc = subprocess.Popen(["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 20.0
    while True:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                break
        if time.monotonic() > deadline or proc.poll() is not None:
            proc.kill()
            pytest.fail("roscore did not start")
        time.sleep(0.1)
    yield env
    proc.terminate()
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    if not LAB_B.exists():
        pytest.skip(f"shared data not found at {LAB_B} (set BOMC_SHARED to the shared folder)")
    root = tmp_path_factory.mktemp("publish")
    (root / "perfect.yaml").write_text("detector: {preset: perfect}\n")
    cfg = run.build_config([str(root / "perfect.yaml")])
    assert run.run_build(LAB_B, root / "site", seed=0, config=cfg, quiet=True).succeeded
    assert run.run_monitor(LAB_B, root / "site", 1, seed=1, config=cfg, quiet=True).succeeded
    return root / "site"


def test_a_subscriber_receives_the_latched_map_and_objects(master, site):
    publisher = subprocess.Popen(bomc_command("publish", str(site), "--duration", "60", "--map-topic", "/t/map",
                                              "--objects-topic", "/t/objects"),
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO, env=master)
    try:
        line = publisher.stdout.readline()  # printed once both messages went out
        assert "publishing the map" in line and "12 object(s)" in line, (line, publisher.stderr.read())
        probe = subprocess.run([sys.executable, "-c", SUBSCRIBER, "/t/map", "/t/objects"], capture_output=True,
                               text=True, env=master, timeout=60)
        assert probe.returncode == 0, probe.stderr
        got = json.loads(probe.stdout)
    finally:
        publisher.terminate()
        publisher.wait(30)
    grid = load_map(Site(site).map_yaml)
    m = got["map"]
    assert (m["frame"], m["width"], m["height"]) == ("map", grid.width, grid.height)
    assert m["resolution"] == pytest.approx(grid.resolution) and m["origin"] == pytest.approx(list(grid.origin))
    assert np.array_equal(np.array(m["data"], dtype=np.int8).reshape(grid.data.shape), grid.data)
    with open_site(site) as reader:
        objects = {o.id: o for o in reader.objects()}
    markers = got["markers"]
    assert markers[0]["action"] == 3  # DELETEALL: markers of an earlier publish go
    cubes = {mk["id"]: mk for mk in markers if mk["ns"] == "objects"}
    labels = {mk["id"]: mk["text"] for mk in markers if mk["ns"] == "labels"}
    assert set(cubes) == set(objects) == set(labels)
    for nid, o in objects.items():
        assert cubes[nid]["xyz"] == pytest.approx(list(o.position)) and cubes[nid]["frame"] == "map"
        assert labels[nid] == f"{o.category} #{nid}"


def test_publish_without_a_master_is_one_line_exit_2(site, tmp_path):
    if _ros_missing():
        pytest.skip(f"ROS 1 unavailable: {_ros_missing()}")
    env = {**bomc_env(), "ROS_MASTER_URI": f"http://127.0.0.1:{_free_port()}", "ROS_HOME": str(tmp_path)}
    result = subprocess.run(bomc_command("publish", str(site), "--duration", "1"), capture_output=True, text=True,
                            cwd=REPO, env=env, timeout=60)
    assert "cannot reach the ROS master" in error_line(result)
    assert "no object graph here" in error_line(subprocess.run(
        bomc_command("publish", str(tmp_path)), capture_output=True, text=True, cwd=REPO, env=env, timeout=60))
