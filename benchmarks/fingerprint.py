"""Fingerprint of whole missions: proves a refactor changed no behaviour.

Builds a world and runs monitor sessions with fixed seeds, then prints one line per
artefact with its SHA-256 (map image, map YAML, trajectory, the graph's node table and
full event history, the traversal plan) and the F1 of every session. Run it before and
after a change and ``diff`` the outputs: identical lines mean identical behaviour.

    python benchmarks/fingerprint.py --world ../shared/worlds/lab-b.yaml --sessions 3

``--config FILE`` (repeatable) layers config files over the defaults, as every ``bomc``
command does: e.g. a file with ``association: {mode: paper}`` fingerprints Algorithm 2.
"""

from __future__ import annotations

import argparse
import hashlib
import sqlite3
import sys
import tempfile
from pathlib import Path

# the node table's columns before schema 5 (the colours have their own line, so a run of a
# version 4 store and one of today's compare line by line)
_NODE_COLUMNS = ("id, category, x, y, z, confidence, first_session, last_session, state, observations, misses, "
                 "fx0, fy0, fx1, fy1")


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _table(db: Path, sql: str) -> str:
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        rows = con.execute(sql).fetchall()
    finally:
        con.close()
    return _sha(repr(rows).encode())


def fingerprint(world: Path, sessions: int, seed: int, config_files: list[str] = ()) -> list[str]:
    from bomc_bt import run
    from bomc_bt.evaluate_site import evaluate_session

    lines = []
    with tempfile.TemporaryDirectory() as tmp:
        site = Path(tmp) / "site"
        config = run.build_config(list(config_files))
        build = run.run_build(world, site, seed=seed, config=config)
        lines.append(f"build succeeded={build.succeeded} sim_time={build.sim_time:.3f} ticks={build.ticks}")
        for name in ("map.pgm", "map.yaml", "trajectory.csv"):
            lines.append(f"{name} {_sha((site / name).read_bytes())}")
        for n in range(1, sessions + 1):
            result = run.run_monitor(world, site, n, seed=seed + n, config=config)
            f1 = evaluate_session(world, site, n, config).overall.f1
            db = site / "site.db"
            lines.append(f"session {n} succeeded={result.succeeded} sim_time={result.sim_time:.3f} "
                         f"ticks={result.ticks} f1={f1}")
            lines.append(f"session {n} nodes {_table(db, f'SELECT {_NODE_COLUMNS} FROM nodes ORDER BY id')}")
            lines.append(f"session {n} colours {_table(db, 'SELECT id, cr, cg FROM nodes ORDER BY id')}")
            history = _table(db, "SELECT id, session, stamp, kind, category, x, y, z, confidence, px, py, pz "
                                 "FROM node_history ORDER BY seq")
            lines.append(f"session {n} history {history}")
            lines.append(f"session {n} plan.json {_sha((site / 'plan.json').read_bytes())}")
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--world", required=True)
    p.add_argument("--sessions", type=int, default=3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--config", action="append", default=[], help="config file layered over the defaults")
    args = p.parse_args(argv)
    for line in fingerprint(Path(args.world), args.sessions, args.seed, args.config):
        print(line, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
