"""``bomc``: the command line (CONTRACTS.md section 2).

Exit codes: 0 success, 1 the mission ran and failed (or was interrupted), 2 bad input
with a one-line message and no traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bomc_bt.errors import BomcError


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse's own usage errors: exit 2, one line
        self.print_usage(sys.stderr)
        print(f"bomc: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def parser() -> argparse.ArgumentParser:
    p = _Parser(prog="bomc", description="Build once, monitor continuously: a behaviour-tree mission executive.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def common(sp, world_required: bool = True) -> None:
        sp.add_argument("--world", required=world_required, help="simulation world file (YAML, CONTRACTS 1)")
        sp.add_argument("--site", required=True, help="site directory (CONTRACTS 3)")
        sp.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="extra config file layered over config/defaults.yaml (repeatable)")

    b = sub.add_parser("build", help="explore once and save the map")
    common(b)
    b.add_argument("--seed", type=int, default=0)
    b.add_argument("--max-time", type=float, default=None, help="simulated seconds (default: until done)")
    b.add_argument("--explorer", choices=["dwfe", "baseline"], default=None)
    b.add_argument("--tree", default=None, help="tree file (default trees/build.yaml)")
    b.add_argument("--viewer", action="store_true", help="serve the live viewer on 127.0.0.1")
    b.add_argument("--viewer-port", type=int, default=8765)
    b.add_argument("--quiet", action="store_true", help="no live tree view")
    b.add_argument("--ros", action="store_true", help="run against a ROS 1 robot instead of the simulator")

    m = sub.add_parser("monitor", help="one monitoring pass that updates the object graph")
    common(m)
    m.add_argument("--session", type=int, required=True)
    m.add_argument("--seed", type=int, default=0)
    m.add_argument("--tree", default=None, help="tree file (default trees/monitor.yaml)")
    m.add_argument("--resume", action="store_true", help="continue a pass that was killed")
    m.add_argument("--viewer", action="store_true")
    m.add_argument("--viewer-port", type=int, default=8765)
    m.add_argument("--quiet", action="store_true")
    m.add_argument("--ros", action="store_true")

    e = sub.add_parser("evaluate", help="score the graph after a session against the world's ground truth")
    common(e)
    e.add_argument("--session", type=int, required=True)
    e.add_argument("--json", action="store_true")

    d = sub.add_parser("demo", help="build once, then monitor sessions 1..3 and print the paper's tables")
    d.add_argument("--world", default=None, help="world file (default: lab-b from the shared worlds)")
    d.add_argument("--site", default="sites/demo")
    d.add_argument("--seed", type=int, default=0)
    d.add_argument("--sessions", type=int, default=3)
    d.add_argument("--config", action="append", default=[], metavar="FILE")
    d.add_argument("--quiet", action="store_true")

    c = sub.add_parser("config", help="print the effective configuration")
    c.add_argument("--config", action="append", default=[], metavar="FILE")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return _dispatch(args)
    except BomcError as exc:
        print(f"bomc: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("bomc: interrupted", file=sys.stderr)
        return 1


def _dispatch(args) -> int:
    from bomc_bt import run

    if args.command == "config":
        import yaml

        from bomc_bt.config import config_to_dict

        print(yaml.safe_dump(config_to_dict(run.build_config(args.config)), sort_keys=False), end="")
        return 0
    if getattr(args, "ros", False):
        raise BomcError("the ROS 1 backend is not available in this version", None, "--ros")
    if getattr(args, "viewer", False):
        raise BomcError("the live web viewer is not available in this version (the terminal view is)",
                        None, "--viewer")
    config = run.build_config(args.config)
    if args.command == "build":
        result = run.run_build(args.world, args.site, seed=args.seed, max_time=args.max_time,
                               explorer=args.explorer, tree=args.tree, config=config, quiet=args.quiet)
        s = result.summary
        print(f"build {s['outcome']}: {s['termination']} ({s['reason']}); explored {s['explored_area_m2']} m², "
              f"path {s['path_length_m']} m, {s['sim_time_s']} s simulated; map in {Path(args.site) / 'map.yaml'}")
        return 0 if result.succeeded else 1
    if args.command == "monitor":
        result = run.run_monitor(args.world, args.site, args.session, seed=args.seed, tree=args.tree,
                                 config=config, resume=args.resume, quiet=args.quiet)
        s = result.summary
        print(f"session {args.session} {s['outcome']}: {s['nodes']} nodes, events {s['events']}, "
              f"coverage {s['coverage']['fraction']:.0%}, waypoints missed {s['traversal'].get('missed', 0)}, "
              f"{s['sim_time_s']} s simulated")
        return 0 if result.succeeded else 1
    if args.command == "evaluate":
        from bomc_bt.evaluate_site import evaluate_session, format_result
        from bomc_bt.evaluation import to_json

        result = evaluate_session(args.world, args.site, args.session, config)
        print(json.dumps(to_json(result)) if args.json else format_result(result))
        return 0
    if args.command == "demo":
        from bomc_bt.demo import run_demo

        return run_demo(args.world, args.site, seed=args.seed, sessions=args.sessions, config=config,
                        quiet=args.quiet)
    raise BomcError(f"unknown command {args.command!r}")


if __name__ == "__main__":
    sys.exit(main())
