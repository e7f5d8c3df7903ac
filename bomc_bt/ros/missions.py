"""``bomc build --ros`` / ``bomc monitor --ros``: the same trees against a ROS 1 robot.

The wiring mirrors :func:`bomc_bt.run.run_build` and :func:`bomc_bt.run.run_monitor`
with a :class:`~bomc_bt.ros.robot.RosRobot` instead of the simulator. There is no world:
the dock pose (the relocalization hint) is where the build started (the first row of
the site's trajectory), and perception prompts come from ``perception.categories``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TextIO

from bomc_bt.config import Config
from bomc_bt.errors import BomcError, MissionFailed
from bomc_bt.geometry import Pose2D
from bomc_bt.mission import MissionContext
from bomc_bt.params import from_mapping
from bomc_bt.ros import import_ros
from bomc_bt.ros.params import RosParams
from bomc_bt.run import MissionResult, build_config, check_session, default_tree, make_perception, run_tree
from bomc_bt.site import Site


def ros_params(config: Config) -> RosParams:
    """The ``ros:`` section as a validated record (errors name the config file).

    The simulated detector reads the per-pixel instance image that only the sim-over-ROS
    bridge publishes, so with ``perception.backend: sim`` an unset ``ros.instances_topic``
    means the bridge's topic (a real robot runs the ONNX backend and never needs it).
    """
    if isinstance(config.ros, RosParams):
        params = replace(config.ros)
    else:  # a plain mapping (configs built by hand)
        params = from_mapping(RosParams, config.ros, config.source[-1] if config.source else None, "ros")
    if config.perception.backend == "sim" and not params.instances_topic:
        from bomc_bt.ros.bridge import SIM_INSTANCES_TOPIC

        params.instances_topic = SIM_INSTANCES_TOPIC
    return params


def dock_pose(site: Site) -> Pose2D:
    """Where the build started: the first pose of ``trajectory.csv``."""
    try:
        with open(site.trajectory_csv) as f:
            f.readline()
            t, x, y, yaw = (float(v) for v in f.readline().split(",")[:4])
    except (OSError, ValueError):
        raise BomcError(
            "no start pose in the trajectory (run `bomc build` first)", site.trajectory_csv
        ) from None
    return Pose2D(x, y, yaw)


def _hooks(robot, ctx: MissionContext, params: RosParams, hooks: list[Callable]) -> list[Callable]:
    out = list(hooks)
    if params.publish:
        from bomc_bt.ros.publish import MissionPublisher

        out.append(MissionPublisher(ctx, params))
    return out


def _report_failure(robot, ctx: MissionContext, exc: MissionFailed) -> None:
    """The robot could not go on (no camera_info, a dead /clock): stop it and write the report.

    The simulator never fails this way, so :func:`bomc_bt.run.run_monitor` has no such
    path; on a robot the report of what the pass saw before is what tells the operator
    what happened. The session stays open in the store, as after Ctrl-C, so that
    ``--resume`` can finish it once the robot is fixed.
    """
    from bomc_bt.report import write_session_report

    robot.cancel_all()
    ctx.outcome, ctx.reason = "failed", " ".join(str(exc).split())
    write_session_report(ctx, close=False)


def run_build_ros(
    site_dir: str | Path,
    config: Config | None = None,
    *,
    max_time: float | None = None,
    explorer: str | None = None,
    tree: str | Path | None = None,
    quiet: bool = True,
    stream: TextIO = sys.stdout,
    hooks: list[Callable] = (),
    context_hooks: list[Callable] = (),
) -> MissionResult:
    """Explore with the build tree on the ROS robot (GMapping's /map, move_base); save the map."""
    from bomc_bt.build_record import build_summary, save_build
    from bomc_bt.ros.robot import RosRobot
    from bomc_bt.site import write_json

    import_ros()  # before anything is created: a missing ROS is a one-line error with the apt command
    config = config or build_config(robot="fetch")
    if explorer:
        config.exploration.explorer = explorer
    params = ros_params(config)
    site = Site(Path(site_dir)).create()
    robot = RosRobot(params, mode="build")
    try:
        ctx = MissionContext(robot=robot, config=config, site=site, mission="build", max_time=max_time)
        limit = max_time if max_time is not None else config.exploration.max_time
        result = run_tree(
            ctx,
            Path(tree) if tree else default_tree("build"),
            quiet=quiet,
            stream=stream,
            max_time=limit * 1.25 + 120.0,
            hooks=_hooks(robot, ctx, params, hooks),
            context_hooks=context_hooks,
            on_interrupt=save_build,
        )
        if ctx.trajectory is not None:
            ctx.trajectory.close()
        if not site.map_yaml.exists():
            save_build(ctx)
        result.summary = build_summary(ctx)
        result.summary["outcome"] = (
            "succeeded" if result.succeeded else ("interrupted" if result.interrupted else "failed")
        )
        write_json(site.build_json, result.summary)
        return result
    finally:
        robot.cancel_all()
        robot.close()


def run_monitor_ros(
    site_dir: str | Path,
    session: int,
    config: Config | None = None,
    *,
    seed: int = 0,
    tree: str | Path | None = None,
    resume: bool = False,
    quiet: bool = True,
    stream: TextIO = sys.stdout,
    hooks: list[Callable] = (),
    context_hooks: list[Callable] = (),
    max_time: float = 4 * 3600.0,
) -> MissionResult:
    """One monitoring pass on the ROS robot (map_server + AMCL + move_base + the head camera)."""
    from bomc_bt.graph import ObjectGraph
    from bomc_bt.grid import load_map
    from bomc_bt.monitoring import Perception
    from bomc_bt.report import session_summary, write_session_report
    from bomc_bt.ros.robot import RosRobot
    from bomc_bt.store import SiteStore

    if session < 1:
        raise BomcError("must be 1 or more", None, "--session")
    config = config or build_config(robot="fetch")
    params = ros_params(config)
    site = Site(Path(site_dir))
    site.require_build()
    grid = load_map(site.map_yaml)
    dock = dock_pose(site)
    categories = list(config.perception.categories)
    if not categories:  # no world to take them from
        raise BomcError(
            "set the objects to look for (perception.categories) when running on ROS",
            config.source[-1] if config.source else None,
            "perception.categories",
        )
    import_ros()
    store = SiteStore(site.store_path)
    robot = None
    try:
        check_session(store, session, resume, site.store_path)
        graph: ObjectGraph = store.load_graph(config.association)
        robot = RosRobot(params, mode="monitor")
        robot.use_map(grid)
        detector, segmenter = make_perception(
            config, seed, Path(config.source[-1]).parent if config.source else Path.cwd()
        )
        perception = Perception(
            detector,
            segmenter,
            categories,
            config.projection,
            graph,
            store,
            session,
            grid,
            occlusion_check=config.association.mode != "paper",
        )
        ctx = MissionContext(
            robot=robot,
            config=config,
            site=site,
            mission="monitor",
            session=session,
            seed=seed,
            store=store,
            graph=graph,
            perception=perception,
            dock=dock,
            resume=resume,
        )

        def interrupted(c: MissionContext) -> None:
            robot.cancel_all()
            c.outcome = "interrupted"
            write_session_report(c, close=False)

        try:
            result = run_tree(
                ctx,
                Path(tree) if tree else default_tree("monitor"),
                quiet=quiet,
                stream=stream,
                max_time=max_time,
                hooks=_hooks(robot, ctx, params, hooks),
                context_hooks=context_hooks,
                on_interrupt=interrupted,
            )
        except MissionFailed as exc:
            _report_failure(robot, ctx, exc)
            raise
        result.summary = session_summary(ctx)
        result.summary["outcome"] = ctx.outcome or ("interrupted" if result.interrupted else "failed")
        return result
    finally:
        if robot is not None:
            robot.cancel_all()
            robot.close()
        store.close()
