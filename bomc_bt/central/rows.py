"""The object graph's rows, read from a site's SQLite store or from the central schema, and written locally.

The same five tables on both sides, with the same columns (:data:`COLUMNS`): sessions,
nodes (current state of every id), node history (append-only, ordered by ``seq``), the
pass's resume progress and the change model's rows per pass and region. Rows are plain
tuples, compared as they are: a float read from SQLite and from a PostgreSQL ``double
precision`` column is the same float, so equal tuples mean an equal graph.

The local side is read in ONE read transaction (one snapshot: a pass writing beside the
sync adds whole frames after it, never half of one) and written in ONE write transaction
(a killed pull leaves the store as it was).
"""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bomc_bt.errors import BomcError
from bomc_bt.store_schema import connect, open_schema, select_list

COLUMNS: dict[str, tuple[str, ...]] = {
    "sessions": ("number", "started_stamp", "started_wall", "ended_stamp", "ended_wall", "outcome", "counts",
                 "report", "info"),
    "nodes": ("id", "category", "x", "y", "z", "confidence", "first_session", "last_session", "state",
              "observations", "misses", "fx0", "fy0", "fx1", "fy1", "cr", "cg"),
    "node_history": ("seq", "id", "session", "stamp", "kind", "category", "x", "y", "z", "confidence", "px", "py",
                     "pz", "detail"),
    "progress": ("key", "value"),
    "region_passes": ("session", "size", "i", "j", "seen", "changes", "stamp"),
}
ORDER = {"sessions": "number", "nodes": "id", "node_history": "seq", "progress": "key",
         "region_passes": "session, size, i, j"}
REGION_TABLE_SINCE = 4  # local store version that has region_passes (the change model)


@dataclass
class GraphRows:
    """One generation's graph: every row of each table (history: those after ``since``)."""

    sessions: list[tuple] = field(default_factory=list)
    nodes: list[tuple] = field(default_factory=list)
    node_history: list[tuple] = field(default_factory=list)
    progress: list[tuple] = field(default_factory=list)
    region_passes: list[tuple] = field(default_factory=list)
    since: int = 0  # history rows with seq <= since are not in node_history

    def table(self, name: str) -> list[tuple]:
        return getattr(self, name)

    @property
    def last_seq(self) -> int:
        return self.node_history[-1][0] if self.node_history else self.since


def read_local(path: Path, since: int = 0) -> GraphRows:
    """All rows of a site store (history after seq ``since``), one snapshot, read-only."""
    db, version = _open_local(path, readonly=True)
    try:
        db.execute("BEGIN")
        rows = GraphRows(since=since)
        for table in COLUMNS:
            if table == "region_passes" and version < REGION_TABLE_SINCE:
                continue  # an older store: no change model yet
            where = " WHERE seq > ?" if table == "node_history" else ""
            args = (since,) if where else ()
            rows.table(table).extend(db.execute(
                f"SELECT {_local_columns(table, version)} FROM {table}{where} ORDER BY {ORDER[table]}",
                args).fetchall())
        db.execute("COMMIT")
        return rows
    except sqlite3.DatabaseError as exc:
        raise BomcError(f"cannot read the site store ({exc})", path) from None
    finally:
        db.close()


def local_history_row(path: Path, seq: int) -> tuple | None:
    db, version = _open_local(path, readonly=True)
    try:
        cols = _local_columns("node_history", version)
        return db.execute(f"SELECT {cols} FROM node_history WHERE seq = ?", (seq,)).fetchone()
    finally:
        db.close()


def read_central(conn: Any, key: tuple[str, str, int], since: int = 0) -> GraphRows:
    """The rows of one floor's generation in the central store (the caller holds the transaction)."""
    rows = GraphRows(since=since)
    for table, cols in COLUMNS.items():
        extra = " AND seq > %s" if table == "node_history" else ""
        rows.table(table).extend(tuple(r) for r in conn.execute(
            f"SELECT {', '.join(cols)} FROM bomc.{table} WHERE building = %s AND floor = %s AND generation = %s"
            f"{extra} ORDER BY {ORDER[table]}", (*key, since) if extra else key).fetchall())
    return rows


def write_local(path: Path, rows: GraphRows) -> None:
    """Make a site store hold ``rows``: history appended, other tables replaced; one transaction.

    The caller holds the site's writer lock and has checked that the store's history is
    a prefix of ``rows`` (``rows.since`` is the store's last seq).
    """
    from bomc_bt.store import SiteStore

    SiteStore(path).close()  # creates (or upgrades) the schema
    db, _ = _open_local(path, readonly=False)
    try:
        db.execute("BEGIN IMMEDIATE")
        try:
            for table, cols in COLUMNS.items():
                if table != "node_history":
                    db.execute(f"DELETE FROM {table}")
                marks = ", ".join("?" * len(cols))
                db.executemany(f"INSERT INTO {table} ({', '.join(cols)}) VALUES ({marks})", rows.table(table))
        except BaseException:
            db.execute("ROLLBACK")
            raise
        db.execute("COMMIT")
    except sqlite3.DatabaseError as exc:
        raise BomcError(f"cannot write the site store ({exc})", path) from None
    finally:
        db.close()


def _local_columns(table: str, version: int) -> str:
    """The SELECT list of ``table`` in a local store of ``version`` (version 2 has no ``detail``,
    versions before 5 no node colours)."""
    return select_list(COLUMNS[table], version)


def _open_local(path: Path, readonly: bool) -> tuple[sqlite3.Connection, int]:
    try:
        db = connect(path, 5.0, readonly)
        return db, open_schema(db, path, readonly)
    except sqlite3.DatabaseError as exc:
        raise BomcError(f"not a bomc site store ({exc})", path) from None
