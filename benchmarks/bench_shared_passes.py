"""Monitor passes on the shared worlds with the perfect detector: pass sim time, path, F1.

Builds each world once per build seed, then monitors sessions 1..3 (seed n for session n)
and prints per session the pass's simulated time and path (the session's report) and the
object F1 (``evaluate_session``), as tests/test_missions.py does for lab-b:

    python benchmarks/bench_shared_passes.py --world lab-b --world office-s --build-seed 0 --build-seed 2
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from shared_folder import SHARED

from bomc_bt import run
from bomc_bt.evaluate_site import evaluate_session


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", action="append", default=[], metavar="NAME", help="a shared world (lab-b, office-s)")
    ap.add_argument("--build-seed", action="append", type=int, default=[], metavar="N", help="build seed (default 0)")
    ap.add_argument("--sessions", type=int, default=3)
    ap.add_argument("--shared", default=str(SHARED), help="shared folder")
    args = ap.parse_args(argv)
    print(f"{'world':10s} {'build':>5s} {'session':>7s} {'sim s':>8s} {'path m':>8s} {'F1':>6s}")
    for name in args.world or ["lab-b"]:
        world = Path(args.shared) / "worlds" / f"{name}.yaml"
        for seed in args.build_seed or [0]:
            with tempfile.TemporaryDirectory() as tmp:
                extra = Path(tmp) / "perfect.yaml"
                extra.write_text("detector: {preset: perfect}\n")
                config = run.build_config([str(extra)])
                site = Path(tmp) / "site"
                run.run_build(world, site, seed=seed, config=config)
                for n in range(1, args.sessions + 1):
                    run.run_monitor(world, site, n, seed=n, config=config)
                    report = json.loads((site / "sessions" / str(n) / "report.json").read_text())
                    f1 = evaluate_session(world, site, n, config).overall.f1
                    print(f"{name:10s} {seed:5d} {n:7d} {report['sim_time_s']:8.1f} {report['path_length_m']:8.1f} "
                          f"{f1:6.3f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
