"""The mission runner: config, site, store, perception, tree and run, for any robot.

A mission is wired once here, by :func:`run_build_mission` and :func:`run_monitor_mission`;
what differs between the simulator and a ROS robot (how the robot is made, where the dock
is, which objects to look for, what to let go of at the end) comes from a
:class:`RobotFactory` (:class:`bomc_bt.sim.factory.SimRobots`,
:class:`bomc_bt.ros.missions.RosRobots`). ``run_build`` and ``run_monitor`` do what
``bomc build`` and ``bomc monitor`` do in the simulator, minus argument parsing and exit
codes, so tick-simulation tests call them directly.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, TextIO

from bomc_bt.config import Config, load_config, resource_dir
from bomc_bt.errors import BomcError, MissionFailed
from bomc_bt.geometry import Pose2D
from bomc_bt.mission import MissionContext
from bomc_bt.robot import RobotPort
from bomc_bt.site import Site
from bomc_bt.tree.loader import load_tree
from bomc_bt.tree.runner import TreeRunner
from bomc_bt.tree.view import TerminalView


@dataclass
class MissionResult:
    """How a mission run ended."""

    succeeded: bool
    reason: str
    sim_time: float
    ticks: int
    summary: dict[str, Any] = field(default_factory=dict)
    interrupted: bool = False
    context: MissionContext | None = None
    site_note: str = ""  # where a build's map went (bomc_bt.generations): current, or kept aside


def default_tree(name: str) -> Path:
    return resource_dir("trees") / f"{name}.yaml"


def build_config(config_files: list[str] = (), robot: str = "sim") -> Config:
    """The validated configuration: defaults, the robot's file, then ``config_files``."""
    return load_config(list(config_files), robot=robot)


def progress_line(ctx: MissionContext) -> str:
    p = ctx.progress
    parts = [f"t={ctx.now():7.1f} s"]
    if ctx.mission == "build":
        parts += [f"explored {p.explored_area:7.1f} m²", f"path {p.path_length:6.1f} m"]
        if ctx.explorer is not None:
            parts.append(f"goals {ctx.explorer.goals}")
    else:
        parts += [f"waypoint {p.waypoint}/{p.waypoints}", f"frames {p.frames}", f"nodes {p.nodes}",
                  f"path {p.path_length:6.1f} m"]
    if p.message:
        parts.append(p.message)
    return "  ".join(parts)


def run_tree(ctx: MissionContext, tree_path: Path, *, quiet: bool = True, stream: TextIO = sys.stdout,
             max_time: float | None = None, hooks: list[Callable] = (),
             context_hooks: list[Callable[[MissionContext], Callable]] = (),
             on_interrupt: Callable[[MissionContext], None] | None = None) -> MissionResult:
    """Load ``tree_path`` with ``ctx`` and tick it against ``ctx.robot`` until it ends.

    ``hooks`` are called as ``hook(runner)`` after every tick; ``context_hooks`` are
    factories called once with the mission context that return such a hook (the viewer).
    """
    from bomc_bt.tree.registry import load_registry

    root = load_tree(tree_path, load_registry(), ctx, clock=ctx.robot.now)
    on_tick = list(hooks) + [factory(ctx) for factory in context_hooks]
    view = None
    if not quiet:
        view = TerminalView(stream, progress=lambda: progress_line(ctx))
        on_tick.append(view)
    runner = TreeRunner(root, ctx.robot, max_time=max_time, on_tick=_chain(on_tick))
    previous = _install_sigint(runner)
    try:
        result = runner.run()
    finally:
        _restore_sigint(previous)
        if view is not None:
            view.close()
    interrupted = result.reason == "stopped"
    if interrupted and on_interrupt is not None:
        on_interrupt(ctx)
    succeeded = result.status.name == "SUCCESS"
    reason = ctx.reason or result.reason
    return MissionResult(succeeded, reason, ctx.now(), result.ticks, interrupted=interrupted, context=ctx)


def _chain(hooks: list[Callable]) -> Callable | None:
    if not hooks:
        return None

    def on_tick(runner) -> None:
        for hook in hooks:
            hook(runner)

    return on_tick


def _install_sigint(runner: TreeRunner):
    try:
        return signal.signal(signal.SIGINT, lambda *_: runner.request_stop())
    except ValueError:  # not the main thread (tests): no handler
        return None


def _restore_sigint(previous) -> None:
    if previous is not None:
        signal.signal(signal.SIGINT, previous)


class RobotFactory(Protocol):
    """What the mission runner asks of a kind of robot (simulator, ROS); it does the rest."""

    def default_config(self) -> Config:
        """The configuration when none is given (defaults and the robot's file)."""

    def connect(self) -> None:
        """Make sure the robot can be reached at all (ROS: rospy imports), before any file is touched."""

    def prepare(self, config: Config) -> None:
        """Read what the robot needs from ``config`` and its inputs (a world), failing early."""

    def build_robot(self, config: Config) -> RobotPort:
        """The robot of a build mission, at its start pose."""

    def monitor_robot(self, config: Config, session: int) -> RobotPort:
        """The robot of monitoring pass ``session``, camera included (the saved map comes next)."""

    def dock(self, site: Site) -> Pose2D:
        """Where the build started: the pass's relocalization hint and its way home."""

    def categories(self, config: Config) -> list[str]:
        """The prompts of the detector: the objects the pass looks for."""

    def mission_hooks(self, ctx: MissionContext) -> list[Callable]:
        """Extra per-tick hooks of this robot (ROS: the RViz publisher)."""

    def release(self, robot: RobotPort) -> None:
        """Let go of the robot after the mission, whatever happened (ROS: cancel, unsubscribe)."""


def perception_base_dir(config: Config) -> Path:
    """The folder relative model paths are read from: the last config file's."""
    return Path(config.source[-1]).parent if config.source else Path.cwd()


# -- build ---------------------------------------------------------------------------------
def run_build_mission(factory: RobotFactory, site_dir: str | Path, *, config: Config | None = None,
                      seed: int = 0, max_time: float | None = None, explorer: str | None = None,
                      tree: str | Path | None = None, quiet: bool = True, stream: TextIO = sys.stdout,
                      hooks: list[Callable] = (), context_hooks: list[Callable] = (),
                      new_map: bool = False) -> MissionResult:
    """Explore from the robot's start pose with the build tree; the map is always saved.

    It is saved into a new map generation, made current only when the build succeeds
    (:mod:`bomc_bt.generations`); ``new_map`` allows that over a site that has a graph.
    """
    from bomc_bt.build_record import build_summary, save_build
    from bomc_bt.generations import begin_build
    from bomc_bt.mission_trees import check_mission_tree
    from bomc_bt.site import write_json

    if max_time is not None and not 0.0 < max_time < 1e9:
        raise BomcError(f"must be a positive number of seconds, got {max_time}", None, "--max-time")
    factory.connect()
    config = config or factory.default_config()
    if explorer:
        config.exploration.explorer = explorer
    factory.prepare(config)
    check_mission_tree(Path(tree) if tree else default_tree("build"), "build")
    build = begin_build(Path(site_dir), new_map=new_map)  # locked; writes only into a new generation
    site = build.site
    robot = None
    try:
        robot = factory.build_robot(config)
        ctx = MissionContext(robot=robot, config=config, site=site, mission="build", seed=seed, max_time=max_time)
        # No limit unless the user set one (--max-time, exploration.max_time > 0): the explorer
        # ends by itself (done, no_progress, stuck). The tree runner's limit is only a backstop
        # past the explorer's own, for a custom tree that never checks it.
        limit = max_time if max_time is not None else config.exploration.time_limit
        limit = limit if limit is not None and limit > 0 else None
        result = run_tree(ctx, Path(tree) if tree else default_tree("build"), quiet=quiet, stream=stream,
                          max_time=None if limit is None else limit + 120.0,
                          hooks=list(hooks) + factory.mission_hooks(ctx), context_hooks=context_hooks,
                          on_interrupt=save_build)
        if result.reason == "time limit" and ctx.explorer is not None and ctx.explorer.status == "exploring":
            ctx.explorer.status, ctx.explorer.reason = "time_limit", f"time limit of {limit:.0f} s reached"
        if not site.map_yaml.exists():  # a custom tree that never saved: never lose the map
            save_build(ctx)
        if ctx.trajectory is not None:
            ctx.trajectory.close()
        result.summary = build_summary(ctx)
        result.summary["outcome"] = build_outcome(result, result.summary["termination"])
        write_json(site.build_json, result.summary)
        build.finish(result.succeeded)
        result.site_note = build.note()
        return result
    finally:
        if robot is not None:
            factory.release(robot)
        build.close()


def build_outcome(result: MissionResult, termination: str) -> str:
    """``succeeded`` (exploration done), ``incomplete`` (a time limit or the progress guard
    cut it short: the map is saved but has unexplored border), ``interrupted`` or ``failed``."""
    if result.interrupted:
        return "interrupted"
    if result.succeeded:
        return "succeeded"
    return "incomplete" if termination in ("time_limit", "no_progress") else "failed"


def run_build(world_path: str | Path, site_dir: str | Path, *, seed: int = 0, max_time: float | None = None,
              explorer: str | None = None, tree: str | Path | None = None, config: Config | None = None,
              quiet: bool = True, stream: TextIO = sys.stdout, hooks: list[Callable] = (),
              context_hooks: list[Callable] = (), new_map: bool = False) -> MissionResult:
    """Explore the world from its start pose with the build tree in the simulator."""
    from bomc_bt.sim.factory import SimRobots

    return run_build_mission(SimRobots(world_path, seed), site_dir, config=config, seed=seed, max_time=max_time,
                             explorer=explorer, tree=tree, quiet=quiet, stream=stream, hooks=hooks,
                             context_hooks=context_hooks, new_map=new_map)


# -- monitor -------------------------------------------------------------------------------
def make_perception(config: Config, seed: int, base_dir: Path):
    """The detector and segmenter named by ``perception.backend``."""
    if config.perception.backend == "onnx":
        from bomc_bt.params import from_mapping
        from bomc_bt.perception.onnx_backend import OnnxPerceptionParams, build_onnx_backend

        params = from_mapping(OnnxPerceptionParams, config.perception.onnx, config.source[-1], "perception.onnx")
        return build_onnx_backend(params, base_dir)
    from bomc_bt.sim.detector import SimDetector

    detector = SimDetector(config.detector, seed=seed)
    return detector, detector


def check_session(store, session: int, resume: bool, store_path: Path, seed: int | None = None,
                  world_last: int = 1) -> None:
    """Sessions run in order and history is never overwritten; a resumed pass keeps its seed
    (the continued pass draws from the same random streams)."""
    records = {s.number: s for s in store.sessions()}
    last = max(records, default=0)
    if session in records:
        if records[session].ended:
            raise BomcError(f"session {session} is already recorded (next is {last + 1}); history is never "
                            "overwritten", store_path, "--session")
        if not resume:
            raise BomcError(f"session {session} was started but not finished: add --resume to continue it",
                            store_path, "--session")
        started = records[session].info.get("seed") if isinstance(records[session].info, dict) else None
        if seed is not None and isinstance(started, int) and started != seed:
            raise BomcError(f"session {session} was started with --seed {started}; resume it with --seed {started}",
                            store_path, "--seed")
    elif session < last:
        raise BomcError(f"session {session} is older than the last recorded session {last}", store_path,
                        "--session")
    elif session > max(last, world_last) + 1:
        raise BomcError(f"session {session} is beyond what the site and the world hold (the site's last is {last}, "
                        f"the world's {world_last}): the next is {last + 1}", store_path, "--session")


def run_monitor_mission(factory: RobotFactory, site_dir: str | Path, session: int, *,
                        config: Config | None = None, seed: int = 0, tree: str | Path | None = None,
                        resume: bool = False, quiet: bool = True, stream: TextIO = sys.stdout,
                        hooks: list[Callable] = (), context_hooks: list[Callable] = (),
                        max_time: float = 4 * 3600.0) -> MissionResult:
    """One monitoring pass of session ``session`` that updates the site's object graph."""
    from bomc_bt.first_seen import seen_before_for
    from bomc_bt.generations import lock_for_monitor
    from bomc_bt.grid import load_map
    from bomc_bt.mission_trees import check_mission_tree
    from bomc_bt.monitoring import Perception
    from bomc_bt.pass_resume import restore_pass
    from bomc_bt.report import session_summary
    from bomc_bt.store import SiteStore
    from bomc_bt.timeline import TimelineRecorder

    if session < 1:
        raise BomcError("must be 1 or more", None, "--session")
    config = config or factory.default_config()
    factory.prepare(config)
    check_mission_tree(Path(tree) if tree else default_tree("monitor"), "monitor")
    lock = lock_for_monitor(Path(site_dir))  # one writer for the whole pass (bomc_bt.site_lock)
    store = robot = lease = None
    try:
        site = Site(Path(site_dir))  # after the lock: the current generation, read once
        site.require_build()
        grid = load_map(site.map_yaml)
        dock = factory.dock(site)
        categories = factory.categories(config)
        factory.connect()
        store = SiteStore(site.store_path)
        store.verify()  # a corrupt store is refused before the pass writes anything
        world = getattr(factory, "world", None)  # the simulator's: sessions it describes
        check_session(store, session, resume, site.store_path, seed, getattr(world, "last_session", 1))
        lease = _floor_lease(site, store, config)  # a fleet site: one pass per floor (bomc_bt.central.lease)
        graph = store.load_graph(config.association)
        robot = factory.monitor_robot(config, session)
        robot.use_map(grid)
        detector, segmenter = make_perception(config, seed, perception_base_dir(config))
        perception = Perception(detector, segmenter, categories, config.projection, graph, store, session, grid,
                                occlusion_check=config.association.mode != "paper", robot=robot,
                                near_range=config.budget.view_range,
                                seen_before=seen_before_for(store, session, grid, config.association))
        restored = resume and restore_pass(store, session, robot, perception)  # bomc_bt.pass_resume
        ctx = MissionContext(robot=robot, config=config, site=site, mission="monitor", session=session,
                             seed=seed, store=store, graph=graph, perception=perception, dock=dock, resume=resume,
                             restored=restored)
        timeline = TimelineRecorder.open(ctx)  # sessions/<n>/timeline.jsonl for replay; None when off
        try:
            result = run_tree(ctx, Path(tree) if tree else default_tree("monitor"), quiet=quiet, stream=stream,
                              max_time=max_time, context_hooks=context_hooks, on_interrupt=_pass_interrupted,
                              hooks=[*hooks, *factory.mission_hooks(ctx), *([timeline] if timeline else [])])
        except MissionFailed as exc:
            _pass_failed(ctx, exc)
            raise
        finally:
            if timeline is not None:
                timeline.close()
        result.summary = session_summary(ctx)
        result.summary["outcome"] = ctx.outcome or ("interrupted" if result.interrupted else "failed")
        return result
    finally:
        if robot is not None:
            factory.release(robot)
        if store is not None:
            store.close()
        if lease is not None:
            lease.release()
        lock.release()


def _floor_lease(site: Site, store, config: Config):
    """The floor's lease when the site is part of a fleet (site.json names a central store), else None."""
    from bomc_bt.site import current_generation

    if not (site.root / "site.json").exists():
        return None
    from bomc_bt.central.lease import take_floor_lease

    sessions = {s.number for s in store.sessions()}
    return take_floor_lease(site.root, config.central, sessions, current_generation(site.root) or 1)


def _pass_interrupted(ctx: MissionContext) -> None:
    """Ctrl-C: stop the robot and write the report, but leave the session open in the store
    so that `bomc monitor --resume` can finish it."""
    from bomc_bt.report import write_session_report

    ctx.robot.cancel_all()
    ctx.outcome = "interrupted"
    write_session_report(ctx, close=False)


def _pass_failed(ctx: MissionContext, exc: MissionFailed) -> None:
    """The robot could not go on (ROS: no camera_info, a dead /clock): stop it and write the report.

    The report of what the pass saw before is what tells the operator what happened. The
    session stays open in the store, as after Ctrl-C, so that ``--resume`` can finish it
    once the robot is fixed.
    """
    from bomc_bt.report import write_session_report

    ctx.robot.cancel_all()
    ctx.outcome, ctx.reason = "failed", " ".join(str(exc).split())
    write_session_report(ctx, close=False)


def run_monitor(world_path: str | Path, site_dir: str | Path, session: int, *, seed: int = 0,
                tree: str | Path | None = None, config: Config | None = None, resume: bool = False,
                quiet: bool = True, stream: TextIO = sys.stdout, hooks: list[Callable] = (),
                context_hooks: list[Callable] = (), max_time: float = 4 * 3600.0) -> MissionResult:
    """One monitoring pass of session ``session`` in the simulator."""
    from bomc_bt.sim.factory import SimRobots

    return run_monitor_mission(SimRobots(world_path, seed), site_dir, session, config=config, seed=seed,
                               tree=tree, resume=resume, quiet=quiet, stream=stream, hooks=hooks,
                               context_hooks=context_hooks, max_time=max_time)

