"""``bomc demo``: build once, then monitor sessions 1..N of a world and print the paper's tables.

This is the README's main job: it shows the whole system on the built-in simulator in
about a minute, and leaves a site with the map, the object graph, per-session reports
and PNGs, and the two tables of the paper (Markdown and JSON).
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

from bomc_bt.config import Config
from bomc_bt.errors import BomcError
from bomc_bt.evaluate_site import evaluate_session
from bomc_bt.evaluation import counts_table, counts_table_data, scores_table, scores_table_data, to_json
from bomc_bt.site import Site, write_json

# Files of ours that a demo may clear from its site before starting again.
_OWN = ("map.yaml", "map.pgm", "trajectory.csv", "build.json", "plan.json", "site.db", "site.db-wal",
        "site.db-shm", "tables.md", "tables.json", "current")


def shared_dir() -> Path:
    """The shared data folder: $BOMC_SHARED, or ``shared/`` beside the checkout."""
    env = os.environ.get("BOMC_SHARED")
    candidates = [Path(env)] if env else []
    here = Path(__file__).resolve().parent.parent
    candidates += [here.parent / "shared", here / "shared", Path.cwd().parent / "shared"]
    for c in candidates:
        if (c / "worlds").is_dir():
            return c
    raise BomcError("cannot find the shared worlds; pass --world or set BOMC_SHARED", None, "--world")


def reset_site(site: Site) -> None:
    """Clear what an earlier demo left in ``site`` (only our own files)."""
    for name in _OWN:
        (site.root / name).unlink(missing_ok=True)
    shutil.rmtree(site.root / "sessions", ignore_errors=True)
    shutil.rmtree(site.root / "generations", ignore_errors=True)


def run_demo(world: str | None, site_dir: str, *, seed: int, sessions: int, config: Config, quiet: bool,
             stream=sys.stdout) -> int:
    from bomc_bt import run
    from bomc_bt.world import load_world

    world_path = Path(world) if world else shared_dir() / "worlds" / "lab-b.yaml"
    loaded = load_world(world_path)
    site = Site(Path(site_dir)).create()
    reset_site(site)
    print(f"demo: world {loaded.name} ({world_path}), site {site.root}", file=stream)
    build = run.run_build(world_path, site.root, seed=seed, config=config, quiet=quiet, stream=stream)
    s = build.summary
    print(f"build: {s['termination']} after {s['sim_time_s']} s simulated, explored {s['explored_area_m2']} m², "
          f"path {s['path_length_m']} m", file=stream)
    if not site.map_yaml.exists():
        print("demo: the build saved no map; stopping", file=stream)
        return 1
    results = {}
    for n in range(1, sessions + 1):
        monitor = run.run_monitor(world_path, site.root, n, seed=seed + n, config=config, quiet=quiet, stream=stream)
        m = monitor.summary
        results[n] = evaluate_session(loaded, site.root, n, config)
        overall = results[n].overall
        f1 = "-" if overall.f1 is None else f"{overall.f1:.3f}"
        print(f"session {n}: {m['outcome']}, {m['sim_time_s']} s simulated, {m['nodes']} nodes, "
              f"events {m['events']}, coverage {m['coverage']['fraction']:.0%}, F1 {f1}", file=stream)
        if not monitor.succeeded:
            print(f"demo: session {n} did not complete ({monitor.reason})", file=stream)
            break
    counts, scores = counts_table(results), scores_table(results)
    print("\nObject counts (session 1 absolute, later sessions relative to session 1):\n", file=stream)
    print(counts, file=stream)
    print("Detection scores per class and session:\n", file=stream)
    print(scores, file=stream)
    (site.root / "tables.md").write_text(f"# {loaded.name}\n\n## Object counts\n\n{counts}\n## Scores\n\n{scores}")
    write_json(site.root / "tables.json", {
        "world": loaded.name, "counts": counts_table_data(results), "scores": scores_table_data(results),
        "sessions": {n: to_json(r) for n, r in results.items()},
    })
    print(f"demo: tables in {site.root / 'tables.md'}, maps in {site.root / 'sessions'}/*/semantic_map.png",
          file=stream)
    return 0 if len(results) == sessions else 1
