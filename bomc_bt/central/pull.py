"""``bomc pull --from postgresql://... --building B --floor F SITE``: a local site from the central store.

Makes (or brings up to date) a site directory holding the floor's current map generation
and its graph, so another robot can run the next pass. Everything is read in one
REPEATABLE READ transaction (one consistent picture of the floor, whatever a sync does
meanwhile), and written under the site's writer lock in this order, each step crash-safe
and each skipped when already done, so a killed pull is finished by running it again:

1. ``site.json`` (building, floor, this robot, the store without its password);
2. the map generation, by the same protocol as a build (``generations/<n>.partial``,
   renamed, ``current`` switched atomically, top-level copies published);
3. the graph's rows in one SQLite transaction (history appended after the site's last
   ``seq``; sessions, nodes and progress replaced);
4. the plan and the session reports, each replaced atomically.

A SITE that exists must be a site of the same floor whose history the central store
extends (it was pulled or synced from there and ran nothing since): a site with passes
the store lacks is refused, "sync first", and a site on another map generation is
refused rather than mixed.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from bomc_bt.atomic import atomic_write
from bomc_bt.central import schema
from bomc_bt.central.connection import central_errors, check_name, connect, redact, remembered
from bomc_bt.central.identity import SiteIdentity, default_robot, read_identity, save_identity
from bomc_bt.central.rows import read_central, read_local, write_local
from bomc_bt.central.site_files import MAP, local_path, safe_name, sha256
from bomc_bt.errors import BomcError
from bomc_bt.generations import INTENT, PARTIAL, recover
from bomc_bt.site import GENERATIONS, current_generation, generation_dir
from bomc_bt.site_lock import SiteLock


def pull_site(root: Path, conninfo: str, building: str, floor: str, robot: str | None = None,
              timeout: float = 10.0) -> str:
    """Pull the floor into ``root``; returns one line saying what the site now holds."""
    root = Path(root)
    check_name(building, "--building")
    check_name(floor, "--floor")
    robot = check_name(robot, "--robot") if robot else None
    known = read_identity(root) if root.is_dir() else None
    if known is None and root.is_dir() and any(root.iterdir()):
        raise BomcError("not empty and not a synchronised site: pull into a new folder", root)
    if known is not None and (known.building, known.floor) != (building, floor):
        raise BomcError(f"this site is building {known.building!r} floor {known.floor!r}: pull another floor into "
                        "a new folder", root / "site.json")
    conn = connect(conninfo, timeout)
    try:
        schema.migrate(conn, redact(conninfo))
        with central_errors(conninfo, "pull"), conn.transaction():
            conn.execute("SET TRANSACTION ISOLATION LEVEL REPEATABLE READ, READ ONLY")
            generation, rows, files = _read_floor(conn, building, floor)
    finally:
        conn.close()
    identity = SiteIdentity(building, floor, robot or (known.robot if known else default_robot()),
                            remembered(conninfo))
    lock = SiteLock.acquire(root, "pull", create=True)
    try:
        recover(root)
        save_identity(root, identity)
        _install_generation(root, generation, {k[len(MAP):]: v for k, v in files.items() if k.startswith(MAP)})
        store = root / "site.db"
        since = _local_head(store, rows)
        rows.node_history = [r for r in rows.node_history if r[0] > since]
        rows.since = since
        write_local(store, rows)
        for name, payload in files.items():
            if not name.startswith(MAP):
                path = local_path(root, generation, name)
                if not path.is_file() or path.read_bytes() != payload:
                    atomic_write(path, payload)
    finally:
        lock.release()
    return (f"pull: building {building!r} floor {floor!r}: map generation {generation}, {len(rows.sessions)} "
            f"session(s), {sum(1 for n in rows.nodes if n[8] == 'present')} present nodes in {root}")


def _read_floor(conn: Any, building: str, floor: str) -> tuple[int, Any, dict[str, bytes]]:
    row = conn.execute("SELECT current_generation FROM bomc.floors WHERE building = %s AND floor = %s",
                       (building, floor)).fetchone()
    if row is None or row[0] is None:
        known = conn.execute("SELECT building || ' / ' || floor FROM bomc.floors ORDER BY 1").fetchall()
        raise BomcError(f"no floor {floor!r} of building {building!r} in the central store (floors: "
                        f"{', '.join(r[0] for r in known) or 'none'})", None, "--floor")
    key = (building, floor, int(row[0]))
    rows = read_central(conn, key)
    files = {}
    for name, digest, payload in conn.execute("SELECT path, sha256, content FROM bomc.files WHERE building = %s"
                                              " AND floor = %s AND generation = %s", key).fetchall():
        payload = bytes(payload)
        if not safe_name(name) or sha256(payload) != digest:
            raise BomcError(f"refusing central file {name!r} (unsafe name or checksum mismatch)", None, "files")
        files[name] = payload
    if not any(name == MAP + "map.yaml" for name in files):
        raise BomcError(f"generation {key[2]} of the floor has no map in the central store", None, "files")
    return key[2], rows, files


def _install_generation(root: Path, number: int, files: dict[str, bytes]) -> None:
    """Make ``number`` the site's current generation by the build's commit protocol (bomc_bt.generations)."""
    current = current_generation(root)
    if current == number:
        return
    if current is not None or (root / "site.db").exists():
        raise BomcError(f"this site is on map generation {current}, the central floor on {number}: pull into a new "
                        "folder", root / "current")
    partial = root / GENERATIONS / f"{number}{PARTIAL}"
    for name, payload in files.items():
        atomic_write(partial / name, payload)
    atomic_write(partial / INTENT, json.dumps({"generation": number, "previous": None,
                                               "archive_graph": False}).encode())
    os.rename(partial, generation_dir(root, number))
    recover(root)  # steps c-f: current, the top-level copies, the intent removed


def _local_head(store: Path, rows: Any) -> int:
    """The site's last history seq, after checking the central rows extend the site's."""
    if not store.exists():
        return 0
    local = read_local(store)
    central_sessions = {r[0] for r in rows.sessions}
    extra = sorted({r[0] for r in local.sessions} - central_sessions)
    head = local.last_seq
    central_at_head = next((r for r in rows.node_history if r[0] == head), None)
    if extra or (head and tuple(local.node_history[-1]) != tuple(central_at_head or ())):
        what = f"session {extra[0]}" if extra else f"history up to seq {head}"
        raise BomcError(f"this site has {what} that the central store lacks: `bomc sync` it first", store,
                        "sessions" if extra else "node_history")
    return head
