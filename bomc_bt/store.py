"""The site store: ``<site>/site.db``, the object graph's current state and its full history.

One SQLite file (stdlib ``sqlite3``) per site, because a monitor pass must survive being
killed: every frame's events and changed nodes are written in ONE transaction, so a kill
loses at most the frame in flight and a resumed pass starts from a consistent graph.
WAL journaling keeps readers (``bomc evaluate``, a viewer) off the writer's back; they
open the store with ``readonly=True`` and change no byte of the site
(:mod:`bomc_bt.store_schema`, which also holds the schema and its upgrade).

Tables:

* ``schema_version`` -- one row; an unknown version or a file without our tables is
  refused (:class:`BomcError`). A writer upgrades older stores in place, in one
  transaction, adding empty columns and tables (:mod:`bomc_bt.store_schema`): nothing in
  them changes meaning. A reader reads versions 2 to 5 as they are.
* ``nodes`` -- the current state of every id ever issued (removed ones ``removed``), so the
  next id continues from the max id ever issued; with the floor footprint the association
  learned and its colour (``cr``, ``cg``, version 5 on, :mod:`bomc_bt.graph.looks`), or NULL.
* ``node_history`` -- every event, append-only; :meth:`SiteStore.graph_after` rebuilds
  the graph as it stood at the end of any session from it. Nothing is overwritten.
  ``detail`` (JSON, may be NULL) holds a removal's evidence (misses, seen, merged), marks the
  rows an ended session writes to reconcile positions, and carries an operator's edit
  (:data:`~bomc_bt.graph.OPERATOR_KINDS`, :mod:`bomc_bt.site.edits`), which
  :meth:`SiteStore.events` leaves out unless asked: a pass's events are what it observed.
* ``sessions`` -- one row per monitor pass: started/ended robot time and wall time (the
  wall time is for people reading the report, never for timing), outcome, counts, report.
* ``progress`` -- JSON key/value pairs for resuming a mission: a pass's plan and next waypoint,
  its masks, its resume point in rows written when changed (:mod:`bomc_bt.resume_rows`).
* ``region_passes`` -- per pass and map region: how much of it was seen, how many changes
  (the change model's history, :mod:`bomc_bt.change_model`; version 4 on).

Every sqlite3 failure (not a database, locked, disk full) becomes a ``BomcError`` naming
the file: a user meets these by pointing at the wrong file or running two passes at once.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import json
import sqlite3
import threading
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.graph import OPERATOR_KINDS, PRESENT, AssociationParams, Event, Node, ObjectGraph
from bomc_bt.graph.history import replay_graph  # also what readers of the central store replay
from bomc_bt.graph.operator_edits import OperatorEdits
from bomc_bt.json_text import to_jsonable as _jsonable
from bomc_bt.store_progress import put_progress as _put_progress
from bomc_bt.store_schema import (
    EVENT_COLUMNS,
    NAMES,
    NODE_COLUMNS,
    REGION_COLUMNS,
    SCHEMA,
    SESSION_COLUMNS,
    checked_rows,
    connect,
    open_schema,
    row_node,
    select_list,
)

FILENAME = "site.db"
_OPERATOR_SQL = "(" + ", ".join(f"'{k}'" for k in OPERATOR_KINDS) + ")"
_SCHEMA = SCHEMA  # the schema text, for tests that write old versions of it


@dataclass
class SessionRecord:
    """One row of the ``sessions`` table."""

    number: int
    started_stamp: float | None
    started_wall: str
    ended_stamp: float | None = None
    ended_wall: str | None = None
    outcome: str | None = None
    counts: dict[str, Any] = field(default_factory=dict)
    report: dict[str, Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def ended(self) -> bool:
        return self.ended_wall is not None


class SiteStore:
    """The persistent graph of one site. ``path`` is ``<site>/site.db`` or the site folder."""

    def __init__(self, path: str | Path, busy_timeout: float = 2.0, readonly: bool = False):
        path = Path(path) / FILENAME if Path(path).is_dir() else Path(path)
        self.path, self.readonly = path, readonly
        self._lock = threading.Lock()
        if not readonly:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise BomcError(f"cannot create the site folder ({exc.strerror})", path) from None
        with self._errors("open"):
            self._db = connect(path, busy_timeout, readonly)
        try:
            with self._errors("open"):
                self.version = open_schema(self._db, path, readonly)
        except BomcError:
            self._db.close()
            raise

    # ------------------------------------------------------------- plumbing
    @contextlib.contextmanager
    def _errors(self, action: str) -> Iterator[None]:
        try:
            yield
        except sqlite3.DatabaseError as exc:
            text = str(exc)
            if "disk is full" in text or "disk I/O error" in text:  # the environment, not the input: exit 1
                raise OSError(errno.ENOSPC if "full" in text else errno.EIO, text, str(self.path)) from None
            if "not a database" in text or "malformed" in text:
                msg = f"not a bomc site store (the file is not an SQLite database or is corrupt: {text})"
            elif "locked" in text or "busy" in text:
                msg = f"the site store is locked by another process ({action}: {text})"
            else:
                msg = f"site store error during {action}: {text}"
            raise BomcError(msg, self.path) from None

    @contextlib.contextmanager
    def _transaction(self, action: str, durable: bool = True) -> Iterator[sqlite3.Connection]:
        """BEGIN IMMEDIATE ... COMMIT, rolled back on any exception (also non-sqlite ones).

        ``durable`` False commits without syncing the disk (WAL ``synchronous=NORMAL``): the
        commit is atomic and survives a kill or a crash of the process; only a power loss
        may take it back, and with it nothing older than the last durable commit, whose
        sync writes every commit before it. A monitor pass commits each frame this way
        (a sync per frame was 3 ms, about 50 s of an Environment-A pass) and each
        waypoint durably.
        """
        with self._lock, self._errors(action):
            if not durable:
                self._db.execute("PRAGMA synchronous=NORMAL")
            try:
                self._db.execute("BEGIN IMMEDIATE")
                try:
                    yield self._db
                except BaseException:
                    if self._db.in_transaction:  # SQLite rolls back by itself on SQLITE_FULL and I/O errors
                        self._db.execute("ROLLBACK")
                    raise
                self._db.execute("COMMIT")
            finally:
                if not durable:
                    self._db.execute("PRAGMA synchronous=FULL")

    def _query(self, sql: str, args: tuple = (), kinds: str = "", table: str = "") -> list[tuple]:
        """Rows of ``sql``; with ``kinds``, each value checked (store_schema.checked_rows)."""
        with self._lock, self._errors("read"):
            rows = self._db.execute(sql, args).fetchall()
        return checked_rows(rows, kinds, self.path, table) if kinds else rows

    def verify(self) -> None:
        """Read every row once, checked: a writer calls it before it writes, so that a corrupt
        store is refused (exit 2) with nothing changed instead of failing half-way."""
        self.sessions()
        self.nodes(include_removed=True)
        self.events()
        self.region_rows()
        for (key,) in self._query("SELECT key FROM progress", (), "s", "progress"):
            self.get_progress(key)

    def close(self) -> None:
        with self._lock:
            self._db.close()

    def __enter__(self) -> SiteStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------- sessions
    def next_session(self) -> int:
        """The number a new session should get: one past the highest recorded (1 if none)."""
        rows = self._query("SELECT MAX(number) FROM sessions", (), "I", "sessions")
        return (rows[0][0] or 0) + 1

    def begin_session(self, number: int, info: dict[str, Any] | None = None) -> bool:
        """Start session ``number`` (``info["stamp"]``: robot time). Returns True when resuming.

        Beginning a session that was started but never ended resumes it (a killed pass);
        one that already ended is refused, since its history is final.
        """
        info = dict(info or {})
        with self._transaction("begin_session") as db:
            row = db.execute("SELECT ended_wall FROM sessions WHERE number=?", (number,)).fetchone()
            if row is not None:
                if row[0] is not None:
                    raise BomcError(f"session {number} has already ended", self.path, "sessions")
                return True
            db.execute(
                "INSERT INTO sessions (number, started_stamp, started_wall, info) VALUES (?, ?, ?, ?)",
                (number, _opt_float(info.get("stamp")), _now(), json.dumps(info, default=_jsonable)),
            )
            return False

    def end_session(self, number: int, outcome: str, summary: dict[str, Any] | None = None,
                    regions: list[tuple] = (), progress: dict[str, Any] | None = None) -> None:
        """Close session ``number`` in one transaction: reconcile history with the nodes, store counts,
        report, ``regions`` rows (:mod:`bomc_bt.change_model`), ``progress`` keys (final masks).

        Reconciling appends an ``updated`` row for each present node whose position or
        confidence differs from its last history row (refreshes between sparse events), so
        :meth:`graph_after` is exact at session boundaries.
        """
        summary = dict(summary or {})
        stamp = _opt_float(summary.get("stamp"))
        with self._transaction("end_session") as db:
            if db.execute("SELECT 1 FROM sessions WHERE number=?", (number,)).fetchone() is None:
                raise BomcError(f"session {number} was never begun", self.path, "sessions")
            self._reconcile(db, number, stamp)
            db.executemany("INSERT OR REPLACE INTO region_passes VALUES (?, ?, ?, ?, ?, ?, ?)", regions)
            _put_progress(db, progress)
            counts = dict(db.execute(
                f"SELECT kind, COUNT(*) FROM node_history WHERE session=? AND kind NOT IN {_OPERATOR_SQL}"
                " GROUP BY kind", (number,)
            ).fetchall())
            present = db.execute("SELECT COUNT(*) FROM nodes WHERE state=?", (PRESENT,)).fetchone()[0]
            counts["present"] = present
            counts.update(summary.get("counts", {}))
            db.execute(
                "UPDATE sessions SET ended_stamp=?, ended_wall=?, outcome=?, counts=?, report=?"
                " WHERE number=?",
                (stamp, _now(), outcome, json.dumps(counts, default=_jsonable),
                 json.dumps(summary, default=_jsonable), number),
            )

    def reconcile(self, session: int, stamp: float | None) -> None:
        """Append the ``updated`` rows that make the history exact now (what :meth:`end_session`
        does first; calling it before changes nothing the end writes)."""
        with self._transaction("reconcile") as db:
            self._reconcile(db, session, stamp)

    def _reconcile(self, db: sqlite3.Connection, session: int, stamp: float | None) -> None:
        rows = db.execute(
            """SELECT n.id, n.category, n.x, n.y, n.z, n.confidence, h.x, h.y, h.z, h.confidence
               FROM nodes n JOIN node_history h ON h.seq =
                   (SELECT MAX(seq) FROM node_history WHERE id = n.id)
               WHERE n.state = ?""",
            (PRESENT,),
        ).fetchall()
        if stamp is None:
            last = db.execute("SELECT MAX(stamp) FROM node_history WHERE session=?", (session,)).fetchone()[0]
            stamp = last if last is not None else 0.0
        for nid, cat, x, y, z, c, hx, hy, hz, hc in rows:
            if (x, y, z, c) != (hx, hy, hz, hc):
                db.execute("INSERT INTO node_history (id, session, stamp, kind, category, x, y, z, confidence,"
                           " detail) VALUES (?, ?, ?, 'updated', ?, ?, ?, ?, ?, '{\"reconciled\": true}')",
                           (nid, session, stamp, cat, x, y, z, c))

    def sessions(self) -> list[SessionRecord]:
        rows = self._query("SELECT number, started_stamp, started_wall, ended_stamp, ended_wall, outcome, counts,"
                           " report, info FROM sessions ORDER BY number", (), SESSION_COLUMNS, "sessions")
        return [SessionRecord(*row) for row in rows]

    # ---------------------------------------------------------------- graph
    def record(
        self, events: Iterable[Event], nodes_changed: Iterable[Node], progress: dict[str, Any] | None = None,
        durable: bool = True,
    ) -> None:
        """Write one frame's events, changed nodes (and progress keys) in ONE transaction
        (``durable``: see :meth:`_transaction`)."""
        with self._transaction("record", durable) as db:
            for e in events:
                prev = (None, None, None) if e.previous is None else tuple(map(float, _xyz(e.previous)))
                detail = None if e.detail is None else json.dumps(e.detail, default=_jsonable)
                db.execute(
                    "INSERT INTO node_history (id, session, stamp, kind, category, x, y, z, confidence,"
                    " px, py, pz, detail) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (int(e.node_id), int(e.session), float(e.stamp), e.kind, e.category,
                     *map(float, _xyz(e.position)), float(e.confidence), *prev, detail),
                )
            for n in nodes_changed:
                box = (None,) * 4 if n.footprint is None else tuple(map(float, n.footprint))
                look = (None,) * 2 if n.colour is None else tuple(map(float, n.colour))
                db.execute(
                    "INSERT OR REPLACE INTO nodes VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (int(n.id), n.category, *map(float, _xyz(n.position)), float(n.confidence),
                     int(n.first_session), int(n.last_session), n.state, int(n.observations), int(n.misses),
                     *box, *look),
                )
            _put_progress(db, progress)

    def load_graph(self, params: AssociationParams) -> ObjectGraph:
        """The live graph (present nodes) with the operator's edits it must respect; new ids
        continue past every id ever issued."""
        nodes = self._nodes("WHERE state=? ORDER BY id", (PRESENT,))
        top = self._query("SELECT MAX(m) FROM (SELECT MAX(id) AS m FROM nodes UNION ALL"
                          " SELECT MAX(id) FROM node_history)", (), "I", "nodes")[0][0]
        edited = self._events(f" WHERE id IN (SELECT id FROM node_history WHERE kind IN {_OPERATOR_SQL})"
                              " ORDER BY seq", ())
        return ObjectGraph(params, nodes, next_id=0 if top is None else top + 1,
                           edits=OperatorEdits.from_history(edited))

    def categories(self) -> list[str]:
        """Every category a node of this store ever had, sorted."""
        return [r[0] for r in self._query("SELECT category FROM node_history UNION SELECT category FROM nodes"
                                          " ORDER BY 1", (), "s", "node_history")]

    def nodes(self, include_removed: bool = False) -> list[Node]:
        """The current node table (present nodes, or all ids ever issued)."""
        if include_removed:
            return self._nodes("ORDER BY id", ())
        return self._nodes("WHERE state=? ORDER BY id", (PRESENT,))

    def _nodes(self, tail: str, args: tuple) -> list[Node]:
        """Nodes of ``SELECT ... FROM nodes <tail>``."""
        sql = f"SELECT {select_list(NAMES['nodes'], self.version)} FROM nodes {tail}"
        return [row_node(row) for row in self._query(sql, args, NODE_COLUMNS, "nodes")]

    def graph_after(self, session: int) -> list[Node]:
        """The present nodes as they stood at the end of ``session``, replayed from history.

        ``observations`` counts the node's add/update/move events (history does not keep
        every match) and ``misses`` is 0: both are bookkeeping, not part of the map.
        Operator edits count from the pass they are filed under, the one after them
        (:mod:`bomc_bt.site.edits`): the map that pass started from.
        """
        return replay_graph(self.events(until=session, operator=True))

    def events(self, session: int | None = None, until: int | None = None, operator: bool = False) -> list[Event]:
        """History in write order: of one ``session``, up to and including ``until``, or all.

        The robot's events only, unless ``operator``: a pass's events are what it observed,
        an operator's edits (:data:`~bomc_bt.graph.OPERATOR_KINDS`) are asked for apart.
        """
        where = [] if operator else [f"kind NOT IN {_OPERATOR_SQL}"]
        args: tuple = ()
        if session is not None:
            where, args = [*where, "session=?"], (session,)
        elif until is not None:
            where, args = [*where, "session<=?"], (until,)
        return self._events((" WHERE " + " AND ".join(where) if where else "") + " ORDER BY seq", args)

    def _events(self, tail: str, args: tuple) -> list[Event]:
        columns = select_list(NAMES["node_history"], self.version)
        rows = self._query(f"SELECT {columns} FROM node_history" + tail, args, EVENT_COLUMNS + "J", "node_history")
        for n, row in enumerate(rows):
            if len({v is None for v in row[9:12]}) > 1:  # a previous position is all three or none
                raise BomcError(f"corrupt site store: node_history row {n + 1} has a partial previous position",
                                self.path, "node_history.px")
        return [
            Event(kind, nid, cat, np.array([x, y, z]), sess, stamp,
                  None if px is None else np.array([px, py, pz]), conf, text)
            for nid, sess, stamp, kind, cat, x, y, z, conf, px, py, pz, text in rows
        ]

    def region_rows(self) -> list[tuple]:
        """(session, size, i, j, seen, changes, stamp) per pass and region; none before version 4."""
        sql = "SELECT session, size, i, j, seen, changes, stamp FROM region_passes ORDER BY session, i, j"
        return [] if self.version < 4 else self._query(sql, (), REGION_COLUMNS, "region_passes")

    # ------------------------------------------------------------- progress
    def set_progress(self, key: str, value: Any) -> None:
        """Store a JSON-able value (e.g. the next waypoint index) for resuming."""
        with self._transaction("set_progress") as db:
            _put_progress(db, {key: value})

    def get_progress(self, key: str, default: Any = None) -> Any:
        rows = self._query("SELECT value FROM progress WHERE key=?", (key,), "J", "progress")
        return rows[0][0] if rows else default

    def progress_below(self, key: str) -> dict[str, Any]:
        """Row ``key`` and the rows below it (``key/...``), read in one statement: one moment's
        rows while a pass is writing them (:mod:`bomc_bt.resume_rows`)."""
        sql = "SELECT key, value FROM progress WHERE key=? OR substr(key, 1, ?)=?"
        return dict(self._query(sql, (key, len(key) + 1, key + "/"), "sJ", "progress"))


def _xyz(p: np.ndarray) -> np.ndarray:
    arr = np.asarray(p, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"position must be 3 finite numbers, got {arr.tolist()}")
    return arr


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def _opt_float(value: Any) -> float | None:
    return None if value is None else float(value)
