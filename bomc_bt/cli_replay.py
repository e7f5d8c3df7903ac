"""``bomc replay BAG --site DIR --session N [--rate R | --as-fast-as-possible]``.

Registers the subcommand's parser and runs it (:mod:`bomc_bt.replay`). Exit 0 when the
replay completed (problems with single frames are one line each on stderr, counted in
the report), 2 on bad input (no such bag, no usable frame, a bad rate), as every command.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(sub: argparse._SubParsersAction) -> None:
    r = sub.add_parser("replay", help="map from a recorded ROS 1 bag at the rate it was recorded (or --rate)")
    r.add_argument("bag", help="ROS 1 bag with RGB-D images, camera_info and tf (topics from the ros: section)")
    r.add_argument("--site", required=True, help="site directory (CONTRACTS 3): its map and object graph")
    r.add_argument("--session", type=int, required=True)
    r.add_argument("--seed", type=int, default=0, help="the simulated detector's seed (perception.backend: sim)")
    r.add_argument("--config", action="append", default=[], metavar="FILE",
                   help="extra config file layered over config/defaults.yaml (repeatable)")
    pace = r.add_mutually_exclusive_group()
    pace.add_argument("--rate", type=float, default=None,
                      help="frames arrive at R per second of wall time (default: at the recorded stamps)")
    pace.add_argument("--as-fast-as-possible", action="store_true",
                      help="process every frame, none dropped, no waiting")


def replay(args: argparse.Namespace) -> int:
    """Run ``bomc replay``; print the session line and return the exit code."""
    from bomc_bt.replay import run_replay
    from bomc_bt.run import build_config

    config = build_config(args.config)
    result = run_replay(Path(args.bag), args.site, args.session, config, rate=args.rate,
                        as_fast_as_possible=args.as_fast_as_possible, seed=args.seed)
    s, r = result.summary, result.summary["replay"]
    print(f"session {args.session} {s['outcome']} (replayed, {r['rate']}): {s['nodes']} nodes, "
          f"events {s['events']}; frames processed {r['processed']}, dropped {r['dropped']}, "
          f"skipped {r['skipped']} of {r['frames_in_bag']}; not-model cost {r['not_model_ms_per_frame']} ms/frame")
    return 0
