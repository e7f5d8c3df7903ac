"""Whole missions in the simulator: how fast they run and how a monitor pass compares with a build.

For each world: one build mission (what ``bomc build`` does, default time limit), then one
monitor pass of session 1 on the site it made (what ``bomc monitor --session 1`` does).
Per mission the table gives the simulated seconds, the wall seconds spent ticking the tree
(first to last tick, the simulator's real-time factor is sim / that), the wall seconds of
the whole call (world loading, map saving, reports included) and the path driven. The
monitor rows add the monitor / build ratio in SIM time: the paper reports 35 vs 150
minutes (0.23) for its Environment A.

Run:  .venv/bin/python benchmarks/bench_missions.py [--worlds PATH ...] [--seed N] [--max-time S]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from shared_folder import SHARED

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt.exploration.coverage import map_coverage, solid_mask  # noqa: E402
from bomc_bt.grid import load_map  # noqa: E402
from bomc_bt.run import MissionResult, run_build, run_monitor  # noqa: E402
from bomc_bt.site import Site  # noqa: E402
from bomc_bt.world import load_world  # noqa: E402

WORLDS_DIR = SHARED / "worlds"
DEFAULT_WORLDS = [str(WORLDS_DIR / "office-s.yaml"), str(WORLDS_DIR / "lab-b.yaml")]


@dataclass
class Row:
    """One mission's timing and outcome."""

    world: str
    mission: str
    sim_s: float
    tick_wall_s: float
    call_wall_s: float
    ticks: int
    path_m: float
    outcome: str
    detail: str
    ratio: float | None = None

    @property
    def rtf(self) -> float:
        return self.sim_s / self.tick_wall_s if self.tick_wall_s > 0 else float("inf")


class TickClock:
    """A tick hook that remembers the wall time of the first and the last tick."""

    def __init__(self) -> None:
        self.first: float | None = None
        self.last = 0.0

    def __call__(self, _runner) -> None:
        now = time.perf_counter()
        if self.first is None:
            self.first = now
        self.last = now

    @property
    def elapsed(self) -> float:
        return self.last - self.first if self.first is not None else 0.0


def timed(fn, *args, **kwargs) -> tuple[MissionResult, float, float]:
    """Run a mission; return it with the tick-loop wall time and the whole call's wall time."""
    clock = TickClock()
    t0 = time.perf_counter()
    result = fn(*args, hooks=[clock], quiet=True, **kwargs)
    return result, clock.elapsed, time.perf_counter() - t0


def build_row(world_path: Path, site: Path, seed: int, max_time: float | None) -> Row:
    result, tick_wall, call_wall = timed(run_build, world_path, site, seed=seed, max_time=max_time)
    s = result.summary
    world = load_world(world_path)
    solid = solid_mask(world.grid, world.walls(), [o.footprint() for o in world.objects_in_session(1).values()])
    cov = map_coverage(load_map(Site(site).map_yaml), world.grid, solid, world.start)
    detail = (f"{s['termination']}; map covers {cov.covered_m2:.0f}/{cov.reachable_m2:.0f} m² "
              f"({100 * cov.fraction:.0f} %), {s['goals']} goals")
    return Row(world.name, "build", float(s["sim_time_s"]), tick_wall, call_wall, result.ticks,
               float(s["path_length_m"]), s["outcome"], detail)


def monitor_row(world_path: Path, site: Path, seed: int, build: Row) -> Row:
    result, tick_wall, call_wall = timed(run_monitor, world_path, site, 1, seed=seed)
    s = result.summary
    trav = s.get("traversal") or {}
    visited = "" if not trav else (f", waypoints {trav['visited']}+{trav['detoured']} detoured/"
                                   f"{trav['waypoints']} ({trav['missed']} missed)")
    detail = f"{s['nodes']} nodes, {s['frames']} frames, observed {100 * s['coverage']['fraction']:.0f} %{visited}"
    sim = float(s["sim_time_s"])
    return Row(build.world, "monitor", sim, tick_wall, call_wall, result.ticks, float(s["path_length_m"]),
               str(s["outcome"]), detail, ratio=sim / build.sim_s if build.sim_s else None)


def print_table(rows: list[Row]) -> None:
    print(f"{'world':<10} {'mission':<8} {'sim s':>7} {'sim min':>7} {'tick wall s':>11} {'RTF':>6} "
          f"{'call wall s':>11} {'ticks':>6} {'path m':>7} {'mon/build':>9}  {'outcome':<10} detail")
    for r in rows:
        ratio = f"{r.ratio:9.2f}" if r.ratio is not None else f"{'':>9}"
        print(f"{r.world:<10} {r.mission:<8} {r.sim_s:>7.0f} {r.sim_s / 60:>7.1f} {r.tick_wall_s:>11.1f} "
              f"{r.rtf:>6.0f} {r.call_wall_s:>11.1f} {r.ticks:>6} {r.path_m:>7.1f} {ratio}  {r.outcome:<10} "
              f"{r.detail}")
    print("\nRTF = sim s / tick wall s (real-time factor of the whole stack: simulator, mapper, planner, tree).")
    print("mon/build = monitor pass sim time / build sim time (paper, Environment A: 35/150 min = 0.23).")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=DEFAULT_WORLDS, help="world files, one build + monitor each")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-time", type=float, default=None, help="build time limit in robot s (default: config)")
    args = ap.parse_args()
    rows: list[Row] = []
    with tempfile.TemporaryDirectory(prefix="bench_missions_") as tmp:
        for i, world in enumerate(args.worlds):
            site = Path(tmp) / f"site-{i}"
            build = build_row(Path(world), site, args.seed, args.max_time)
            rows += [build, monitor_row(Path(world), site, args.seed, build)]
    print_table(rows)


if __name__ == "__main__":
    main()
