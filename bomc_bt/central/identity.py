"""Who a site is in the fleet: ``<site>/site.json`` with its building, floor and robot.

::

    {"building": "hq", "floor": "2", "robot": "fetch-1", "central": "postgresql://bomc@db/fleet"}

``building`` and ``floor`` say which floor of the central store the site's rows belong to,
``robot`` who pushes and runs passes from this copy, ``central`` where it was last synced
or pulled from (the connection string without its password, ``""`` when libpq's ``PG*``
variables gave it; ``$BOMC_CENTRAL`` overrides it). A site with ``central`` set (not null)
is part of a fleet: its monitor passes take the floor's lease (:mod:`bomc_bt.central.lease`).

The file is an extension of the site layout (CONTRACTS.md 3 leaves everything but the map
and trajectory to us). It is written by the first ``bomc sync`` (from ``--building`` /
``--floor`` / ``--robot``, or defaulted: the site folder's name, floor ``1``, the host
name) and by ``bomc pull``; afterwards a flag that contradicts it is refused, since a
site that changed floor would mix two floors' graphs.
"""

from __future__ import annotations

import re
import socket
from dataclasses import asdict, dataclass
from pathlib import Path

from bomc_bt.atomic import atomic_write
from bomc_bt.central.connection import check_name
from bomc_bt.errors import BomcError

FILENAME = "site.json"
DEFAULT_FLOOR = "1"


@dataclass(frozen=True)
class SiteIdentity:
    building: str
    floor: str
    robot: str
    central: str | None = None


def identity_path(root: Path) -> Path:
    return Path(root) / FILENAME


def read_identity(root: Path) -> SiteIdentity | None:
    """The site's identity, or None for a site that was never synchronised or pulled."""
    from bomc_bt.site import read_json

    path = identity_path(root)
    if not path.exists():
        return None
    data = read_json(path)
    if not isinstance(data, dict):
        raise BomcError("expected a JSON object with building, floor and robot", path)
    values = {}
    for key in ("building", "floor", "robot"):
        values[key] = check_name(data.get(key), key, path)
    central = data.get("central")
    if central is not None and not isinstance(central, str):
        raise BomcError("must be a connection string or null", path, "central")
    return SiteIdentity(**values, central=central)


def settle_identity(root: Path, building: str | None, floor: str | None, robot: str | None,
                    central: str | None) -> SiteIdentity:
    """The identity from ``site.json`` and the flags (nothing is written: :func:`save_identity`).

    A flag that contradicts the file is an error; ``central`` replaces the remembered one.
    """
    path = identity_path(root)
    known = read_identity(root)
    given = {"building": building, "floor": floor, "robot": robot}
    for key, value in given.items():
        if value is not None:
            check_name(value, f"--{key}")
            if known is not None and getattr(known, key) != value:
                raise BomcError(f"this site is {key} {getattr(known, key)!r}, not {value!r} (site.json); a site "
                                "never changes floor: pull the other floor into a new folder", path, key)
    if known is None:
        known = SiteIdentity(building or default_building(root), floor or DEFAULT_FLOOR, robot or default_robot())
    return SiteIdentity(known.building, known.floor, known.robot, central if central is not None else known.central)


def save_identity(root: Path, identity: SiteIdentity) -> None:
    """Write ``site.json`` (atomically) when it does not already say ``identity``."""
    import json

    if identity == read_identity(root):
        return
    atomic_write(identity_path(root), (json.dumps(asdict(identity), indent=2) + "\n").encode())


def default_building(root: Path) -> str:
    name = re.sub(r"[^A-Za-z0-9 ._-]", "-", Path(root).resolve().name).lstrip(" ._-")[:100]
    return check_name(name or "site", "--building", root)


def default_robot() -> str:
    name = re.sub(r"[^A-Za-z0-9._-]", "-", socket.gethostname()).lstrip("._-")[:100]
    return name or "robot"
