"""Exploration protocol of the paper on several maps: each explorer from the same starts.

Every explorer runs the full build mission (behaviour tree, simulator, mapper) on the same
world from the same start poses. Start poses are free cells with enough clearance in the
largest free connected region of the map, drawn with a seeded generator, so every run of
this script uses the same starts. Each start gets its own world file (a copy of the base
world with another ``start``) in a temporary directory.

Worlds (``--suite``, comma separated):

* ``hospital``: the paper's benchmark world (shared ``worlds/hospital.yaml``, with objects);
* ``maps``: every other real map in shared ``maps/`` as a world without objects;
* ``office``: a generated Environment-A-size office (``--office-size``, ``--office-seed``);
* or a path to any world file.

Shared data is found as the tests find it: ``$BOMC_SHARED``, else ``shared/`` beside the
checkout. While a run drives, the live map is compared with the true reachable floor
every ``--sample`` s of robot time (bomc_bt.exploration.coverage), so each run reports
the covered area at ``--at`` minutes, the time and path at which 90 % and 95 % of the
reachable floor were mapped, and how it ended. The summary gives per explorer the means,
and the ratio to the baseline per start (paired) with a 95 % t-interval over the starts.
The paper reports DWFE at +7.8 % area and -12 % path against the baseline (hospital,
20 starts x 15 min).

Run:  .venv/bin/python benchmarks/bench_exploration.py [--suite hospital,maps,office]
          [--starts N] [--minutes M] [--explorers gain,dwfe,baseline] [--jobs J] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path

import cv2
import numpy as np
import yaml
from shared_folder import SHARED

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt.exploration.coverage import reachable_free, solid_mask  # noqa: E402
from bomc_bt.geometry import Pose2D  # noqa: E402
from bomc_bt.officegen.generate import draft_office, write_office  # noqa: E402
from bomc_bt.officegen.params import OfficeParams  # noqa: E402
from bomc_bt.run import run_build  # noqa: E402
from bomc_bt.world import World, load_world  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
BASELINE = "baseline"
# two-sided 95 % quantiles of Student's t, by degrees of freedom (normal beyond 30)
T95 = [12.71, 4.30, 3.18, 2.78, 2.57, 2.45, 2.36, 2.31, 2.26, 2.23, 2.20, 2.18, 2.16, 2.14, 2.13, 2.12,
       2.11, 2.10, 2.09, 2.09, 2.08, 2.07, 2.07, 2.06, 2.06, 2.06, 2.05, 2.05, 2.05, 2.04]


@dataclass
class RunRecord:
    """One build run: coverage over time, path, and how it ended."""

    world: str
    explorer: str
    start: int
    reachable_m2: float
    covered_at_m2: float  # at the --at time (or the end, if earlier)
    covered_end_m2: float
    path_m: float
    sim_s: float
    wall_s: float
    termination: str
    goals: int
    failed_goals: int
    reason: str = ""
    t90: float | None = None
    t95: float | None = None
    path90: float | None = None
    path95: float | None = None
    curve: list[tuple[float, float, float]] = field(default_factory=list)  # (s, covered m2, path m)


def solid(world: World) -> np.ndarray:
    """Walls and session-1 object footprints: what the robot can never stand on or see through."""
    footprints = [o.footprint() for o in world.objects_in_session(1).values()]
    return solid_mask(world.grid, world.walls(), footprints)


def sample_starts(world: World, n: int, clearance: float, seed: int) -> list[Pose2D]:
    """``n`` distinct poses on cells at least ``clearance`` m from any solid cell, in the
    largest 4-connected free region and on the floor the planner's robot drives from there
    (so every run can reach the same floor); yaws drawn too."""
    blocked = solid(world)
    blocked[[0, -1], :] = True  # the simulator treats the image edge as solid
    blocked[:, [0, -1]] = True
    _, labels, stats, _ = cv2.connectedComponentsWithStats((~world.walls()).astype(np.uint8), connectivity=4)
    if len(stats) < 2:
        raise SystemExit(f"{world.path}: the map has no free region")
    largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    dist = cv2.distanceTransform((~blocked).astype(np.uint8), cv2.DIST_L2, 5)
    ok = (labels == largest) & ~blocked & (dist * world.grid.resolution >= clearance)
    rows, cols = np.nonzero(ok)
    if len(rows) < n:
        raise SystemExit(f"{world.path}: only {len(rows)} cells with {clearance} m clearance, {n} starts asked")
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(rows), size=n, replace=False)
    yaws = rng.uniform(-math.pi, math.pi, size=n)
    pick = _drivable_picks(pick, _on_main_floor(dist * world.grid.resolution, ok)[rows, cols], rng)
    xs, ys = world.grid.cell_to_world(rows[pick], cols[pick])
    return [Pose2D(float(x), float(y), float(yaw)) for x, y, yaw in zip(xs, ys, yaws, strict=True)]


def _on_main_floor(clearance: np.ndarray, ok: np.ndarray, radius: float = 0.3) -> np.ndarray:
    """``ok`` cells in the component of the floor a robot of ``radius`` (the planner's) can
    drive, 8-connected, that holds most of them. A real SLAM map's free space leaks through
    one-cell gaps (lidar rays out of a window, a door drawn ajar): the largest 4-connected
    region then holds pockets no robot gets out of, and a start there ended at 0 s with
    "no frontiers left" (PAL office, 0.05 m)."""
    count, labels = cv2.connectedComponents((clearance >= radius).astype(np.uint8), connectivity=8)
    votes = np.bincount(labels[ok], minlength=count)
    votes[0] = 0
    return ok & (labels == int(np.argmax(votes)))


def _drivable_picks(pick: np.ndarray, good: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``pick`` with every index whose ``good`` is False drawn again among the good ones not
    picked yet; the draws that were good (and the yaws drawn after them) stay as they were,
    so the starts on maps without such pockets are the ones measured before."""
    pick = pick.copy()
    for k in np.nonzero(~good[pick])[0]:
        free = np.setdiff1d(np.nonzero(good)[0], pick)
        if not len(free):
            raise SystemExit("no start on the main floor left to draw")
        pick[k] = rng.choice(free)
    return pick


def write_world(base: Path, start: Pose2D, path: Path) -> Path:
    """A copy of the base world with another start; the map path made absolute."""
    data = yaml.safe_load(base.read_text())
    data["map"] = str((base.parent / data["map"]).resolve())
    data["start"] = [round(start.x, 4), round(start.y, 4), round(start.yaw, 4)]
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def map_world(map_yaml: Path, out: Path) -> Path:
    """A world without objects on a real map (its start is replaced per run)."""
    out.write_text(yaml.safe_dump({"version": 1, "name": map_yaml.stem, "map": str(map_yaml.resolve()),
                                   "start": [0.0, 0.0, 0.0], "objects": []}, sort_keys=False))
    return out


def suite_worlds(suite: str, root: Path, office_size: str, office_seed: int) -> list[Path]:
    """The base worlds a suite name stands for."""
    out: list[Path] = []
    for name in suite.split(","):
        if name == "hospital":
            out.append(SHARED / "worlds" / "hospital.yaml")
        elif name == "maps":
            out += [map_world(m, root / f"map-{m.stem}.yaml") for m in sorted((SHARED / "maps").glob("*.yaml"))
                    if m.stem != "hospital"]
        elif name == "office":
            w, h = (float(v) for v in office_size.lower().split("x"))
            params = OfficeParams(width=w, height=h, seed=office_seed, sessions=2).check()
            out.append(Path(write_office(draft_office(params), root / f"office-{office_size}-{office_seed}.yaml").path))
        else:
            out.append(Path(name))
    for p in out:
        if not p.exists():
            raise SystemExit(f"{p}: world not found (shared data: set BOMC_SHARED)")
    return out


class CoverageProbe:
    """A per-tick hook: every ``period`` s of robot time, the live map's covered share of the
    true reachable floor and the path driven so far."""

    def __init__(self, world: World, period: float):
        reach = reachable_free(world.grid, solid(world), world.start)
        rows, cols = np.nonzero(reach)
        self.xs, self.ys = world.grid.cell_to_world(rows, cols)
        self.cell = world.grid.resolution ** 2
        self.reachable = float(len(rows)) * self.cell
        self.period = period
        self.curve: list[tuple[float, float, float]] = []
        self.next = 0.0

    def __call__(self, ctx):
        self.ctx = ctx

        def hook(_runner) -> None:
            now = ctx.now()
            if now >= self.next:
                self.next = now + self.period
                self.sample(ctx, now)
        return hook

    def sample(self, ctx, now: float) -> None:
        grid = ctx.robot.live_map()
        rows, cols = grid.world_to_cell(self.xs, self.ys)
        inside = grid.in_bounds(rows, cols)
        covered = np.count_nonzero(grid.data[rows[inside], cols[inside]] == 0) * self.cell
        self.curve.append((round(now, 1), round(float(covered), 2), round(float(ctx.progress.path_length), 1)))


def first_at(curve: list[tuple[float, float, float]], area: float) -> tuple[float | None, float | None]:
    """(time, path) at which the covered area first reached ``area``."""
    return next(((t, p) for t, a, p in curve if a >= area), (None, None))


def one_run(job: tuple) -> RunRecord:
    """Build once with ``explorer`` from ``world_path``, sampling coverage as it goes."""
    world_name, explorer, index, world_path, site_dir, max_time, seed, at, period = job
    world = load_world(world_path)
    probe = CoverageProbe(world, period)
    t0 = time.perf_counter()
    result = run_build(world_path, site_dir, seed=seed, max_time=max_time, explorer=explorer, quiet=True,
                       context_hooks=[probe])
    wall = time.perf_counter() - t0
    s = result.summary
    end = float(s["sim_time_s"])
    probe.sample(probe.ctx, end)  # the map as the build left it
    at_curve = [a for t, a, _ in probe.curve if t <= at] or [0.0]
    t90, p90 = first_at(probe.curve, 0.90 * probe.reachable)
    t95, p95 = first_at(probe.curve, 0.95 * probe.reachable)
    return RunRecord(world_name, explorer, index, probe.reachable, at_curve[-1], probe.curve[-1][1],
                     float(s["path_length_m"]), end, wall, str(s["termination"]), int(s["goals"]),
                     int(s["failed_goals"]), str(s.get("reason", "")), t90, t95, p90, p95, probe.curve)


def interval(ratios: list[float]) -> str:
    """Mean of per-start ratios as a percentage change, with a 95 % t-interval."""
    ratios = [r for r in ratios if math.isfinite(r)]
    if not ratios:
        return "n/a"
    m = statistics.fmean(ratios)
    if len(ratios) < 2:
        return f"{100 * (m - 1):+.1f} %"
    half = T95[min(len(ratios) - 2, len(T95) - 1)] * statistics.stdev(ratios) / math.sqrt(len(ratios))
    return f"{100 * (m - 1):+.1f} % [{100 * (m - half - 1):+.1f}, {100 * (m + half - 1):+.1f}]"


def fmt(v: float | None, unit: str = "") -> str:
    return "-" if v is None else f"{v:.0f}{unit}"


def print_world(world: str, records: list[RunRecord], explorers: list[str], at_min: float) -> None:
    rs = [r for r in records if r.world == world]
    print(f"\n== {world}: reachable {statistics.fmean(r.reachable_m2 for r in rs):.0f} m², "
          f"{len({r.start for r in rs})} start(s)")
    print(f"{'explorer':<9} {'area@' + format(at_min, 'g') + 'min':>12} {'path m':>8} {'t90 s':>7} {'t95 s':>7} "
          f"{'path95 m':>8} {'end s':>7} {'goals':>5} {'fail':>4} {'<90% early':>10}  terminations")
    by = {e: sorted((r for r in rs if r.explorer == e), key=lambda r: r.start) for e in explorers}
    for e, runs in by.items():
        if not runs:
            continue
        terms: dict[str, int] = {}
        for r in runs:
            terms[r.termination] = terms.get(r.termination, 0) + 1
        early = sum(r.termination != "time_limit" and r.covered_end_m2 < 0.9 * r.reachable_m2 for r in runs)

        def mean(vals):
            vals = [v for v in vals if v is not None]
            return statistics.fmean(vals) if vals else None
        reached = sum(r.t95 is not None for r in runs)
        print(f"{e:<9} {mean(r.covered_at_m2 for r in runs):>12.1f} {mean(r.path_m for r in runs):>8.1f} "
              f"{fmt(mean(r.t90 for r in runs)):>7} {fmt(mean(r.t95 for r in runs)):>7} "
              f"{fmt(mean(r.path95 for r in runs)):>8} {mean(r.sim_s for r in runs):>7.0f} "
              f"{mean(r.goals for r in runs):>5.0f} {mean(r.failed_goals for r in runs):>4.0f} {early:>10}  "
              f"{', '.join(f'{k}: {v}' for k, v in sorted(terms.items()))}; 95 % reached {reached}/{len(runs)}")
    base = by.get(BASELINE, [])
    for e, runs in by.items():
        if e == BASELINE or not runs or not base:
            continue
        pairs = list(zip(runs, base, strict=True))
        print(f"  {e} / baseline (per start, 95 % CI): area@{at_min:g}min {paired(pairs, 'covered_at_m2')}, "
              f"path {paired(pairs, 'path_m')}, t95 {paired(pairs, 't95')}, "
              f"path to 95 % {paired(pairs, 'path95')}")


def paired(pairs: list[tuple[RunRecord, RunRecord]], attr: str) -> str:
    """Per-start ratio of ``attr`` (explorer / baseline) as a change with its 95 % interval;
    starts where either run lacks the value (95 % never reached) are left out."""
    return interval([getattr(a, attr) / getattr(b, attr) if getattr(a, attr) and getattr(b, attr)
                     else math.nan for a, b in pairs])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", default="hospital", help="hospital, maps, office or world paths, comma separated")
    ap.add_argument("--explorers", default="gain,dwfe,baseline")
    ap.add_argument("--starts", type=int, default=20, help="starts per world; 0: the world's own start")
    ap.add_argument("--minutes", type=float, default=15.0, help="robot time per run; 0: until the build ends")
    ap.add_argument("--at", type=float, default=15.0, help="minutes at which the covered area is compared")
    ap.add_argument("--sample", type=float, default=10.0, help="s of robot time between coverage samples")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes")
    ap.add_argument("--seed", type=int, default=0, help="seeds the start sampling and the simulator")
    ap.add_argument("--clearance", type=float, default=0.6, help="m from any wall or object to a start")
    ap.add_argument("--office-size", default="93x90")
    ap.add_argument("--office-seed", type=int, default=31)
    ap.add_argument("--json", help="write every run (with its coverage curve) to this file")
    ap.add_argument("--only", default="", help="comma-separated start indices to run (of the --starts drawn); "
                    "empty: all")
    args = ap.parse_args()
    explorers = args.explorers.split(",")
    max_time = args.minutes * 60.0 if args.minutes > 0 else None
    t0 = time.perf_counter()
    records: list[RunRecord] = []
    with tempfile.TemporaryDirectory(prefix="bench_exploration_") as tmp:
        root = Path(tmp)
        jobs = []
        for base in suite_worlds(args.suite, root, args.office_size, args.office_seed):
            world = load_world(base)
            starts = ([world.start] if args.starts == 0
                      else sample_starts(world, args.starts, args.clearance, args.seed))
            only = {int(v) for v in args.only.split(",") if v.strip()}
            for i, start in enumerate(starts):
                if only and i not in only:
                    continue
                world_path = write_world(base, start, root / f"{base.stem}-{i:02d}.yaml")
                for e in explorers:
                    jobs.append((base.stem, e, i, str(world_path), str(root / f"site-{base.stem}-{i:02d}-{e}"),
                                 max_time, args.seed + i, args.at * 60.0, args.sample))
        print(f"{len(jobs)} runs ({args.suite}; {args.starts} start(s), seed {args.seed}; "
              f"{'until done' if max_time is None else f'{args.minutes:g} min'}), {args.jobs} worker(s)")
        with get_context("fork").Pool(max(1, args.jobs)) as pool:
            for r in pool.imap_unordered(one_run, jobs, chunksize=1):
                records.append(r)
                print(f"  [{len(records):>3}/{len(jobs)}] {r.world} start {r.start:>2} {r.explorer:<8} "
                      f"covered {r.covered_end_m2:7.1f}/{r.reachable_m2:.0f} m², path {r.path_m:6.1f} m, "
                      f"{r.sim_s:.0f} s {r.termination} ({r.reason}), wall {r.wall_s:5.1f} s", file=sys.stderr,
                      flush=True)
    print(f"total wall time {time.perf_counter() - t0:.0f} s")
    for world in dict.fromkeys(r.world for r in records):
        print_world(world, records, explorers, args.at)
    if args.json:
        Path(args.json).write_text(json.dumps([asdict(r) for r in records]))


if __name__ == "__main__":
    main()
