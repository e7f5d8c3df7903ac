"""Calibrate ``budget.speed`` and ``budget.heading_time`` from measured budgeted passes.

A budgeted tour is planned as ``metres / speed + headings * heading_time`` seconds of
robot time (:mod:`bomc_bt.budget_pass`), each heading a waypoint (the dock at the end is
one more). This script measures what waypoints really take: on generated offices
(``--sizes``, each built and mapped by one full pass) it runs one budgeted pass per
budget share and strategy, each on its own copy of the site, records for every waypoint
the robot time from handing it out to handing out the next (driving, turning, Look Around)
and the grid path length of its leg, and fits ``time = metres / speed + heading_time`` by
least squares over all waypoints. It prints each pass (planned, used, budget) and the
fitted values, with the upper quantile of the per-waypoint residual (what the runtime
guard must allow for), and, for comparison, a fit with one more term, a time per stop
arrived at (a waypoint whose leg is longer than ``ARRIVAL_M``; a stop's further headings
are turns on the spot), which the planner does not use: on the offices it lowered the
residual little.

    python benchmarks/calibrate_budget.py --sizes 24x20,30x24 --shares 15,25,40,60
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt import run  # noqa: E402
from bomc_bt.cli import main as bomc  # noqa: E402
from bomc_bt.grid import load_map  # noqa: E402
from bomc_bt.planner import GridPlanner  # noqa: E402
from bomc_bt.store import SiteStore  # noqa: E402


def measure(size: str, seed: int, shares: list[float], strategies: list[str], root: Path) -> list[tuple]:
    world = root / size / "office.yaml"
    if bomc(["world", "office", "--out", str(world), "--size", size, "--seed", str(seed), "--sessions", "3",
             "--hot-rooms", "0.15", "--force"]):
        raise SystemExit(2)
    base = root / size / "base"
    run.run_build(world, base, seed=seed)
    full_s = run.run_monitor(world, base, 1, seed=seed).sim_time
    rows, legs = [], []
    for share in shares:
        for strategy in strategies:
            site = root / size / f"{strategy}-{share:g}"
            shutil.copytree(base, site)
            config = run.build_config([])
            config.budget.seconds, config.budget.strategy = round(share / 100 * full_s, 1), strategy
            ticks: list[tuple[float, int | None, tuple[float, float] | None]] = []

            def record(ctx, ticks=ticks):
                def on_tick(*_):
                    pose = ctx.robot.pose()
                    current = ctx.traverse.current if ctx.traverse is not None else None
                    ticks.append((ctx.now(), current, None if pose is None else (pose.x, pose.y)))
                return on_tick

            used = run.run_monitor(world, site, 2, seed=seed, config=config, context_hooks=[record]).sim_time
            legs += waypoint_legs(ticks, GridPlanner(load_map(site / "map.yaml"), config.sim.planner))
            with SiteStore(site, readonly=True) as store:
                b = next(s for s in store.sessions() if s.number == 2).report["budget"]
            rows.append((size, strategy, share, b["seconds"], b["planned_s"], used, b["planned_m"], b["headings"],
                         b.get("elapsed", 0.0)))
            print(f"{size} {strategy}@{share:g}%: budget {b['seconds']:.0f} s, planned {b['planned_s']:.0f} s "
                  f"({b['planned_m']:.1f} m, {b['headings']} headings), used {used:.1f} s", flush=True)
    return rows, legs


def waypoint_legs(ticks: list[tuple], planner: GridPlanner) -> list[tuple[float, float]]:
    """(metres driven on the map's grid, robot seconds) per waypoint: from the tick it was
    handed out to the tick the next one was (the last one: to the end of the pass)."""
    out = []
    starts = [k for k in range(1, len(ticks)) if ticks[k][1] is not None and ticks[k][1] != ticks[k - 1][1]]
    for a, b in zip(starts, [*starts[1:], len(ticks) - 1], strict=True):
        p, q = ticks[a][2], ticks[b][2]
        if p is None or q is None:
            continue
        d = planner.distance(p, q)
        out.append((d if math.isfinite(d) else math.dist(p, q), ticks[b][0] - ticks[a][0]))
    return out


ARRIVAL_M = 0.3  # [m] a waypoint whose leg is longer arrives at a new stop; shorter: a turn on the spot


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--sizes", default="24x20,30x24")
    p.add_argument("--seed", type=int, default=5)
    p.add_argument("--shares", default="15,25,40,60", help="budgets, percent of the full pass")
    p.add_argument("--strategies", default="expected_changes,uniform")
    args = p.parse_args(argv)
    root = Path(tempfile.mkdtemp(prefix="calibrate_budget_"))
    rows, legs = [], []
    for size in args.sizes.split(","):
        r, g = measure(size, args.seed, [float(s) for s in args.shares.split(",")], args.strategies.split(","), root)
        rows, legs = rows + r, legs + g
    leg = np.array(legs, dtype=float)
    a = np.stack([leg[:, 0], np.ones(len(leg))], axis=1)
    (per_m, per_heading), *_ = np.linalg.lstsq(a, leg[:, 1], rcond=None)
    residual = leg[:, 1] - a @ np.array([per_m, per_heading])
    print(f"\nfit over {len(leg)} waypoints of {len(rows)} passes: speed {1 / per_m:.3f} m/s, heading_time "
          f"{per_heading:.2f} s; residual 90 % quantile {np.quantile(residual, 0.9):+.1f} s, "
          f"max {residual.max():+.1f} s; passes over budget: {sum(r[5] > r[3] for r in rows)} of {len(rows)}; "
          f"budget used: {np.mean([r[5] / r[3] for r in rows]):.1%} on average")
    arrival = (leg[:, 0] > ARRIVAL_M).astype(float)
    a = np.stack([leg[:, 0], arrival, np.ones(len(leg))], axis=1)
    (per_m, per_stop, per_heading), *_ = np.linalg.lstsq(a, leg[:, 1], rcond=None)
    residual = leg[:, 1] - a @ np.array([per_m, per_stop, per_heading])
    print(f"with a time per stop ({int(arrival.sum())} arrivals): speed {1 / per_m:.3f} m/s, {per_stop:.2f} s per "
          f"stop, {per_heading:.2f} s per heading; residual 90 % quantile {np.quantile(residual, 0.9):+.1f} s")
    shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
