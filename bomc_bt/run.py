"""Wiring a mission: config, robot, site, tree and runner, for the CLI and for tests.

``run_build`` and ``run_monitor`` do what ``bomc build`` and ``bomc monitor`` do, minus
argument parsing and exit codes, so tick-simulation tests call them directly.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from bomc_bt.config import Config, load_config, resource_dir
from bomc_bt.errors import BomcError
from bomc_bt.mission import MissionContext
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


# -- build ---------------------------------------------------------------------------------
def run_build(world_path: str | Path, site_dir: str | Path, *, seed: int = 0, max_time: float | None = None,
              explorer: str | None = None, tree: str | Path | None = None, config: Config | None = None,
              quiet: bool = True, stream: TextIO = sys.stdout, hooks: list[Callable] = (),
              context_hooks: list[Callable] = ()) -> MissionResult:
    """Explore the world from its start pose with the build tree; the map is always saved."""
    from bomc_bt.build_record import build_summary, save_build
    from bomc_bt.sim.robot import SimRobot
    from bomc_bt.world import load_world

    config = config or build_config()
    if explorer:
        config.exploration.explorer = explorer
    world = load_world(world_path)
    site = Site(Path(site_dir)).create()
    robot = SimRobot(world, session=1, params=config.sim, seed=seed, mode="build")
    ctx = MissionContext(robot=robot, config=config, site=site, mission="build", seed=seed, max_time=max_time)
    limit = max_time if max_time is not None else config.exploration.max_time
    result = run_tree(ctx, Path(tree) if tree else default_tree("build"), quiet=quiet, stream=stream,
                      max_time=limit * 1.25 + 120.0, hooks=hooks, context_hooks=context_hooks,
                      on_interrupt=save_build)
    if ctx.trajectory is not None:
        ctx.trajectory.close()
    if not site.map_yaml.exists():  # a custom tree that never saved: never lose the map
        save_build(ctx)
    result.summary = build_summary(ctx)
    result.summary["outcome"] = "succeeded" if result.succeeded else ("interrupted" if result.interrupted else "failed")
    from bomc_bt.site import write_json

    write_json(site.build_json, result.summary)
    return result


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


def world_categories(world) -> list[str]:
    """Every category that appears in the world in any session (the sim's default prompts)."""
    cats = {o.category for o in world.objects.values()}
    for change in world.sessions.values():
        cats.update(o.category for o in change.add)
    for during in world.during:
        cats.update(o.category for o in during.change.add)
    return sorted(cats)


def parked_near(world, dock, seed: int, clearance: float, max_offset: float = 0.5, max_angle: float = 0.35):
    """Where the simulated robot really is at the start of a pass: near the dock, not on it.

    A robot parked by hand or by a previous run is off by decimetres and degrees; the
    monitor tree's relocalization has to find it from the dock pose. Seeded, and always
    on free floor with room for the robot.
    """
    import math

    import numpy as np

    from bomc_bt.geometry import Pose2D, wrap_angle

    rng = np.random.default_rng([seed, 4242])
    walls = world.walls()
    grid = world.grid
    for _ in range(50):
        r, a = max_offset * math.sqrt(rng.random()), rng.uniform(0.0, 2.0 * math.pi)
        x, y = dock.x + r * math.cos(a), dock.y + r * math.sin(a)
        rows, cols = grid.world_to_cell(x + clearance * np.cos(np.linspace(0, 6.28, 12)),
                                        y + clearance * np.sin(np.linspace(0, 6.28, 12)))
        inside = grid.in_bounds(rows, cols)
        if inside.all() and not walls[rows, cols].any():
            return Pose2D(x, y, wrap_angle(dock.yaw + rng.uniform(-max_angle, max_angle)))
    return dock


def check_session(store, session: int, resume: bool, store_path: Path) -> None:
    """Sessions run in order and history is never overwritten."""
    records = {s.number: s for s in store.sessions()}
    last = max(records, default=0)
    if session in records:
        if records[session].ended:
            raise BomcError(f"session {session} is already recorded (next is {last + 1}); history is never "
                            "overwritten", store_path, "--session")
        if not resume:
            raise BomcError(f"session {session} was started but not finished: add --resume to continue it",
                            store_path, "--session")
    elif session < last:
        raise BomcError(f"session {session} is older than the last recorded session {last}", store_path,
                        "--session")


def run_monitor(world_path: str | Path, site_dir: str | Path, session: int, *, seed: int = 0,
                tree: str | Path | None = None, config: Config | None = None, resume: bool = False,
                quiet: bool = True, stream: TextIO = sys.stdout, hooks: list[Callable] = (),
                context_hooks: list[Callable] = (), max_time: float = 4 * 3600.0) -> MissionResult:
    """One monitoring pass of session ``session`` in the simulator."""
    from bomc_bt.graph import ObjectGraph
    from bomc_bt.grid import load_map
    from bomc_bt.monitoring import Perception
    from bomc_bt.report import session_summary, write_session_report
    from bomc_bt.sim.camera import SimCamera
    from bomc_bt.sim.robot import SimRobot
    from bomc_bt.store import SiteStore
    from bomc_bt.world import load_world

    if session < 1:
        raise BomcError("must be 1 or more", None, "--session")
    config = config or build_config()
    world = load_world(world_path)
    site = Site(Path(site_dir))
    site.require_build()
    grid = load_map(site.map_yaml)
    store = SiteStore(site.store_path)
    try:
        check_session(store, session, resume, site.store_path)
        graph: ObjectGraph = store.load_graph(config.association)
        camera = SimCamera(config.camera, seed=seed)
        robot = SimRobot(world, session=session, params=config.sim, seed=seed, mode="monitor", camera=camera,
                         relocalization=config.relocalization,
                         start=parked_near(world, world.start, seed, config.sim.planner.robot_radius + 0.1))
        robot.use_map(grid)
        detector, segmenter = make_perception(config, seed, Path(config.source[-1]).parent)
        categories = config.perception.categories or world_categories(world)
        perception = Perception(detector, segmenter, categories, config.projection, graph, store, session, grid,
                                occlusion_check=config.association.mode != "paper")
        ctx = MissionContext(robot=robot, config=config, site=site, mission="monitor", session=session,
                             seed=seed, store=store, graph=graph, perception=perception,
                             dock=world.start, resume=resume)

        def interrupted(c: MissionContext) -> None:
            # Ctrl-C: stop the robot and write the report, but leave the session open in
            # the store so that `bomc monitor --resume` can finish it.
            robot.cancel_all()
            c.outcome = "interrupted"
            write_session_report(c, close=False)

        result = run_tree(ctx, Path(tree) if tree else default_tree("monitor"), quiet=quiet, stream=stream,
                          max_time=max_time, hooks=hooks, context_hooks=context_hooks,
                          on_interrupt=interrupted)
        result.summary = session_summary(ctx)
        result.summary["outcome"] = ctx.outcome or ("interrupted" if result.interrupted else "failed")
        return result
    finally:
        store.close()
