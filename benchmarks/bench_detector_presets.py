"""The simulated detector's presets side by side: how much harder is ``hard`` than ``realistic``?
(issue 17, item 6)

For each floor (the shared office-s, and a generated office) the script builds the map
once with ``bomc build``, then for each preset runs ``bomc monitor --session 1..N`` on a
copy of that build with a ``--config`` file setting ``detector.preset`` (same world, same
pass seeds, so the runs differ only by the detector) and scores each pass with
``bomc evaluate --json``. It prints per floor, preset and session: object F1 (and the
objects' false positives and misses), change precision / recall / F1, phantom events and
nodes standing on one of the world's look-alikes, then each preset's ratios to ``realistic`` measured in the same run.

    python benchmarks/bench_detector_presets.py                       # office-s + 36x28 seed 707, 3 sessions
    python benchmarks/bench_detector_presets.py --no-office-s --size 36x28 --seed 707 --presets realistic,hard

Everything goes through the CLI, as an operator would run it. ``--keep DIR`` leaves the
worlds, sites and config files there.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import zlib
from dataclasses import dataclass
from pathlib import Path

from shared_folder import SHARED

REPO = Path(__file__).resolve().parents[1]


@dataclass
class Row:
    floor: str
    preset: str
    session: int
    object_f1: float | None
    object_fp: int
    object_fn: int
    change_p: float | None
    change_r: float | None
    change_f1: float | None
    phantom: int
    lookalike_nodes: int
    wall_s: float


def bomc(*args: str) -> str:
    """Run the CLI in a child process (this checkout first on the path); its stdout."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-m", "bomc_bt.cli", *args], env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"bomc {' '.join(args)} failed ({done.returncode}): {done.stderr.strip()[-800:]}")
    return done.stdout


def run_preset(floor: str, world: Path, build_site: Path, root: Path, preset: str, sessions: int,
               extra: list[str]) -> list[Row]:
    config = root / f"{floor}-{preset}.yaml"
    config.write_text(f"detector:\n  preset: {preset}\n")
    layers = [arg for path in extra for arg in ("--config", path)] + ["--config", str(config)]
    site = root / f"{floor}-{preset}"
    shutil.copytree(build_site, site)
    rows = []
    for n in range(1, sessions + 1):
        start = time.perf_counter()
        bomc("monitor", "--world", str(world), "--site", str(site), *layers, "--session", str(n), "--seed", str(n),
             "--quiet")
        wall = time.perf_counter() - start
        scores = json.loads(bomc("evaluate", "--world", str(world), "--site", str(site), *layers,
                                 "--session", str(n), "--json"))
        overall, changes = scores["overall"], scores["changes"]
        rows.append(Row(floor, preset, n, overall["f1"], overall["fp"], overall["fn"],
                        changes["overall"]["precision"], changes["overall"]["recall"], changes["overall"]["f1"],
                        changes["phantom"], lookalike_nodes(world, site, n), wall))
        print(format_row(rows[-1]), flush=True)
    return rows


def lookalike_nodes(world_path: Path, site: Path, session: int, near: float = 0.8) -> int:
    """Nodes after the pass that sit on one of the world's look-alikes (of the category it is
    mistaken for) with no true object of that category within ``near``: false objects the
    ``hard`` preset's look-alikes put in the map (0 is expected for other presets)."""
    import numpy as np

    from bomc_bt.sim.detector_hard import lookalike_sites
    from bomc_bt.sim.factory import world_categories
    from bomc_bt.sim.params import HardDetectorParams
    from bomc_bt.store import SiteStore
    from bomc_bt.world import load_world

    world = load_world(world_path)
    grid = world.grid
    size = np.array(grid.data.shape[::-1]) * grid.resolution
    centre = np.asarray(grid.origin[:2], dtype=float) + size / 2.0
    everywhere = HardDetectorParams(lookalike_sector_share=1.0, lookalike_range=float(np.hypot(*size)))
    key = zlib.crc32(world.name.encode("utf-8"))
    sites = lookalike_sites(key, centre, everywhere, world_categories(world))
    truth = list(world.ground_truth(session).values())
    with SiteStore(site / "site.db", readonly=True) as store:
        nodes = store.graph_after(session)
    count = 0
    for node in nodes:
        xy = np.asarray(node.position[:2], dtype=float)
        on_site = any(cat == node.category and np.hypot(*(xy - p)) < near for p, cat in sites)
        real = any(o.category == node.category and np.hypot(xy[0] - o.position[0], xy[1] - o.position[1]) < near
                   for o in truth)
        count += on_site and not real
    return count


HEADER = (f"{'floor':<10} {'preset':<9} {'pass':>4} {'obj F1':>6} {'obj FP':>6} {'obj FN':>6} {'chg P':>6} "
          f"{'chg R':>6} {'chg F1':>6} {'phantom':>7} {'lookalk':>7} {'wall s':>7}")


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.3f}"


def format_row(r: Row) -> str:
    return (f"{r.floor:<10} {r.preset:<9} {r.session:>4} {_f(r.object_f1):>6} {r.object_fp:>6} {r.object_fn:>6} "
            f"{_f(r.change_p):>6} {_f(r.change_r):>6} {_f(r.change_f1):>6} {r.phantom:>7} {r.lookalike_nodes:>7} "
            f"{r.wall_s:>7.0f}")


def _ratio(a: float | None, b: float | None) -> str:
    return "-" if a is None or b is None or b == 0 else f"{a / b:.2f}"


def ratios(rows: list[Row]) -> list[str]:
    """Each non-realistic row against realistic's row of the same floor and session."""
    base = {(r.floor, r.session): r for r in rows if r.preset == "realistic"}
    out = [f"{'floor':<10} {'preset':<9} {'pass':>4} {'obj F1 x':>8} {'chg F1 x':>8} {'phantom':>12} {'obj FP':>10}"]
    for r in rows:
        b = base.get((r.floor, r.session))
        if r.preset == "realistic" or b is None:
            continue
        out.append(f"{r.floor:<10} {r.preset:<9} {r.session:>4} {_ratio(r.object_f1, b.object_f1):>8} "
                   f"{_ratio(r.change_f1, b.change_f1):>8} {f'{r.phantom} vs {b.phantom}':>12} "
                   f"{f'{r.object_fp} vs {b.object_fp}':>10}")
    return out


def floors(args, root: Path) -> list[tuple[str, Path]]:
    out = []
    if not args.no_office_s:
        shared = SHARED / "worlds" / "office-s.yaml"
        if shared.exists():
            out.append(("office-s", shared))
        else:
            print(f"# office-s skipped: {shared} not found (set BOMC_SHARED)", file=sys.stderr)
    if args.size:
        world = root / f"office-{args.size}-{args.seed}.yaml"
        bomc("world", "office", "--out", str(world), "--size", args.size, "--seed", str(args.seed),
             "--sessions", str(args.sessions))
        out.append((f"{args.size}", world))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--presets", default="realistic,hard", help="detector presets, comma-separated")
    p.add_argument("--sessions", type=int, default=3)
    p.add_argument("--size", default="36x28", help="WxH of the generated office ('' for none)")
    p.add_argument("--seed", type=int, default=707, help="the generated office's seed")
    p.add_argument("--no-office-s", action="store_true", help="skip the shared office-s floor")
    p.add_argument("--config", action="append", default=[], help="config file under each preset's (repeatable)")
    p.add_argument("--keep", help="directory to keep the worlds, sites and configs in")
    args = p.parse_args(argv)
    tmp = tempfile.TemporaryDirectory()
    root = Path(args.keep) if args.keep else Path(tmp.name)
    root.mkdir(parents=True, exist_ok=True)
    presets = args.presets.split(",")
    rows: list[Row] = []
    print(HEADER, flush=True)
    for floor, world in floors(args, root):
        build_site = root / f"{floor}-build"
        start = time.perf_counter()
        bomc("build", "--world", str(world), "--site", str(build_site), "--seed", "0", "--quiet",
             *[arg for path in args.config for arg in ("--config", path)])
        print(f"# {floor}: {world}, built in {time.perf_counter() - start:.0f} s wall", flush=True)
        for preset in presets:
            rows += run_preset(floor, world, build_site, root, preset, args.sessions, args.config)
    print("\n" + HEADER)
    for r in sorted(rows, key=lambda r: (r.floor, r.session, presets.index(r.preset))):
        print(format_row(r))
    print("\nratios to realistic (same floor, same pass seed):")
    print("\n".join(ratios(rows)))
    tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
