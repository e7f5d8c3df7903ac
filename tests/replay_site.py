"""A small generated office, built and monitored in session 1 with its timeline recorded.

Shared by the timeline tests and the viewer's replay and corrections tests (a 12 x 12 m
floor: the build and the pass take a few seconds). ``timeline_records`` reads the file
with the standard library only, so the tests check the recorder and the page against
the file itself, not against the code that reads it for the viewer.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from bomc_bt import run
from bomc_bt.officegen import OfficeParams, generate_office


def make_replay_site(root: Path) -> dict[str, Any]:
    """``root/office.yaml`` and ``root/site`` (built, session 1 monitored); the pass's result."""
    world = root / "office.yaml"
    generate_office(OfficeParams(width=12, height=12, seed=4, sessions=2), world)
    site = root / "site"
    config = run.build_config()
    assert run.run_build(world, site, seed=0, config=config).succeeded
    result = run.run_monitor(world, site, 1, seed=1, config=config)
    assert result.succeeded
    return {"world": world, "site": site, "sim_time": result.sim_time, "ticks": result.ticks}


def timeline_records(site: Path, session: int) -> list[dict[str, Any]]:
    path = site / "sessions" / str(session) / "timeline.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def status_at(records: list[dict[str, Any]], t: float) -> list[str]:
    """Each tree node's status letter at robot time ``t`` (``i`` before its first change)."""
    tree = [r for r in records if r["k"] == "tree"][-1]["n"]
    status = ["i"] * len(tree)
    for r in records:
        if r["k"] == "st" and r["t"] <= t:
            for index, letter, _ in r["c"]:
                status[index] = letter
    return status
