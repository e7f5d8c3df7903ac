"""Opening ``site.db``: the schema, its version check and upgrade, and read-only connections.

A writer (a monitor pass) opens the file read-write: an empty file gets the schema, a
version 1 file is upgraded in place (see :mod:`bomc_bt.store`). A reader (``bomc
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

import sqlite3
import urllib.parse
from pathlib import Path

from bomc_bt.errors import BomcError

SCHEMA_VERSION = 3
FOOTPRINT = ("fx0", "fy0", "fx1", "fy1")
# the evidence a removal was decided on (version 3): misses counted, robot time last seen, merge
EVIDENCE = ("misses", "seen", "merged_into")
_ADDED_COLUMNS = {"nodes": [f"{c} REAL" for c in FOOTPRINT],
                  "node_history": ["misses INTEGER", "seen REAL", "merged_into INTEGER"]}

SCHEMA = """
CREATE TABLE schema_version (version INTEGER NOT NULL);
CREATE TABLE nodes (
    id INTEGER PRIMARY KEY, category TEXT NOT NULL, x REAL NOT NULL, y REAL NOT NULL, z REAL NOT NULL,
    confidence REAL NOT NULL, first_session INTEGER NOT NULL, last_session INTEGER NOT NULL,
    state TEXT NOT NULL, observations INTEGER NOT NULL, misses INTEGER NOT NULL,
    fx0 REAL, fy0 REAL, fx1 REAL, fy1 REAL);
CREATE TABLE node_history (
    seq INTEGER PRIMARY KEY AUTOINCREMENT, id INTEGER NOT NULL, session INTEGER NOT NULL,
    stamp REAL NOT NULL, kind TEXT NOT NULL, category TEXT NOT NULL,
    x REAL NOT NULL, y REAL NOT NULL, z REAL NOT NULL, confidence REAL NOT NULL,
    px REAL, py REAL, pz REAL, misses INTEGER, seen REAL, merged_into INTEGER);
CREATE INDEX node_history_session ON node_history (session);
CREATE TABLE sessions (
    number INTEGER PRIMARY KEY, started_stamp REAL, started_wall TEXT NOT NULL,
    ended_stamp REAL, ended_wall TEXT, outcome TEXT, counts TEXT, report TEXT, info TEXT);
CREATE TABLE progress (key TEXT PRIMARY KEY, value TEXT NOT NULL);
"""
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


def open_schema(db: sqlite3.Connection, path: Path, readonly: bool) -> None:
    """Check (reader) or create / upgrade (writer) the schema of an open store."""
    tables = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    tables.discard("sqlite_sequence")
    if not tables and not readonly:
        db.execute("PRAGMA journal_mode=WAL")
        _script(db, f"BEGIN IMMEDIATE;{SCHEMA}INSERT INTO schema_version VALUES ({SCHEMA_VERSION});COMMIT;")
        return
    if not tables >= TABLES:
        missing = ", ".join(sorted(TABLES - tables))
        raise BomcError(f"not a bomc site store (missing tables: {missing})", path)
    rows = db.execute("SELECT version FROM schema_version").fetchall()
    if len(rows) == 1 and rows[0][0] == 1 and readonly:
        raise BomcError("a version 1 store is upgraded by the next `bomc monitor`; it cannot be read "
                        "before that", path, "schema_version")
    if len(rows) == 1 and rows[0][0] == 2 and readonly:
        return  # read as it is: its history has no removal evidence (has_evidence is False)
    if len(rows) == 1 and rows[0][0] in (1, 2):
        _script(db, "BEGIN IMMEDIATE;" + "".join(_missing_columns(db))
                + f"UPDATE schema_version SET version = {SCHEMA_VERSION};COMMIT;")
        rows = [(SCHEMA_VERSION,)]
    if len(rows) != 1 or rows[0][0] != SCHEMA_VERSION:
        found = rows[0][0] if len(rows) == 1 else "none"
        raise BomcError(f"unsupported site store schema version {found} (expected {SCHEMA_VERSION})",
                        path, "schema_version")
    if not readonly:
        db.execute("PRAGMA journal_mode=WAL")


def _missing_columns(db: sqlite3.Connection) -> list[str]:
    """ALTER TABLE statements adding what versions 1 (footprints) and 2 (evidence) lack."""
    out = []
    for table, columns in _ADDED_COLUMNS.items():
        have = {r[1] for r in db.execute(f"PRAGMA table_info({table})")}
        out += [f"ALTER TABLE {table} ADD COLUMN {c};" for c in columns if c.split()[0] not in have]
    return out


def has_evidence(db: sqlite3.Connection) -> bool:
    """Whether the history has the removal evidence columns (a version 2 store read-only has not)."""
    return {r[1] for r in db.execute("PRAGMA table_info(node_history)")} >= set(EVIDENCE)


def _script(db: sqlite3.Connection, script: str) -> None:
    """Run a BEGIN ... COMMIT script, rolled back if any statement fails."""
    try:
        db.executescript(script)
    except BaseException:
        if db.in_transaction:
            db.execute("ROLLBACK")
        raise
