"""Many passes over a changing office: does any pass get stuck, and for how long?

Issue 15 item 6: on a 36 x 28 m office after five passes of chairs and tables being moved
around, a sixth pass detoured once and then reached none of its remaining ~100 waypoints
for more than 3,500 s of robot time. This generates such worlds (``bomc world office
--sessions K --churn 0.15 --corridor-chairs 2``: chairs left in the middle of corridors),
builds each once and runs passes 1..K, and prints per pass: robot time, waypoints
reached / planned, missed, the outcome and the recovery rounds with their diagnosis
(``bomc_bt/stuck.py``). A pass that ends early shows its reason.

Run:  .venv/bin/python benchmarks/bench_stuck.py [--seeds 1 3 5] [--sessions 6] [--size 36x28]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt.officegen import OfficeParams, generate_office  # noqa: E402
from bomc_bt.run import run_build, run_monitor  # noqa: E402


def passes(seed: int, sessions: int, size: tuple[float, float], churn: float, out: Path) -> list[list[str]]:
    world = out / f"office-{seed}.yaml"
    generate_office(OfficeParams(width=size[0], height=size[1], seed=seed, sessions=sessions, churn=churn,
                                 corridor_chair_every=2), world)
    site = out / f"site-{seed}"
    build = run_build(world, site, seed=0)
    rows = [[str(seed), "build", f"{build.sim_time:.0f}", "", "", build.summary.get("termination", ""), ""]]
    for n in range(1, sessions + 1):
        t0 = time.perf_counter()
        result = run_monitor(world, site, n, seed=n)
        s, t = result.summary, result.summary.get("traversal", {})
        reached = t.get("visited", 0) + t.get("detoured", 0)
        rounds = "; ".join(f"{r['cause']} ({r['action'] or 'none'})" for r in s.get("recoveries", []))
        outcome = s["outcome"] + (f": {s['reason']}" if s["outcome"] == "ended_early" else "")
        rows.append([str(seed), f"pass {n}", f"{s['sim_time_s']:.0f}", f"{reached}/{t.get('waypoints', 0)}",
                     str(t.get("missed", 0)), outcome, rounds or "-"])
        print(f"  seed {seed} pass {n}: {time.perf_counter() - t0:.0f} s wall", file=sys.stderr)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 3])
    ap.add_argument("--sessions", type=int, default=6)
    ap.add_argument("--size", default="36x28")
    ap.add_argument("--churn", type=float, default=0.15)
    args = ap.parse_args()
    size = tuple(float(v) for v in args.size.lower().split("x"))
    head = ["seed", "mission", "robot time s", "reached", "missed", "outcome", "recovery rounds"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-stuck-") as tmp:
        for seed in args.seeds:
            rows += passes(seed, args.sessions, size, args.churn, Path(tmp))
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
