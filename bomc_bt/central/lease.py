"""One pass per floor: a lease row in the central store, with an expiry, held while a pass runs.

A monitor pass on a site that belongs to a fleet (``site.json`` names a central store)
takes its floor's lease before it touches the graph, renews it every
``central.lease_renew`` seconds from a background thread, and deletes it when the pass
ends. A second robot's pass is refused (exit 2) naming the holder while the lease is held
and unexpired. A robot that died holding it blocks the floor for at most
``central.lease_ttl`` seconds; the same robot (by name) may take its own lease again at
once, to resume the pass it was running. Taking the lease also refuses a pass on a site
that lacks sessions the central store has (another robot ran a pass since the pull).

Taking the lease is one transaction under the floor's advisory lock, with expiry judged by
the database's clock (``now()``), so two robots racing for it never both win and no two
robots' clocks need to agree. ``BOMC_LEASE=skip`` runs a fleet site's pass without the
lease (a robot that is offline on purpose; the operator then answers for the floor).
"""

from __future__ import annotations

import os
import shlex
import socket
import sys
import threading
from pathlib import Path
from typing import Any

from bomc_bt.central import schema
from bomc_bt.central.connection import ENV, central_errors, connect, redact
from bomc_bt.central.identity import SiteIdentity, read_identity
from bomc_bt.central.params import CentralParams
from bomc_bt.errors import BomcError

SKIP_ENV = "BOMC_LEASE"


class FloorLease:
    """The held lease of one floor, renewed in the background until :meth:`release`."""

    def __init__(self, conninfo: str, identity: SiteIdentity, params: CentralParams):
        self.conninfo, self.identity, self.params = conninfo, identity, params
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.renew_errors = 0

    @property
    def key(self) -> tuple[str, str]:
        return self.identity.building, self.identity.floor

    def take(self, sessions: set[int], generation: int | None) -> FloorLease:
        conn = connect(self.conninfo, self.params.connect_timeout)
        try:
            schema.migrate(conn, redact(self.conninfo))
            with central_errors(self.conninfo, "take the floor lease"), conn.transaction():
                _take(conn, self.identity, self.params.lease_ttl, sessions, generation)
        finally:
            conn.close()
        self._thread = threading.Thread(target=self._renew_loop, name="bomc-lease", daemon=True)
        self._thread.start()
        return self

    def _renew_loop(self) -> None:
        while not self._stop.wait(self.params.lease_renew):
            try:
                self._execute("UPDATE bomc.leases SET expires_at = now() + make_interval(secs => %s)"
                              " WHERE building = %s AND floor = %s AND robot = %s",
                              (self.params.lease_ttl, *self.key, self.identity.robot))
            except BomcError as exc:  # offline for a while: the pass goes on, the lease may lapse
                self.renew_errors += 1
                print(f"bomc: warning: cannot renew the floor lease: {exc}", file=sys.stderr)

    def release(self) -> None:
        """Stop renewing and delete the lease (a failure only lets it expire)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        try:
            self._execute("DELETE FROM bomc.leases WHERE building = %s AND floor = %s AND robot = %s AND pid = %s",
                          (*self.key, self.identity.robot, os.getpid()))
        except BomcError as exc:
            print(f"bomc: warning: cannot release the floor lease (it expires by itself): {exc}", file=sys.stderr)

    def _execute(self, sql: str, args: tuple) -> None:
        conn = connect(self.conninfo, self.params.connect_timeout)
        try:
            with central_errors(self.conninfo, "renew the floor lease"), conn.transaction():
                conn.execute(sql, args)
        finally:
            conn.close()


def _take(conn: Any, me: SiteIdentity, ttl: float, sessions: set[int], generation: int | None) -> None:
    conn.execute("SELECT pg_advisory_xact_lock(hashtext(%s))", (f"bomc-floor/{me.building}/{me.floor}",))
    holder = conn.execute(
        "SELECT robot, host, pid, command, to_char(expires_at AT TIME ZONE 'UTC', 'YYYY-MM-DD HH24:MI:SS'),"
        " ceil(extract(epoch FROM expires_at - now())) FROM bomc.leases WHERE building = %s AND floor = %s"
        " AND expires_at > now()", (me.building, me.floor)).fetchone()
    if holder is not None and holder[0] != me.robot:
        robot, host, pid, command, until, left = holder
        raise BomcError(f"robot {robot!r} holds the lease of building {me.building!r} floor {me.floor!r} (pid {pid} "
                        f"on {host}: {command}) until {until} UTC ({int(left)} s): wait for its pass to end",
                        redact(conn.info.dsn), "leases")
    if generation is not None:
        central = {r[0] for r in conn.execute("SELECT number FROM bomc.sessions WHERE building = %s AND floor = %s"
                                              " AND generation = %s", (me.building, me.floor, generation))}
        missing = sorted(central - sessions)
        if missing:
            raise BomcError(f"the central store has session {missing[0]} of this floor that this site lacks: "
                            "`bomc pull` before the next pass", redact(conn.info.dsn), "sessions")
    conn.execute(
        "INSERT INTO bomc.leases (building, floor, robot, host, pid, command, taken_at, expires_at)"
        " VALUES (%s, %s, %s, %s, %s, %s, now(), now() + make_interval(secs => %s))"
        " ON CONFLICT (building, floor) DO UPDATE SET robot = EXCLUDED.robot, host = EXCLUDED.host,"
        " pid = EXCLUDED.pid, command = EXCLUDED.command, taken_at = now(), expires_at = EXCLUDED.expires_at",
        (me.building, me.floor, me.robot, socket.gethostname(), os.getpid(), _command_line(), ttl))


def _command_line() -> str:
    return " ".join(shlex.quote(a) for a in ["bomc", *sys.argv[1:]])[:500]


def take_floor_lease(root: Path, params: CentralParams, sessions: set[int], generation: int | None
                     ) -> FloorLease | None:
    """The floor's lease for a pass on ``root``; None for a site that is not part of a fleet (or BOMC_LEASE=skip)."""
    identity = read_identity(root)
    if identity is None or identity.central is None or os.environ.get(SKIP_ENV) == "skip":
        return None
    conninfo = os.environ.get(ENV) or identity.central
    return FloorLease(conninfo, identity, params).take(sessions, generation)
