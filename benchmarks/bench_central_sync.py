"""``bomc sync`` time for an Environment-A-size site with 20 sessions, on a loopback PostgreSQL.

The site is written through the real store API (:class:`bomc_bt.store.SiteStore`): 420
objects (the Environment A mix at 93 x 90 m), 20 sessions, each a pass of frames in which
every present node is re-seen ``--updates`` times (an ``updated`` event each), 5 % of the
movable ones removed, moved or added, and closed by ``end_session`` (reconciliation,
counts, report); the map is a generated 93 x 90 m office (1860 x 1800 cells, 3.3 MB), the
trajectory 10,000 poses, each session a 50 kB report, a 600 kB picture and a new 60 kB
plan. The server is the tests' (``tests/postgres_server.py``: initdb + pg_ctl in a
temporary folder).

Sized after a real Environment-A-size site (the generated 93 x 90 m office, seed 31,
three passes with the default detector): 439 node ids, 1,300-1,700 history rows per
pass, a 3.4 MB map, 9,900 trajectory poses, 600 kB of report per session, a 57 kB plan.
With ``--updates 6`` a synthetic pass writes about 2,600 history rows: more than a real
one, so the time is an upper bound. Acceptance (issue 22): the first, full sync of 20
sessions under 10 s on loopback.

Rows: the first (full) sync, a sync after one more pass (incremental), a sync with
nothing new, and the central's row counts.

Run: .venv/bin/python benchmarks/bench_central_sync.py [--sessions 20] [--updates 6]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from bomc_bt.central.sync import sync_site  # noqa: E402
from bomc_bt.graph import Event, Node  # noqa: E402
from bomc_bt.store import SiteStore  # noqa: E402


def write_pass(store: SiteStore, site: Path, number: int, nodes: dict[int, Node], rng, updates: int) -> None:
    store.begin_session(number, {"stamp": 0.0})
    t = 0.0
    next_id = max(nodes, default=-1) + 1
    if number == 1:
        for i in range(420):
            nodes[i] = Node(i, f"class{i % 8}", rng.uniform([0, 0, 0.3], [93, 90, 1.0]), 0.9, 1, 1)
            store.record([Event("added", i, nodes[i].category, nodes[i].position, 1, t, None, 0.9)], [nodes[i]])
            t += 0.5
    else:
        for nid in rng.choice(sorted(nodes), size=len(nodes) // 20, replace=False):
            node = nodes.pop(int(nid))
            node.state = "removed"
            store.record([Event("removed", node.id, node.category, node.position, number, t, None, 0.9)], [node])
        for _ in range(len(nodes) // 20 + 1):
            node = Node(next_id, "class1", rng.uniform([0, 0, 0.3], [93, 90, 1.0]), 0.9, number, number)
            nodes[next_id] = node
            store.record([Event("added", node.id, node.category, node.position, number, t, None, 0.9)], [node])
            next_id += 1
    for _ in range(updates):  # frames: a handful of nodes re-seen per frame, every node several times a pass
        ids = sorted(nodes)
        for start in range(0, len(ids), 5):
            events, changed = [], []
            for nid in ids[start:start + 5]:
                node = nodes[nid]
                node.position = node.position + rng.normal(0, 0.01, 3)
                node.last_session = number
                events.append(Event("updated", nid, node.category, node.position, number, t, None, 0.9))
                changed.append(node)
            store.record(events, changed, {"next_waypoint": start})
            t += 0.2
    store.end_session(number, "completed", {"stamp": t, "counts": {}})
    folder = site / "sessions" / str(number)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "report.json").write_text(json.dumps({"pad": "x" * 50_000}))
    (folder / "semantic_map.png").write_bytes(os.urandom(600_000))
    (site / "plan.json").write_text(json.dumps({"session": number, "pad": "x" * 60_000}))


def make_site(site: Path, sessions: int, updates: int) -> tuple[SiteStore, dict[int, Node]]:
    from bomc_bt.officegen import OfficeParams, generate_office

    gen = site / "generations" / "1"
    gen.mkdir(parents=True)
    generate_office(OfficeParams(width=93, height=90, seed=31), str(site / "world" / "env-a.yaml"))
    (gen / "map.pgm").write_bytes((site / "world" / "env-a-map.pgm").read_bytes())
    (gen / "map.yaml").write_text((site / "world" / "env-a-map.yaml").read_text().replace("env-a-map.pgm", "map.pgm"))
    (gen / "trajectory.csv").write_text("t,x,y,yaw\n" + "".join(f"{i}.000,1.0,2.0,0.0\n" for i in range(10_000)))
    (gen / "build.json").write_text("{}")
    (site / "current").write_text("1\n")
    rng = np.random.default_rng(0)
    store, nodes = SiteStore(site / "site.db"), {}
    for n in range(1, sessions + 1):
        write_pass(store, site, n, nodes, rng, updates)
    return store, nodes


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--sessions", type=int, default=20)
    parser.add_argument("--updates", type=int, default=6, help="times each node is re-seen per pass")
    args = parser.parse_args()
    from postgres_server import start_server, stop_server

    server = start_server()
    try:
        url = server.create_database()
        with tempfile.TemporaryDirectory() as tmp:
            site = Path(tmp) / "env-a"
            t0 = time.perf_counter()
            store, nodes = make_site(site, args.sessions, args.updates)
            print(f"site written in {time.perf_counter() - t0:.1f} s: {len(store.events())} history rows, "
                  f"{len(store.nodes(include_removed=True))} node ids, {args.sessions} sessions")
            print(f"{'sync':<24} {'wall s':>7}  pushed")
            times = {}
            for label in ("first (full)", "after one more pass", "nothing new"):
                if label == "after one more pass":
                    write_pass(store, site, args.sessions + 1, nodes, np.random.default_rng(1), args.updates)
                t0 = time.perf_counter()
                result = sync_site(site, url, building="env-a", floor="1", robot="bench")
                times[label] = time.perf_counter() - t0
                print(f"{label:<24} {times[label]:>7.2f}  {result.pushed or 'nothing'}")
            verdict = "met" if times["first (full)"] < 10 else "NOT met"
            print(f"acceptance (full sync of {args.sessions} sessions < 10 s): {verdict}")
            store.close()
    finally:
        stop_server(server)


if __name__ == "__main__":
    main()
