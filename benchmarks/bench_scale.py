"""Building scale, end to end: one build and several monitor passes per floor, one table.

For each floor (a generated office at Environment A's size, 93 x 90 m, and the shared
office-s by default) the script builds a site with the default configuration, runs the
monitor sessions the world defines, and prints per floor:

* the build: simulated time, wall time, path, how it ended, the share of the floor that is
  reachable from the dock that the map holds (the world's own map is the truth);
* per pass: simulated and wall time, path, the pass/build time ratio, object F1 (precision,
  recall), the net change events (added / removed / moved) against the true changes since
  the previous pass, change F1 and phantom events;
* per pass, the missed objects by cause (:mod:`bomc_bt.miss_causes`): removed without
  evidence, mislabelled, displaced, merged with a neighbour, never mapped.

The baseline is the build measured in the same run: a pass's cost is its ratio to it
(the paper: 35 min against 150 min, 0.23). Worlds are generated on the fly (seedable);
nothing large is committed.

    python benchmarks/bench_scale.py                              # Env A seed 101 + office-s
    python benchmarks/bench_scale.py --size 50x45 --seed 5 --no-office-s --sessions 2
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from shared_folder import SHARED

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt import run  # noqa: E402
from bomc_bt.evaluate_changes import evaluate_changes  # noqa: E402
from bomc_bt.evaluate_site import evaluate_session, session_misses  # noqa: E402
from bomc_bt.exploration.coverage import map_coverage, solid_mask  # noqa: E402
from bomc_bt.grid import load_map  # noqa: E402
from bomc_bt.miss_causes import CAUSES, cause_counts  # noqa: E402
from bomc_bt.officegen import OfficeParams, generate_office  # noqa: E402
from bomc_bt.officegen.params import walls_at  # noqa: E402
from bomc_bt.world import load_world  # noqa: E402


@dataclass
class PassRow:
    session: int
    sim_s: float
    wall_s: float
    path_m: float
    f1: float
    precision: float
    recall: float
    net: dict[str, int]  # net change events by kind
    true: dict[str, int]  # true changes by kind
    change_f1: float | None
    phantom: int
    misses: dict[str, int] = field(default_factory=dict)  # false negatives by cause


@dataclass
class FloorRow:
    name: str
    build_sim_s: float
    build_wall_s: float
    build_path_m: float
    termination: str
    mapped: float  # share of the reachable floor the saved map holds
    passes: list[PassRow] = field(default_factory=list)
    peak_rss_mb: float = 0.0


def reachable_mapped(world_path: Path, site: Path) -> float:
    """Share of the world's free floor reachable from the dock that the site's map knows
    (walls and session 1's objects are solid, as in bench_exploration)."""
    world = load_world(world_path)
    footprints = [o.footprint() for o in world.objects_in_session(1).values()]
    solid = solid_mask(world.grid, world.walls(), footprints)
    cov = map_coverage(load_map(site / "map.yaml"), world.grid, solid, world.start)
    return cov.covered_m2 / cov.reachable_m2 if cov.reachable_m2 else 0.0


def measure_floor(name: str, world: Path, site: Path, sessions: int | None, config) -> FloorRow:
    t = time.perf_counter()
    build = run.run_build(world, site, seed=0, config=config)
    summary = json.loads((site / "build.json").read_text())
    row = FloorRow(name, build.sim_time, time.perf_counter() - t, float(summary["path_length_m"]),
                   str(summary.get("termination", "")), reachable_mapped(world, site))
    count = sessions or load_world(world).last_session
    for n in range(1, count + 1):
        t = time.perf_counter()
        result = run.run_monitor(world, site, n, seed=n, config=config)
        wall = time.perf_counter() - t
        report = json.loads((site / "sessions" / str(n) / "report.json").read_text())
        objects = evaluate_session(world, site, n, config)
        changes = evaluate_changes(world, site, n, config)
        row.passes.append(PassRow(
            n, result.sim_time, wall, float(report["path_length_m"]), objects.overall.f1 or 0.0,
            objects.overall.precision or 0.0, objects.overall.recall or 0.0,
            {k: s.mapped for k, s in changes.kinds.items()}, {k: s.gt for k, s in changes.kinds.items()},
            changes.overall.f1, changes.phantom, cause_counts(session_misses(world, site, n, config))))
        print(f"  {name} session {n}: {result.sim_time:.0f} s, F1 {row.passes[-1].f1:.3f}, "
              f"{wall:.0f} s wall", file=sys.stderr, flush=True)
    row.peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return row


def _changes(p: PassRow) -> str:
    kinds = ("added", "removed", "moved")
    if p.session == 1:
        return f"+{p.net.get('added', 0)} (first map)"
    return " ".join(f"{k[0]}{p.net.get(k, 0)}/{p.true.get(k, 0)}" for k in kinds)


def print_table(rows: list[FloorRow]) -> None:
    print("| floor | build sim s | build wall s | build path m | ended | reachable mapped | peak RSS MB |")
    print("| --- | ---: | ---: | ---: | --- | ---: | ---: |")
    for r in rows:
        print(f"| {r.name} | {r.build_sim_s:.0f} | {r.build_wall_s:.0f} | {r.build_path_m:.0f} | {r.termination} "
              f"| {r.mapped:.3f} | {r.peak_rss_mb:.0f} |")
    print()
    print("| floor | pass | sim s | pass/build | wall s | path m | F1 | P | R | events net/true (a r m) "
          "| change F1 | phantom |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: |")
    for r in rows:
        for p in r.passes:
            cf1 = "-" if p.change_f1 is None else f"{p.change_f1:.3f}"
            print(f"| {r.name} | {p.session} | {p.sim_s:.0f} | {p.sim_s / r.build_sim_s:.2f} | {p.wall_s:.0f} "
                  f"| {p.path_m:.0f} | {p.f1:.3f} | {p.precision:.3f} | {p.recall:.3f} | {_changes(p)} | {cf1} "
                  f"| {p.phantom} |")
    print()
    print("| floor | pass | missed objects by cause: " + " | ".join(CAUSES) + " |")
    print("| --- | ---: | " + " | ".join("---:" for _ in CAUSES) + " |")
    for r in rows:
        for p in r.passes:
            print(f"| {r.name} | {p.session} | " + " | ".join(str(p.misses.get(c, 0)) for c in CAUSES) + " |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="93x90", help="generated floor WxH in metres (default: Environment A)")
    ap.add_argument("--seed", type=int, default=101, help="generator seed (not one the tests use)")
    ap.add_argument("--sessions", type=int, default=3)
    ap.add_argument("--churn", type=float, default=0.05)
    ap.add_argument("--resolution", type=float, default=0.05, help="generated map metres per cell (0.02 to 0.1)")
    ap.add_argument("--no-office-s", action="store_true", help="skip the shared office-s floor")
    ap.add_argument("--config", action="append", default=[], help="extra config file (repeatable)")
    args = ap.parse_args(argv)
    config = run.build_config(args.config)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        w, h = (float(v) for v in args.size.lower().split("x"))
        world = tmp / "gen" / "world.yaml"
        generate_office(OfficeParams(width=w, height=h, seed=args.seed, sessions=args.sessions, churn=args.churn,
                                     resolution=args.resolution, **walls_at(args.resolution)).check(), world)
        rows.append(measure_floor(f"generated {args.size} seed {args.seed}", world, tmp / "site-gen",
                                  args.sessions, config))
        if not args.no_office_s:
            shared = SHARED / "worlds" / "office-s.yaml"
            if shared.exists():
                rows.append(measure_floor("office-s", shared, tmp / "site-office-s", None, config))
            else:
                print(f"office-s skipped: {shared} not found (set BOMC_SHARED)", file=sys.stderr)
    print_table(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
