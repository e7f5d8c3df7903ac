"""Two robots alternating passes on one floor through the central store, against one robot alone.

Issue 22's first acceptance at a size beyond CI's (tests/test_central_fleet.py runs a 16 x
12 m office): a generated office is built once (seed 0); one robot runs passes 1..N on a
copy (seeds 1..N); the build is synced to a PostgreSQL server (the tests' own,
``tests/postgres_server.py``), and robots A and B take turns: pull the floor, run the next
pass with the same seed, sync. The table says, per central table, whether it equals the
lone robot's site (session rows without their wall-clock columns), then the report files,
and the time each way.

Run: .venv/bin/python benchmarks/bench_central_alternate.py [--size 24x18] [--seed 7] [--sessions 6]
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import psycopg  # noqa: E402

from bomc_bt import run  # noqa: E402
from bomc_bt.central.pull import pull_site  # noqa: E402
from bomc_bt.central.rows import read_central, read_local  # noqa: E402
from bomc_bt.central.site_files import local_files, local_generations, sha256  # noqa: E402
from bomc_bt.central.sync import sync_site  # noqa: E402
from bomc_bt.officegen import OfficeParams, generate_office  # noqa: E402


def without_wall_times(sessions: list[tuple]) -> list[tuple]:
    return [row[:2] + row[3:4] + row[5:] for row in sessions]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--size", default="24x18", help="office width x height [m]")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--sessions", type=int, default=6)
    args = parser.parse_args()
    width, height = (float(v) for v in args.size.split("x"))
    from postgres_server import start_server, stop_server

    server = start_server()
    try:
        url = server.create_database()
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp)
            world = root / "office.yaml"
            generate_office(OfficeParams(width=width, height=height, seed=args.seed, sessions=args.sessions), world)
            config = run.build_config()
            t0 = time.perf_counter()
            assert run.run_build(world, root / "built", seed=0, config=config).succeeded
            print(f"office {args.size} m seed {args.seed}: built in {time.perf_counter() - t0:.0f} s")
            alone = shutil.copytree(root / "built", root / "alone")
            t0 = time.perf_counter()
            for n in range(1, args.sessions + 1):
                assert run.run_monitor(world, alone, n, seed=n, config=config).succeeded
            alone_s = time.perf_counter() - t0
            sync_site(shutil.copytree(root / "built", root / "builder"), url, building="hq", floor="1",
                      robot="builder")
            t0, central_s = time.perf_counter(), 0.0
            for n in range(1, args.sessions + 1):
                robot = root / ("A" if n % 2 else "B")
                t1 = time.perf_counter()
                pull_site(robot, url, "hq", "1", robot.name)
                central_s += time.perf_counter() - t1
                assert run.run_monitor(world, robot, n, seed=n, config=config).succeeded
                t1 = time.perf_counter()
                sync_site(robot, url)
                central_s += time.perf_counter() - t1
            fleet_s = time.perf_counter() - t0
            expected = read_local(alone / "site.db")
            with psycopg.connect(url) as conn:
                got = read_central(conn, ("hq", "1", 1))
                files = dict(conn.execute("SELECT path, sha256 FROM bomc.files").fetchall())
            (generation,) = local_generations(alone)
            want_files = {name: sha256(path.read_bytes()) for name, path in local_files(generation).items()}
            print(f"{'what':<14} {'alone':>7} {'central':>7}  equal")
            for table in ("nodes", "node_history", "progress", "sessions"):
                a, b = expected.table(table), got.table(table)
                same = without_wall_times(a) == without_wall_times(b) if table == "sessions" else a == b
                print(f"{table:<14} {len(a):>7} {len(b):>7}  {'yes' if same else 'NO'}")
            print(f"{'files':<14} {len(want_files):>7} {len(files):>7}  {'yes' if files == want_files else 'NO'}")
            print(f"passes alone {alone_s:.0f} s; alternating {fleet_s:.0f} s, of which pull + sync {central_s:.1f} s")
    finally:
        stop_server(server)


if __name__ == "__main__":
    main()
