"""Where the central database is, and one place that turns its failures into one-line errors.

The connection string comes from the command line (``--to`` / ``--from``), else from the
``BOMC_CENTRAL`` environment variable, else from libpq's own ``PG*`` variables (``PGHOST``,
``PGDATABASE``, ``PGSERVICE``, ...); a password from ``PGPASSWORD`` or ``~/.pgpass``.
Never from a file in the repository. A site that was synchronised remembers the string
*without its password* in ``site.json`` (:mod:`bomc_bt.central.identity`).

A ``postgresql://`` *site* (``bomc evaluate --site``, ``bomc view``) names the floor in
the URL's query: ``postgresql://host:5432/db?building=hq&floor=2`` (optionally
``&generation=N``, default the floor's current map generation). Those keys are ours and
are taken out before the rest goes to libpq.

psycopg (3) is imported only here and only when a central store is used, so the rest of
bomc runs without it (``pip install 'bomc-bt[central]'``).
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qsl, urlencode, urlsplit, urlunsplit

from bomc_bt.errors import BomcError

ENV = "BOMC_CENTRAL"
SCHEMES = ("postgresql://", "postgres://")
SITE_KEYS = ("building", "floor", "generation")
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9 ._-]{0,99}$")


@dataclass(frozen=True)
class CentralSite:
    """A floor in the central store, named by a ``postgresql://...?building=B&floor=F`` site."""

    conninfo: str
    building: str
    floor: str
    generation: int | None = None

    @property
    def shown(self) -> str:
        return f"{redact(self.conninfo)} (building {self.building!r}, floor {self.floor!r})"


def is_central(site: object) -> bool:
    """Whether a site argument names the central store rather than a directory."""
    return str(site).startswith(SCHEMES)


def check_name(value: str, field: str, where: object = None) -> str:
    """A building, floor or robot name: 1-100 letters, digits, space, ``.``, ``_``, ``-``."""
    if not isinstance(value, str) or not NAME.match(value):
        raise BomcError(f"must be 1-100 letters, digits, spaces, '.', '_' or '-' (got {value!r})", where, field)
    return value


def parse_central_site(url: str) -> CentralSite:
    """Split our ``building`` / ``floor`` / ``generation`` keys off a ``postgresql://`` site URL."""
    parts = urlsplit(url)
    ours = {k: v for k, v in parse_qsl(parts.query, keep_blank_values=True) if k in SITE_KEYS}
    rest = [(k, v) for k, v in parse_qsl(parts.query, keep_blank_values=True) if k not in SITE_KEYS]
    shown = redact(url)
    for key in ("building", "floor"):
        if key not in ours:
            raise BomcError(f"a postgresql:// site names its floor: add ?building=B&floor=F to the URL "
                            f"(missing {key})", shown, key)
        check_name(ours[key], key, shown)
    generation = None
    if "generation" in ours:
        if not ours["generation"].isdigit() or not 1 <= int(ours["generation"]) < 10**9:
            raise BomcError(f"must be a map generation number, got {ours['generation']!r}", shown, "generation")
        generation = int(ours["generation"])
    conninfo = urlunsplit(parts._replace(query=urlencode(rest)))
    return CentralSite(conninfo, ours["building"], ours["floor"], generation)


def resolve(given: str | None, flag: str) -> str:
    """The connection string: ``given`` (a flag), else ``$BOMC_CENTRAL``, else libpq's PG* variables."""
    if given:
        return given
    if os.environ.get(ENV):
        return os.environ[ENV]
    if any(os.environ.get(v) for v in ("PGHOST", "PGDATABASE", "PGSERVICE")):
        return ""  # libpq fills everything from the environment
    raise BomcError(f"no central store given: pass {flag} postgresql://... or set {ENV} (or PGHOST / PGDATABASE)",
                    None, flag)


def redact(conninfo: str) -> str:
    """The connection string without its password (for messages and ``site.json``)."""
    if not conninfo:
        return "(the PG* environment)"
    if is_central(conninfo):
        parts = urlsplit(conninfo)
        netloc = parts.netloc.rsplit("@", 1)
        if len(netloc) == 2:
            netloc[0] = netloc[0].split(":", 1)[0]
        query = [(k, v) for k, v in parse_qsl(parts.query, keep_blank_values=True) if k != "password"]
        return urlunsplit(parts._replace(netloc="@".join(netloc), query=urlencode(query)))
    return re.sub(r"password\s*=\s*('(?:[^'\\]|\\.)*'|\S+)", "password=***", conninfo)


def remembered(conninfo: str) -> str:
    """What ``site.json`` keeps: the string without its password ("" when libpq's PG* variables gave it)."""
    return redact(conninfo) if conninfo else ""


def psycopg_module() -> Any:
    try:
        import psycopg
    except ImportError:
        raise BomcError("the central store needs psycopg 3: pip install 'psycopg[binary]' "
                        "(or install bomc-bt with the [central] extra)") from None
    return psycopg


def connect(conninfo: str, timeout: float = 10.0) -> Any:
    """An open psycopg connection (not autocommit: every unit of work is one transaction)."""
    psycopg = psycopg_module()
    with central_errors(conninfo, "connect"):
        return psycopg.connect(conninfo, connect_timeout=max(1, int(timeout)),
                               application_name="bomc")


@contextlib.contextmanager
def central_errors(conninfo: str, action: str) -> Iterator[None]:
    """psycopg failures (unreachable, refused, no such database) as a one-line BomcError."""
    psycopg = psycopg_module()
    try:
        yield
    except psycopg.Error as exc:
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise BomcError(f"central store error during {action}: {text}", redact(conninfo)) from None
