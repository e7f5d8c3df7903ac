"""A real PostgreSQL server for the central-store tests: Debian's ``initdb`` and ``pg_ctl``.

One server per test session, in a temporary folder, on a free loopback port, with trust
authentication for loopback only; every test gets its own fresh database
(:func:`central_url`). PostgreSQL refuses to run as root, so where the tests run as root
the server runs as the ``postgres`` system user that Debian's ``postgresql`` package
creates (``runuser -u postgres --``), in a folder owned by that user. Where PostgreSQL,
that user or psycopg is missing the tests skip and say which.
"""

from __future__ import annotations

import itertools
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest

_databases = itertools.count(1)


@dataclass
class PostgresServer:
    port: int
    folder: Path
    as_user: list[str]
    bindir: Path

    def url(self, database: str = "postgres") -> str:
        return f"postgresql://bomc@127.0.0.1:{self.port}/{database}"

    def create_database(self) -> str:
        import psycopg

        name = f"bomc_test_{os.getpid()}_{next(_databases)}"
        with psycopg.connect(self.url(), autocommit=True) as conn:
            conn.execute(f"CREATE DATABASE {name}")
        return self.url(name)


def _bindir() -> Path | None:
    found = shutil.which("initdb")
    if found:
        return Path(found).parent
    versions = sorted(Path("/usr/lib/postgresql").glob("*/bin/initdb"), key=lambda p: int(p.parts[-3]))
    return versions[-1].parent if versions else None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _as_user() -> tuple[list[str], int | None]:
    """The command prefix that runs the server as a non-root user, and that user's uid."""
    if os.geteuid() != 0:
        return [], None
    try:
        user = pwd.getpwnam("postgres")
    except KeyError:
        pytest.skip("running as root and there is no 'postgres' user to run PostgreSQL as "
                    "(apt-get install postgresql creates it)")
    if not shutil.which("runuser"):
        pytest.skip("running as root without runuser to start PostgreSQL as the 'postgres' user")
    return ["runuser", "-u", "postgres", "--"], user.pw_uid


def start_server() -> PostgresServer:
    try:
        import psycopg  # noqa: F401
    except ImportError:
        pytest.skip("psycopg 3 is not installed (pip install 'psycopg[binary]')")
    bindir = _bindir()
    if bindir is None:
        pytest.skip("PostgreSQL is not installed (apt-get install postgresql): no initdb")
    prefix, uid = _as_user()
    folder = Path(tempfile.mkdtemp(prefix="bomc-pg-"))
    folder.chmod(0o755)
    if uid is not None:
        os.chown(folder, uid, -1)
    data = folder / "data"
    run = lambda *args: subprocess.run([*prefix, *args], capture_output=True, text=True, timeout=120)  # noqa: E731
    made = run(str(bindir / "initdb"), "-D", str(data), "-A", "trust", "-U", "bomc", "-E", "UTF8", "--no-sync")
    if made.returncode != 0:
        shutil.rmtree(folder, ignore_errors=True)
        pytest.skip(f"initdb failed: {made.stderr.strip()[-300:]}")
    for _ in range(3):
        port = _free_port()
        options = (f"-p {port} -k {folder} -c listen_addresses=127.0.0.1 -c fsync=off "
                   "-c synchronous_commit=off -c full_page_writes=off")
        started = run(str(bindir / "pg_ctl"), "-D", str(data), "-l", str(folder / "log"), "-o", options, "-w",
                      "-t", "60", "start")
        if started.returncode == 0:
            return PostgresServer(port, folder, prefix, bindir)
    log = (folder / "log").read_text()[-300:] if (folder / "log").exists() else started.stderr
    shutil.rmtree(folder, ignore_errors=True)
    pytest.skip(f"pg_ctl could not start PostgreSQL: {log.strip()}")


def stop_server(server: PostgresServer) -> None:
    subprocess.run([*server.as_user, str(server.bindir / "pg_ctl"), "-D", str(server.folder / "data"), "-m",
                    "immediate", "-w", "stop"], capture_output=True, timeout=60)
    shutil.rmtree(server.folder, ignore_errors=True)


@pytest.fixture(scope="session")
def postgres():
    server = start_server()
    yield server
    stop_server(server)


@pytest.fixture
def central_url(postgres) -> str:
    """A fresh, empty database on the session's server."""
    return postgres.create_database()
