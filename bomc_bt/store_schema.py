"""Opening ``site.db``: the schema, its version check and upgrade, and read-only connections.

A writer (a monitor pass) opens the file read-write: an empty file gets the schema, an
older version is upgraded in place (see :mod:`bomc_bt.store`). A reader (``bomc
evaluate``, ``bomc view``, a build checking whether the site has a graph) opens it
read-only, so it works on a site nobody may write (a copy, an archive, ``chmod a-w``)
and changes no byte of it. SQLite's WAL mode needs care there:

* a ``mode=ro`` connection on a WAL database needs the ``-wal`` and ``-shm`` files, and
  *creates* them when they are missing and the folder is writable (two new files in a
  site that was only read), or fails when the folder is read-only;
* ``immutable=1`` reads the main file alone, creates nothing and takes no lock, but is
  only right while nobody writes.

A writer keeps a ``-wal`` file for as long as it has the database open, and the last
connection to close checkpoints it and deletes it. So: no ``-wal`` file means no writer
had the file open when we looked, and the reader opens it ``immutable`` (nothing created,
nothing written); a ``-wal`` file means a writer is running (or one was killed and its
last frames are only in the WAL), and the reader opens ``mode=ro`` so that it sees them,
falling back to ``immutable`` where the folder cannot hold the ``-shm`` file. A writer
that starts while an immutable reader is reading writes into its new WAL, not the main
file, until 1000 pages have piled up: far longer than ``bomc evaluate`` or the viewer
take to read a site.
"""

from __future__ import annotations

import json
import sqlite3
import urllib.parse
from pathlib import Path

import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.graph.records import Node

SCHEMA_VERSION = 5
READABLE_VERSIONS = (2, 3, 4, 5)  # a reader reads these as they are (version 2 has no event details,
# versions before 4 no region history: their change model is the uniform prior)
FOOTPRINT = ("fx0", "fy0", "fx1", "fy1")
COLOUR = ("cr", "cg")  # a node's look: (r, g) chromaticity (bomc_bt.graph.looks), version 5 on
# Upgrades, in place, from each old version: the columns it lacks (table, column). Version 2
# added the node footprints, version 3 the event details (operator edits, removal evidence),
# version 4 the region history of the change model (a new table: NEW_TABLES), version 5 the
# nodes' colours.
UPGRADES = {1: (("nodes", "fx0"), ("nodes", "fy0"), ("nodes", "fx1"), ("nodes", "fy1")),
            2: (("node_history", "detail"),), 3: (), 4: (("nodes", "cr"), ("nodes", "cg"))}
REGION_TABLE = """CREATE TABLE IF NOT EXISTS region_passes (
    session INTEGER NOT NULL, size REAL NOT NULL, i INTEGER NOT NULL, j INTEGER NOT NULL,
    seen REAL NOT NULL, changes INTEGER NOT NULL, stamp REAL,
    PRIMARY KEY (session, size, i, j));
"""
NEW_TABLES = {3: REGION_TABLE}  # upgrading from version 3 creates the region history (empty)

SCHEMA = """
CREATE TABLE schema_version (version INTEGER NOT NULL);
CREATE TABLE nodes (
    id INTEGER PRIMARY KEY, category TEXT NOT NULL, x REAL NOT NULL, y REAL NOT NULL, z REAL NOT NULL,
    confidence REAL NOT NULL, first_session INTEGER NOT NULL, last_session INTEGER NOT NULL,
    state TEXT NOT NULL, observations INTEGER NOT NULL, misses INTEGER NOT NULL,
    fx0 REAL, fy0 REAL, fx1 REAL, fy1 REAL,
    cr REAL, cg REAL);
CREATE TABLE node_history (
    seq INTEGER PRIMARY KEY AUTOINCREMENT, id INTEGER NOT NULL, session INTEGER NOT NULL,
    stamp REAL NOT NULL, kind TEXT NOT NULL, category TEXT NOT NULL,
    x REAL NOT NULL, y REAL NOT NULL, z REAL NOT NULL, confidence REAL NOT NULL,
    px REAL, py REAL, pz REAL, detail TEXT);
CREATE INDEX node_history_session ON node_history (session);
CREATE TABLE sessions (
    number INTEGER PRIMARY KEY, started_stamp REAL, started_wall TEXT NOT NULL,
    ended_stamp REAL, ended_wall TEXT, outcome TEXT, counts TEXT, report TEXT, info TEXT);
CREATE TABLE progress (key TEXT PRIMARY KEY, value TEXT NOT NULL);
""" + REGION_TABLE
TABLES = {"schema_version", "nodes", "node_history", "sessions", "progress"}


def connect(path: Path, busy_timeout: float, readonly: bool) -> sqlite3.Connection:
    """A connection to ``path``: read-write, or read-only as the module docstring explains."""
    if not readonly:
        return sqlite3.connect(str(path), timeout=busy_timeout, isolation_level=None, check_same_thread=False)
    if not path.is_file():
        raise BomcError("no site store here", path)
    wal = path.with_name(path.name + "-wal")
    if wal.exists():
        db = _connect_ro(path, busy_timeout, immutable=False)
        try:
            db.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()
            return db
        except sqlite3.OperationalError:  # no -shm and a read-only folder: read the main file alone
            db.close()
    return _connect_ro(path, busy_timeout, immutable=True)


def _connect_ro(path: Path, busy_timeout: float, immutable: bool) -> sqlite3.Connection:
    uri = f"file:{urllib.parse.quote(str(path.resolve()))}?mode=ro" + ("&immutable=1" if immutable else "")
    return sqlite3.connect(uri, uri=True, timeout=busy_timeout, isolation_level=None, check_same_thread=False)


def open_schema(db: sqlite3.Connection, path: Path, readonly: bool) -> int:
    """Check (reader) or create / upgrade (writer) the schema of an open store; its version.

    A writer upgrades an old store in place, one version at a time, in one transaction
    (new columns are NULL: nothing already stored changes meaning). A reader takes a
    version 2 store as it is: the event details it lacks read as None.
    """
    tables = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    tables.discard("sqlite_sequence")
    if not tables and not readonly:
        db.execute("PRAGMA journal_mode=WAL")
        _script(db, f"BEGIN IMMEDIATE;{SCHEMA}INSERT INTO schema_version VALUES ({SCHEMA_VERSION});COMMIT;")
        return SCHEMA_VERSION
    if not tables >= TABLES:
        missing = ", ".join(sorted(TABLES - tables))
        raise BomcError(f"not a bomc site store (missing tables: {missing})", path)
    rows = db.execute("SELECT version FROM schema_version").fetchall()
    found = rows[0][0] if len(rows) == 1 else None
    if readonly and found in READABLE_VERSIONS:
        return found
    if readonly and found == 1:
        raise BomcError("a version 1 store is upgraded by the next `bomc monitor`; it cannot be read "
                        "before that", path, "schema_version")
    if not readonly and found in UPGRADES:
        _script(db, "BEGIN IMMEDIATE;" + _upgrade_sql(db, found)
                + f"UPDATE schema_version SET version = {SCHEMA_VERSION};COMMIT;")
        found = SCHEMA_VERSION
    if found != SCHEMA_VERSION:
        raise BomcError(f"unsupported site store schema version {'none' if found is None else found} "
                        f"(expected {SCHEMA_VERSION})", path, "schema_version")
    if not readonly:
        db.execute("PRAGMA journal_mode=WAL")
    return found


def _upgrade_sql(db: sqlite3.Connection, version: int) -> str:
    """The ALTER statements that bring a store of ``version`` to the current schema
    (a column already there is skipped)."""
    statements = []
    for step in range(version, SCHEMA_VERSION):
        statements.append(NEW_TABLES.get(step, ""))
        for table, column in UPGRADES[step]:
            have = {r[1] for r in db.execute(f"PRAGMA table_info({table})")}
            if column not in have:
                statements.append(f"ALTER TABLE {table} ADD COLUMN {column} {_TYPES[column]};")
    return "".join(statements)


_TYPES = {**dict.fromkeys(FOOTPRINT + COLOUR, "REAL"), "detail": "TEXT"}


def _script(db: sqlite3.Connection, script: str) -> None:
    """Run a BEGIN ... COMMIT script, rolled back if any statement fails."""
    try:
        db.executescript(script)
    except BaseException:
        if db.in_transaction:
            db.execute("ROLLBACK")
        raise


# What each column read back must hold: a file edited by hand or by another program can put
# text in a number column or broken JSON in a report; that is an error naming the table,
# column and row, never a crash further on. Kinds: i int, f finite number, s text, j JSON
# object text, J any JSON text; upper case: NULL allowed.
NODE_COLUMNS = "isffffiisiiFFFFFF"
EVENT_COLUMNS = "iifssffffFFF"
SESSION_COLUMNS = "iFsFSSjjj"
REGION_COLUMNS = "ifiifiF"
NAMES = {
    "nodes": ("id", "category", "x", "y", "z", "confidence", "first_session", "last_session", "state",
              "observations", "misses", *FOOTPRINT, *COLOUR),
    "node_history": ("id", "session", "stamp", "kind", "category", "x", "y", "z", "confidence", "px", "py", "pz",
                     "detail"),
    "sessions": ("number", "started_stamp", "started_wall", "ended_stamp", "ended_wall", "outcome", "counts",
                 "report", "info"),
    "progress": ("value",),
    "region_passes": ("session", "size", "i", "j", "seen", "changes", "stamp"),
}
_INT_LIMIT = 2**62


# the store version that added each column a version 2 store lacks (read as NULL before it)
SINCE = {"detail": 3, **dict.fromkeys(COLOUR, 5)}


def select_list(columns: tuple[str, ...], version: int) -> str:
    """A SELECT list of ``columns`` for a store of ``version``: NULL for a column it lacks."""
    return ", ".join("NULL" if version < SINCE.get(c, 0) else c for c in columns)


def row_node(row: tuple) -> Node:
    """A node from a checked row of the ``nodes`` columns (:func:`select_list` of ``NAMES["nodes"]``)."""
    nid, cat, x, y, z, conf, first, last, state, obs, misses, *box, cr, cg = row
    return Node(nid, cat, np.array([x, y, z]), conf, first, last, state, obs, misses,
                None if None in box else np.array(box, dtype=float), colour=None if None in (cr, cg) else (cr, cg))


def checked_rows(rows: list[tuple], kinds: str, path: Path, table: str) -> list[tuple]:
    """``rows`` with every value checked against ``kinds`` (JSON columns parsed)."""
    return [tuple(_checked(v, k, path, table, i, n) for i, (v, k) in enumerate(zip(row, kinds, strict=True)))
            for n, row in enumerate(rows)]


def _checked(value, kind: str, path: Path, table: str, column: int, row: int):
    if value is None and kind in "IFSJj":
        return {} if kind == "j" else None
    if kind in "iI" and isinstance(value, int) and abs(value) < _INT_LIMIT:
        return value
    if kind in "fF" and isinstance(value, (int, float)) and abs(value) < 1e12:  # also refuses NaN
        return value
    if kind in "sS" and isinstance(value, str):
        return value
    if kind in "jJ" and isinstance(value, str):
        if kind == "j" and not value:
            return {}
        try:
            parsed = json.loads(value)
        except ValueError:
            parsed = _BAD
        if parsed is not _BAD and (kind == "J" or isinstance(parsed, dict)):
            return parsed
    names = NAMES.get(table, ())
    name = names[column] if column < len(names) else f"column {column + 1}"
    raise BomcError(f"corrupt site store: {table}.{name} of row {row + 1} holds {repr(value)[:40]}", path,
                    f"{table}.{name}")


_BAD = object()
