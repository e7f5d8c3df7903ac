"""The change model's heat map for the site viewer: ``/api/change_model``.

Per region of the map (:mod:`bomc_bt.change_model`): its rate of changes per pass, the
passes since a pass last saw it and the changes expected to be waiting there at the next
pass, with the map-frame square each covers, for the page to draw over the map
(``static/heatmap.js``); and per pass with a budget, the regions it skipped. Read-only:
the store is opened as every viewer opens it (nothing written).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bomc_bt.errors import BomcError


def change_model_json(site_dir: str | Path) -> dict[str, Any]:
    """The model as of the site's next pass; the uniform prior for a site with no history."""
    from bomc_bt.config import load_config
    from bomc_bt.grid import load_map
    from bomc_bt.site import Site
    from bomc_bt.store import SiteStore

    site = Site(Path(site_dir))
    if not site.map_yaml.exists():
        raise BomcError("no map: the change model needs a built site", site.root)
    grid = load_map(site.map_yaml)
    config = load_config()
    if not site.store_path.exists():
        model_json = _model(None, grid, config, 1)
    else:
        with SiteStore(site.store_path, readonly=True) as store:
            model_json = _model(store, grid, config, max((s.number for s in store.sessions()), default=0) + 1)
    return model_json


def _model(store, grid, config, session: int) -> dict[str, Any]:
    from bomc_bt.change_model import ChangeModel, RegionGrid

    if store is None:
        model = ChangeModel(RegionGrid(grid, config.budget.region_size), config.budget)
    else:
        from bomc_bt.budget_pass import load_model

        model = load_model(store, grid, config)
    out = model.to_json(session)
    out["max_waiting"] = max((r["waiting"] for r in out["regions"]), default=0.0)
    out["skipped"] = {} if store is None else skipped_by_session(store.sessions())
    return out


def skipped_by_session(sessions) -> dict[str, list[dict[str, Any]]]:
    """Per session with a budget (by number, as text for JSON): the regions its report says
    the pass did not see, with how stale each was left."""
    out = {}
    for s in sessions:
        budget = s.report.get("budget") if isinstance(s.report, dict) else None
        if isinstance(budget, dict) and budget.get("seconds") and not budget.get("full_pass"):
            out[str(s.number)] = list(budget.get("skipped_regions") or [])
    return out
