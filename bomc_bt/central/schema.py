"""The central schema (PostgreSQL schema ``bomc``), its version, and its migrations in place.

Every table is keyed by building and floor, the graph's tables also by map generation;
the robot that ran a pass is a column of its session (the first robot to push a session
is the one that ran it: another robot can only have it by pulling it from here). The
column lists mirror the local SQLite store (:mod:`bomc_bt.store_schema`) so that rows
travel unchanged and the graph replayed from either is the same to the last bit.

``MIGRATIONS[n]`` takes a version ``n - 1`` schema to version ``n`` (version 0: nothing
there). A writer (sync, pull, a pass taking its lease) runs the missing steps in one
transaction under an advisory lock, so two robots upgrading at once do it once and a
kill leaves the old version whole; a reader checks the version and never writes. Table by
table with its meaning: ``docs/central-store.md``.
"""

from __future__ import annotations

from typing import Any

from bomc_bt.errors import BomcError

SCHEMA = "bomc"
VERSION = 5
MIGRATION_LOCK = 0x626F6D63  # pg_advisory_xact_lock key of schema changes ("bomc")

_FLOOR = "building text NOT NULL, floor text NOT NULL"
_GEN = _FLOOR + ", generation integer NOT NULL"

MIGRATIONS: dict[int, str] = {
    1: f"""
CREATE TABLE bomc.floors ({_FLOOR}, current_generation integer, PRIMARY KEY (building, floor));
CREATE TABLE bomc.generations ({_GEN}, robot text NOT NULL, first_synced timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY (building, floor, generation), FOREIGN KEY (building, floor) REFERENCES bomc.floors);
CREATE TABLE bomc.sessions ({_GEN}, number integer NOT NULL, robot text NOT NULL,
    started_stamp double precision, started_wall text NOT NULL, ended_stamp double precision, ended_wall text,
    outcome text, counts text, report text, info text,
    PRIMARY KEY (building, floor, generation, number), FOREIGN KEY (building, floor, generation)
    REFERENCES bomc.generations);
CREATE TABLE bomc.nodes ({_GEN}, id integer NOT NULL, category text NOT NULL,
    x double precision NOT NULL, y double precision NOT NULL, z double precision NOT NULL,
    confidence double precision NOT NULL, first_session integer NOT NULL, last_session integer NOT NULL,
    state text NOT NULL, observations integer NOT NULL, misses integer NOT NULL,
    fx0 double precision, fy0 double precision, fx1 double precision, fy1 double precision,
    PRIMARY KEY (building, floor, generation, id), FOREIGN KEY (building, floor, generation)
    REFERENCES bomc.generations);
CREATE TABLE bomc.node_history ({_GEN}, seq bigint NOT NULL, id integer NOT NULL, session integer NOT NULL,
    stamp double precision NOT NULL, kind text NOT NULL, category text NOT NULL,
    x double precision NOT NULL, y double precision NOT NULL, z double precision NOT NULL,
    confidence double precision NOT NULL, px double precision, py double precision, pz double precision,
    PRIMARY KEY (building, floor, generation, seq), FOREIGN KEY (building, floor, generation)
    REFERENCES bomc.generations);
CREATE INDEX node_history_session ON bomc.node_history (building, floor, generation, session);
CREATE TABLE bomc.progress ({_GEN}, key text NOT NULL, value text NOT NULL,
    PRIMARY KEY (building, floor, generation, key));
CREATE TABLE bomc.files ({_GEN}, path text NOT NULL, sha256 text NOT NULL, content bytea NOT NULL,
    PRIMARY KEY (building, floor, generation, path), FOREIGN KEY (building, floor, generation)
    REFERENCES bomc.generations);
""",
    2: f"""
CREATE TABLE bomc.leases ({_FLOOR}, robot text NOT NULL, host text NOT NULL, pid integer NOT NULL,
    command text NOT NULL, taken_at timestamptz NOT NULL, expires_at timestamptz NOT NULL,
    PRIMARY KEY (building, floor));
CREATE TABLE bomc.sync_log (id bigserial PRIMARY KEY, {_FLOOR}, robot text NOT NULL,
    synced_at timestamptz NOT NULL DEFAULT now(), rows jsonb NOT NULL);
""",
    # the local store's node_history.detail (site.db schema 3): removal evidence, operator edits
    3: "ALTER TABLE bomc.node_history ADD COLUMN IF NOT EXISTS detail text;",
    # the local store's change model rows (site.db schema 4): what each pass looked at and found per region
    4: f"""
CREATE TABLE bomc.region_passes ({_GEN}, session integer NOT NULL, size double precision NOT NULL,
    i integer NOT NULL, j integer NOT NULL, seen double precision NOT NULL, changes integer NOT NULL,
    stamp double precision, PRIMARY KEY (building, floor, generation, session, size, i, j));
""",
    # the local store's node colours (site.db schema 5): how each object looks (bomc_bt.graph.looks)
    5: "ALTER TABLE bomc.nodes ADD COLUMN IF NOT EXISTS cr double precision, "
       "ADD COLUMN IF NOT EXISTS cg double precision;",
}


def installed_version(conn: Any) -> int:
    """The schema version in the database (0: no bomc schema yet)."""
    exists = conn.execute("SELECT to_regclass('bomc.schema_version')").fetchone()[0]
    if exists is None:
        return 0
    rows = conn.execute("SELECT version FROM bomc.schema_version").fetchall()
    if len(rows) != 1:
        raise BomcError(f"bomc.schema_version has {len(rows)} rows (expected 1)", None, "schema_version")
    return int(rows[0][0])


def migrate(conn: Any, shown: str) -> int:
    """Bring the schema to :data:`VERSION` in one transaction; returns the version found before."""
    with conn.transaction():
        conn.execute("SELECT pg_advisory_xact_lock(%s)", (MIGRATION_LOCK,))
        found = installed_version(conn)
        _refuse_newer(found, shown)
        if found == 0:
            conn.execute(f"CREATE SCHEMA IF NOT EXISTS {SCHEMA}")
            conn.execute("CREATE TABLE bomc.schema_version (version integer NOT NULL)")
            conn.execute("INSERT INTO bomc.schema_version VALUES (0)")
        for step in range(found + 1, VERSION + 1):
            for statement in _statements(MIGRATIONS[step]):
                conn.execute(statement)
        conn.execute("UPDATE bomc.schema_version SET version = %s", (VERSION,))
    return found


def check(conn: Any, shown: str) -> None:
    """A reader's check: the schema is there and is the version this code reads."""
    found = installed_version(conn)
    _refuse_newer(found, shown)
    if found == 0:
        raise BomcError("no bomc schema in this database: `bomc sync` a site to it first", shown)
    if found < VERSION:
        raise BomcError(f"central schema version {found} is older than {VERSION}: the next `bomc sync` or "
                        "`bomc pull` upgrades it in place", shown, "schema_version")


def _refuse_newer(found: int, shown: str) -> None:
    if found > VERSION:
        raise BomcError(f"central schema version {found} is newer than this bomc reads ({VERSION}): "
                        "upgrade bomc", shown, "schema_version")


def _statements(script: str) -> list[str]:
    return [s.strip() for s in script.split(";") if s.strip()]
