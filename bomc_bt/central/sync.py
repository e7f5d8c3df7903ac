"""``bomc sync SITE --to postgresql://...``: push what is new in a local site to the central store.

The whole push is ONE PostgreSQL transaction, under an advisory lock on the floor (two
robots syncing the same floor take turns). A sync killed at any point (kill -9, a lost
network) therefore leaves the central state exactly as before it, and the next sync does
all of it; a sync repeated with nothing new changes nothing (not even the log).

What is pushed, per map generation of the site (:mod:`bomc_bt.central.site_files`):

* the generation row (with the robot that first pushed it) and its map files;
* node history after the central's last ``seq`` for that generation (append-only:
  only new rows travel, by ``COPY``);
* sessions, nodes and resume progress whose row differs from the central one (and the
  central progress rows the site no longer has are deleted);
* report files whose SHA-256 differs.

Before pushing, the site must *extend* what the central store has for that generation:
every central session is in the site and the central's last history row is the site's
row with the same ``seq``. Otherwise another robot ran a pass this site does not have
(or the site diverged): refused, exit 2, "pull first". The floor's current generation
becomes the site's when it is newer.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bomc_bt.central import schema
from bomc_bt.central.connection import central_errors, connect, redact, remembered
from bomc_bt.central.identity import SiteIdentity, save_identity, settle_identity
from bomc_bt.central.rows import COLUMNS, GraphRows, local_history_row, read_central, read_local
from bomc_bt.central.site_files import LocalGeneration, local_files, local_generations, sha256
from bomc_bt.errors import BomcError
from bomc_bt.site import current_generation

KEY_COLUMNS = {"sessions": ("number",), "nodes": ("id",), "progress": ("key",),
               "region_passes": ("session", "size", "i", "j")}  # each table's leading columns


@dataclass
class SyncResult:
    """What one sync pushed (row counts per table) and for whom."""

    identity: SiteIdentity
    pushed: dict[str, int] = field(default_factory=dict)

    def add(self, what: str, count: int) -> None:
        if count:
            self.pushed[what] = self.pushed.get(what, 0) + count

    def line(self) -> str:
        who = f"building {self.identity.building!r} floor {self.identity.floor!r} robot {self.identity.robot!r}"
        if not self.pushed:
            return f"sync: {who}: already up to date"
        return f"sync: {who}: pushed " + ", ".join(f"{n} {what}" for what, n in sorted(self.pushed.items()))


def floor_lock(conn: Any, building: str, floor: str) -> None:
    """Serialise the writers of one floor (sync, pull's reads need none) until the transaction ends."""
    conn.execute("SELECT pg_advisory_xact_lock(hashtext(%s))", (f"bomc-floor/{building}/{floor}",))


def sync_site(root: Path, conninfo: str, *, building: str | None = None, floor: str | None = None,
              robot: str | None = None, timeout: float = 10.0) -> SyncResult:
    """Push the site at ``root`` to the central store; ``site.json`` is written after the commit."""
    root = Path(root)
    if not root.is_dir():
        raise BomcError("not a site directory", root)
    generations = local_generations(root)
    if not generations:
        raise BomcError("nothing to sync: this site has no map (run `bomc build` first)", root)
    identity = settle_identity(root, building, floor, robot, remembered(conninfo))
    result = SyncResult(identity)
    conn = connect(conninfo, timeout)
    try:
        schema.migrate(conn, redact(conninfo))
        with central_errors(conninfo, "sync"), conn.transaction():
            _push(conn, root, identity, generations, result)
    finally:
        conn.close()
    save_identity(root, identity)
    return result


def _push(conn: Any, root: Path, identity: SiteIdentity, generations: list[LocalGeneration],
          result: SyncResult) -> None:
    b, f = identity.building, identity.floor
    floor_lock(conn, b, f)
    conn.execute("INSERT INTO bomc.floors (building, floor) VALUES (%s, %s) ON CONFLICT DO NOTHING", (b, f))
    for gen in generations:
        key = (b, f, gen.number)
        result.add("generations", conn.execute(
            "INSERT INTO bomc.generations (building, floor, generation, robot) VALUES (%s, %s, %s, %s)"
            " ON CONFLICT DO NOTHING", (*key, identity.robot)).rowcount)
        if gen.store is not None:
            _push_graph(conn, key, gen.store, identity.robot, result)
        result.add("files", _push_files(conn, key, local_files(gen)))
    current = current_generation(root) or 1
    conn.execute("UPDATE bomc.floors SET current_generation = %s WHERE building = %s AND floor = %s"
                 " AND (current_generation IS NULL OR current_generation < %s)", (current, b, f, current))
    if result.pushed:
        conn.execute("INSERT INTO bomc.sync_log (building, floor, robot, rows) VALUES (%s, %s, %s, %s)",
                     (b, f, identity.robot, json.dumps(result.pushed, sort_keys=True)))


def _push_graph(conn: Any, key: tuple[str, str, int], store: Path, robot: str, result: SyncResult) -> None:
    head = conn.execute("SELECT COALESCE(MAX(seq), 0) FROM bomc.node_history WHERE building = %s AND floor = %s"
                        " AND generation = %s", key).fetchone()[0]
    local = read_local(store, since=head)
    central = read_central(conn, key, since=head)  # history: nothing after head; the rest whole
    check_extends(key, store, local, central, head, conn)
    for table in ("sessions", "nodes", "progress", "region_passes"):
        result.add(table, _upsert_changed(conn, table, key, local.table(table), central.table(table), robot))
    result.add("progress rows dropped", _drop_gone(conn, key, local.progress, central.progress))
    if local.node_history:
        cols = ", ".join(("building", "floor", "generation", *COLUMNS["node_history"]))
        with conn.cursor().copy(f"COPY bomc.node_history ({cols}) FROM STDIN") as copy:
            for row in local.node_history:
                copy.write_row((*key, *row))
        result.add("history rows", len(local.node_history))


def check_extends(key: tuple[str, str, int], store: Path, local: GraphRows, central: GraphRows, head: int,
                  conn: Any) -> None:
    """Refuse to push a site that lacks what the central store already has for this generation."""
    where = f"building {key[0]!r} floor {key[1]!r} generation {key[2]}"
    robots = dict(conn.execute("SELECT number, robot FROM bomc.sessions WHERE building = %s AND floor = %s"
                               " AND generation = %s", key).fetchall())
    missing = sorted(set(robots) - {row[0] for row in local.sessions})
    if missing:
        raise BomcError(f"the central store has session {missing[0]} of {where} (robot {robots[missing[0]]!r}) that "
                        "this site lacks: `bomc pull` it first", store, "sessions")
    if head:
        ours = local_history_row(store, head)
        theirs = conn.execute(
            f"SELECT {', '.join(COLUMNS['node_history'])} FROM bomc.node_history WHERE building = %s AND floor = %s"
            " AND generation = %s AND seq = %s", (*key, head)).fetchone()
        if ours is None or tuple(ours) != tuple(theirs):
            raise BomcError(f"this site's history diverged from the central store's at seq {head} of {where} "
                            "(another robot ran a pass here): pull into a new folder", store, "node_history")


def _upsert_changed(conn: Any, table: str, key: tuple[str, str, int], local: list[tuple], central: list[tuple],
                    robot: str) -> int:
    """Insert or update the local rows that differ from the central ones; returns how many."""
    k = len(KEY_COLUMNS[table])
    have = {tuple(row[:k]): tuple(row) for row in central}
    changed = [row for row in local if have.get(tuple(row[:k])) != tuple(row)]
    if not changed:
        return 0
    cols = COLUMNS[table]
    extra = ("robot",) if table == "sessions" else ()
    names = ("building", "floor", "generation", *cols, *extra)
    conflict = ("building", "floor", "generation", *KEY_COLUMNS[table])
    updates = ", ".join(f"{c} = EXCLUDED.{c}" for c in cols if c not in KEY_COLUMNS[table])
    sql = (f"INSERT INTO bomc.{table} ({', '.join(names)}) VALUES ({', '.join(['%s'] * len(names))})"
           f" ON CONFLICT ({', '.join(conflict)}) DO UPDATE SET {updates}")
    with conn.cursor() as cur:
        cur.executemany(sql, [(*key, *row, *((robot,) if extra else ())) for row in changed])
    return len(changed)


def _drop_gone(conn: Any, key: tuple[str, str, int], local: list[tuple], central: list[tuple]) -> int:
    """Delete the central progress rows the site no longer has (the parts of a pass's resume
    point it dropped, :mod:`bomc_bt.resume_rows`), so the central rows are the site's; returns how many."""
    gone = sorted({row[0] for row in central} - {row[0] for row in local})
    if gone:
        conn.execute("DELETE FROM bomc.progress WHERE building = %s AND floor = %s AND generation = %s"
                     " AND key = ANY(%s)", (*key, gone))
    return len(gone)


def _push_files(conn: Any, key: tuple[str, str, int], files: dict[str, Path]) -> int:
    have = dict(conn.execute("SELECT path, sha256 FROM bomc.files WHERE building = %s AND floor = %s"
                             " AND generation = %s", key).fetchall())
    changed = []
    for name, path in files.items():
        try:
            payload = path.read_bytes()
        except OSError as exc:
            raise BomcError(f"cannot read ({exc.strerror})", path) from None
        digest = sha256(payload)
        if have.get(name) != digest:
            changed.append((*key, name, digest, payload))
    if changed:
        with conn.cursor() as cur:
            cur.executemany("INSERT INTO bomc.files (building, floor, generation, path, sha256, content)"
                            " VALUES (%s, %s, %s, %s, %s, %s) ON CONFLICT (building, floor, generation, path)"
                            " DO UPDATE SET sha256 = EXCLUDED.sha256, content = EXCLUDED.content", changed)
    return len(changed)
