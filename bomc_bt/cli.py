"""``bomc``: the command line (CONTRACTS.md section 2).

Exit codes: 0 success, 1 the mission ran and failed (or was interrupted), 2 bad input
with a one-line message and no traceback.

``--ros`` runs ``build`` / ``monitor`` against a ROS 1 robot (:mod:`bomc_bt.ros`): there
is no world then, the robot is the world. ``bomc sim-ros`` serves the built-in simulator
through ROS, so the two together try the ROS path without a robot.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bomc_bt import cli_args as arg
from bomc_bt.errors import BomcError, MissionFailed


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse's own usage errors: exit 2, one line
        self.print_usage(sys.stderr)
        print(f"bomc: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def parser() -> argparse.ArgumentParser:
    p = _Parser(prog="bomc", description="Build once, monitor continuously: a behaviour-tree mission executive.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def common(sp, world_required: bool = True) -> None:
        sp.add_argument("--world", required=world_required,
                        help="simulation world file (YAML, CONTRACTS 1)" + ("" if world_required else
                                                                             "; not with --ros"))
        sp.add_argument("--site", required=True, help="site directory (CONTRACTS 3)")
        sp.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="extra config file layered over config/defaults.yaml (repeatable)")

    b = sub.add_parser("build", help="explore once and save the map")
    common(b, world_required=False)
    b.add_argument("--seed", type=arg.seed, default=0)
    b.add_argument("--max-time", type=float, default=None, help="simulated seconds (default: until done)")
    b.add_argument("--explorer", choices=["gain", "dwfe", "baseline"], default=None)
    b.add_argument("--tree", default=None, help="tree file (default trees/build.yaml)")
    b.add_argument("--new-map", action="store_true",
                   help="re-build a site that has an object graph: archive the graph with its map (README: Sites)")
    b.add_argument("--viewer", action="store_true", help="serve the live viewer on 127.0.0.1")
    b.add_argument("--viewer-port", type=arg.port, default=8765)
    b.add_argument("--quiet", action="store_true", help="no live tree view")
    b.add_argument("--ros", action="store_true", help="run against a ROS 1 robot instead of the simulator")

    m = sub.add_parser("monitor", help="one monitoring pass that updates the object graph")
    common(m, world_required=False)
    m.add_argument("--session", type=arg.session, required=True)
    m.add_argument("--seed", type=arg.seed, default=0)
    m.add_argument("--tree", default=None, help="tree file (default trees/monitor.yaml)")
    m.add_argument("--resume", action="store_true", help="continue a pass that was killed")
    m.add_argument("--budget", type=arg.budget, default=None, help="robot seconds for the pass (default: a full pass)")
    m.add_argument("--viewer", action="store_true")
    m.add_argument("--viewer-port", type=arg.port, default=8765)
    m.add_argument("--quiet", action="store_true")
    m.add_argument("--ros", action="store_true", help="run against a ROS 1 robot instead of the simulator")

    e = sub.add_parser("evaluate", help="score the graph after a session against the world's ground truth")
    common(e)
    e.add_argument("--session", type=arg.session, required=True)
    e.add_argument("--json", action="store_true")

    d = sub.add_parser("demo", help="build once, then monitor sessions 1..3 and print the paper's tables")
    d.add_argument("--world", default=None, help="world file (default: lab-b from the shared worlds)")
    d.add_argument("--site", default="sites/demo")
    d.add_argument("--seed", type=arg.seed, default=0)
    d.add_argument("--sessions", type=arg.session_count, default=3)
    d.add_argument("--config", action="append", default=[], metavar="FILE")
    d.add_argument("--quiet", action="store_true")

    w = sub.add_parser("world", help="generate a simulation world (CONTRACTS 1)")
    kinds = w.add_subparsers(dest="kind", required=True, parser_class=_Parser)
    o = kinds.add_parser("office", help="an office floor of any size with sessions of changes")
    o.add_argument("--out", required=True, help="world file to write (NAME.yaml; the map goes beside it)")
    o.add_argument("--size", default="93x90", help="floor size WxH in metres (default 93x90, Environment A)")
    o.add_argument("--seed", type=arg.seed, default=0)
    o.add_argument("--sessions", type=int, default=3)
    o.add_argument("--churn", type=float, default=None,
                   help="share of movable objects changed before each session (default 0.05)")
    o.add_argument("--static", action="store_true", help="nothing ever changes (all sessions identical)")
    o.add_argument("--corridor-chairs", type=int, default=0, metavar="N",
                   help="sessions N, 2N, ... leave a chair in the middle of a corridor (default 0: never)")
    o.add_argument("--resolution", type=float, default=0.05,
                   help="map metres per cell, 0.02 to 0.1 (walls are drawn at least two cells thick)")
    o.add_argument("--hot-rooms", type=float, default=0.0, help="share of rooms where most changes happen (default 0)")
    o.add_argument("--force", action="store_true", help="replace existing files")
    from bomc_bt.worldgen_cli import add_parser as add_map_world

    add_map_world(kinds, _Parser)

    v = sub.add_parser("view", help="browse a finished site in the web viewer")
    v.add_argument("site", help="site directory")
    v.add_argument("--port", type=arg.port, default=8765)
    v.add_argument("--no-browser", action="store_true", help="only print the address")

    c = sub.add_parser("config", help="print the effective configuration")
    c.add_argument("--config", action="append", default=[], metavar="FILE")
    c.add_argument("--defaults", action="store_true", help="the code's defaults (config/defaults.yaml)")
    c.add_argument("--trees", action="store_true", help="the leaf parameters written in the shipped trees")

    from bomc_bt import cli_site

    cli_site.add_parsers(sub, _Parser)  # objects, changes, export, publish, edit
    from bomc_bt.cli_replay import add_parser as add_replay

    add_replay(sub)

    from bomc_bt.cli_fleet import add_fleet_commands

    add_fleet_commands(sub)  # sync, pull: the central store
    # Parsed by the bridge itself (main() hands it the rest of the line); listed for --help.
    sub.add_parser("sim-ros", add_help=False,
                   help="serve the simulator over ROS 1 for --ros (bomc sim-ros --help for its options)")
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] == "sim-ros":
        from bomc_bt.ros.bridge import main as sim_ros

        return sim_ros(argv[1:])
    p = parser()
    args = p.parse_args(argv)
    if args.command in ("build", "monitor"):
        if args.ros and args.world:
            p.error("--world is for the simulator: with --ros the robot is the world "
                    "(give the world to `bomc sim-ros --world` instead)")
        if not args.ros and not args.world:
            p.error("the following arguments are required: --world (or --ros for a ROS 1 robot)")
    try:
        return _dispatch(args)
    except BomcError as exc:
        print(f"bomc: error: {exc}", file=sys.stderr)
        return 2
    except MissionFailed as exc:  # the robot could not go on (ROS: no camera_info, a dead /clock, ...)
        print(f"bomc: mission failed: {_one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("bomc: interrupted", file=sys.stderr)
        return 1
    except OSError as exc:  # out of disk, permission taken away mid-run: what was saved stays saved
        where = f" ({exc.filename})" if exc.filename else ""
        print(f"bomc: failed: {exc.strerror or _one_line(exc)}{where}; the site keeps what was saved before",
              file=sys.stderr)
        return 1


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _config(args) -> int:
    """``bomc config``: the effective configuration, the code's defaults, or the trees' parameters."""
    from bomc_bt.config import EFFECTIVE_HEADER, defaults_yaml, load_config, resource_dir
    from bomc_bt.config_docs import documented_yaml

    if args.trees:
        from bomc_bt.config_trees import trees_yaml

        print(trees_yaml(resource_dir("trees")), end="")
    elif args.defaults:
        print(defaults_yaml(), end="")
    else:
        config = load_config(args.config)
        print(EFFECTIVE_HEADER.format(files=", ".join(config.source)) + documented_yaml(config), end="")
    return 0


def _dispatch(args) -> int:
    from bomc_bt import run

    if args.command == "config":
        return _config(args)
    if args.command in ("build", "monitor"):
        return _mission(args)
    if args.command == "view":
        return _view(args)
    if args.command in ("objects", "changes", "export", "publish", "edit"):
        from bomc_bt import cli_site

        return cli_site.run(args)
    if args.command == "replay":
        from bomc_bt.cli_replay import replay

        return replay(args)
    if args.command in ("sync", "pull"):
        from bomc_bt.cli_fleet import run_fleet_command

        return run_fleet_command(args)
    if args.command == "world":
        if args.kind == "map":
            from bomc_bt.worldgen_cli import generate_from_args
        else:
            from bomc_bt.officegen.cli import generate_from_args

        print(generate_from_args(args))
        return 0
    config = run.build_config(args.config)
    if args.command == "evaluate":
        from bomc_bt.evaluate_changes import changes_to_json, evaluate_changes, format_changes
        from bomc_bt.evaluate_site import evaluate_session, format_result
        from bomc_bt.evaluation import to_json

        result = evaluate_session(args.world, args.site, args.session, config)
        changes = evaluate_changes(args.world, args.site, args.session, config)
        if args.json:
            print(json.dumps({**to_json(result), "changes": changes_to_json(changes)}))
        else:
            print(format_result(result) + "\n\n" + format_changes(changes))
        return 0
    if args.command == "demo":
        from bomc_bt.demo import run_demo

        return run_demo(args.world, args.site, seed=args.seed, sessions=args.sessions, config=config,
                        quiet=args.quiet)
    raise BomcError(f"unknown command {args.command!r}")


def _mission(args) -> int:
    """``build`` / ``monitor``: one mission runner, given the simulator or (``--ros``) a ROS 1 robot."""
    from bomc_bt import run

    if args.ros:
        from bomc_bt.ros.missions import RosRobots

        config, robots = run.build_config(args.config, robot="fetch"), RosRobots()
    else:
        from bomc_bt.sim.factory import SimRobots

        config, robots = run.build_config(args.config), SimRobots(args.world, args.seed)
    if getattr(args, "budget", None):
        config.budget.seconds = args.budget
    hooks, server = _live_viewer(args)
    try:
        if args.command == "build":
            # A ROS build has nothing seeded: its build record keeps seed 0.
            result = run.run_build_mission(robots, args.site, config=config, seed=0 if args.ros else args.seed,
                                           max_time=args.max_time, explorer=args.explorer, tree=args.tree,
                                           quiet=args.quiet, context_hooks=hooks, new_map=args.new_map)
        else:
            result = run.run_monitor_mission(robots, args.site, args.session, config=config, seed=args.seed,
                                             tree=args.tree, resume=args.resume, quiet=args.quiet,
                                             context_hooks=hooks)
    finally:
        _close(server)
    if args.command == "build":
        print(result.site_note, file=sys.stderr)
        return _report_build(result, args.site)
    return _report_monitor(result, args.session)


def _report_build(result, site: str) -> int:
    """One summary line of a build (simulator or ROS) and its exit code."""
    s = result.summary
    print(f"build {s['outcome']}: {s['termination']} ({s['reason']}); explored {s['explored_area_m2']} m², "
          f"path {s['path_length_m']} m, {s['sim_time_s']} s robot time; map in {Path(site) / 'map.yaml'}")
    left = s.get("frontiers_left") or {}
    if s["outcome"] == "incomplete":  # the map is saved, but exploration did not finish: exit 1
        print(f"bomc: build incomplete ({s['termination']}): {left.get('reachable', '?')} reachable frontier(s), "
              f"{left.get('reachable_m', '?')} m of unexplored border left; the partial map was saved",
              file=sys.stderr)
    return 0 if result.succeeded else 1


def _report_monitor(result, session: int) -> int:
    """One summary line of a monitor pass (simulator or ROS) and its exit code."""
    s = result.summary
    print(f"session {session} {s['outcome']}: {s['nodes']} nodes, events {s['events']}, "
          f"coverage {s['coverage']['fraction']:.0%}, waypoints missed {s['traversal'].get('missed', 0)}, "
          f"detoured {s['traversal'].get('detoured', 0)}, {s['sim_time_s']} s robot time"
          + (f"; {s['reason']}" if s.get("outcome") == "ended_early" and s.get("reason") else ""))
    return 0 if result.succeeded else 1


def _live_viewer(args):
    """With --viewer: serve the live page and return the hook factory that feeds it."""
    if not getattr(args, "viewer", False):
        return [], None
    from bomc_bt.viewer import serve_live

    server, factory = serve_live(args.viewer_port)
    print(f"viewer: {server.url}", file=sys.stderr)
    return [factory], server


def _close(server) -> None:
    if server is not None:
        server.close()


def _view(args) -> int:
    """``bomc view SITE``: serve the finished site until Ctrl-C."""
    import time
    import webbrowser

    from bomc_bt.viewer import serve_site

    server = serve_site(args.site, args.port)
    print(f"viewer: {server.url} (Ctrl-C to stop)")
    if not args.no_browser:
        webbrowser.open(server.url)
    try:
        while True:  # short naps: a Ctrl-C the kernel hands to a server thread ends the wait too
            time.sleep(0.5)
    except KeyboardInterrupt:
        return 0
    finally:
        server.close()


if __name__ == "__main__":
    sys.exit(main())
