"""Many monitor passes on a generated office: does the map stay right, and are the changes it
reports the real ones? (issue 17, items 3-5)

Generates an office (``bomc world office``), builds its map once, then runs sessions
1..N with each association mode on a copy of that build (same world, same seeds, so the
modes differ only by association) and prints, per session and mode: object F1, change
precision / recall / F1 (overall, net changes against the world's true ones), phantom
events, late and transient ones (false positives with a real change behind them: one the
previous pass missed, one undone before the pass ended), raw change events, nodes with
more than one change event in the pass (flips), simulated and wall pass time and the
store's size.

    python benchmarks/bench_passes.py --size 36x28 --seed 501 --sessions 12 --churn 0.05
    python benchmarks/bench_passes.py --size 36x28 --seed 501 --sessions 3 --static --modes robust
    python benchmarks/bench_passes.py --map ../shared/maps/warehouse.yaml --seed 7 --sessions 12 --churn 0.1

With ``--map`` the world is an existing occupancy map furnished by ``bomc world map``
(labelled boxes over its free floor, the same churn per session) instead of an office.

Wall times are of the whole pass (simulator, rendering and perception included) on
whatever machine runs it. ``--keep DIR`` leaves the world and the sites there.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

CHANGE_EVENT_KINDS = ("added", "removed", "moved")


@dataclass
class PassRow:
    mode: str
    session: int
    object_f1: float | None
    change_p: float | None
    change_r: float | None
    change_f1: float | None
    true_changes: int
    net_changes: int
    phantom: int
    late: int  # false positives that report a change the previous pass missed (not phantoms)
    transient: int  # false positives that report a change undone before the pass ended (not phantoms)
    raw_changes: int
    flipping_nodes: int
    sim_s: float
    wall_s: float
    store_mb: float
    outcome: str = ""  # the session report's: completed, ended_early, ...


def flipping_nodes(events) -> int:
    """Nodes with more than one added / removed / moved event in the pass."""
    per_node = Counter(e.node_id for e in events if e.kind in CHANGE_EVENT_KINDS)
    return sum(1 for n in per_node.values() if n > 1)


def store_megabytes(site: Path) -> float:
    return sum(p.stat().st_size for p in site.glob("site.db*")) / 1e6


def run_mode(world: Path, build_site: Path, site: Path, mode: str, sessions: int, seed: int,
             config_files: list[str]) -> list[PassRow]:
    from bomc_bt import run
    from bomc_bt.evaluate_changes import evaluate_changes
    from bomc_bt.evaluate_site import evaluate_session
    from bomc_bt.store import SiteStore

    mode_file = site.parent / f"{mode}.yaml"
    mode_file.write_text(f"association:\n  mode: {mode}\n")
    config = run.build_config([*config_files, str(mode_file)])
    shutil.copytree(build_site, site)
    rows = []
    for n in range(1, sessions + 1):
        start = time.perf_counter()
        result = run.run_monitor(world, site, n, seed=seed + n, config=config)
        wall = time.perf_counter() - start
        f1 = evaluate_session(world, site, n, config).overall.f1
        changes = evaluate_changes(world, site, n, config)
        with SiteStore(site / "site.db", readonly=True) as store:
            events = store.events(session=n)
        ov = changes.overall
        rows.append(PassRow(mode, n, f1, ov.precision, ov.recall, ov.f1, ov.gt, ov.mapped, changes.phantom,
                            len(changes.late), len(changes.transient),
                            sum(changes.raw_events.get(k, 0) for k in CHANGE_EVENT_KINDS), flipping_nodes(events),
                            result.sim_time, wall, store_megabytes(site), str(result.summary.get("outcome", ""))))
        print(format_row(rows[-1]), flush=True)
    return rows


HEADER = (f"{'mode':<7} {'pass':>4} {'obj F1':>6} {'chg P':>6} {'chg R':>6} {'chg F1':>6} {'true':>5} {'net':>5} "
          f"{'phantom':>7} {'late':>4} {'trans':>5} {'raw':>5} {'flips':>5} {'sim s':>7} {'wall s':>7} "
          f"{'store MB':>8} end")


def format_row(r: PassRow) -> str:
    def f(x):
        return "    -" if x is None else f"{x:.3f}"

    return (f"{r.mode:<7} {r.session:>4} {f(r.object_f1):>6} {f(r.change_p):>6} {f(r.change_r):>6} "
            f"{f(r.change_f1):>6} {r.true_changes:>5} {r.net_changes:>5} {r.phantom:>7} {r.late:>4} {r.transient:>5} "
            f"{r.raw_changes:>5} {r.flipping_nodes:>5} {r.sim_s:>7.0f} {r.wall_s:>7.1f} {r.store_mb:>8.2f} {r.outcome}")


def make_world(args: argparse.Namespace, root: Path) -> Path:
    """The benchmark's world: a generated office, or the given map furnished (``bomc world map``)."""
    churn = 0.0 if args.static else args.churn
    if args.map:
        from bomc_bt.grid import load_map
        from bomc_bt.worldgen import generate_world, reachable_free
        from bomc_bt.worldgen_cli import DEFAULT_CATEGORIES, FLOOR_PER_OBJECT

        grid = load_map(args.map)
        n = args.objects or max(1, round(float(reachable_free(grid).sum()) * grid.resolution ** 2 / FLOOR_PER_OBJECT))
        world = root / "world.yaml"
        generate_world(args.map, args.seed, n, DEFAULT_CATEGORIES.split(","), world, sessions=args.sessions,
                       churn=churn)
        return world
    from bomc_bt.officegen import OfficeParams, generate_office
    from bomc_bt.officegen.params import walls_at

    width, height = (float(v) for v in args.size.lower().split("x"))
    world = root / "office.yaml"
    generate_office(OfficeParams(width=width, height=height, seed=args.seed, sessions=args.sessions,
                                 churn=args.churn, static=args.static, resolution=args.resolution,
                                 **walls_at(args.resolution)), world)
    return world


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="36x28", help="WxH of the office, metres")
    p.add_argument("--seed", type=int, default=501, help="world seed (the passes use seed+1, seed+2, ...)")
    p.add_argument("--sessions", type=int, default=12)
    p.add_argument("--churn", type=float, default=0.05)
    p.add_argument("--static", action="store_true", help="nothing ever changes")
    p.add_argument("--resolution", type=float, default=0.05, help="generated office: map metres per cell (0.02 to 0.1)")
    p.add_argument("--modes", default="robust,paper", help="association modes, comma-separated")
    p.add_argument("--config", action="append", default=[], help="config file layered over the defaults")
    p.add_argument("--keep", help="directory to keep the world and sites in")
    p.add_argument("--map", help="furnish this map_server map instead of generating an office")
    p.add_argument("--objects", type=int, default=None, help="with --map: how many objects (default one per 20 m^2)")
    args = p.parse_args(argv)
    from bomc_bt import run

    tmp = tempfile.TemporaryDirectory()
    root = Path(args.keep) if args.keep else Path(tmp.name)
    root.mkdir(parents=True, exist_ok=True)
    world = make_world(args, root)
    build_site = root / "build"
    start = time.perf_counter()
    build = run.run_build(world, build_site, seed=args.seed, config=run.build_config(args.config))
    floor = Path(args.map).stem if args.map else f"office {args.size}"
    print(f"# {floor} seed {args.seed}, {args.sessions} sessions, churn "
          f"{0 if args.static else args.churn}; build {build.reason or 'done'} at {build.sim_time:.0f} s simulated, "
          f"{time.perf_counter() - start:.0f} s wall", flush=True)
    print(HEADER, flush=True)
    rows = []
    for mode in args.modes.split(","):
        rows += run_mode(world, build_site, root / mode, mode, args.sessions, args.seed, args.config)
    print("\n" + HEADER)
    for r in sorted(rows, key=lambda r: (r.session, r.mode)):
        print(format_row(r))
    tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
