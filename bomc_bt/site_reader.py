"""What the read-only commands read a site's graph through: a local ``site.db``, or a floor of the central store.

``bomc evaluate --site`` and ``bomc view`` take a site directory or a
``postgresql://host/db?building=B&floor=F`` URL (bomc_bt.central.connection); both give
an object with ``sessions()``, ``events()``, ``graph_after()``, ``close()`` and ``path``
(what an error message names).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bomc_bt.central.connection import is_central
from bomc_bt.errors import BomcError


def open_graph(site: str | Path) -> Any:
    """The site's graph store, read-only: a SiteStore or a CentralGraph."""
    if is_central(site):
        from bomc_bt.central.reader import CentralGraph

        return CentralGraph(str(site))
    from bomc_bt.site import Site
    from bomc_bt.store import SiteStore

    path = Site(Path(site)).store_path
    if not path.exists():
        raise BomcError("no object graph here: run `bomc monitor` first", path)
    return SiteStore(path, readonly=True)
