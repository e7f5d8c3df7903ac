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

This module is the command line; the serving loop is :mod:`bomc_bt.ros.bridge_server`,
what it publishes :mod:`bomc_bt.ros.bridge_publish`.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path

from bomc_bt.errors import BomcError
from bomc_bt.ros import import_ros
from bomc_bt.ros.bridge_server import COUNT_WAIT, SimBridge
from bomc_bt.ros.ground_truth import SIM_INSTANCES_TOPIC
from bomc_bt.ros.node import check_master

__all__ = ["COUNT_WAIT", "SimBridge", "build_bridge", "main", "parse_args"]


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
    from bomc_bt.sim.factory import SimRobots

    config = load_config(args.config, robot="sim")
    params = replace(config.ros)  # a copy: the command-line overrides below stay local
    if args.depth_encoding:
        params.depth_encoding = args.depth_encoding
    # The simulated detector needs the per-pixel instances: served on a sim-only topic.
    params.instances_topic = params.instances_topic or SIM_INSTANCES_TOPIC
    robots = SimRobots(args.world, args.seed)
    robots.prepare(config)
    grid = None
    if args.mode == "monitor":
        if not args.map:
            raise BomcError("monitor mode needs the map to serve (the site's map.yaml)", None, "--map")
        grid = load_map(args.map)
        # Parked near the dock, as `bomc monitor` without ROS does: relocalization has work to do.
        sim = robots.monitor_robot(config, args.session)
        sim.use_map(grid)
    else:
        sim = robots.build_robot(config)
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
